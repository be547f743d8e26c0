"""How often the discrepancy analysis is right: hidden effects in simulated laboratory data, over seeds.

A *case* is a robot, a measurement protocol (:class:`stiffcal.testing.truth.Protocol`: hanging weights, pushes in
several directions, 3-D pushes, one random load; the load sequence repeated or not, replicates
interleaved in time, unloaded reference rows, tracker noise growing with distance), a set of hidden
effects (:mod:`stiffcal.testing.truth`, written from the physics and independent of the analysis's regressors) and
a seed. Its log is written as the CSV a lab would write, with and without ``pose_id``, read back with
:func:`stiffcal.measured.measurements.read_measurements` and analysed; both variants must give the same verdict.

Each effect is scaled so that the RMS of its displacement, less what the nominal model absorbs, is a random
multiple (log-uniform) of the noise, so cases range from invisible to obvious. Whether a case *should* be
found is decided by an **oracle**: the most powerful test of that one effect, which knows its exact shape
(its noise-free displacement vector e): the one-degree-of-freedom F-test of e against the nominal model
(and the other hidden effects), with the noise known row by row. Its power at level alpha is
1 - F'(F_crit; 1, df, lambda), lambda = |(I - P) W e|^2 with W the whitening by the noise and P the
projection on the whitened nominal columns (Scheffe, *The Analysis of Variance*, 1959, sec. 2.8). The
analysis is required to name an effect in at least 95 % of the cases where the oracle's power is at least
0.9, and to raise at most alpha false alarms on clean data. A weaker oracle, which knows which cause is
present but not its parameters (the F-test of that cause's regressors at level alpha), is also reported.
For effects outside the catalogue the oracle tests the part of e that no catalogue cause explains, and the
expected verdict is ``unexplained``.
"""

from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import stats

from ..measured import discrepancy as D
from . import truth as T
from ..measured.measurements import read_measurements
from ..model.robot import Robot, load_robot, planar_robot, with_masses, with_targets

#: the effects a case can hide (the simulator's registry, :data:`stiffcal.testing.truth.EFFECTS`): the catalogue's
#: causes, then those outside the catalogue (:data:`OUTSIDE`)
EFFECTS = tuple(T.EFFECTS)
OUTSIDE = tuple(e for e in EFFECTS if e not in D.CAUSES)
#: the warning of ``diagnostics`` that names an effect outside the catalogue
WARNING_OF = {"drift": "time", "tilted_load": "load_direction", "held_backlash": "return_to_zero"}
#: the catalogue cause that also names an effect outside it: a backlash held by friction is the catalogue's backlash
#: wherever the arm's weight brings the gear back on unloading, and its loaded rows are that backlash from the flank
#: the gear rested on (a shift shared by the visit's rows, like the reference reading's error) where no reading
#: after a load shows that the gear stays
ALSO_NAMED_AS = {"held_backlash": "backlash"}

PROTOCOLS = {
    "hanging x4, repeated": T.Protocol("hanging x4, repeated"),
    "hanging x4, once": T.Protocol("hanging x4, once", repeats=1),
    "4 directions x 2, repeated": T.Protocol("4 directions x 2, repeated", loads="directions",
                                             magnitudes_N=(250.0, 600.0)),
    "4 directions x 2, interleaved": T.Protocol("4 directions x 2, interleaved", loads="directions",
                                                magnitudes_N=(250.0, 600.0), interleaved=True),
    "3-D pushes x 2, repeated": T.Protocol("3-D pushes x 2, repeated", loads="pushes3d", n_directions=3,
                                           magnitudes_N=(400.0, 1000.0)),
    "3-D pushes x 2, once": T.Protocol("3-D pushes x 2, once", loads="pushes3d", n_directions=3,
                                       magnitudes_N=(400.0, 1000.0), repeats=1),
    "random load x3, unloaded rows, tracker": T.Protocol("random load x3, unloaded rows, tracker", loads="random",
                                                         magnitudes_N=(100.0, 400.0), repeats=3,
                                                         unloaded_rows=True, sigma_m=5e-6, sigma_per_m=5e-6),
    "hanging x4, unloaded rows, tracker": T.Protocol("hanging x4, unloaded rows, tracker", unloaded_rows=True,
                                                     sigma_m=5e-6, sigma_per_m=5e-6),
    "4 directions x 2, shared reference": T.Protocol("4 directions x 2, shared reference", loads="directions",
                                                     magnitudes_N=(250.0, 600.0), unloaded_rows=True,
                                                     reference="configuration"),
    # the lab's own reference readings (stiffcal.testing.truth.Protocol): one per visit, or one per configuration with
    # later visits measured against it (the robot back within its pose repeatability); hanging masses only
    "hanging x3, reference per visit, 2 passes": T.Protocol(
        "hanging x3, reference per visit, 2 passes", magnitudes_N=(196.1, 392.3, 588.4), repeats=1,
        reference="visit", passes=2, shuffle=True, zero_rows=True, return_to_zero=True, sigma_m=5e-6,
        sigma_per_m=5e-6, repeatability_m=1e-5, timestamps=True),
    "loading bar x3, reference per visit, 2 passes": T.Protocol(
        "loading bar x3, reference per visit, 2 passes", magnitudes_N=(98.1, 245.2, 392.3), repeats=1,
        lever_m=0.3, bar_sides=2, reference="visit", passes=2, shuffle=True, return_to_zero=True,
        repeatability_m=1e-5, timestamps=True),
    "gauge +-axes, reference per visit, half revisited": T.Protocol(
        "gauge +-axes, reference per visit, half revisited", loads="gauge", magnitudes_N=(300.0,), repeats=1,
        reference="visit", passes=2, revisit_fraction=0.5, shuffle=True, relabel=True, return_to_zero=True,
        repeatability_m=1e-5, timestamps=True),
    "hanging x3, reference per configuration, half revisited": T.Protocol(
        "hanging x3, reference per configuration, half revisited", magnitudes_N=(147.1, 294.2, 490.3), repeats=1,
        reference="configuration", passes=2, revisit_fraction=0.5, shuffle=True, relabel=True, zero_rows=True,
        repeatability_m=1.5e-5, sigma_m=5e-6, sigma_per_m=5e-6, timestamps=True),
    "hanging x3, 2 targets, reference per configuration, 2 passes": T.Protocol(
        "hanging x3, 2 targets, reference per configuration, 2 passes", magnitudes_N=(147.1, 294.2, 490.3),
        repeats=1, targets=("A", "B"), reference="configuration", passes=2, shuffle=True, zero_rows=True,
        repeatability_m=1e-5, timestamps=True),
    "one hanging mass, reference per visit, 2 passes": T.Protocol(
        "one hanging mass, reference per visit, 2 passes", magnitudes_N=(490.3,), repeats=1, reference="visit",
        passes=2, shuffle=True, zero_rows=True, return_to_zero=True, repeatability_m=1e-5, timestamps=True),
    # a hand-held gauge is never held exactly along the axis the log names: each push 3 degrees off it (RMS)
    "gauge +-axes 3 deg off axis, reference per visit, half revisited": T.Protocol(
        "gauge +-axes 3 deg off axis, reference per visit, half revisited", loads="gauge", magnitudes_N=(300.0,),
        repeats=1, reference="visit", passes=2, revisit_fraction=0.5, shuffle=True, relabel=True, return_to_zero=True,
        repeatability_m=1e-5, timestamps=True, gauge_angle_deg=3.0),
}

#: the targets (tracker SMRs on the last link) of the arms of the matrix, in the tip frame [m]
TARGETS = {2: {"A": [-0.04, 0.05], "B": [-0.12, -0.04]}, 3: {"A": [0.08, 0.0, 0.06], "B": [-0.05, 0.07, 0.09]}}


def robots(root: str | Path) -> dict[str, Robot]:
    """The arms of the study: the paper's 2-link arm and a 3-link planar arm (no weight of their own: a lab arm
    whose weight is compensated), and the 6-axis KUKA of the config with its links' masses (about 0.9 t in all,
    :data:`KUKA_MASSES`) and a 60 kg spindle: its own weight preloads the joints (a backlash jumps only where
    the load reverses the total torque). Each carries two tracker targets (:data:`TARGETS`)."""
    root = Path(root)
    arms = {"2-link": load_robot(root / "config/robots/paper_2r.yaml"),
            "3-link": planar_robot([0.5, 0.4, 0.3], "3-link"),
            "6-axis": with_masses(load_robot(root / "config/robots/kuka_kr210_r2700.yaml"), KUKA_MASSES, "<rates>")}
    return {name: with_targets(arm, TARGETS[arm.task_dim], "<rates>") for name, arm in arms.items()}


#: the 6-axis arm's own weight (a KR 210 class arm: masses and centres in its DH frames, roughly)
KUKA_MASSES = {"link_masses_kg": [400.0, 250.0, 150.0, 60.0, 30.0, 10.0],
               "link_coms_m": [[-0.15, 0.1, 0.0], [-0.6, 0.0, 0.15], [-0.1, -0.1, 0.0], [0.0, 0.25, 0.0],
                               [0.0, 0.0, 0.05], [0.0, 0.0, -0.05]],
               "payload_kg": 60.0}


def compliances(robot: Robot) -> np.ndarray:
    """The true joint compliances [rad/(N m)]: the robot file's, else 1.5e-6 .. 3e-6 (tenths of a millimetre
    under a few hundred newtons for a metre-long arm)."""
    return robot.compliances if robot.compliances is not None else np.linspace(1.5e-6, 3e-6, robot.n_joints)


def protocols_for(robot: Robot) -> list[str]:
    """The protocols that make sense for the robot: 3-D pushes for a spatial arm only, the old plain hanging
    protocols for a planar arm in its vertical plane only (on a spatial arm with a vertical first axis hanging
    masses never load joint 1: the analysis leaves it out, and the lab protocols with their own reference
    readings cover that case), every other protocol for both."""
    spatial = robot.task_dim == 3
    plain_hanging = ("hanging x4, repeated", "hanging x4, once", "hanging x4, unloaded rows, tracker")
    return [p for p, pr in PROTOCOLS.items()
            if not (pr.loads == "pushes3d" and not spatial) and not (spatial and p in plain_hanging)]


def _unit_truth(effect: str, robot: Robot, k: np.ndarray, rng: np.random.Generator, log: T.LabLog) -> T.Truth:
    """A truth with the effect at an arbitrary size (scaled afterwards by :func:`_scaled_truth`;
    :data:`stiffcal.testing.truth.EFFECTS`)."""
    return T.EFFECTS[effect].unit(robot, k, rng, log)


def _effect_displacement(robot, truth: T.Truth, base: T.Truth, log: T.LabLog) -> np.ndarray:
    """(N_noisy, w): the effect's noise-free part of every noisy row (every row but the exact-zero references;
    the unloaded rows see a drift)."""
    return (T.row_means(robot, truth, log) - T.row_means(robot, base, log))[log.noisy]


def _columns(robot: Robot, log: T.LabLog, causes=()) -> np.ndarray:
    """(N_noisy, w, p): the regressors of nominal + causes of the log's noisy rows (its targets, moments and
    orientation), zero on the unloaded rows (no load, no deflection)."""
    rows = np.flatnonzero(log.noisy)
    ob = D.Observed(log.target_names, None if log.target is None else log.target[rows], log.orientation)
    load = log.force[rows] if log.moment is None else np.hstack([log.force[rows], log.moment[rows]])
    X = D.model_columns(robot, log.q[rows], load, causes, observed=ob)
    X[~log.loaded[rows]] = 0.0
    return X


def _scaled_truth(effect: str, truth: T.Truth, base: T.Truth, robot, log, target_rms: float) -> T.Truth:
    """Scale the effect's parameter so that the RMS of its displacement, less what the nominal model absorbs
    (its projection on the nominal columns), is ``target_rms`` [m]."""
    def with_scale(s: float) -> T.Truth:
        return T.EFFECTS[effect].scaled(truth, s)

    X0 = D._stack(_columns(robot, log))
    Q = np.linalg.qr(X0)[0]

    def rms(s):  # of the part the nominal model cannot absorb
        e = _effect_displacement(robot, with_scale(s), base, log).ravel()
        return float(np.sqrt(np.mean((e - Q @ (Q.T @ e)) ** 2)))

    if not T.EFFECTS[effect].inverse:
        return with_scale(target_rms / rms(1.0))
    lo, hi = 1e-6, 3.0  # tau_max = max|tau| / (0.3 s) stays above the largest torque for s < 3.33
    if rms(hi) < target_rms:
        return with_scale(hi)
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if rms(mid) < target_rms else (lo, mid)
    return with_scale(hi)


def oracle_power(robot: Robot, log: T.LabLog, e: np.ndarray, others: list[np.ndarray], alpha: float, df: int,
                 against_catalogue: bool = False, block: str | None = None) -> float:
    """Power of an oracle test of one effect (module docstring). e: (N_loaded, d) [m] its displacement;
    others: the displacements of the other hidden effects (kept in the oracle's model); df: the error
    degrees of freedom of the analysis; against_catalogue: project out every catalogue cause too (for an
    effect outside the catalogue).

    block=None: the exact-shape oracle, a 1-degree-of-freedom F-test of e itself. block=<cause>: the weaker
    cause-block oracle, which knows which catalogue cause is present but not its parameters: the F-test of
    that cause's regressors (rank r) at level alpha, without multiplicity, noncentrality = the part of e in
    their span beyond the nominal model."""
    white = _whitening(robot, log)
    causes = D.CAUSES if against_catalogue else ()
    X = D._stack(white(_columns(robot, log, causes)))
    if others:
        X = np.hstack([X, D._stack(white(np.stack(others, -1)))])
    y = D._stack(white(e[..., None]))[:, 0]

    def rss(A):
        return float(np.sum((y - A @ np.linalg.lstsq(A, y, rcond=None)[0]) ** 2))

    if block is None:
        lam, r = rss(X), 1
    else:
        B = D._stack(white(_cause_block(robot, log, block)))
        r = np.linalg.matrix_rank(np.hstack([X, B])) - np.linalg.matrix_rank(X)
        lam = rss(X) - rss(np.hstack([X, B]))
        if r == 0:
            return 0.0
    crit = stats.f.isf(alpha, r, df)
    return float(stats.ncf.sf(crit, r, df, max(lam, 0.0)))


def oracle_global_p(robot: Robot, log: T.LabLog, dp: np.ndarray, alpha: float = 0.01) -> float:
    """The p-value of "no catalogue cause is needed" by the analysis's own closed test
    (:func:`stiffcal.measured.discrepancy.closed_testing`, its global intersection) on the rows ``dp`` (N, w) [m] of
    ``log`` whitened by their true covariance (:func:`stiffcal.testing.truth.row_covariance`) with the noise scale
    known: the oracle against which the analysis's estimated error model (weights, variance components,
    noise) is compared seed by seed (``benchmarks/oracle_false_alarms.py``)."""
    white = _whitening(robot, log)
    y = D._stack(white(dp[log.noisy][..., None]))[:, 0]
    X0 = D._stack(white(_columns(robot, log)))
    blocks = {c: D._stack(white(_cause_block(robot, log, c))) for c in D.CAUSES}
    sel = D.closed_testing(D.Design(X0, blocks, y, robot.task_dim), D.CAUSES,
                           D.Noise(1.0, 10**9, "the true covariance", 0.0, 0), lambda S, f: None, alpha)
    return float(sel.local.get((frozenset(sel.causes), False), 1.0))


def _cause_block(robot: Robot, log: T.LabLog, cause: str) -> np.ndarray:
    """(N_noisy, w, p_c): one cause's regressors on the noisy rows (zero on the unloaded ones)."""
    n = _columns(robot, log).shape[-1]
    return _columns(robot, log, (cause,))[..., n:]


def _whitening(robot: Robot, log: T.LabLog):
    """The map A (N_noisy, w, k) -> Sigma^(-1/2) A for the true covariance of the log's noisy rows
    (:func:`stiffcal.testing.truth.row_covariance`: independent readings, each row a reading less its reference
    reading, the returns' pose errors shared by a visit, a hand-held gauge's turns about the logged loads),
    configuration by configuration (the inverse of the Cholesky factor of each block)."""
    where = np.full(len(log.q), -1)
    where[np.flatnonzero(log.noisy)] = np.arange(int(log.noisy.sum()))
    blocks = [(where[rows], np.linalg.inv(np.linalg.cholesky(S)))
              for rows, S in T.row_covariance(robot, log, compliances(robot))]

    def white(A):
        out = np.empty_like(A, dtype=float)
        w = A.shape[1]
        for mine, Wc in blocks:
            flat = A[mine].reshape(len(mine) * w, -1)
            out[mine] = (Wc @ flat).reshape(A[mine].shape)
        return out
    return white


@dataclass(frozen=True)
class CaseResult:
    """One analysed case: the hidden effects, each effect's oracle power (exact shape; ``power_block``: the
    cause-block oracle, catalogue causes only), both verdicts (``compared``: both CSV variants were analysed;
    else the second is the first)."""
    robot: str
    protocol: str
    effects: tuple[str, ...]
    seed: int
    power: dict
    verdict_with_pose_id: dict
    verdict_without: dict
    power_block: dict = field(default_factory=dict)
    compared: bool = True

    @property
    def agree(self) -> bool:
        keys = ("cause", "causes", "indistinguishable_from", "outlier_rows")
        return all(self.verdict_with_pose_id[k] == self.verdict_without[k] for k in keys)

    def named(self, effect: str) -> bool:
        """The verdict names the effect: an effect outside the catalogue as ``unexplained``, or by the warning
        that says what it is (a drift: ``diagnostics.time``; a tilted load: ``diagnostics.load_direction``; a
        backlash held by friction: ``diagnostics.return_to_zero``, at the verdict's alpha, or as the catalogue
        cause of :data:`ALSO_NAMED_AS`); a catalogue cause in ``causes`` or ``indistinguishable_from`` (a span that
        coincides with a named cause's), in a verdict that is not ``unexplained``."""
        v = self.verdict_with_pose_id
        if effect in OUTSIDE:
            warning = WARNING_OF.get(effect)
            diag = (v.get("diagnostics") or {}).get(warning) if warning else None
            also = ALSO_NAMED_AS.get(effect)
            return v["cause"] == "unexplained" or bool(diag and diag["p_value"] <= v["alpha"]) or (
                also is not None and also in {*v["causes"], *v["indistinguishable_from"]})
        return v["cause"] != "unexplained" and effect in {*v["causes"], *v["indistinguishable_from"]}

    @property
    def false_alarm(self) -> bool:
        return self.verdict_with_pose_id["cause"] != "none"

    @property
    def warned(self) -> bool:
        """A warning of ``diagnostics`` (a drift, a tilted load, a gear that does not return, a load direction that
        scatters) at the verdict's alpha."""
        v = self.verdict_with_pose_id
        diag = v.get("diagnostics") or {}
        return any(diag.get(k) and diag[k]["p_value"] <= v["alpha"] for k in (*WARNING_OF.values(), "load_scatter"))


def simulate_case(robot: Robot, protocol: str | T.Protocol, effects: tuple[str, ...], seed: int, n_configs: int = 40,
                  size_range=(0.02, 1.0)) -> tuple[T.LabLog, np.ndarray, dict]:
    """One case's lab log, its measured rows dp (N, w) [m] and each hidden effect's noise-free displacement
    {effect: (N_noisy, w)} (module docstring; effect sizes as :func:`run_case`), all drawn from ``seed``;
    ``protocol`` a name of :data:`PROTOCOLS` or a protocol of its own."""
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, PROTOCOLS[protocol] if isinstance(protocol, str) else protocol, rng, n_configs)
    k = compliances(robot)
    base = T.Truth(k)
    truth, disp = base, {}
    sigma = float(np.median(log.sigma))
    for eff in effects:
        unit = _unit_truth(eff, robot, k, rng, log)
        size = sigma * float(np.exp(rng.uniform(*np.log(size_range))))
        scaled = _scaled_truth(eff, unit, base, robot, log, size)
        disp[eff] = _effect_displacement(robot, scaled, base, log)
        truth = _merge(truth, scaled)
    return log, T.measure(robot, truth, log, rng), disp


def run_case(robot_name: str, robot: Robot, protocol: str, effects: tuple[str, ...], seed: int,
             alpha: float = 0.01, n_configs: int = 40, size_range=(0.02, 1.0), workdir: str | None = None,
             both: bool = True) -> CaseResult:
    """Simulate one case (module docstring), analyse both CSV variants (``both=False``: the one with pose_id
    only, its verdict standing for both), and return the verdicts and the oracle power of each hidden effect.
    Effect sizes: RMS displacement log-uniform in ``size_range`` times the median noise."""
    log, dp, disp = simulate_case(robot, protocol, effects, seed, n_configs, size_range)
    verdicts = []
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        for with_id in (True, False) if both else (True,):
            path = Path(tmp) / f"case{int(with_id)}.csv"
            path.write_text(T.lab_csv(robot, log, dp, pose_id=with_id), encoding="utf-8")
            meas = read_measurements(path, robot)
            verdicts.append(D.analyse(robot, meas, alpha, gain=False))
    if not both:
        verdicts.append(verdicts[0])
    df = verdicts[0]["nominal"]["sigma_df"]
    others = {e: [disp[o] for o in effects if o != e] for e in effects}
    power = {e: oracle_power(robot, log, disp[e], others[e], alpha, df, e in OUTSIDE) for e in effects}
    block = {e: oracle_power(robot, log, disp[e], others[e], alpha, df, block=e) for e in effects if e not in OUTSIDE}
    return CaseResult(robot_name, protocol, tuple(effects), seed, power, *verdicts, block, both)


def _merge(a: T.Truth, b: T.Truth) -> T.Truth:
    """The truth with the effects of both: every effect field (a :class:`stiffcal.testing.truth.Truth` field whose
    default is None: absent) that b sets, over a's."""
    set_by_b = {f.name: getattr(b, f.name) for f in dataclasses.fields(T.Truth)
                if f.default is None and getattr(b, f.name) is not None}
    return replace(a, **set_by_b)


def rates(results: list[CaseResult], min_power: float = 0.9, oracle: str = "exact") -> dict:
    """Per hidden effect: cases where the oracle's power >= min_power (``oracle``: "exact" shape, or "block" of
    the cause's regressors, which falls back to the exact one outside the catalogue), how many of those the
    verdict names, and the rate; for clean cases (no effect): the false-alarm count and rate; and the share of
    cases where the two CSV variants agree."""
    out: dict = {}
    for r in results:
        if not r.effects:
            row = out.setdefault("clean", {"cases": 0, "false_alarms": 0, "warnings": 0})
            row["cases"] += 1
            row["false_alarms"] += r.false_alarm
            row["warnings"] += r.warned
        for e in r.effects:
            row = out.setdefault(e, {"cases": 0, "qualifying": 0, "named": 0})
            row["cases"] += 1
            power = r.power_block.get(e, r.power[e]) if oracle == "block" else r.power[e]
            if power >= min_power:
                row["qualifying"] += 1
                row["named"] += r.named(e)
    for row in out.values():
        if "qualifying" in row:
            row["rate"] = row["named"] / row["qualifying"] if row["qualifying"] else None
        else:
            row["rate"] = row["false_alarms"] / row["cases"]
    compared = [r for r in results if r.compared]
    out["variants_agree"] = sum(r.agree for r in compared) / max(len(compared), 1)
    return out
