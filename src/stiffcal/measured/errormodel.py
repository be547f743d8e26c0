"""The error model of measured rows: which reference reading each displacement was taken from, the errors
that rows share because of it (variance components, estimated by REML), and the generalised least squares
that every fit and test of :mod:`stiffcal.measured.discrepancy` then uses.

A laser tracker logs readings; a lab's row is the difference of two: the loaded reading and the protocol's
unloaded *reference reading* of the same target. Where a reference serves several rows, its error enters all
of them; where a later visit of a configuration is measured against a reference read on an earlier visit,
the robot's return error (its pose repeatability) enters every row of that visit too. Labs do all of these:

- **per load**: every load its own unloaded reading just before it (rows independent);
- **per visit**: one unloaded reading at the start of a visit, shared by the visit's loads (hanging masses, a
  loading bar, a hand-held gauge), often with a return-to-zero row at the end;
- **per configuration**: one reading at the first visit, the later visits (a second pass, shuffled or
  relabelled) measured against it.

**The structure** (:func:`reading_structure`) comes from the ``reference`` and ``visit`` columns when the lab
logs them, else from what the rows show: a reference logged as a row of exact zeros starts a reference for
its target at its configuration, and every later row of that target there (in time order: ``timestamp_s``,
else the file's order) is measured from it, whatever the visit; a visit is a run of consecutive rows at one
configuration (ended by a change of configuration or ``pose_id``, by an exact-zero row after loaded rows, or by
a load repeated after a return-to-zero row, the next visit then beginning at the exact-zero rows logged between
the two: a configuration that ends one pass and begins the next). Exact-zero rows are the reference itself and
never a noise sample. Where no exact-zero row says which reading a row was taken from, the model holds both hypotheses
(a reference per visit and one per configuration) and lets the data weigh them, at the configurations whose
rows can show a shared error (unloaded rows with noise, or several visits); rows of other configurations
(one visit, no unloaded row) are taken as independent, as nothing in them could tell a shared reference
from a misfit of the model.

**The components**, each a random effect per group, independent between groups (Searle, Casella & McCulloch,
*Variance Components*, 1992, ch. 6):

- ``reference`` (a known reference reading: its rows), ``visit`` and ``configuration`` (per visit, per
  configuration, where the reference is not known), of every target apart: the reference reading's error, one
  effect per measured component (x, y (, z), and the weighted rotation), of variance ``lambda sigma_i^2``
  relative to the row's own noise (the same tracker at the same place);
- ``return``: the robot's pose error on a visit measured against another visit's reference, a joint error
  ``dq ~ N(0, lambda sigma_0^2 I)`` (sigma_0 the noise of the median row) that moves every target and the
  rotation of the visit's rows through the arm's Jacobian at the configuration, normalised so that the tool
  point's displacement has the variance ``lambda sigma_0^2`` per coordinate on average everywhere
  (:func:`return_loading`: the
  repeatability is stated as a distance of the tool point, ISO 9283): in metres whatever the tracker's noise,
  and as anisotropic as the arm (a planar arm near a stretched pose hardly moves along its links);
- ``load_direction``: a load whose direction scatters push by push about the logged one (a hand-held gauge held
  off its axis): one effect per loaded row, the push turned by a small random angle, whose loading is the
  deflection of the turned part of the load through the nominal model's compliance (:func:`load_direction`);
  in radians, reported as the push's RMS angle.

Rows of different configurations are independent, so the covariance is block diagonal by configuration: on
the rows weighted by the tracker's noise model and flattened row by row, coordinate by coordinate,
``V_c = sigma^2 (I + sum_k lambda_k Z_ck Z_ck^T)`` with ``Z = Z_group (x) I_w`` for the reference readings and
the group's loadings for the return.

**Estimation** by restricted maximum likelihood (Patterson & Thompson 1971; Harville, *JASA* 72, 1977) on the
residuals of the union of every catalogue cause, the unloaded rows (of mean zero) included: the union holds any
catalogue effect, so none of them is read as a shared error, and the whole data set informs the components (the
pure error's contrasts alone hold too little of a reference shared by a configuration: the lack-of-fit tests on
them were anticonservative, 7 % at 1 % on a protocol with a reference per configuration). An effect outside the
catalogue can only make a component larger (its lack of fit then harder to see), not smaller. Our own
implementation, for speed and for the structure statsmodels' ``MixedLM`` (univariate, unweighted, no loadings
across the measured components) does not take: per configuration H = I + Z Lambda Z^T has a few columns, so
every likelihood is the Woodbury identity on sufficient statistics reduced once (Z^T Z, Z^T Y, Z^T X per block;
the fixed effects in an orthonormal basis), about a millisecond for a 6-axis data set; it is checked against
``MixedLM`` and against the dense likelihood in the tests. A component's
likelihood-ratio p-value is against the boundary mixture 1/2 chi^2_0 + 1/2 chi^2_1 (Self & Liang, *JASA* 82,
1987).

**Generalised least squares.** The loaded rows are taken conditionally on the unloaded ones (which have no
regressor, so the likelihood of the compliances factors through that conditional: y_L - B y_U with covariance
H_LL - H_LU H_UU^-1 H_UL, B = H_LU H_UU^-1), and whitened by the symmetric inverse square root of that
covariance per configuration (a row stays mostly itself, so residual diagnostics keep their rows). Every fit,
F-test, interval and leave-one-configuration-out prediction of the analysis is then ordinary least squares on
the whitened rows; the error variance on its degrees of freedom comes from the whitened pure error (with the
unloaded rows), else from the union of all extensions.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import distributions as dist
from ..errors import InputError
from .measurements import rows_by_label

#: a component is estimated only where its groups have some row left after the fixed effects (relative norm)
IDENTIFIABLE_RTOL = 1e-8
#: fewest groups of a component for its variance to be estimated: one group's shared error is one draw, which REML
#: cannot tell from the noise with any reliability (a fresh user's log with one reference row lost: a 'visit'
#: component of one group, estimated at zero, inflated every parameter's Kenward-Roger variance by 287 %); lme4
#: refuses a grouping factor of one level for the same reason (Bates et al., J. Stat. Softw. 67(1), 2015, sec. 2.2)
MIN_COMPONENT_GROUPS = 2
#: largest variance ratio searched (a shared error 1000 times the row's own noise is not a tracker's)
MAX_RATIO = 1e6
#: variance inflation (:func:`variance_inflation`) above which the verdict says the plug-in understates the
#: parameters' variances
INFLATION_NOTE = 0.1
#: relative singular value below which a direction of a design counts as absent (as stiffcal.measured.discrepancy)
RANK_RTOL = 1e-9
#: fewest degrees of freedom of the replicates' pure error (and the unloaded rows) for it to be the error variance
#: while the residuals of the union of all extensions have more: an F test at 1 % on 20 denominator degrees of
#: freedom needs a ratio 1.2 times the one on infinitely many (8.10 against 6.63); a chance pair of replicates (a
#: hand-held gauge's push that repeats another's force within the force resolution) gives 3
MIN_PURE_ERROR_DF = 20


KINDS = {"reference": "one known reference reading (its rows)",
         "visit": "one visit (where the reference is not known)",
         "configuration": "one configuration (where the reference is not known)",
         "return": "the robot's return to the configuration on a visit measured against another visit's reference",
         "load_direction": "one load (its direction scattered about the logged one: a hand-held gauge off its axis)"}


# --- which reading each row was taken from ---------------------------------------------------------------------

@dataclass(frozen=True)
class Component:
    """One variance component: ``label`` (R,) int, the group of every model row (-1: not in it); ``absolute``:
    its variance is in metres whatever the tracker's noise (the return's pose error; else relative to the
    row's noise, the reference reading's error); ``loading`` (R, w, r) or None: the motion of every row's
    measured components per unit of the group's effect (the return: the robot's joint error, through the
    Jacobian of what the row measures; the load's direction: the deflection of the load turned about each axis),
    else None: one independent effect per measured component; ``unit`` [m]: the loading's scale (the effect's
    standard deviation is sqrt(lambda) sigma / unit in the effect's own unit: rad for the load's direction);
    ``shared``: an error that rows share through a reading or a pose (a group of one row is then its own noise and
    is not a component), else an effect of each row of its own (the load's direction: one group per row, which is
    no reference reading)."""
    name: str
    label: np.ndarray
    absolute: bool = False
    loading: np.ndarray | None = None
    unit: float = 1.0
    shared: bool = True

    @property
    def n_groups(self) -> int:
        return int(self.label.max(initial=-1)) + 1


@dataclass(frozen=True)
class ReadingStructure:
    """Which reference reading every row's displacement was taken from (module docstring).

    Model rows (R = N + M): the loaded rows used (N, in the order of the measurements) then the unloaded rows
    that carry noise (M: not exact zeros, at a configuration with loaded rows, not blunders); ``zero_index``
    (M,) their indices into ``Measurements.zero_rows``; ``block`` (R,) int the configuration of every model row
    (configurations are independent); ``visit`` (R,) int; ``components``; ``kind`` what the references are
    ("independent", "load", "visit", "configuration", "mixed", "unknown: from the row order" or
    :data:`SCATTERED_KIND`); ``source`` how it was found; counts: visits, configurations visited more than once,
    known references, exact-zero reference rows; ``notes``; ``time`` (R,) [s] every model row's time (or file
    order) and ``ref_time`` (R,) that of the reading it was taken from (the exact-zero reference row; where it is
    not known, the first row of the visit)."""
    n_loaded: int
    zero_index: np.ndarray
    block: np.ndarray
    visit: np.ndarray
    components: tuple[Component, ...]
    kind: str
    source: str
    n_visits: int
    n_revisited: int
    n_references: int
    n_exact_rows: int
    notes: tuple[str, ...] = ()
    time: np.ndarray | None = None
    ref_time: np.ndarray | None = None

    @property
    def n_rows(self) -> int:
        return len(self.block)

    def as_dict(self) -> dict:
        return {"kind": self.kind, "source": self.source, "n_visits": int(self.n_visits),
                "n_configurations_revisited": int(self.n_revisited), "n_known_references": int(self.n_references),
                "n_exact_zero_rows": int(self.n_exact_rows), "n_unloaded_rows_used": int(len(self.zero_index))}


def _file_rows(meas, keep: np.ndarray, zero_out) -> dict:
    """Every data row the structure looks at (loaded rows ``keep``, unloaded rows but ``zero_out``), with what the
    file says of it (:class:`stiffcal.measured.measurements.RowLog`, or the row order for measurements made in
    memory)."""
    loaded_idx = np.flatnonzero(keep)
    zero_idx = np.setdiff1d(np.arange(len(meas.zero_rows)), np.asarray(zero_out, int))
    log = meas.log
    file_l, file_u = meas.rows[loaded_idx], meas.zero_rows[zero_idx]
    n_file = max(int(np.max(meas.rows, initial=-1)), int(np.max(meas.zero_rows, initial=-1))) + 1
    if log is None:  # in memory: the row order, one target per row, configurations as the measurements have them
        zero_dp = meas.zero_dp if meas.zero_rot is None else np.hstack([meas.zero_dp, meas.zero_rot])
        get = {"time": np.arange(n_file, dtype=float), "label": None, "visit": None, "reference": None}
        config = np.full(n_file, -1)
        config[meas.rows] = meas.config
        config[meas.zero_rows] = meas.zero_config
        target = np.zeros(n_file, int)
        target[meas.rows] = meas.target
        exact = np.zeros(n_file, bool)
        exact[meas.zero_rows] = np.all(zero_dp == 0.0, axis=1)
        group = np.full(n_file, -1)
        group[meas.rows] = meas.group
    else:
        get = {"time": log.time, "label": log.label, "visit": log.visit, "reference": log.reference}
        config, target, exact, group = log.config, log.target, log.exact, log.group
    rows = np.concatenate([file_l, file_u])
    loaded = np.concatenate([np.ones(len(file_l), bool), np.zeros(len(file_u), bool)])
    first = {int(c): i for i, c in reversed(list(enumerate(meas.config)))}  # a loaded row of every configuration
    zero_q = np.array([meas.q[first[int(c)]] if int(c) in first else np.full(meas.q.shape[1], np.nan)
                       for c in meas.zero_config[zero_idx]]).reshape(-1, meas.q.shape[1])
    return {"rows": rows, "loaded": loaded, "loaded_idx": loaded_idx, "zero_idx": zero_idx,
            "time": get["time"][rows], "label": None if get["label"] is None else get["label"][rows],
            "visit": None if get["visit"] is None else get["visit"][rows],
            "reference": None if get["reference"] is None else get["reference"][rows],
            "config": config[rows], "target": target[rows], "exact": exact[rows], "group": group[rows],
            "q": np.vstack([meas.q[loaded_idx], zero_q]), "target_names": tuple(meas.target_names)}


def _visits(f: dict) -> np.ndarray:
    """(n,) int: the visit of every row of :func:`_file_rows` (module docstring), numbered in time order."""
    n = len(f["rows"])
    order = np.lexsort((f["rows"], f["time"]))
    visit = np.full(n, -1)
    if f["visit"] is not None:
        keys = {}
        for i in order:
            visit[i] = keys.setdefault((int(f["config"][i]), f["visit"][i]), len(keys))
        return visit
    cur, prev, seen, closed, zeros = -1, None, set(), False, []
    for i in order:
        repeated = bool(f["loaded"][i] and closed and f["group"][i] in seen)
        new = (prev is None or f["config"][i] != f["config"][prev]
               or (f["label"] is not None and f["label"][i] != f["label"][prev])
               or (f["exact"][i] and f["loaded"][prev]) or repeated)
        if new:
            cur, seen, closed = cur + 1, set(), False
            if repeated:  # the next visit began at the reference reading logged after the return-to-zero row
                visit[zeros] = cur  # (the robot left and came back between the two)
        zeros = zeros + [i] if f["exact"][i] and closed else []
        if f["loaded"][i]:
            seen.add(int(f["group"][i]))
        elif seen and not f["exact"][i]:
            closed = True  # a return-to-zero row: a load repeated after it starts the next visit
        visit[i] = cur
        prev = i
    return visit


def _references(f: dict, visit: np.ndarray) -> tuple[np.ndarray, np.ndarray, str | None]:
    """(reference (n,) int, -1 where not known; visit holding each reference's reading; how they were found)."""
    n = len(f["rows"])
    ref = np.full(n, -1)
    holder = []
    order = np.lexsort((f["rows"], f["time"]))
    if f["reference"] is not None:
        keys = {}
        for i in order:
            k = (int(f["config"][i]), int(f["target"][i]), f["reference"][i])
            if k not in keys:
                keys[k] = len(keys)
                holder.append(visit[i])
            ref[i] = keys[k]
        return ref, np.array(holder, int), "the reference column"
    if not f["exact"].any():
        return ref, np.zeros(0, int), None
    current = {}
    for i in order:
        k = (int(f["config"][i]), int(f["target"][i]))
        if f["exact"][i]:
            current[k] = len(holder)
            holder.append(visit[i])
        if k in current:
            ref[i] = current[k]
    return ref, np.array(holder, int), "the exact-zero reference rows"


def _renumber(label: np.ndarray) -> np.ndarray:
    """Labels (-1: none) renumbered 0.. in order of first appearance, -1 kept."""
    out = np.full(len(label), -1)
    keys = {}
    for i, v in enumerate(label.tolist() if label.dtype != object else label):
        if v == -1 or v is None:
            continue
        out[i] = keys.setdefault(v if not isinstance(v, np.ndarray) else tuple(v), len(keys))
    return out


def _pairs(a: np.ndarray, b: np.ndarray, where: np.ndarray) -> np.ndarray:
    """Group labels of the pairs (a_i, b_i) where ``where``, -1 elsewhere."""
    lab = np.full(len(a), -1)
    keys = {}
    for i in np.flatnonzero(where):
        lab[i] = keys.setdefault((int(a[i]), int(b[i])), len(keys))
    return lab


def _shared_reference_evidence(f: dict, visit: np.ndarray, model: np.ndarray) -> set[int]:
    """The configurations whose rows show a shared reference where no exact-zero row or column says which
    reading a row was taken from: unloaded rows with noise (readings against the reference), or several visits;
    elsewhere nothing in the data could tell it from the model's own misfit."""
    evidence = set()
    in_config = rows_by_label(f["config"])
    for c in np.unique(f["config"][model]):
        at = in_config[c]
        loaded = f["loaded"][at]
        if (~loaded & ~f["exact"][at]).any() or len(np.unique(visit[at][loaded])) > 1:
            evidence.add(int(c))
    return evidence


def _reference_times(f: dict, visit: np.ndarray, ref: np.ndarray, known: np.ndarray) -> np.ndarray:
    """The time of each file row's reference reading: its known reference's exact-zero row (else that reference's
    first row), or the start of its visit."""
    start = {}
    for i in np.lexsort((f["rows"], f["time"])):
        start.setdefault(int(visit[i]), f["time"][i])
    ref_time = np.array([start[int(v)] for v in visit], float)
    for r in np.unique(ref[known]):
        rows = ref == r
        ref_time[rows] = f["time"][rows & f["exact"]].min() if (rows & f["exact"]).any() else f["time"][rows].min()
    return ref_time


def reading_structure(meas, keep: np.ndarray, zero_out=(), motion=None, turn=None) -> ReadingStructure:
    """The :class:`ReadingStructure` of the loaded rows ``keep`` (bool (N,)) of ``meas`` and its unloaded rows but
    ``zero_out`` (indices into ``zero_rows``: blunders among them), from the ``reference`` and ``visit``
    columns, the exact-zero reference rows, the ``pose_id`` labels and the time order (module docstring).

    motion: ``motion(q (R, n) [rad], target (R,)) -> (R, w, n)``, the motion of what each model row measures
    per unit joint error at its configuration (the return's loading, :func:`return_loading`), or None: the
    return taken as an independent error per measured component.

    turn: (N, w, A) [m/rad] the deflection of every loaded row kept (in the order of ``keep``) per unit angle of
    its load turned about each of A axes (:func:`stiffcal.measured.discrepancy.turned_load_deflections`): the
    component ``load_direction``, one group per loaded row (:func:`load_direction`); None: no such component."""
    f = _file_rows(meas, np.asarray(keep, bool), zero_out)
    loaded_cfg = set(f["config"][f["loaded"]].tolist())
    at_loaded = np.array([c in loaded_cfg for c in f["config"]])
    model = f["loaded"] | (~f["exact"] & at_loaded)  # rows with noise, at a configuration with loads
    scattered = _scattered_runs(f, meas)
    visit, ref, holder, how, evidence = _visits_and_references(f, model, scattered)
    first_visit = {}
    for i in np.lexsort((f["rows"], f["time"])):
        first_visit.setdefault(int(f["config"][i]), visit[i])
    known = ref >= 0
    comps = []
    if known.any():
        comps.append(Component("reference", _renumber(np.where(known & model, ref, -1))))
    unknown = ~known & model & np.array([int(c) in evidence for c in f["config"]])
    if unknown.any():
        comps.append(Component("visit", _pairs(visit, f["target"], unknown)))
        comps.append(Component("configuration", _pairs(f["config"], f["target"], unknown)))
    away = np.where(known, visit != np.where(known, holder[np.maximum(ref, 0)] if len(holder) else -1, -1),
                    unknown & (visit != np.array([first_visit[int(c)] for c in f["config"]])))
    comps.append(Component("return", _renumber(np.where(away & model, visit, -1)), absolute=True))
    # the model rows: loaded first (in the measurements' order), then the unloaded rows with noise
    idx = np.flatnonzero(model)
    loading = None if motion is None else motion(f["q"][idx], f["target"][idx])
    comps = [Component(c.name, _renumber(c.label[idx]), c.absolute, loading if c.name == "return" else None)
             for c in comps]
    if turn is not None:
        comps.append(load_direction(np.asarray(turn, float), len(idx)))
    comps = _pruned(comps)
    cfg = f["config"][idx]
    block = _renumber(cfg)
    kind = _kind(f, ref, visit, known, holder) if any(c.shared for c in comps) else "independent"
    kind = SCATTERED_KIND if scattered is not None and kind != "independent" else kind
    source = (how or ("the visit column" if f["visit"] is not None else "the row order"
                      + (" (timestamp_s)" if meas.log is not None and meas.log.has_time else "")))
    if how and f["visit"] is not None and "visit" not in how:  # a reviewer could not tell the column was read
        source = f"the visit column and {how}"
    visits_at = {}
    for c, v in zip(f["config"][f["loaded"]], visit[f["loaded"]]):
        visits_at.setdefault(int(c), set()).add(int(v))
    zero_model = model[~f["loaded"]]
    ref_time = _reference_times(f, visit, ref, known)
    return ReadingStructure(int(f["loaded"].sum()), f["zero_idx"][zero_model], block, _renumber(visit[idx]),
                            tuple(comps), kind, source, len(set(visit[f["loaded"]].tolist())),
                            sum(len(v) > 1 for v in visits_at.values()), len(holder), int(f["exact"].sum()),
                            tuple(_label_notes(f, visit) + _lost_reference_notes(f, ref, how)
                                  + _scattered_rows_notes(scattered)),
                            np.asarray(f["time"][idx], float), ref_time[idx])


#: the error model's kind where rows scattered through a file without a clock share one error per configuration
SCATTERED_KIND = "unknown: per configuration (rows scattered)"
#: runs of consecutive rows per configuration (on average) beyond which rows without timestamps or visit columns
#: look sorted or shuffled: a lab's protocols visit a configuration once or twice (passes), three times at most
SCATTERED_RUNS = 3.0


def _scattered_runs(f: dict, meas) -> tuple[int, int] | None:
    """(runs, configurations) where the file has no ``timestamp_s``, ``visit`` or ``reference`` column and its rows of
    a configuration are scattered through it (more than :data:`SCATTERED_RUNS` runs of consecutive rows per
    configuration, not in rounds over the configurations in one order, :func:`_rounds`: sorted or shuffled rows),
    else None. The row order is then no clock: a fresh user's shuffled gauge log read as 102 visits for 18
    configurations, another's shuffled log of a reference per configuration raised a tilted load and a load offset
    (p = 0.002 and 1.5e-5) that the intact log did not."""
    if (meas.log is not None and meas.log.has_time) or f["visit"] is not None or f["reference"] is not None:
        return None
    config = f["config"][np.argsort(f["rows"], kind="stable")]
    n_configs = len(np.unique(config))
    order = config[np.r_[True, config[1:] != config[:-1]]] if len(config) else config  # the configuration of each run
    if not n_configs or len(order) <= SCATTERED_RUNS * n_configs or _rounds(order) >= ROUNDS_SHARE:
        return None
    return len(order), n_configs


#: the share of a file's runs of one configuration followed by that configuration's most frequent successor at or
#: above which the runs are rounds over the configurations in one order (a protocol, not a shuffle)
ROUNDS_SHARE = 0.5


def _rounds(order: np.ndarray) -> float:
    """The share of the runs ``order`` (the configuration of each run of consecutive rows, in file order) whose
    successor is their configuration's most frequent one: about 1 for rounds over the configurations in one order
    (every load measured at every configuration in turn: a fresh user's 2R log, 95 runs for 12 configurations), about
    1/runs-per-configuration for shuffled rows."""
    if len(order) < 2:
        return 1.0
    pairs = np.stack([order[:-1], order[1:]], axis=1)
    kinds, counts = np.unique(pairs, axis=0, return_counts=True)
    best = {}
    for (a, _), c in zip(kinds, counts):
        best[int(a)] = max(best.get(int(a), 0), int(c))
    return sum(best.values()) / len(pairs)


def _scattered_rows_notes(scattered: tuple[int, int] | None) -> list[str]:
    """The note on rows scattered through the file (:func:`_scattered_runs`)."""
    if scattered is None:
        return []
    runs, n_configs = scattered
    return [f"the rows of a configuration are scattered through the file ({runs} runs of consecutive rows for "
            f"{n_configs} configurations) and it has no timestamp_s, visit or reference column: the row order is no "
            "clock (sorted or shuffled rows?), so each configuration's rows are taken to share one unknown reference "
            "error, whatever visits and reference readings they came from; log timestamp_s (or visit and reference) to "
            "make the protocol known"]


def _lost_reference_notes(f: dict, ref: np.ndarray, how: str | None) -> list[str]:
    """A note naming the loaded rows that no exact-zero reference row precedes at their configuration and target,
    where the exact-zero rows give the other rows' references (no ``reference`` or ``visit`` column:
    :func:`_visit_column_notes` says it with one) and most loaded rows have one: a reference row lost (a fresh
    user's log without its columns and one zero row deleted was read in silence, as an unlogged reference of its
    own)."""
    if how != "the exact-zero reference rows" or f["visit"] is not None:
        return []
    lost = f["loaded"] & (ref < 0)
    if not lost.any() or lost.sum() >= f["loaded"].sum() / 2:
        return []
    from .measurements import _rows_text

    where = ""
    if f["label"] is not None:  # the configurations and targets by the file's names (a fresh user had only rows)
        pairs = sorted({(str(f["label"][i]), int(f["target"][i])) for i in np.flatnonzero(lost)})
        names = f.get("target_names") or ()
        where = " (" + ", ".join(f"{c}" + (f" target {names[t]}" if len(names) > 1 else "") for c, t in pairs[:4]) \
            + (" ..." if len(pairs) > 4 else "") + ")"
    return [f"{_rows_text(np.sort(f['rows'][lost]))}{where} have no exact-zero reference row before them at their "
            "configuration, while most loaded rows do: a reference row lost? They are read as measured from an "
            "unlogged reference reading of their own"]


def _visits_and_references(f: dict, model: np.ndarray, scattered) -> tuple:
    """(visit (n,), reference (n,) (-1: not known), the visit holding each reference, how they were found, the
    configurations whose rows show a shared reference) of :func:`_file_rows`' rows; where the rows are scattered
    (:func:`_scattered_runs`) the row order is no clock: one visit, of an unknown reference, per configuration."""
    if scattered is None:
        visit = _visits(f)
        ref, holder, how = _references(f, visit)
        return visit, ref, holder, how, _shared_reference_evidence(f, visit, model)
    evidence = set(np.unique(f["config"][model]).tolist()) if f["exact"].any() else set()
    return (_renumber(f["config"]), np.full(len(f["rows"]), -1), np.zeros(0, int),
            "the configurations (rows scattered: the row order is no clock)", evidence)


def _label_notes(f: dict, visit: np.ndarray) -> list[str]:
    """Notes where the ``visit`` or ``reference`` column and the exact-zero reference rows disagree: a visit label
    holding two reference readings of one target (two visits under one label?), reference labels without an
    exact-zero row beside labels with one (a typo?). The exact-zero rows decide which reading a row was taken from
    only where no ``reference`` column is given."""
    notes = _visit_column_notes(f, visit) if f["visit"] is not None else _repeated_load_notes(f, visit)
    exact = np.flatnonzero(f["exact"])
    if f["visit"] is not None and exact.size:
        kinds, per = np.unique(np.column_stack([visit[exact], f["target"][exact]]), axis=0, return_counts=True)
        if (per > 1).any():
            twice = [_visit_name(f, visit, int(v)) for v in np.unique(kinds[per > 1, 0])]
            notes.append(f"{int((per > 1).sum())} visit(s) of the visit column hold two or more reference readings "
                         f"(exact-zero rows) of one target ({'; '.join(twice[:3])}{' ...' if len(twice) > 3 else ''}): "
                         "each reference reading is taken as the start of a "
                         "reference of its own, the visits as the column says; if the robot left and came back "
                         "between them, give each return a visit label of its own (the robot's return error is "
                         "modelled per visit)")
    if f["reference"] is not None and exact.size:
        def keys(rows):  # (configuration, target, reference label) of each row
            return {(int(f["config"][i]), int(f["target"][i]), str(f["reference"][i])) for i in rows}
        orphan = sorted({label for _, _, label in keys(np.flatnonzero(~f["exact"])) - keys(exact)})
        if orphan:
            notes.append(f"reference label(s) {', '.join(orphan[:5])}{' ...' if len(orphan) > 5 else ''} have no "
                         "exact-zero row while other labels do: a reference row lost, or a typo? Their rows are taken "
                         "as measured from an unlogged reading of their own, one per label")
    return notes


def _repeated_load_notes(f: dict, visit: np.ndarray) -> list[str]:
    """Without a ``visit`` column: a note naming the visits (read from the row order) that hold every one of their
    loads two or more times where more visits hold each once (a fresh user's shuffled second pass began at the
    configuration the first ended at, its reference reused: two visits back to back, read as one, in silence; a
    protocol that repeats every load within every visit is not named)."""
    from .measurements import _rows_text

    loaded = np.flatnonzero(f["loaded"])
    twice, once = [], 0
    for v in np.unique(visit[loaded]):
        mine = loaded[visit[loaded] == v]
        _, counts = np.unique(f["group"][mine], return_counts=True)
        if counts.min() >= 2:
            twice.append(_rows_text(np.sort(f["rows"][visit == v])))
        once += int(counts.max() == 1)
    if not twice or len(twice) >= once:
        return []
    return [f"{len(twice)} visit(s) read from the row order hold each of their loads two or more times with no "
            f"reference reading between ({'; '.join(twice[:3])}{' ...' if len(twice) > 3 else ''}): two visits back to "
            "back (the robot leaving and returning to the configuration)? They are read as one visit, whose loads "
            "repeat within it; a visit column tells them apart"]


def _visit_name(f: dict, visit: np.ndarray, v: int) -> str:
    """'label 1 at configuration C05 (rows 34, 35 (data rows 32, 33))': the visit v of :func:`_visits` as the file
    gives it (its configuration by its ``pose_id``, else by its first row)."""
    from .measurements import _rows_text

    mine = visit == v
    at = f"configuration {f['label'][mine][0]}" if f["label"] is not None else "the configuration of its rows"
    return f"label {f['visit'][mine][0]} at {at} ({_rows_text(np.sort(f['rows'][mine]))})"


def _visit_column_notes(f: dict, visit: np.ndarray) -> list[str]:
    """Notes where the ``visit`` column disagrees with the rows (a fresh user's IRB 6700 logs, read in silence):
    visits without an exact-zero reference row of a target they measure where most visits of their kind (the first
    at a configuration, or a later one) have one (a reference row lost: a later visit with none is the protocol of a
    reference per configuration); visit labels whose rows are not consecutive in time (rows of other visits between
    them: one label used for two visits?); and consecutive visits at one configuration with no other between them,
    the second without a reference reading of its own, one of the two labels used at that configuration alone (one
    visit split under two labels? Labels of passes, each at many configurations, meet at one where a shuffled pass
    begins where the last ended: a helper's Z1 log). ``visit`` (n,): the
    visits of :func:`_visits`."""
    order = np.lexsort((f["rows"], f["time"]))
    first_at = {}
    for i in order:
        first_at.setdefault((int(f["config"][i]), int(f["target"][i])), int(visit[i]))
    label = {int(visit[i]): str(f["visit"][i]) for i in order}
    measured = {(int(visit[i]), int(f["target"][i]), first_at[(int(f["config"][i]), int(f["target"][i]))] == visit[i])
                for i in np.flatnonzero(f["loaded"])}
    with_zero = {(int(visit[i]), int(f["target"][i])) for i in np.flatnonzero(f["exact"])}
    lost = []
    for kind in (True, False):  # the first visits at a configuration, then the later ones
        mine = [(v, t) for v, t, first in measured if first == kind]
        has = [k for k in mine if k in with_zero]
        if len(has) > len(mine) / 2:
            lost += [v for v, t in mine if (v, t) not in with_zero]
    notes = []
    if lost:
        lost = [_visit_name(f, visit, v) for v in sorted(set(lost))]
        notes.append(f"the visit(s) {'; '.join(lost[:3])}{' ...' if len(lost) > 3 else ''} have no "
                     "exact-zero reference row of a target they measure, while most visits of their kind do: a "
                     "reference row lost, or a label that splits a visit? "
                     + ("The reference column says which reading their rows were taken from" if f["reference"]
                        is not None else "Their rows are read against the last reference of their target at their "
                        "configuration before them (else as measured from an unlogged reading of their own)"))
    runs = [int(order[0])] + [int(b) for a, b in zip(order[:-1], order[1:]) if visit[a] != visit[b]] if len(order) \
        else []
    seen = [int(visit[i]) for i in runs]  # a visit is a configuration and a label: labels may repeat across them
    split = [_visit_name(f, visit, v) for v in sorted({v for v in seen if seen.count(v) > 1})]
    if split:
        notes.append(f"the visit(s) {'; '.join(split[:3])}{' ...' if len(split) > 3 else ''} hold rows that are not "
                     "consecutive in time (rows of other visits between them): one label used for two visits? Rows of "
                     "one configuration and label are read as one visit")
    own = {v for v, _ in with_zero}  # a visit that begins with its own reference reading is a new visit
    at: dict = {}  # label -> the configurations it labels: a label at several is a pass's (a shuffled second pass
    for c, lab in zip(f["config"], f["visit"]):  # may begin where the first ended: two passes, not a split visit)
        at.setdefault(str(lab), set()).add(int(c))
    twice = [f"{label[int(visit[a])]} and {label[int(visit[b])]}" for a, b in zip(runs[:-1], runs[1:])
             if f["config"][a] == f["config"][b] and int(visit[b]) not in own
             and min(len(at[label[int(visit[a])]]), len(at[label[int(visit[b])]])) == 1]
    if twice:
        notes.append(f"visit labels {', '.join(twice[:3])}{' ...' if len(twice) > 3 else ''} follow each other at one "
                     "configuration with no other configuration between them: one visit split under two labels? (A "
                     "new visit is the robot brought back to the configuration; its return error is modelled per "
                     "visit)")
    return notes


def return_loading(jacobian: np.ndarray, tool_jacobian: np.ndarray) -> np.ndarray:
    """(R, w, n): the loading of the return component, the Jacobian of what each row measures ``jacobian``
    (R, w, n) [m/rad, rotation rows weighted as the rows are] scaled by sqrt(d) / ||J_tool||_F with
    ``tool_jacobian`` (R, d, n) [m/rad] the tool point's position Jacobian at the row's configuration: a joint
    error N(0, lambda sigma_0^2 I) then moves the tool point with the variance lambda sigma_0^2 per coordinate
    on average at every configuration, its repeatability (RMS distance, ISO 9283 sec. 7.2.2) the same
    everywhere, and every target and the rotation move with it as the arm's geometry says. A zero tool Jacobian
    (the arm cannot move its tool point) leaves the loading unscaled."""
    d = tool_jacobian.shape[1]
    norm = np.sqrt(np.einsum("rdn,rdn->r", tool_jacobian, tool_jacobian))
    return jacobian * (np.sqrt(d) / np.where(norm > 0, norm, 1.0))[:, None, None]


def load_direction(turn: np.ndarray, n_rows: int) -> Component:
    """The component of a load whose direction scatters push by push about the logged one (a hand-held gauge held
    off the axis it logs, a swinging mass): a push turned by a small random angle theta about the axes a normal to
    its force F adds the deflection C(q) (a x F) theta (C the compliance at the pose), one independent effect per
    loaded row with the loading ``turn`` (N, w, A) [m/rad] (the first N of the ``n_rows`` model rows; zero on the
    unloaded rows, which carry no load), scaled by c, the loadings' RMS over the rows' coordinates. A push turned by
    theta (RMS) about a random axis normal to it adds the covariance theta_rms^2 / k C (|F|^2 I - F F^T) C^T,
    k = A - 1 = 2 axes normal to a spatial force (k = 1 in the plane, A = 1), and the component lambda sigma^2 / c^2
    times the same sum over the A axes: the component's unit is c / sqrt(k), so that sqrt(lambda) sigma / unit is
    the push's RMS angle [rad] whatever its axis."""
    N, w, A = turn.shape
    loading = np.zeros((n_rows, w, A))
    loading[:N] = turn
    c = float(np.sqrt(np.sum(turn**2) / max(N * w, 1)))
    label = np.full(n_rows, -1)
    label[:N] = np.arange(N)
    if not c > 0:
        return Component("load_direction", label, absolute=True, loading=loading, shared=False)
    return Component("load_direction", label, absolute=True, loading=loading / c, unit=c / np.sqrt(max(A - 1, 1)),
                     shared=False)


def independent(n_loaded: int) -> ReadingStructure:
    """The structure of n_loaded rows taken as independent (no shared reference, no unloaded row)."""
    t = np.arange(n_loaded, dtype=float)
    return ReadingStructure(n_loaded, np.zeros(0, int), np.zeros(n_loaded, int), np.arange(n_loaded), (),
                            "independent", "given", n_loaded, 0, 0, 0, (), t, t)


def _pruned(comps: list[Component]) -> list[Component]:
    """The components that can be estimated: a shared error with some group of two or more rows (a group of one
    is noise of its own row), an effect of each row's own (``shared`` False) with some nonzero loading; each
    partition once (a visit that is the whole configuration is one component)."""
    out, seen = [], []
    for c in comps:
        counts = np.bincount(c.label[c.label >= 0]) if (c.label >= 0).any() else np.zeros(0, int)
        if not np.any(counts >= (2 if c.shared else 1)) or not (c.shared or np.any(c.loading)):
            continue
        key = (c.absolute, c.loading is not None, tuple(c.label.tolist()))
        if key in seen:
            continue
        seen.append(key)
        out.append(c)
    return out


def _kind(f: dict, ref: np.ndarray, visit: np.ndarray, known: np.ndarray, holder: np.ndarray) -> str:
    """What the references are: per load, per visit, per configuration (across visits), mixed, or unknown."""
    if not known.any():
        return "unknown: from the row order"
    kinds = set()
    for r in np.unique(ref[known]):
        rows = (ref == r) & f["loaded"]
        if rows.sum() <= 1:
            kinds.add("load")
        elif len(np.unique(visit[ref == r])) > 1:
            kinds.add("configuration")
        else:
            kinds.add("visit")
    if (~known & f["loaded"]).any():
        kinds.add("unknown")
    if kinds == {"visit", "configuration"}:  # a configuration's reference; some configurations visited once
        return "configuration"
    return kinds.pop() if len(kinds) == 1 else "mixed"


# --- restricted maximum likelihood -------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Batch:
    """Blocks with the same random-effect columns (m of them, by component), reduced once for the Woodbury
    identity H^-1 = I - Z D (I + D Z^T Z D)^-1 D Z^T, D = diag(sqrt(lambda)) per column (Henderson; Searle et
    al. 1992, sec. 6.9), the rows flattened: comp (m,) the component of each column; ZtZ (B, m, m); ZtY (B, m);
    ZtX (B, m, p)."""
    comp: np.ndarray
    ZtZ: np.ndarray
    ZtY: np.ndarray
    ZtX: np.ndarray


def _fixed(block: dict) -> np.ndarray:
    """A block's fixed effects: the union's regressors X and the further ones D (when given), side by side."""
    return block["X"] if block.get("D") is None else np.concatenate([block["X"], block["D"]], axis=-1)


@dataclass
class _Likelihood:
    """The REML log-likelihood of a variance-components model over independent blocks (module docstring),
    from sufficient statistics reduced once: with H = I + Z Lambda Z^T per block, every term needs only the small
    matrices of :class:`_Batch` and the totals Y^T Y, X^T Y, X^T X (columns of X scaled to unit norm), the rows
    flattened row by row, coordinate by coordinate."""
    batches: list
    yty: float
    xty: np.ndarray
    xtx: np.ndarray
    n_obs: int
    rank: int

    @classmethod
    def of(cls, blocks: list[dict], comps: list[int]) -> "_Likelihood":
        """blocks: per configuration ``Y`` (n, w), ``Z`` {k: (n w, m)}, ``X`` (n, w, p) and ``D`` (n, w, k) or None
        (the fixed effects, :func:`_fixed`); comps: the components' indices (their lambdas, in this order)."""
        fixed = [_fixed(b) for b in blocks]
        scale = np.sqrt(sum(np.einsum("nwp,nwp->p", X, X) for X in fixed))  # unit norm, as discrepancy.fit
        scale[scale == 0] = 1.0
        stacked = np.concatenate([(X / scale).reshape(-1, X.shape[-1]) for X in fixed])
        _, sv, Vt = np.linalg.svd(stacked, full_matrices=False)
        rank = int(np.sum(sv > RANK_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        T = Vt[:rank].T / sv[:rank] / scale[:, None]  # X T: an orthonormal basis of the fixed effects' span
        yty, xty = 0.0, np.zeros(rank)
        by_size: dict[tuple, list] = {}
        for b, X in zip(blocks, fixed):
            X = (X @ T).reshape(-1, rank)
            Y = b["Y"].ravel()
            yty += float(Y @ Y)
            xty += X.T @ Y
            parts = [(i, b["Z"][k]) for i, k in enumerate(comps) if k in b["Z"]]
            if not parts:
                continue
            Z = np.hstack([z for _, z in parts])
            comp = np.concatenate([np.full(z.shape[1], i) for i, z in parts])
            by_size.setdefault(tuple(comp), []).append((Z.T @ Z, Z.T @ Y, Z.T @ X))
        batches = [_Batch(np.array(key, int), np.stack([p[0] for p in v]), np.stack([p[1] for p in v]),
                          np.stack([p[2] for p in v])) for key, v in by_size.items()]
        n_obs = sum(b["Y"].size for b in blocks)
        return cls(batches, yty, xty, np.eye(rank), n_obs, rank)

    def parts(self, lam: np.ndarray, gradient: bool = False):
        """(log|H| summed over blocks, log det M up to a constant, residual quadratic form Q), M = X^T H^-1 X in
        the orthonormal basis of the fixed effects (full rank); with ``gradient`` also (t, u), each (K,): the
        derivatives d(log|H| + log det M)/d lambda_k = tr(Z_k^T P Z_k) and dQ/d lambda_k = -||Z_k^T P y||^2,
        P = H^-1 - H^-1 X M^-1 X^T H^-1 (Harville 1977, eqs. 4.2-4.3), from the same reduced statistics."""
        lam = np.asarray(lam, float)
        logdet, Q = 0.0, self.yty
        M, b = self.xtx.copy(), self.xty.copy()
        kept = []
        for bt in self.batches:
            d = np.sqrt(lam[bt.comp])  # (m,)
            C = np.eye(len(d)) + d[None, :, None] * bt.ZtZ * d[None, None, :]
            L = np.linalg.cholesky(C)
            logdet += 2.0 * float(np.log(np.diagonal(L, axis1=1, axis2=2)).sum())
            a = d[None, :] * bt.ZtY  # (B, m)
            bx = d[None, :, None] * bt.ZtX  # (B, m, p)
            Ci = np.linalg.inv(C)  # C = I + D Z^T Z D is well conditioned; inv and a product beat a stacked solve
            sol = Ci @ np.concatenate([a[:, :, None], bx], axis=2)
            sa, sx = sol[:, :, 0], sol[:, :, 1:]
            Q -= float((a * sa).sum())
            flat = bx.reshape(-1, bx.shape[-1])
            M -= flat.T @ sx.reshape(-1, bx.shape[-1])
            b -= flat.T @ sa.reshape(-1)
            if gradient:
                kept.append((bt, d, Ci, sa, sx))
        logdet_M, beta = 0.0, np.zeros(self.rank)
        if self.rank:
            LM = np.linalg.cholesky(M)
            logdet_M = 2.0 * float(np.log(np.diagonal(LM)).sum())
            z = np.linalg.solve(LM, b)
            Q -= float(z @ z)
            if gradient:
                beta = np.linalg.solve(LM.T, z)  # M^-1 X^T H^-1 y
        if not gradient:
            return logdet, logdet_M, max(Q, 1e-300)
        t, u = np.zeros(len(lam)), np.zeros(len(lam))
        Minv = np.linalg.inv(M) if self.rank else np.zeros((0, 0))
        for bt, d, Ci, sa, sx in kept:
            # Woodbury: Z^T H^-1 A = Z^T A - G D C^-1 D Z^T A, G = Z^T Z, for A = Z, y, X
            GD = bt.ZtZ * d[None, None, :]  # (B, m, m)
            ZHZ = bt.ZtZ - GD @ Ci @ np.swapaxes(GD, 1, 2)
            ZHy = bt.ZtY - np.einsum("bij,bj->bi", GD, sa)
            ZHX = bt.ZtX - GD @ sx
            Pz = ZHy - ZHX @ beta  # Z^T P y (B, m)
            tr = np.einsum("bii->bi", ZHZ) - np.einsum("bip,bip->bi", ZHX @ Minv, ZHX)  # diag of Z^T P Z
            np.add.at(t, bt.comp, tr.sum(axis=0))
            np.add.at(u, bt.comp, -(Pz ** 2).sum(axis=0))
        return logdet, logdet_M, max(Q, 1e-300), t, u

    @property
    def df(self) -> int:
        return self.n_obs - self.rank

    def loglik(self, lam: np.ndarray, sigma2: float | None = None) -> float:
        """The REML log-likelihood (constants dropped) at the variance ratios lam (K,), sigma^2 profiled out (or
        fixed at ``sigma2``)."""
        return self._value(*self.parts(lam), sigma2)

    def loglik_and_gradient(self, lam: np.ndarray, sigma2: float | None = None) -> tuple[float, np.ndarray]:
        """(:meth:`loglik`, its gradient (K,) in lam) at lam, from one pass over the blocks."""
        logdet, logdet_M, Q, t, u = self.parts(lam, gradient=True)
        return (self._value(logdet, logdet_M, Q, sigma2),
                -0.5 * (t + (self.df / Q if sigma2 is None else 1.0 / sigma2) * u))

    def _value(self, logdet: float, logdet_M: float, Q: float, sigma2: float | None) -> float:
        if sigma2 is None:
            return -0.5 * (logdet + logdet_M + self.df * np.log(Q / self.df))
        return -0.5 * (logdet + logdet_M + self.df * np.log(sigma2) + Q / sigma2)

    def sigma2(self, lam: np.ndarray) -> float:
        return self.parts(lam)[2] / max(self.df, 1)


def _maximise(lik: _Likelihood, k: int, sigma2: float | None = None, fixed: dict | None = None,
              start: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(lam (k,), log-likelihood) at the REML estimate over lam >= 0 (L-BFGS-B with the analytic gradient of
    :meth:`_Likelihood.loglik_and_gradient`, from two starts, on
    log(1 + lam) so that both small and large ratios are found; from ``start`` alone when given); ``fixed``
    {index: value} held."""
    from scipy.optimize import minimize

    fixed = fixed or {}
    free = [i for i in range(k) if i not in fixed]
    top = np.log1p(MAX_RATIO)  # the bound of x = log(1 + lam)

    def full(x):
        lam = np.zeros(k)
        for i, v in fixed.items():
            lam[i] = v
        lam[free] = np.expm1(np.clip(x, 0.0, top))
        return lam

    def objective(x):
        """-loglik and its gradient in x (lam = expm1(x): d lam / d x = 1 + lam; zero beyond the clip)."""
        lam = full(x)
        try:
            value, grad = lik.loglik_and_gradient(lam, sigma2)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros(len(free))
        inside = (x >= 0.0) & (x <= top)
        return -value, np.where(inside, -grad[free] * (1.0 + lam[free]), 0.0)

    if not free:
        lam = full(np.zeros(0))
        return lam, lik.loglik(lam, sigma2)
    best = None
    starts = (np.zeros(len(free)), np.full(len(free), np.log(2.0))) if start is None else (np.log1p(start[free]),)
    for x0 in starts:
        res = minimize(objective, x0, jac=True, method="L-BFGS-B", bounds=[(0.0, top)] * len(free),
                       options={"ftol": 1e-12, "gtol": 1e-8, "maxiter": 200})
        if best is None or res.fun < best.fun:
            best = res
    lam = full(best.x)
    lam[np.abs(lam) < 1e-9] = 0.0
    return lam, -float(best.fun)


# --- the error model -------------------------------------------------------------------------------------------

def _apply(M: np.ndarray, A: np.ndarray, n_out: int | None = None) -> np.ndarray:
    """M (n_out w, n w) applied to the rows of A (n, w, ...) flattened row by row, coordinate by coordinate:
    (n_out, w, ...)."""
    n, w = A.shape[:2]
    rest = A.shape[2:]
    return (M @ A.reshape(n * w, -1)).reshape((n if n_out is None else n_out, w) + rest)


@dataclass(frozen=True)
class ErrorModel:
    """The fitted error model of one data set (module docstring).

    structure: :class:`ReadingStructure`; ratios (K,): lambda of each component (0: not needed, or not
    estimable); estimable (K,) bool; p_values (K,): likelihood-ratio p of each component (None where not
    estimable); stage: what the variance components were estimated on; sigma2 [m^2 of the median row], df,
    source: the error variance the tests use; ss_pe, df_pe: the whitened pure error of the loaded rows;
    blocks: per configuration ``(loaded rows (n_L,), unloaded model rows (n_U,), W (n_L w, n_L w), B (n_L w,
    n_U w))`` with W = H_{L|U}^{-1/2} and B = H_LU H_UU^-1 on the rows flattened row by row, coordinate by
    coordinate (only for configurations whose rows share an error);
    q_unloaded: the unloaded rows' quadratic form y_U^T H_UU^-1 y_U, on df_unloaded; notes; inflation: the largest
    relative increase of a parameter combination's variance from estimating the components
    (:func:`variance_inflation`; the intervals take them as known, the tests do not: ``small_sample``)."""
    structure: ReadingStructure
    ratios: np.ndarray
    estimable: np.ndarray
    p_values: tuple
    stage: str
    sigma2: float
    df: int
    source: str
    ss_pe: float
    df_pe: int
    blocks: tuple
    q_unloaded: float
    df_unloaded: int
    notes: tuple[str, ...] = ()
    zero_y: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    inflation: float = 0.0
    #: the Kenward-Roger quantities of the fixed effects (:class:`KenwardRoger`; None: no component in use, or not
    #: computed), with which the tests take the components' estimation into account (:meth:`KenwardRoger.f_test`)
    small_sample: "KenwardRoger | None" = field(default=None, repr=False, compare=False)
    #: ``estimate(..., lrt="deferred")``: the callable that computes (p_values, inflation) (:func:`with_tests`)
    pending: object = field(default=None, repr=False, compare=False)
    #: ((Y, groups, X_union, weights), blocks): the per-configuration arrays :func:`estimate` built from those very
    #: inputs (without a drift), reused by :func:`unloaded_tests` when it is given the same objects
    arrays: tuple | None = field(default=None, repr=False, compare=False)
    #: the REML log-likelihood at the estimate (sigma^2 profiled out; Harville's, of the weighted rows)
    loglik: float = float("nan")

    @property
    def shared(self) -> bool:
        """Some rows share an error (the fits are generalised least squares)."""
        return bool(np.any(self.ratios > 0))

    def whiten(self, A: np.ndarray) -> np.ndarray:
        """(N, w, ...) the loaded rows (weighted by the noise model) -> W A per configuration (GLS; a regressor
        is zero on the unloaded rows, so it needs no conditioning)."""
        out = np.array(A, float, copy=True)
        for rows, _, W, _ in self.blocks:
            out[rows] = _apply(W, out[rows])
        return out

    def whiten_observations(self, Y: np.ndarray) -> np.ndarray:
        """(N, w) the loaded rows' observations (weighted) -> W (y_L - B y_U): conditional on the unloaded rows."""
        return self.whiten(self.adjusted(Y))

    def whiten_columns(self, A: np.ndarray, A_unloaded: np.ndarray) -> np.ndarray:
        """(N, w, k) regressors of the loaded rows with their values on the unloaded model rows (M, w, k) (a
        regressor that is not zero there, such as a drift) -> W (A_L - B A_U) per configuration."""
        out = np.array(A, float, copy=True)
        for rows, zrows, W, B in self.blocks:
            block = out[rows] - _apply(B, A_unloaded[zrows], len(rows)) if len(zrows) else out[rows]
            out[rows] = _apply(W, block)
        return out

    def adjusted(self, Y: np.ndarray) -> np.ndarray:
        """(N, w): y_L - B y_U, the loaded rows less the shared error the unloaded rows predict (weighted)."""
        out = np.array(Y, float, copy=True)
        for rows, zrows, _, B in self.blocks:
            if len(zrows):
                out[rows] -= _apply(B, self.zero_y[zrows], len(rows))
        return out

    def components(self) -> dict:
        """The verdict's ``error_model.components``: per component its groups, sd [m of the median row]
        (sqrt(lambda) sigma), ratio, likelihood-ratio p and whether it could be estimated."""
        out = {}
        for c, lam, est, p in zip(self.structure.components, self.ratios, self.estimable, self.p_values):
            out[c.name] = {"groups": c.n_groups, "what": KINDS[c.name], "ratio": float(lam),
                           "sd_m": float(np.sqrt(lam * self.sigma2)), "p_value": p, "estimable": bool(est)}
            if c.name == "load_direction":
                out[c.name]["angle_rms_deg"] = float(np.degrees(np.sqrt(lam * self.sigma2) / c.unit))
        return out

    def as_dict(self) -> dict:
        return {**self.structure.as_dict(), "components": self.components(), "estimated_on": self.stage,
                "method": "REML (variance components; generalised least squares for every fit)",
                "shared_error": self.shared, "variance_inflation": self.inflation}


def _group_columns(comp: Component, rows: np.ndarray, weights: np.ndarray, w: int) -> np.ndarray | None:
    """(n w, m): the columns of component ``comp``'s random effects on a block's model rows ``rows`` (n,), the
    rows flattened row by row, coordinate by coordinate; None where no row is in it. Without a loading: one
    effect per group and measured component (Z (x) I_w; entries 1, or the row's weight for a component in
    metres); with one: per group the rows' weighted loadings, reduced to their column space (the same
    covariance Z Z^T with as few columns as its rank)."""
    lab = comp.label[rows]
    if not (lab >= 0).any():
        return None
    g, inv = np.unique(lab[lab >= 0], return_inverse=True)
    inv = inv.ravel()
    on = np.flatnonzero(lab >= 0)
    scale = weights[rows][on] if comp.absolute else np.ones(len(on))
    n = len(rows)
    if comp.loading is None:
        M = np.zeros((n, len(g)))
        M[on, inv] = scale
        return kron_eye(M, w)
    if len(g) == len(on):  # a group per row (the load's direction): the rows' SVDs at once
        U, sv, _ = np.linalg.svd(comp.loading[rows[on]] * scale[:, None, None], full_matrices=False)
        kept = (sv > RANK_RTOL * sv[:, :1]) & (sv > 0)  # (k, s)
        j, t = np.nonzero(kept[np.argsort(inv)])  # groups in label order, as below
        j = np.argsort(inv)[j]
        out = np.zeros((n, w, len(j)))
        out[on[j], :, np.arange(len(j))] = U[j, :, t] * sv[j, t][:, None]
        return out.reshape(n * w, -1)
    cols = []
    for j in range(len(g)):
        mine = on[inv == j]
        Z = np.zeros((n, w, comp.loading.shape[-1]))
        Z[mine] = comp.loading[rows[mine]] * scale[inv == j][:, None, None]
        U, sv, _ = np.linalg.svd(Z.reshape(n * w, -1), full_matrices=False)
        r = int(np.sum(sv > RANK_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        cols.append(U[:, :r] * sv[:r])
    return np.hstack(cols)


def _block_arrays(structure: ReadingStructure, Y: np.ndarray, groups: np.ndarray, X: np.ndarray | None,
                  weights: np.ndarray, drift: np.ndarray | None = None) -> list[dict]:
    """Per configuration: rows (n,), Y (n, w), Z {k: (n w, m)} (:func:`_group_columns`), L (n, l) the replicate
    groups of the loaded rows (zero on the unloaded rows), X (n, w, p), D (n, w, k) further fixed effects on
    every model row (``drift``, (R, w, k)) or None."""
    N = structure.n_loaded
    w = Y.shape[1]
    blocks = []
    for rows in rows_by_label(structure.block):
        Z = {}
        for k, comp in enumerate(structure.components):
            cols = _group_columns(comp, rows, weights, w)
            if cols is not None and cols.shape[1]:
                Z[k] = cols
        lr = rows[rows < N]
        gl, inv = np.unique(groups[lr], return_inverse=True)
        L = np.zeros((len(rows), len(gl)))
        L[np.arange(len(lr)), inv.ravel()] = 1.0
        Xb = None
        if X is not None:
            Xb = np.zeros((len(rows), w, X.shape[-1]))
            Xb[: len(lr)] = X[lr]
        blocks.append({"rows": rows, "Y": Y[rows], "Z": Z, "L": L, "X": Xb,
                       "D": None if drift is None else drift[rows]})
    return blocks


def _covariance(block: dict, lam: np.ndarray) -> np.ndarray:
    """(n w, n w): H = I + sum_k lambda_k Z_k Z_k^T of a block's flattened rows (the rows' covariance over
    sigma^2)."""
    n, w = block["Y"].shape
    H = np.eye(n * w)
    for k, Z in block["Z"].items():
        H += lam[k] * (Z @ Z.T)
    return H


def kron_eye(M: np.ndarray, w: int) -> np.ndarray:
    """(n w, g w): the Kronecker product M (x) I_w of M (n, g), equal to ``np.kron(M, np.eye(w))`` to the bit for
    an M without negative entries (kron writes M_ij * 0 off the diagonal: -0.0 for a negative M_ij, 0.0 here),
    without its general broadcasting (about 6x faster on the analysis's small blocks)."""
    n, g = M.shape
    out = np.zeros((n * w, g * w), dtype=np.result_type(M, 1.0))
    view = out.reshape(n, w, g, w)
    for a in range(w):
        view[:, a, :, a] = M
    return out


def flat_index(rows, w: int) -> np.ndarray:
    """The flattened indices (row by row, coordinate by coordinate) of rows (k,) of w components each."""
    return (np.asarray(rows)[:, None] * w + np.arange(w)).ravel()


def _estimable(blocks: list[dict], K: int) -> list[int]:
    """The components (of K) that have rows left after the fixed effects (their columns Z, flattened, not in the
    fixed effects' span)."""
    X = np.concatenate([_fixed(b).reshape(-1, _fixed(b).shape[-1]) for b in blocks])
    norm = np.linalg.norm(X, axis=0)
    Q = _basis(X / np.where(norm > 0, norm, 1.0))
    sizes = np.cumsum([0] + [b["Y"].size for b in blocks])
    out = []
    for k in range(K):  # |Z - Q Q^T Z|^2 = |Z|^2 - |Q^T Z|^2, the columns of Z block by block (linear in the rows)
        mine = [(Q[sizes[i]: sizes[i + 1]], b["Z"][k]) for i, b in enumerate(blocks) if k in b["Z"]]
        if not mine:
            continue
        total = sum(float((z**2).sum()) for _, z in mine)
        kept = sum(float(((Qi.T @ z) ** 2).sum()) for Qi, z in mine)
        if total > 0 and total - kept > IDENTIFIABLE_RTOL * total:
            out.append(k)
    return out


def estimate(structure: ReadingStructure, Y: np.ndarray, weights: np.ndarray, groups: np.ndarray,
             X_union: np.ndarray | None, drift: np.ndarray | None = None, lrt: bool = True,
             start: "ErrorModel | None" = None) -> ErrorModel:
    """The :class:`ErrorModel` of the model rows (module docstring).

    Y (R, w): every model row's measured components, weighted by the noise model (rows multiplied by
    ``weights`` (R,), 1/sigma_i relative to the median row) and the rotation by sigma_m / sigma_rad; groups
    (N,) the loaded rows' replicate groups; X_union (N, w, p): the loaded rows' regressors of the union of
    every catalogue cause, weighted; drift (R, w, k): further fixed effects on every model row, in every stage (a
    tracker's drift, so that it is not read as a shared error); lrt: compute each component's likelihood-ratio
    p-value (else None) and, without a drift, the variance inflation (:func:`variance_inflation`; else 0);
    ``"deferred"``: not yet, but when :func:`with_tests` is called on the result (the same numbers; a fit that
    may be refitted pays for them once); start: an error model of nearly the same rows whose ratios start the
    likelihood's maximisation (:func:`_maximise`; else its two cold starts). Raises :class:`InputError` when no
    degree of freedom is left for the noise."""
    N, R = structure.n_loaded, structure.n_rows
    K = len(structure.components)
    w = Y.shape[1]
    blocks = _block_arrays(structure, Y, groups, X_union, weights, drift)
    paired = np.bincount(groups).max(initial=0) >= 2 if len(groups) else False
    df_pe = (N - len(np.unique(groups)) + R - N) * w if paired else 0  # before whitening
    lam = np.zeros(K)
    estimable = np.zeros(K, bool)
    pvals: list = [None] * K
    notes = []
    if X_union is None:
        raise InputError("no regressors: the noise cannot be estimated")
    est = [k for k in _estimable(blocks, K) if structure.components[k].n_groups >= MIN_COMPONENT_GROUPS]
    lik = _Likelihood.of(blocks, est)
    if lik.df <= 0:
        raise InputError("no degree of freedom is left to estimate the noise")
    lam_u, ll_u = _maximise(lik, len(est), start=_warm_start(start, structure, est))
    lam[est] = lam_u
    estimable[est] = True

    def tests() -> tuple[tuple, "KenwardRoger | None"]:  # the components' likelihood-ratio p-values, Kenward-Roger
        for i, k in enumerate(est):
            pvals[k] = _lrt(lik, lam_u, ll_u, i, None)
        return tuple(pvals), kenward_roger(blocks, lam, _in_use(structure, lam, estimable)) if drift is None else None

    sigma2 = lik.sigma2(lam_u)
    replicated = paired and df_pe >= min(MIN_PURE_ERROR_DF, lik.df)
    if paired and not replicated:
        notes.append(f"the replicates leave only {df_pe} degrees of freedom of pure error (fewer than "
                     f"{MIN_PURE_ERROR_DF}): the noise is estimated from the residuals of the union of all extensions "
                     f"({lik.df} degrees of freedom) instead, and the lack of fit is tested as without replicates")
    stage = "the residuals of the union of all extensions" + (", with the unloaded rows" if R > N else "")
    source = ("replicates (pure error)" + (" and the unloaded rows" if R > N else "") if replicated
              else "residuals of the union of all extensions" + (" and the unloaded rows" if R > N else ""))
    notes += _left_out_notes(structure, estimable)
    em = _finish(structure, blocks, lam, estimable, tuple(pvals), stage, sigma2, None if replicated else lik.df,
                 source, w, notes, Y[N:])
    em = replace(em, arrays=((Y, groups, X_union, weights), blocks) if drift is None else None, loglik=ll_u)
    if lrt == "deferred":
        return replace(em, pending=tests)
    return with_tests(replace(em, pending=tests)) if lrt else em


def _left_out_notes(structure: ReadingStructure, estimable: np.ndarray) -> list[str]:
    """A note per component :func:`estimate` could not estimate, and why."""
    out = []
    for comp, ok in zip(structure.components, estimable):
        if not ok:
            why = ("it has one group only: one draw of it cannot be told from the noise"
                   if comp.n_groups < MIN_COMPONENT_GROUPS else "the fixed effects absorb it")
            out.append(f"a shared error per {KINDS[comp.name]} cannot be estimated from these data ({why}): it is "
                       "left out")
    return out


def _in_use(structure: ReadingStructure, lam: np.ndarray, estimable: np.ndarray) -> np.ndarray:
    """(K,) bool: the components :func:`kenward_roger` counts: those estimated above zero, and a shared error the data
    can estimate at zero too (not an effect of each row of its own, the load's direction)."""
    return np.array([lam[k] > 0 or (estimable[k] and c.shared) for k, c in enumerate(structure.components)], bool)


def _warm_start(prior: "ErrorModel | None", structure: ReadingStructure, est: list) -> np.ndarray | None:
    """The variance ratios (len(est),) of ``prior`` for the components ``est`` of ``structure`` (matched by name; 0
    where ``prior`` has none), or None without a prior."""
    if prior is None:
        return None
    ratios = {c.name: lam for c, lam, ok in zip(prior.structure.components, prior.ratios, prior.estimable) if ok}
    return np.array([ratios.get(structure.components[k].name, 0.0) for k in est], float)


def with_tests(em: ErrorModel) -> ErrorModel:
    """``em`` with the tests :func:`estimate` deferred (``lrt="deferred"``): each component's likelihood-ratio
    p-value and the variance inflation; ``em`` itself when none are pending."""
    if em.pending is None:
        return em
    pvals, kr = em.pending()
    return replace(em, p_values=pvals, inflation=0.0 if kr is None else kr.largest_inflation, small_sample=kr,
                   pending=None)


def _lrt(lik: _Likelihood, lam: np.ndarray, ll: float, i: int, sigma2, fixed: dict | None = None) -> float:
    """The likelihood-ratio p-value of component i (lam_i = 0) against 1/2 chi^2_0 + 1/2 chi^2_1 (the others
    re-estimated from their values at the full estimate)."""
    if lam[i] == 0:
        return 1.0
    _, ll0 = _maximise(lik, len(lam), sigma2, {**(fixed or {}), i: 0.0}, start=lam)
    stat = max(2.0 * (ll - ll0), 0.0)
    return float(0.5 * dist.chi2_sf(stat, 1)) if stat > 0 else 1.0


def _finish(structure, blocks, lam, estimable, pvals, stage, sigma2, df_union, source, w, notes,
            zero_y) -> ErrorModel:
    """The whitening of every block, the whitened pure error and the unloaded rows' quadratic form; the error
    variance: with replicates the whitened pure error and the unloaded rows (their REML estimate), else the
    union's (``sigma2`` on ``df_union``)."""
    N = structure.n_loaded
    out_blocks = []
    ss_pe, df_pe, q_u, df_u = 0.0, 0, 0.0, 0
    for b in blocks:
        rows = b["rows"]
        H = _covariance(b, lam)
        loaded = rows < N
        iL, iU = flat_index(np.flatnonzero(loaded), w), flat_index(np.flatnonzero(~loaded), w)
        HLL, HLU, HUU = H[np.ix_(iL, iL)], H[np.ix_(iL, iU)], H[np.ix_(iU, iU)]
        y = b["Y"].ravel()
        if len(iU):
            Bm = np.linalg.solve(HUU, HLU.T).T
            C = HLL - Bm @ HLU.T
            q_u += float(y[iU] @ np.linalg.solve(HUU, y[iU]))
            df_u += len(iU)
        else:
            Bm, C = np.zeros((len(iL), 0)), HLL
        shared = not np.allclose(H, np.eye(len(H)))
        if shared:
            ev, V = np.linalg.eigh(C)
            W = (V / np.sqrt(ev)) @ V.T
        else:
            W = np.eye(len(iL))
        wy = W @ (y[iL] - Bm @ y[iU])
        Qg = _basis(W @ kron_eye(b["L"][loaded], w))
        resid = wy - Qg @ (Qg.T @ wy)
        ss_pe += float((resid**2).sum())
        df_pe += len(iL) - Qg.shape[1]
        if shared:
            out_blocks.append((rows[loaded], rows[~loaded] - N, W, Bm))
    if df_union is None:
        df, s2 = df_pe + df_u, (ss_pe + q_u) / max(df_pe + df_u, 1)
    else:
        df, s2, df_pe, ss_pe = df_union, sigma2, 0, 0.0
    return ErrorModel(structure, lam, estimable, pvals, stage, float(s2), int(df), source, ss_pe, df_pe,
                      tuple(out_blocks), q_u, df_u, tuple(notes), np.asarray(zero_y, float))


# --- the estimated variance components' share in the fixed effects' covariance ---------------------------------

@dataclass(frozen=True)
class KenwardRoger:
    """The quantities of :func:`kenward_roger` in an orthonormal basis of the fixed effects (X^T H^-1 X = I in it;
    r its dimension): basis (p, r), the coefficients of its directions; P (g, r, r): X^T H^-1 G_i H^-1 X in it
    (G_0 = I for sigma^2, then each component in use); W (g, g): the inverse of the expected REML information of
    (sigma^2, sigma^2 lambda_k) in units of sigma^4; inflation (r, r): Lambda / sigma^2."""
    basis: np.ndarray
    P: np.ndarray
    W: np.ndarray
    inflation: np.ndarray

    @property
    def largest_inflation(self) -> float:
        """The largest eigenvalue of 2 Lambda in the metric of Phi (:func:`variance_inflation`)."""
        return float(max(2.0 * np.linalg.eigvalsh(self.inflation).max(initial=0.0), 0.0))

    def f_test(self, U: np.ndarray, zU: np.ndarray, s2: float, df: int) -> float:
        """The p-value of the Kenward-Roger F-test that the fixed effects' combination U^T c is zero (Kenward &
        Roger, *Biometrics* 53, 1997, sec. 4; Halekoh & Hojsgaard, *J. Stat. Softw.* 59(9), 2014, sec. 3):
        U (r, q) orthonormal columns in :attr:`basis`'s coordinates c (in which the plug-in covariance of the
        estimate is s2 I), zU (q,) the estimate of U^T c, s2 the error variance on df degrees of freedom. The
        statistic uses the adjusted covariance Phi_A = s2 (I + 2 U^T Lambda U); lambda F ~ F(q, m), with m the
        denominator degrees of freedom the estimated components leave (at most df: the plug-in test's, which takes
        them as known)."""
        q = U.shape[1]
        if q == 0 or not s2 > 0:
            return 1.0
        F = float(zU @ np.linalg.solve(np.eye(q) + 2.0 * U.T @ self.inflation @ U, zU)) / q / s2
        m, scale = self.degrees(U, df)
        return float(dist.f_sf(scale * F, q, m)) if F > 0 else 1.0

    @property
    def extra_covariance(self) -> np.ndarray:
        """(p, p): 2 Lambda / sigma^2 in the fixed effects' own coordinates, what estimating the variance ratios adds
        to their plug-in covariance Phi / sigma^2 (Kenward & Roger 1997, eq. 3: Phi_A = Phi + 2 Lambda)."""
        return 2.0 * self.basis @ self.inflation @ self.basis.T

    def combination(self, lam: np.ndarray, df: float) -> tuple[float, float]:
        """(factor, m) for the combination lam^T beta of the fixed effects (lam (p,)): the factor (at least 1) by
        which its plug-in variance grows, [Phi + 2 Lambda] / Phi along lam (Kenward & Roger 1997, eq. 3), and the
        degrees of freedom of its t quantile (:meth:`degrees` with q = 1, at most ``df``); (1, df) for a
        combination the model does not inform."""
        u = self.basis.T @ lam  # (r,): lam^T beta in the orthonormal coordinates
        norm = float(np.sqrt(u @ u))
        if not norm > 0:
            return 1.0, float(df)
        U = (u / norm)[:, None]
        return max(1.0 + 2.0 * float((U.T @ self.inflation @ U)[0, 0]), 1.0), self.degrees(U, df)[0]

    def degrees(self, U: np.ndarray, df: float) -> tuple[float, float]:
        """(m, lambda) of :func:`kr_degrees` for the combinations U (r, q) (orthonormal columns in :attr:`basis`'s
        coordinates): from A1 = sum_ij W_ij tr(U^T P_i U) tr(U^T P_j U) and A2 = sum_ij W_ij tr(U^T P_i U U^T P_j U)
        (Kenward & Roger 1997, eq. 10)."""
        a = U.T @ self.P @ U  # U^T P_i U (g, q, q)
        t = np.einsum("gii->g", a)
        return kr_degrees(U.shape[1], float(t @ self.W @ t), float(np.einsum("ij,iab,jba->", self.W, a, a)), df)


def kr_degrees(q: int, A1: float, A2: float, df: float) -> tuple[float, float]:
    """(m, lambda): Kenward-Roger's denominator degrees of freedom and scale of a q-dimensional F-test from its
    A1 and A2 (Kenward & Roger 1997, eqs. 10-12; rho as pbkrtest's ``Lb_ddf``), m at most ``df``: (df, 1) where the
    estimated components do not affect the test (A2 = 0) or m is beyond df (q rho at or just above 1). In a
    balanced design it is the exact test's: A1 = A2 = 2 / nu for a direction the groups' means carry, m = nu (rho
    infinite at nu = 4, negative below it); m is kept at 1 or more, lambda 1 where m is within 0.01 of 2. Where A2 >= q
    the moments cannot be matched (E = 1 / (1 - A2 / q) is not a variance ratio; pbkrtest's scale turns negative):
    the estimated components leave the test's variance as uncertain as a chi-square's on 2 q / A2 degrees of freedom
    (Satterthwaite's count; nu in a balanced design), m = max(2 q / A2, 1) with lambda 1, never the plug-in test's df
    (which took the shared errors as known exactly where they are least known)."""
    if not A2 > 1e-12:
        return float(df), 1.0
    if A2 >= q:  # no moment match (2 q / A2 <= 2 in a balanced design's terms): Satterthwaite's count, at least 1
        return float(min(df, max(2.0 * q / A2, 1.0))), 1.0
    B = (A1 + 6.0 * A2) / (2.0 * q)
    g = ((q + 1.0) * A1 - (q + 4.0) * A2) / ((q + 2.0) * A2)
    den = 3.0 * q + 2.0 * (1.0 - g)
    if den == 0:
        return float(df), 1.0
    c1, c2, c3 = g / den, (q - g) / den, (q + 2.0 - g) / den
    E = 1.0 / (1.0 - A2 / q)
    V0, V1, V2 = 1.0 + c1 * B, 1.0 - c2 * B, 1.0 - c3 * B
    if V1 == 0:
        return float(df), 1.0
    if abs(V2) <= 1e-12 * max(abs(V0), 1.0):
        m = 4.0  # rho infinite
    else:
        q_rho = ((1.0 - A2 / q) / V1) ** 2 * V0 / V2
        if 0.0 < q_rho <= 1.0:  # no finite moment match: as large as the plug-in's
            return float(df), 1.0
        m = 4.0 + (q + 2.0) / (q_rho - 1.0)
        if m >= df:
            return float(df), 1.0
    m = max(m, 1.0)
    return m, 1.0 if abs(m - 2.0) < 0.01 or m < 2.0 else m / (E * (m - 2.0))


def kenward_roger(blocks: list[dict], lam: np.ndarray, in_use: np.ndarray | None = None) -> KenwardRoger | None:
    """The Kackar-Harville inflation of the generalised least-squares estimator's covariance for variance
    components that are estimated, not known (Kenward & Roger, *Biometrics* 53, 1997, eqs. 2-5): with
    V = sigma^2 H(lambda), theta = (sigma^2, sigma^2 lambda_k for each component in use), G_0 = I, G_k = Z_k Z_k^T,
    P_i = X^T V^-1 G_i V^-1 X, Q_ij = X^T V^-1 G_i V^-1 G_j V^-1 X, W the inverse of the expected REML
    information (1/2 tr(Pi G_i Pi G_j), Pi the REML projection), Phi = (X^T V^-1 X)^-1:
    Var(beta_hat) ~ Phi_A = Phi + 2 Lambda, Lambda = Phi sum_ij W_ij (Q_ij - P_i Phi P_j) Phi (one Lambda for the
    extra variance of beta_hat, one for the bias of Phi(theta_hat)). Lambda / sigma^2 does not depend on sigma^2.

    blocks: as :func:`_block_arrays` (every model row of a configuration; X zero on the unloaded rows), lam (K,)
    the estimated ratios; in_use (K,) bool: the components in use, some estimated at zero among them (default: those
    with lam_k > 0). A shared error estimated at zero (the boundary) is estimated all the same: a direction it would
    carry has its groups' degrees of freedom, not the rows' (in a balanced random-intercept design, a slope between G
    groups keeps the exact test's m = G - 2 there; left out, the test took the rows' and its p-value fell below the
    exact test's in a third of such data sets); :func:`estimate` counts those, not an effect of each row of its own
    (the load's direction: per row, like the noise, whose uncertainty the degrees of freedom already hold; counted
    at zero, it took a 2-link backlash from p = 0.0005 to 0.01). Returns the :class:`KenwardRoger` quantities, among
    them Lambda / sigma^2 (r, r) in an orthonormal basis of the fixed effects in the metric X^T H^-1 X (the whitened
    union; r its rank), in which Phi_A / sigma^2 = I + 2 Lambda / sigma^2; None when no component is in use
    (ordinary least squares: nothing estimated but sigma^2, whose uncertainty the F-tests' degrees of freedom
    hold)."""
    used = [k for k in range(len(lam)) if (lam[k] > 0 if in_use is None else in_use[k])]
    if not used:
        return None
    fixed = [_fixed(b) for b in blocks]
    p = fixed[0].shape[-1]
    g = len(used) + 1
    M = np.zeros((p, p))
    Pm = np.zeros((g, p, p))
    Qm = np.zeros((g, g, p, p))
    t = np.zeros((g, g))
    for b, X in zip(blocks, fixed):
        H = _covariance(b, lam)
        Hi = np.linalg.inv(H)
        X = X.reshape(len(H), p)
        HX = Hi @ X
        G = [b["Z"][k] @ b["Z"][k].T if k in b["Z"] else np.zeros_like(H) for k in used]
        HG = [Hi] + [Hi @ Gi for Gi in G]  # G_0 = I: no product
        GHX = [HX] + [Gi @ HX for Gi in G]
        HGHX = [HGi @ HX for HGi in HG]
        M += X.T @ HX
        for i in range(g):
            Pm[i] += HX.T @ GHX[i]
            for j in range(i, g):
                Qm[i, j] += HGHX[i].T @ GHX[j]
                t[i, j] += float(np.sum(HG[i] * HG[j].T))
    for i in range(g):
        for j in range(i):
            Qm[i, j], t[i, j] = Qm[j, i].T, t[j, i]
    scale = np.sqrt(np.diag(M).copy())
    scale[scale == 0] = 1.0
    ev, V = np.linalg.eigh(M / np.outer(scale, scale))
    keep = ev > RANK_RTOL * max(float(ev.max(initial=0.0)), 1e-300)
    basis = V[:, keep] / np.sqrt(ev[keep]) / scale[:, None]  # (p, r): basis^T M basis = I
    Po = basis.T @ Pm @ basis
    Qo = basis.T @ Qm @ basis
    info = 0.5 * (t - 2.0 * np.einsum("ijaa->ij", Qo) + np.einsum("iab,jba->ij", Po, Po))
    W = np.linalg.pinv(info)
    inflation = np.einsum("ij,ijab->ab", W, Qo - np.einsum("iab,jbc->ijac", Po, Po))
    return KenwardRoger(basis, Po, W, 0.5 * (inflation + inflation.T))


def model_kenward_roger(em: "ErrorModel", columns: np.ndarray) -> KenwardRoger | None:
    """:func:`kenward_roger` for the model whose regressors are the union's ``columns`` (indices into the last axis
    of the union the error model was estimated with: the nominal model's compliances first, then each cause's,
    :meth:`stiffcal.measured.discrepancy.Design.columns`). None where no shared error is estimated (the plug-in
    intervals and tests are then exact) or the error model keeps no arrays (a drift among its fixed effects)."""
    if em.arrays is None:
        return None
    (Y, groups, X_union, weights), _ = em.arrays
    st = em.structure
    return kenward_roger(_block_arrays(st, Y, groups, X_union[..., np.asarray(columns)], weights), em.ratios,
                         _in_use(st, em.ratios, em.estimable))


def further_effects_p(em: "ErrorModel", columns: np.ndarray, further: np.ndarray, arrays: tuple) -> float | None:
    """The p-value of Kenward-Roger's F-test (:meth:`KenwardRoger.f_test`) that the further fixed effects
    ``further`` (R, w, k) on every model row (loaded and unloaded: a tracker's drift) are zero, added to the model of
    the union's ``columns``, with ``em`` the error model estimated with them (its ratios, sigma^2 and degrees of
    freedom): the generalised least-squares estimate over every model row, sum_b X_b^T H_b^-1 y_b in the orthonormal
    coordinates of :func:`kenward_roger` (in which its plug-in covariance is sigma^2 I). ``arrays``: the
    :attr:`ErrorModel.arrays` of the error model of the same rows without them. None where no shared error is in
    use (the plug-in test is then exact)."""
    (Y, groups, X_union, weights), _ = arrays
    st = em.structure
    blocks = _block_arrays(st, Y, groups, X_union[..., np.asarray(columns)], weights, further)
    kr = kenward_roger(blocks, em.ratios, _in_use(st, em.ratios, em.estimable))
    if kr is None:
        return None
    g = sum(_fixed(b).reshape(b["Y"].size, -1).T @ np.linalg.solve(_covariance(b, em.ratios), b["Y"].ravel())
            for b in blocks)
    U, sv, _ = np.linalg.svd(kr.basis[-further.shape[-1]:].T, full_matrices=False)  # their directions there
    U = U[:, sv > RANK_RTOL * max(float(sv.max(initial=0.0)), 1e-300)]
    return kr.f_test(U, U.T @ (kr.basis.T @ g), em.sigma2, em.df) if U.shape[1] else 1.0


def kr_intervals(kr: KenwardRoger, df: float) -> tuple[np.ndarray, np.ndarray]:
    """Per fixed effect j of ``kr``'s model: (factor (p,), degrees of freedom (p,)) of
    :meth:`KenwardRoger.combination` for the unit combination e_j: the interval
    c_j +- t_m(0.975) sqrt(factor sigma^2 Phi_jj). In a balanced random-intercept design it is the exact t
    interval (tests)."""
    out = np.array([kr.combination(e, df) for e in np.eye(kr.basis.shape[0])]).reshape(-1, 2)
    return out[:, 0], out[:, 1]


def variance_inflation(blocks: list[dict], lam: np.ndarray) -> float:
    """The largest relative increase of a fixed-effect combination's variance when the variance components are
    estimated rather than known: the largest eigenvalue of 2 Lambda in the metric of Phi (:func:`kenward_roger`;
    0 without a component in use). The analysis's intervals take the REML ratios as known (plug-in; its closed
    test does not, :meth:`KenwardRoger.f_test`): this says how much that understates the parameters' variances."""
    kr = kenward_roger(blocks, lam)
    return 0.0 if kr is None else kr.largest_inflation


# --- the unloaded rows: blunders among them, and a zero point that moved ------------------------------------------

def _full_roots(em: ErrorModel, blocks: list[dict]) -> list[np.ndarray]:
    """Per block the symmetric inverse square root of its rows' H (every model row, loaded and unloaded;
    flattened)."""
    out = []
    for b in blocks:
        ev, V = np.linalg.eigh(_covariance(b, em.ratios))
        out.append((V / np.sqrt(ev)) @ V.T)
    return out


def unloaded_tests(em: ErrorModel, Y: np.ndarray, groups: np.ndarray, X_union: np.ndarray | None,
                   weights: np.ndarray) -> tuple[np.ndarray, float | None, tuple[int, float]]:
    """F-tests on the unloaded model rows in the fitted error model, against the fixed effects the noise was
    estimated with (the replicate groups' means, else the union of all extensions), in the whitened rows:

    - each unloaded row against the others (a mean shift of that row alone: Cook & Weisberg, *Residuals and
      Influence in Regression*, 1982, sec. 2.2), F(w, df - w) with w its components: (N_U,) p-values;
    - all unloaded rows shifted together (the zero point moved): F(w, df - w), its p-value (None without
      unloaded rows);
    and (w, df) of the tests. Y (R, w), groups (N,), X_union (N, w, p), weights (R,) as :func:`estimate`."""
    st = em.structure
    N, w = st.n_loaded, Y.shape[1]
    made = em.arrays
    same = made is not None and all(a is b for a, b in zip(made[0], (Y, groups, X_union, weights)))
    blocks = made[1] if same else _block_arrays(st, Y, groups, X_union, weights)
    roots = _full_roots(em, blocks)
    local = em.df_pe > 0  # with replicates the reference is their groups' means (the pure error's model)
    if not local:
        Xw = np.concatenate([S @ b["X"].reshape(len(S), -1) for S, b in zip(roots, blocks)])
        Q0 = _basis(Xw)
        Yw = np.concatenate([S @ b["Y"].ravel() for S, b in zip(roots, blocks)])
        r_all = Yw - Q0 @ (Q0.T @ Yw)
    at = 0
    stats_rows = {}
    shift_num, shift_AA, shift_G = np.zeros(w), np.zeros((w, w)), 0.0
    total = 0.0
    for S, b in zip(roots, blocks):
        size = len(S)
        if local:
            Qb = _basis(S @ kron_eye(b["L"], w))
            r = S @ b["Y"].ravel()
            r = r - Qb @ (Qb.T @ r)
        else:
            r, Qb = r_all[at:at + size], Q0[at:at + size]
        total += float(r @ r)
        unloaded = np.flatnonzero(b["rows"] >= N)
        for i in unloaded:
            A = S[:, flat_index([i], w)]  # (n w, w): a shift of that row alone, whitened
            G = Qb.T @ A
            stats_rows[int(b["rows"][i]) - N] = _quadratic(A.T @ r, A.T @ A - G.T @ G)
        if len(unloaded):
            A = S[:, flat_index(unloaded, w)] @ np.tile(np.eye(w), (len(unloaded), 1))  # all unloaded rows shifted
            G = Qb.T @ A
            shift_num += A.T @ r
            shift_AA += A.T @ A - (G.T @ G if local else 0.0)
            shift_G = shift_G + (0.0 if local else G)
        at += size
    df = em.df
    p_rows = np.ones(st.n_rows - N)
    for i, ss in stats_rows.items():
        F = (ss / w) / (max(total - ss, 1e-300) / max(df - w, 1))
        p_rows[i] = float(dist.f_sf(F, w, max(df - w, 1)))
    p_shift = None
    if st.n_rows > N:
        V = shift_AA if local else shift_AA - shift_G.T @ shift_G
        ss = _quadratic(shift_num, V)
        F = (ss / w) / (max(total - ss, 1e-300) / max(df - w, 1))
        p_shift = float(dist.f_sf(F, w, max(df - w, 1)))
    return p_rows, p_shift, (w, max(df - w, 1))


def _basis(A: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of A (k, p) (relative rank :data:`RANK_RTOL`)."""
    U, sv, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, : int(np.sum(sv > RANK_RTOL * sv[0]))] if sv.size and sv[0] > 0 else U[:, :0]


def _quadratic(v: np.ndarray, V: np.ndarray) -> float:
    """v^T V^+ v (0 where V is zero: a shift the fixed effects absorb), V symmetric positive semi-definite."""
    ev, U = np.linalg.eigh(V)
    keep = ev > RANK_RTOL * max(float(ev.max(initial=0.0)), 1e-300)
    z = U[:, keep].T @ v
    return float(z @ (z / ev[keep])) if keep.any() else 0.0
