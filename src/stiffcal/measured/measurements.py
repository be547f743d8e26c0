"""Measured deflections: the CSV contract (docs), read, validated and sorted into configurations, loads,
replicates and the unloaded zero point.

One row per measurement, units in the column names: ``pose_id`` (optional: a label of the robot
configuration), ``q1_deg`` ... ``qn_deg``, ``fx_N``, ``fy_N`` (``fz_N``), ``dx_m``, ``dy_m`` (``dz_m``): the
displacement of the measured point between the unloaded and the loaded state. Optional: the moment
``mx_Nm``, ``my_Nm``, ``mz_Nm`` about the tool point (planar arms: ``mz_Nm``), the orientation deflection
``rx_rad``, ``ry_rad``, ``rz_rad`` (small-angle rotation vector of the tool; planar arms: ``rz_rad``), and
``target``, the name of the target whose displacement the row gives (the robot file's ``targets``, or
``tool``; default the tool point). Forces, moments, displacements and rotations are in the base frame.

How rows are grouped (calibration labs measure every configuration under several loads, often repeating
the load sequence):

- **replicates** are rows of the same target whose joint angles agree within ``angle_resolution_deg``, whose
  force agrees within ``force_resolution_N`` and moment within ``moment_resolution_Nm`` (component by
  component; rows linked through a chain of such pairs form one group), whatever their ``pose_id``. Their
  spread is the pure error.
- **configurations** are rows whose joint angles agree within ``angle_resolution_deg``, whatever their
  ``pose_id``; with a ``pose_id`` column, the labels name the configuration (several labels of the same joint
  angles, a second pass relabelled, are one configuration, with a note), and rows sharing a label must share
  their joint angles. Configurations are what leave-one-configuration-out prediction and the residual plots use.
- **unloaded rows** (every force component within ``force_resolution_N`` of zero, every moment component
  within ``moment_resolution_Nm``) are the zero point of the
  displacement, not a measurement of compliance: they are set aside (``zero_rows``) and used only to check
  that the zero point did not move. Rows below the force resolution that deflect as the loaded rows'
  compliance predicts for their force are loads given in kN under N columns, and refused.

Every problem is one :class:`InputError` naming the file, the row (1-based line of the file and 0-based
data row) and the column; nothing is fitted on bad data.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.observation import force_dim, moment_dim
from ..model.robot import TOOL_TARGET, Robot

#: default resolutions that decide which rows repeat a configuration or a load (documented in docs/)
ANGLE_RESOLUTION_DEG = 0.01
FORCE_RESOLUTION_N = 0.5
MOMENT_RESOLUTION_NM = 0.05

_UNITS = {"q": "deg", "f": "N", "d": "m", "m": "Nm", "r": "rad", "t": "s"}
_PATTERN = re.compile(r"^(q\d+|f[xyz]|d[xyz]|m[xyz]|r[xyz])(?:_(.*))?$")
_NAMES = {"q": "joint angles", "f": "force components", "d": "displacements", "m": "moment components",
          "r": "orientation deflections", "t": "timestamps"}
_MAX_LISTED = 5


def rows_by_label(labels, n: int | None = None) -> list[np.ndarray]:
    """The rows (ascending) of each label 0 .. n - 1 (default: the largest label + 1; a label without rows gets an
    empty array), as ``[np.flatnonzero(labels == g) for g in range(n)]`` gives them, in O(N log N) rather than
    O(N n): a log of 10^5 rows has 10^4 configurations and more."""
    labels = np.asarray(labels).ravel()
    n = int(labels.max(initial=-1)) + 1 if n is None else int(n)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(n + 1))
    return [order[bounds[g]: bounds[g + 1]] for g in range(n)]


def rows_by_value(values) -> tuple[np.ndarray, list[np.ndarray]]:
    """(the distinct values, sorted; the rows (ascending) of each): :func:`rows_by_label` of any labels."""
    distinct, index = np.unique(values, return_inverse=True)
    return distinct, rows_by_label(index, len(distinct))


def cluster(values: np.ndarray, resolution: np.ndarray, period: np.ndarray | None = None) -> np.ndarray:
    """Labels (N,) int of the connected groups of rows that agree within ``resolution`` on every column.

    values: (N, k); resolution: (k,) > 0; period: (k,) the period of each column (360 for an angle in
    degrees, inf for none). Two rows are linked when ``|v_i - v_j| <= resolution`` in every column (modulo
    the period); groups are the connected components of that graph (single linkage). Labels count from 0 in
    the order of each group's first row, so they do not depend on anything but the row order.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    values = np.asarray(values, float)
    n = len(values)
    if n == 0:
        return np.zeros(0, int)
    scaled = values / resolution
    box = None
    if period is not None:
        box = np.where(np.isfinite(period), np.asarray(period, float) / resolution, np.inf)
        periodic = np.isfinite(box)
        # the tree wants every coordinate in [0, box): wrap the periodic ones, shift the others
        scaled = np.where(periodic, np.mod(scaled, np.where(periodic, box, 1.0)), scaled - scaled.min(axis=0))
        scaled = np.where(periodic & (scaled >= box), 0.0, scaled)  # mod(-1e-17, box) rounds to box itself
    pairs = cKDTree(scaled, boxsize=box).query_pairs(1.0 + 1e-9, p=np.inf, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, raw = connected_components(graph, directed=False)
    _, first = np.unique(raw, return_index=True)
    order = np.empty(len(first), int)
    order[np.argsort(np.argsort(first))] = np.arange(len(first))  # relabel by first occurrence
    return order[raw]


#: optional columns that say how the lab took its readings (docs/measured-data.md, "The lab's reference readings")
LOG_COLUMNS = ("timestamp_s", "visit", "reference")
#: what each optional label column is for (the note on a column that looks like a misspelling of one)
_LOG_USE = {"pose_id": "label the configurations", "timestamp_s": "order the rows by it (seconds)",
            "visit": "say which visit each row belongs to", "reference": "say which reference reading each row is "
            "taken from"}


@dataclass(frozen=True)
class RowLog:
    """What the file says of every data row (N_file,), loaded or not, beyond the measurement itself: how the lab
    took its readings (:mod:`stiffcal.measured.errormodel` infers from it which reference reading each displacement was
    taken from).

    time (N_file,) [s]: the ``timestamp_s`` column, else the row's index in the file (the log's order);
    has_time: the file has timestamps; label: the ``pose_id`` of every row (None without); visit, reference:
    the ``visit`` and ``reference`` columns (labels of the visit and of the reference reading, None without);
    target (N_file,) int into the measurements' target names; config (N_file,) int: the joint configuration of
    every row (clusters of the joint angles, loaded and unloaded rows alike); loaded (N_file,) bool;
    exact (N_file,) bool: an unloaded row whose every measured component is exactly zero (the reference
    reading itself, logged as zeros); group (N_file,) int: the replicate group of a loaded row (-1 unloaded)."""

    time: np.ndarray
    has_time: bool
    label: np.ndarray | None
    visit: np.ndarray | None
    reference: np.ndarray | None
    target: np.ndarray
    config: np.ndarray
    loaded: np.ndarray
    exact: np.ndarray
    group: np.ndarray

    @property
    def n_rows(self) -> int:
        return len(self.time)


@dataclass(frozen=True)
class Measurements:
    """Loaded measurements of one data set (unloaded reference rows are kept apart, see the module docstring).

    q (N, n) [rad]; force (N, d) [N]; dp (N, d) [m]; group (N,) int: replicate groups (rows with equal
    group repeat one configuration under one load); source: the file (for messages);
    config (N,) int: configurations (None: from the joint angles at the default resolution);
    config_labels: one label per configuration (the ``pose_id`` or the joint angles);
    rows (N,) int: 0-based data-row index of each measurement in the file (None: 0..N-1);
    zero_rows (N0,) int, zero_dp (N0, d) [m], zero_config (N0,) int: the unloaded reference rows, their
    displacement and configuration (-1 when no loaded row shares their joint angles);
    notes: what the reader noticed (unused columns, ignored blank labels);
    resolutions: (angle [deg], force [N], moment [N m]) used to group the rows;
    moment (N, d_m) [N m] about the tool point (zero without moment columns); rot (N, d_r) [rad] the tool's
    orientation deflection, or None when it was not measured; target (N,) int: the target of each row, an
    index into target_names; zero_rot (N0, d_r) [rad] the unloaded rows' orientation (None without it);
    labelled: config_labels are the data's ``pose_id`` labels (False: the joint angles, or given by the caller);
    log: what the file says of every data row (:class:`RowLog`: times, labels, visits, references, exact-zero
    reference rows), None for measurements made in memory; dp_step_m [m]: the RMS rounding step of the
    displacements as the file prints them (the value of their last digit; :func:`printed_step`), None in memory.
    """

    q: np.ndarray
    force: np.ndarray
    dp: np.ndarray
    group: np.ndarray
    source: str
    config: np.ndarray | None = None
    config_labels: tuple[str, ...] = ()
    rows: np.ndarray | None = None
    zero_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    zero_dp: np.ndarray | None = None
    zero_config: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    notes: tuple[str, ...] = ()
    resolutions: tuple[float, ...] = (ANGLE_RESOLUTION_DEG, FORCE_RESOLUTION_N, MOMENT_RESOLUTION_NM)
    moment: np.ndarray | None = None
    rot: np.ndarray | None = None
    target: np.ndarray | None = None
    target_names: tuple[str, ...] = (TOOL_TARGET,)
    zero_rot: np.ndarray | None = None
    labelled: bool = False
    log: RowLog | None = None
    dp_step_m: float | None = None

    def __post_init__(self):
        n_rows = len(self.q)
        if self.moment is None:
            object.__setattr__(self, "moment", np.zeros((n_rows, 3 if self.force.shape[1] == 3 else 1)))
        if self.target is None:
            object.__setattr__(self, "target", np.zeros(n_rows, int))
        if len(self.resolutions) == 2:
            object.__setattr__(self, "resolutions", (*self.resolutions, MOMENT_RESOLUTION_NM))
        if self.config is None:
            config = cluster(np.degrees(self.q), np.full(self.q.shape[1], self.resolutions[0]),
                             np.full(self.q.shape[1], 360.0))
            object.__setattr__(self, "config", config)
        if not self.config_labels:
            object.__setattr__(self, "config_labels", tuple(_angle_label(np.degrees(self.q[r[0]]))
                                                            for r in rows_by_label(self.config)))
        if self.rows is None:
            object.__setattr__(self, "rows", np.arange(n_rows))
        if self.zero_dp is None:
            object.__setattr__(self, "zero_dp", np.zeros((0, self.dp.shape[1])))

    @classmethod
    def from_arrays(cls, q, force, dp, source: str = "<memory>", config=None,
                    angle_resolution_deg: float = ANGLE_RESOLUTION_DEG,
                    force_resolution_N: float = FORCE_RESOLUTION_N, moment=None, rot=None, target=None,
                    target_names=(TOOL_TARGET,), moment_resolution_Nm: float = MOMENT_RESOLUTION_NM) -> "Measurements":
        """Measurements from arrays of loaded rows, grouped into replicates and configurations by the
        resolutions (module docstring). q (N, n) [rad]; force (N, d) [N]; dp (N, d) [m]; config (N,) optional
        configuration labels; moment (N, d_m) [N m], rot (N, d_r) [rad], target (N,) int into target_names:
        optional (:class:`Measurements`)."""
        q, force, dp = (np.asarray(a, float) for a in (q, force, dp))
        res = (float(angle_resolution_deg), float(force_resolution_N), float(moment_resolution_Nm))
        moment = None if moment is None else np.asarray(moment, float)
        target = None if target is None else np.asarray(target, int)
        group = replicate_groups(np.degrees(q), force, *res[:2], moment, res[2], target)
        cfg = None if config is None else np.unique(np.asarray(config), return_inverse=True)[1].ravel()
        return cls(q, force, dp, group, source, config=cfg, resolutions=res, moment=moment,
                   rot=None if rot is None else np.asarray(rot, float), target=target,
                   target_names=tuple(target_names))

    @property
    def n_rows(self) -> int:
        return len(self.q)

    @property
    def n_configurations(self) -> int:
        return int(self.config.max(initial=-1)) + 1

    def subset(self, keep: np.ndarray) -> "Measurements":
        """The measurements of the rows ``keep`` (bool mask or indices); configurations keep their labels."""
        keep = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep, int)
        used, config = np.unique(self.config[keep], return_inverse=True)
        return Measurements(self.q[keep], self.force[keep], self.dp[keep], self.group[keep], self.source,
                            config.ravel(), tuple(self.config_labels[c] for c in used), self.rows[keep],
                            self.zero_rows, self.zero_dp, self.zero_config, self.notes, self.resolutions,
                            self.moment[keep], None if self.rot is None else self.rot[keep], self.target[keep],
                            self.target_names, self.zero_rot, self.labelled, self.log, self.dp_step_m)

    @property
    def wrench(self) -> np.ndarray:
        """(N, d + d_m) [N, N m]: force and moment of every row."""
        return np.hstack([self.force, self.moment])

    @property
    def has_moment(self) -> bool:
        return bool(np.any(self.moment))

    @property
    def obs(self) -> np.ndarray:
        """(N, d (+ d_r)): the measured quantities of every row, displacement [m] then rotation [rad]."""
        return self.dp if self.rot is None else np.hstack([self.dp, self.rot])

    def structure(self) -> dict:
        """Counts that say how the data were taken: configurations, loads per configuration, replicate
        groups and their sizes, unloaded rows (all plain ints, JSON-ready)."""
        loads = [_loads_at(self.group[r], self.target[r]) for r in rows_by_label(self.config, self.n_configurations)]
        sizes = np.bincount(self.group)
        return {"n_rows": int(self.n_rows), "n_configurations": self.n_configurations,
                "loads_per_configuration": _span(loads), "n_replicate_groups": int(len(sizes)),
                "replicates_per_group": _span(sizes[sizes > 0]),
                "n_groups_with_replicates": int(np.sum(sizes > 1)), "n_unloaded_rows": int(len(self.zero_rows)),
                "angle_resolution_deg": self.resolutions[0], "force_resolution_N": self.resolutions[1],
                "moment_resolution_Nm": self.resolutions[2],
                "targets": [self.target_names[t] for t in np.unique(self.target)],
                "orientation": self.rot is not None}


def _span(counts) -> dict:
    counts = np.asarray(counts, int)
    if counts.size == 0:
        return {"min": 0, "median": 0, "max": 0}
    return {"min": int(counts.min()), "median": float(np.median(counts)), "max": int(counts.max())}


def _angle_label(q_deg: np.ndarray) -> str:
    return "q = (" + ", ".join(f"{v:.2f}" for v in q_deg) + ") deg"


def replicate_groups(q_deg: np.ndarray, force: np.ndarray, angle_resolution_deg: float = ANGLE_RESOLUTION_DEG,
                     force_resolution_N: float = FORCE_RESOLUTION_N, moment: np.ndarray | None = None,
                     moment_resolution_Nm: float = MOMENT_RESOLUTION_NM,
                     target: np.ndarray | None = None) -> np.ndarray:
    """(N,) replicate-group labels: rows of the same target (N,) int whose joint angles [deg] (N, n), forces [N]
    (N, d) and moments [N m] (N, d_m) agree within the resolutions (:func:`cluster`, angles modulo 360 deg)."""
    n, d = q_deg.shape[1], force.shape[1]
    cols, res = [q_deg, force], [np.full(n, angle_resolution_deg), np.full(d, force_resolution_N)]
    period = [np.full(n, 360.0), np.full(d, np.inf)]
    if moment is not None:
        cols.append(moment)
        res.append(np.full(moment.shape[1], moment_resolution_Nm))
        period.append(np.full(moment.shape[1], np.inf))
    if target is not None:  # targets are integers: a resolution of 1/2 keeps different ones apart
        cols.append(np.asarray(target, float)[:, None])
        res.append([0.5])
        period.append([np.inf])
    return cluster(np.hstack(cols), np.concatenate(res), np.concatenate(period))


def _axes(prefix: str, unit: str, k: int, rotation: bool = False) -> list[str]:
    """Column names of a vector quantity: 'fx_N', 'fy_N' (k = 2); rotations and moments of a planar arm: 'mz_Nm'."""
    return [f"{prefix}{a}_{unit}" for a in ("z" if rotation and k == 1 else "xyz"[:k])]


def expected_columns(robot: Robot) -> list[str]:
    """The columns every measured-data CSV of ``robot`` has: joint angles, force, displacement."""
    d = force_dim(robot)
    return [f"q{i + 1}_deg" for i in range(robot.n_joints)] + _axes("f", "N", d) + _axes("d", "m", d)


def optional_columns(robot: Robot) -> dict[str, list[str]]:
    """The optional column groups of ``robot``: 'moment' and 'orientation' (all of a group or none)."""
    dm = moment_dim(robot)
    return {"moment": _axes("m", "Nm", dm, True), "orientation": _axes("r", "rad", dm, True)}


def angle_columns(columns, robot: Robot, source: str) -> list[str]:
    """The file's joint-angle column of each joint (n,): ``q<i>_deg`` (joint i, 1-based) or ``q_<name>_deg``
    (the joint of that name, :attr:`Robot.joint_names`). Raises :class:`InputError` for a joint given both
    ways, a column of a joint number or name the robot does not have, or a named column with another unit;
    a joint given neither way is left to the caller's missing-column message (its ``q<i>_deg`` is returned)."""
    names = {name: i for i, name in enumerate(robot.joint_names)}
    out = [f"q{i + 1}_deg" for i in range(robot.n_joints)]
    expected = (f"expected {robot.n_joints} joint angles for robot {robot.source}: q1_deg ... q{robot.n_joints}_deg "
                f"or q_<name>_deg with a name of {', '.join(robot.joint_names)}")
    for col in columns:
        number = re.fullmatch(r"q(\d+)_deg", col)
        named = re.fullmatch(r"q_(.+)_(\w+)", col)
        if number and not 1 <= int(number.group(1)) <= robot.n_joints:
            raise InputError(f"{expected}; got a column {col}", source=source, field=f"column {col}")
        if number or not named:
            continue
        name, unit = named.groups()
        if name not in names:
            if unit == "deg":
                raise InputError(f"{expected}; got a column {col}", source=source, field=f"column {col}")
            continue
        if unit != "deg":
            raise InputError(f"expected joint angles in deg with the unit in the name ('q_{name}_deg'), got unit "
                             f"'{unit}'", source=source, field=f"column {col}")
        j = names[name]
        if f"q{j + 1}_deg" in columns and name != str(j + 1):
            raise InputError(f"joint {name} is given twice, as q{j + 1}_deg and as {col}; keep one", source=source,
                             field=f"column {col}")
        out[j] = col
    return out


def _loads_at(group: np.ndarray, target: np.ndarray) -> int:
    """The distinct loads of one configuration's rows: replicate groups are per target, so the most groups of any one
    target (a fresh user's one load read by two SMRs counted 2, and the one-load warning stayed silent)."""
    return max((len(np.unique(group[target == t])) for t in np.unique(target)), default=0)


def _rows_text(rows: np.ndarray) -> str:
    """'rows 2, 5 and 9 (data rows 0, 3, 7)': file lines (header = line 1) and 0-based data rows."""
    rows = np.asarray(rows, int)
    more = "" if len(rows) <= _MAX_LISTED else ", ..."
    rows = rows[:_MAX_LISTED]
    return (f"row{'s' if len(rows) > 1 else ''} {', '.join(str(r + 2) for r in rows)}{more} "
            f"(data row{'s' if len(rows) > 1 else ''} {', '.join(str(r) for r in rows)}{more})")


def _spelling(name: str) -> str:
    """A column name without case, spaces and punctuation ('Pose ID' -> 'poseid')."""
    return re.sub(r"[^a-z0-9]", "", name.lower())


#: a clock's column under another name ('time_s', 'Time', 'timestamp', 't [s]'): taken for timestamp_s's misspelling
_CLOCK_NAME = re.compile(r"(?i)^\s*(time(_?stamp)?|t)\s*(_?s(ec)?|\[\s*s\s*\]|\(\s*s\s*\))?\s*$")
#: a column whose spelling (:func:`_spelling`) is this similar to a known name's (difflib's ratio) is taken for it
MISSPELLING_RATIO = 0.85


def _misspelled(columns, known) -> dict[str, str]:
    """{column: known name} for the columns that are not a ``known`` name but look like one that the file lacks:
    the same letters and digits apart from case, spaces and punctuation ('pose id', 'DX_M'), or a spelling
    at least :data:`MISSPELLING_RATIO` similar ('pose_idd')."""
    import difflib

    absent = {_spelling(k): k for k in known if k not in columns}
    out = {}
    for col in columns:
        if col in known:
            continue
        if "timestamp_s" in known and "timestamp_s" not in columns and _CLOCK_NAME.match(col):
            out[col] = "timestamp_s"
            continue
        close = difflib.get_close_matches(_spelling(col), list(absent), n=1, cutoff=MISSPELLING_RATIO)
        if close:
            out[col] = absent[close[0]]
    return out


#: a unit written in a column's name in brackets, as spreadsheets label them ('dx [mm]', 'q1 (deg)')
_BRACKET_UNIT = re.compile(r"[\[(]\s*([^\])]+?)\s*[\])]")


def _renaming(read: dict, needed) -> str:
    """What to do with the columns {column: the name it looks like} of :func:`_misspelled`: rename them (or remove
    one the analysis does not need, not in ``needed``), and where a column's name carries a unit in brackets other
    than that name's, convert it first (a fresh user's 'dx [mm]' was told to rename it dx_m, the millimetres then
    read as metres)."""
    items = []
    for col, name in read.items():
        unit, want = _BRACKET_UNIT.search(col), name.rsplit("_", 1)[-1]
        converted = unit is not None and unit.group(1).replace(" ", "") != want
        items.append(f"{col!r} looks like {name}" + (f" in {unit.group(1)} (convert it to {want})" if converted else "")
                     + ("" if name in needed else " (or remove it)"))
    return (f"{'; '.join(items)}: the analysis reads each only under its name (a misspelling, a unit in brackets?); "
            "rename the column(s) (docs/measured-data.md)")


def _check_units(columns, source: str) -> None:
    for col in columns:
        m = _PATTERN.match(col)
        if not m:
            continue
        kind, unit = m.group(1)[0], m.group(2)
        want = _UNITS[kind]
        if unit != want:
            got = f"unit '{unit}'" if unit else "no unit"
            raise InputError(f"expected {_NAMES[kind]} in {want} with the unit in the name ('{m.group(1)}_{want}'), "
                             f"got {got}", source=source, field=f"column {col}")


#: magnitudes no measurement of a robot reaches (a value beyond is a corrupted cell, not a measurement)
_MAX_ABS = {"q": 3600.0, "f": 1e7, "d": 100.0, "m": 1e7, "r": 10.0, "t": 1e12}


def printed_step(texts) -> float | None:
    """The RMS rounding step of numbers as printed: each nonzero one's step is the value of its last digit (1e-10
    for '2.638988e-04', 1e-6 for '0.000120'), at most 10 times their median (a round number printed without its
    trailing zeros, '0.0002', says little of the writer's digits); None when none is nonzero. Rounding scatters the
    values by this step / sqrt(12) (Sheppard): data whose scatter about the model is no larger carry no
    measurement noise."""
    import pandas as pd

    parts = pd.Series(np.asarray(texts, dtype=str)).str.extract(
        r"^\s*[+-]?(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?\s*$")
    digits = (parts[0].fillna("") + parts[1].fillna("")).str.strip("0")
    keep = (digits != "").to_numpy()
    if not keep.any():
        return None
    exponent = pd.to_numeric(parts[2], errors="coerce").fillna(0).to_numpy()[keep]
    decimals = parts[1].fillna("").str.len().to_numpy()[keep]
    step = 10.0 ** (exponent - decimals)
    return float(np.sqrt(np.mean(np.minimum(step, 10.0 * np.median(step)) ** 2)))


def _numbers(df, cols: list[str], source: str) -> np.ndarray:
    import pandas as pd

    values = np.empty((len(df), len(cols)))
    for j, c in enumerate(cols):
        num = pd.to_numeric(df[c].str.strip(), errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(num))
        if bad.size:
            r = bad[0]
            cell = str(df[c].iloc[r])
            comma = re.fullmatch(r"\s*[-+]?\d+,\d+([eE][-+]?\d+)?\s*", cell)
            hint = (": a decimal comma? write numbers with a decimal point" if comma
                    else ": a date or clock time? give the time in seconds (any origin)"
                    if c.endswith("_s") and re.search(r"\d[-/.:]\d", cell) else "")
            raise InputError(f"expected a finite number, got {cell!r}{hint}", source=source,
                             field=f"row {r + 2} (data row {r}), column {c}")
        limit = _MAX_ABS[c[0]]
        huge = np.flatnonzero(np.abs(num) > limit)
        if huge.size:
            r = huge[0]
            raise InputError(f"expected {_NAMES[c[0]]} of at most {limit:g} {_UNITS[c[0]]} in magnitude, got "
                             f"{df[c].iloc[r].strip()}", source=source, field=f"row {r + 2} (data row {r}), column {c}")
        values[:, j] = num
    return values


def _configurations(labels, q_deg: np.ndarray, angle_res: float, source: str) -> tuple[np.ndarray, tuple, list]:
    """Configuration index per row (the robot's joint configurations: rows whose joint angles agree within
    ``angle_res`` [deg], modulo 360), the label of each and notes. With ``pose_id`` labels (N,): rows sharing a
    label must share their joint angles (else :class:`InputError`); a configuration is labelled by its rows'
    labels ('C01/C13' when several labels name the same joint angles, e.g. a second pass relabelled, with a
    note); without labels, by its joint angles."""
    n = q_deg.shape[1]
    config = cluster(q_deg, np.full(n, angle_res), np.full(n, 360.0))
    in_config = rows_by_label(config)
    first = [int(r[0]) for r in in_config]
    if labels is None:
        return config, tuple(_angle_label(q_deg[i]) for i in first), []
    names, by_name = rows_by_value(labels)
    for c, rows in enumerate(by_name):
        if len(np.unique(config[rows])) > 1:
            other = rows[config[rows] != config[rows[0]]]
            diff = np.abs((q_deg[other[0]] - q_deg[rows[0]] + 180.0) % 360.0 - 180.0)
            j = int(np.argmax(diff))
            raise InputError(
                f"pose_id {names[c]!r} labels one robot configuration, but {_rows_text([rows[0], other[0]])} "
                f"differ by {diff[j]:.4g} deg in q{j + 1} (more than the angle resolution of {angle_res:g} deg); "
                "give each configuration its own pose_id, or raise the angle resolution", source=source,
                field="column pose_id")
    per_config = [list(dict.fromkeys(labels[r])) for r in in_config]  # in file order
    merged = [m for m in per_config if len(m) > 1]
    notes = []
    if merged:
        listed = "; ".join(f"{', '.join(m[:-1])} and {m[-1]}" for m in merged[:_MAX_LISTED])
        more = f"; and {len(merged) - _MAX_LISTED} more" if len(merged) > _MAX_LISTED else ""
        notes.append(f"several pose_id labels name the same joint angles (within the angle resolution of "
                     f"{angle_res:g} deg): {listed}{more}; each set is one configuration ({len(first)} "
                     f"configurations, {len(names)} labels), held out together in the leave-one-configuration-out "
                     "prediction error")
    return config, tuple("/".join(m) for m in per_config), notes


def read_measurements(path: str | Path, robot: Robot, angle_resolution_deg: float = ANGLE_RESOLUTION_DEG,
                      force_resolution_N: float = FORCE_RESOLUTION_N,
                      moment_resolution_Nm: float = MOMENT_RESOLUTION_NM) -> Measurements:
    """Read and validate a measured-data CSV for ``robot`` (module docstring).

    Raises :class:`InputError` (naming the file, row and column) for: an unreadable file; a column with a
    wrong or missing unit; missing or surplus joint, force or displacement columns; some but not all of the
    arm's moment or orientation columns; a value that is not a finite number; a ``target`` the robot file does
    not name, or blank; blank ``pose_id`` cells beside filled ones; rows that share a ``pose_id`` but not their
    joint angles; no loaded row; forces that look like kN (:func:`_check_loads_below_resolution`); a column that
    looks like a misspelling of one the analysis reads ('DX_M', 'Target'). Columns the analysis does not use are
    named in ``notes`` (one that looks like ``pose_id``, 'pose id', with a suggestion), and so are ``pose_id``
    labels merged into one configuration.
    """
    source = str(path)
    for name, v in (("angle resolution", angle_resolution_deg), ("force resolution", force_resolution_N),
                    ("moment resolution", moment_resolution_Nm)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"expected a {name} > 0, got {v}", field=name.replace(" ", "_"))
    df = _read_table(path, source)
    cols, groups, notes = _data_columns(df, robot, source)
    used = cols + groups["moment"] + groups["orientation"]
    values = _numbers(df, used, source)
    n, d, dm = robot.n_joints, force_dim(robot), moment_dim(robot)
    q_deg, force, dp = values[:, :n], values[:, n:n + d], values[:, n + d:n + 2 * d]
    at = n + 2 * d
    moment = values[:, at:at + dm] if groups["moment"] else np.zeros((len(df), dm))
    at += len(groups["moment"])
    rot = values[:, at:at + dm] if groups["orientation"] else None
    target, target_names = _targets(df, robot, source)

    labels, more = _pose_labels(df, source)
    notes += more
    config, names, config_notes = _configurations(labels, q_deg, angle_resolution_deg, source)
    notes += config_notes

    unloaded = _unloaded_rows(force, moment, force_resolution_N, moment_resolution_Nm, bool(groups["moment"]),
                              source)
    _check_loads_below_resolution(q_deg, force, moment if groups["moment"] else None, dp, target, unloaded,
                                  angle_resolution_deg, force_resolution_N, moment_resolution_Nm, cols[n:n + d], source)
    loaded = np.flatnonzero(~unloaded)
    zero = np.flatnonzero(unloaded)
    notes += _unit_checks(robot, df, q_deg, dp, loaded, cols, source)
    if zero.size:
        notes.append(f"{zero.size} unloaded row(s) ({_rows_text(zero)}) taken as the zero point, not as "
                     "measurements")
    cfg_loaded, cfg_index = np.unique(config[loaded], return_inverse=True)
    lookup = {int(c): i for i, c in enumerate(cfg_loaded)}
    zero_config = np.array([lookup.get(int(c), -1) for c in config[zero]], int)
    res = (float(angle_resolution_deg), float(force_resolution_N), float(moment_resolution_Nm))
    has_m = bool(groups["moment"])
    group = replicate_groups(q_deg[loaded], force[loaded], *res[:2], moment[loaded] if has_m else None, res[2],
                             target[loaded])
    log, log_notes = _row_log(df, source, labels, target, config, unloaded, dp, rot, group, loaded)
    return Measurements(np.radians(q_deg[loaded]), force[loaded], dp[loaded], group, source, cfg_index.ravel(),
                        tuple(names[c] for c in cfg_loaded), loaded, zero, dp[zero], zero_config,
                        tuple(notes + log_notes), res, moment[loaded], None if rot is None else rot[loaded],
                        target[loaded], target_names, None if rot is None else rot[zero], labels is not None, log,
                        printed_step(df.loc[loaded, used[n + d:n + 2 * d]].to_numpy().ravel()))


def _read_table(path, source: str):
    """The CSV as a table of strings (pandas), its column names stripped and their units checked."""
    import pandas as pd

    from ..limits import MAX_MEASURED_ROWS

    try:
        _header(path, source, MAX_MEASURED_ROWS)
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read a CSV table ({err})", source=source) from None
    df.columns = [c.strip() for c in df.columns]
    _check_units(df.columns, source)
    return df


def _data_columns(df, robot: Robot, source: str) -> tuple[list[str], dict, list[str]]:
    """(the columns the analysis reads: the joint angles, the force, the displacement; the optional groups
    {"moment": [...], "orientation": [...]} present (each all or none); notes on the columns it ignores) of the
    table ``df``. Raises :class:`InputError` for a misspelled, missing or incomplete column or an empty table."""
    cols = angle_columns(list(df.columns), robot, source) + expected_columns(robot)[robot.n_joints:]
    misspelled = _misspelled(df.columns, cols + sum(optional_columns(robot).values(), []) + ["target", "pose_id",
                                                                                            *LOG_COLUMNS])
    read = {col: name for col, name in misspelled.items() if name not in ("pose_id", *LOG_COLUMNS)}
    if read:  # the analysis would go on without a quantity it reads: refuse, naming every such column at once
        raise InputError(_renaming(read, cols), source=source,
                         field=f"column{'s' if len(read) > 1 else ''} {', '.join(read)}")
    missing = [c for c in cols if c not in df.columns]
    if missing:
        bare = [c for c in df.columns if c in robot.joint_names]  # a joint's name alone, as ROS logs it
        hint = (f"; the column(s) {', '.join(bare)} are the robot's joint names without unit: name each "
                f"q_<name>_deg ('q_{bare[0]}_deg', angles in degrees) or q<i>_deg" if bare else "")
        raise InputError(f"missing column(s) {', '.join(missing)}; expected {', '.join(cols)} (and optionally pose_id, "
                         f"target, the moment and the orientation){hint}", source=source)
    groups = {}
    for what, names in optional_columns(robot).items():
        have = [c for c in names if c in df.columns]
        if have and len(have) < len(names):
            raise InputError(f"missing column(s) {', '.join(c for c in names if c not in have)}: the {what} has "
                             f"{len(names)} component(s) for a {robot.kind} robot ({', '.join(names)}); give all or "
                             "none", source=source, field=f"column {have[0]}")
        groups[what] = names if have else []
    if len(df) == 0:
        raise InputError("no measurements (the file has a header only)", source=source)
    used = cols + groups["moment"] + groups["orientation"]
    notes = []
    surplus = [c for c in df.columns if _PATTERN.match(c) and c not in used]
    if surplus:
        notes.append(f"column(s) {', '.join(surplus)} do not belong to a {robot.kind} robot with {robot.task_dim} "
                     f"measured coordinates and are ignored")
    unnamed = [c for c in df.columns if c not in used and _UNNAMED.fullmatch(c) and (df[c].str.strip() == "").all()]
    if unnamed:
        notes.append(f"{len(unnamed)} column(s) without a name and blank in every row (a comma at the end of every "
                     "line?) are ignored")
    unused = [c for c in df.columns if c not in used and c not in ("pose_id", "target", *LOG_COLUMNS)
              and c not in surplus and c not in unnamed]
    if unused:
        notes.append(f"column(s) {', '.join(unused)} not used by the analysis"
                     + "".join(f"; {c!r} looks like {name} (a misspelling?): rename it {name} to "
                               + _LOG_USE[name] for c, name in misspelled.items()))
    return cols, groups, notes


def _pose_labels(df, source: str) -> tuple[np.ndarray | None, list[str]]:
    """(the ``pose_id`` labels (N,), None without the column or with it blank in every row; notes). Raises
    :class:`InputError` for a label too long or blank cells beside filled ones."""
    if "pose_id" not in df.columns:
        return None, []
    from ..limits import MAX_LABEL_CHARS

    stripped = df["pose_id"].str.strip()
    raw = stripped.to_numpy()
    long = np.flatnonzero(stripped.str.len().to_numpy() > MAX_LABEL_CHARS)
    if long.size:
        r = int(long[0])
        raise InputError(f"expected a label of at most {MAX_LABEL_CHARS} characters (a configuration's name), got "
                         f"{len(raw[r]):,}", source=source, field=f"row {r + 2} (data row {r}), column pose_id")
    blank = np.flatnonzero(raw == "")
    if blank.size == len(raw):
        return None, ["column pose_id is blank in every row: configurations come from the joint angles"]
    if blank.size:
        raise InputError(f"pose_id is blank in {_rows_text(blank)} but filled in the other rows; give every "
                         "row the label of its robot configuration, or drop the column (configurations are "
                         "then found from the joint angles)", source=source, field="column pose_id")
    return raw, []


#: a median displacement of the loaded rows above this fraction of the arm's reach is refused: no serial robot deflects
#: that far elastically, and an elasto-static (small-deflection) model would not describe it (absolute positions,
#: or a unit 1000 too small)
MAX_DISPLACEMENT_OF_REACH = 0.02


def _medians(values) -> str:
    return ", ".join(f"{v:.3g}" for v in values)


def check_displacement_size(robot: Robot, dp: np.ndarray, columns: list[str], source: str) -> None:
    """Raise :class:`InputError` when the loaded rows' displacements ``dp`` (N, d) [m] are, in the median, more than
    :data:`MAX_DISPLACEMENT_OF_REACH` of the robot's reach: not deflections."""
    reach = robot.reach_m
    size = float(np.median(np.linalg.norm(dp, axis=1))) if len(dp) else 0.0
    if reach > 0 and size > MAX_DISPLACEMENT_OF_REACH * reach:
        each = np.median(np.abs(dp), axis=0)  # the columns that alone reach the bound: one column in mm is named
        big = each > MAX_DISPLACEMENT_OF_REACH * reach / np.sqrt(len(columns))
        named = [c for c, b in zip(columns, big) if b] if 0 < big.sum() < len(columns) else list(columns)
        which = "" if len(named) == len(columns) else (
            f"; {', '.join(named)} {_medians(each[big])} m in the median, the other column(s) "
            f"{_medians(each[~big])} m")
        raise InputError(f"expected deflections (each loaded reading less its unloaded reference reading, in metres), "
                         f"but the loaded rows' displacements are {size:.3g} m in the median, {100 * size / reach:.3g} "
                         f"% of the arm's reach ({reach:.3g} m): no serial robot deflects that far elastically; "
                         f"absolute positions, or millimetres in columns labelled metres?{which}", source=source,
                         field=f"column{'s' if len(named) > 1 else ''} {', '.join(named)}")


def _unit_checks(robot: Robot, df, q_deg, dp, loaded: np.ndarray, cols: list[str], source: str) -> list[str]:
    """The reader's checks of the data's units (each raises :class:`InputError` naming the columns): the
    displacements' size against the reach, angles in radians, a log pasted twice; returns the notes of the
    doubtful (angles outside the limits, a row repeated once). The moments' and rotations' units are checked
    against the model by the analysis (:func:`stiffcal.measured.discrepancy.plausibility`)."""
    n, d = robot.n_joints, force_dim(robot)
    check_displacement_size(robot, dp[loaded], cols[n + d:n + 2 * d], source)
    notes = check_angles(q_deg, cols[:n], robot, source, refuse=False)
    return notes + _duplicate_notes(df, loaded[np.any(dp[loaded] != 0, axis=1)], cols[n + d:n + 2 * d], source)


def _unloaded_rows(force: np.ndarray, moment: np.ndarray, force_resolution_N: float, moment_resolution_Nm: float,
                   has_moment: bool, source: str) -> np.ndarray:
    """(N,) bool: the rows whose every force component is within ``force_resolution_N`` of zero and every moment
    within ``moment_resolution_Nm``. Raises :class:`InputError` when every row is (with a hint at kN)."""
    unloaded = np.all(np.abs(force) <= force_resolution_N, axis=1) & np.all(np.abs(moment) <= moment_resolution_Nm,
                                                                            axis=1)
    if unloaded.all():
        largest = float(np.abs(force).max())
        kn = (f"; the largest force component is {largest:g} N, below the force resolution of {force_resolution_N:g} "
              "N: if the forces are in kN (labelled N), give them in newtons (x 1000), or lower the force resolution"
              if largest > 0 else "")
        raise InputError(f"every row is unloaded (all force components within {force_resolution_N:g} N of zero"
                         f"{f' and moments within {moment_resolution_Nm:g} N m' if has_moment else ''}); "
                         f"expected measurements under load{kn}", source=source)
    return unloaded


def _row_log(df, source: str, labels, target, config, unloaded, dp, rot, group, loaded) -> tuple[RowLog, list[str]]:
    """The :class:`RowLog` of the file (its ``timestamp_s``, ``visit`` and ``reference`` columns; docs), and notes.
    Raises :class:`InputError` for a timestamp that is not a finite number, or blank ``visit``/``reference``
    cells beside filled ones."""
    n = len(df)
    notes = []
    time, has_time = np.arange(n, dtype=float), False
    if "timestamp_s" in df.columns:
        time = _numbers(df, ["timestamp_s"], source)[:, 0]
        has_time = True
        back = np.flatnonzero(np.diff(time) < 0)
        if back.size:
            notes.append(f"timestamp_s runs backwards at {_rows_text(back + 1)}: the rows are taken in the order of "
                         "their timestamps (the reference readings and visits are found in that order)")
        notes += _clock_notes(time)
    columns = {}
    for col in ("visit", "reference"):
        if col not in df.columns:
            columns[col] = None
            continue
        raw = df[col].str.strip().to_numpy()
        blank = np.flatnonzero(raw == "")
        if blank.size == n:
            notes.append(f"column {col} is blank in every row: it is not used")
            columns[col] = None
        elif blank.size:
            raise InputError(f"{col} is blank in {_rows_text(blank)} but filled in the other rows; give every row "
                             f"the label of its {'visit' if col == 'visit' else 'reference reading'}, or drop the "
                             "column", source=source, field=f"column {col}")
        else:
            columns[col] = raw
    obs = dp if rot is None else np.hstack([dp, rot])
    exact = unloaded & np.all(obs == 0.0, axis=1)
    full_group = np.full(n, -1)
    full_group[loaded] = group
    return RowLog(time, has_time, labels, columns["visit"], columns["reference"], np.asarray(target, int),
                  np.asarray(config, int), ~unloaded, exact, full_group), notes


#: timestamps [s] whose campaign spans more than this are named (milliseconds labelled seconds?) ...
CLOCK_MAX_SPAN_S = 30 * 86400.0
#: ... and those whose readings follow each other by less than this in the median (hours or minutes labelled seconds?)
CLOCK_MIN_STEP_S = 0.1


def _clock_notes(time: np.ndarray) -> list[str]:
    """A note when the timestamps ``time`` (N,) [s] are in another unit than seconds: a campaign longer than
    :data:`CLOCK_MAX_SPAN_S`, or readings :data:`CLOCK_MIN_STEP_S` apart in the median (a tracker reading under a
    load takes seconds). A fresh user's 3-hour campaign logged in milliseconds was read as a drift of 0.04 um/h at
    p = 5e-17, in hours as 1.4e5 um/h, with no word of the unit."""
    steps = np.diff(np.sort(time))
    steps = steps[steps > 0]
    span = float(np.ptp(time)) if time.size else 0.0
    if span > CLOCK_MAX_SPAN_S:
        return [f"timestamp_s spans {span / 86400:.3g} days from the first row to the last: milliseconds labelled "
                "seconds? The drift test (diagnostics.time) reads its rate per hour of this clock"]
    if steps.size and float(np.median(steps)) < CLOCK_MIN_STEP_S:
        return [f"timestamp_s has the readings {float(np.median(steps)):.3g} s apart in the median (the whole log "
                f"{span:.3g} s): hours or minutes labelled seconds? The drift test (diagnostics.time) reads its rate "
                "per hour of this clock"]
    return []


#: rows classed unloaded that deflect like loaded rows are taken for loads in kN when every force is at most this
KN_MAX_FORCE = 100.0
#: ... and their deflection is within this factor of what the loaded rows' compliance gives for their force
KN_COMPLIANCE_FACTOR = 5.0


def _check_loads_below_resolution(q_deg, force, moment, dp, target, unloaded, angle_res, force_res, moment_res,
                                  force_cols, source) -> None:
    """Refuse forces given in kN under N columns (all of them, or some columns beside others in N) when only some
    rows fall below the force resolution.

    Rows classed unloaded (``unloaded`` (N,) bool) whose force is not zero are loads below the resolution, not the
    zero point, when all of: every force magnitude is at most :data:`KN_MAX_FORCE` (numbers typical of kN); their
    median displacement per unit force is within :data:`KN_COMPLIANCE_FACTOR` of the loaded rows' (they deflect
    as the loaded rows' compliance predicts for their force); and the median of their squared displacements
    over the noise variance is above what noise gives at a level of at most 1 % (Bonferroni over the median of
    ``||dp||^2 / (d sigma^2) ~ chi2(d) / d`` per row, its order statistic through the Beta distribution, at
    0.5 %, and the estimate of sigma^2 ~ sigma^2 chi2(df) / df at 0.5 %; sigma^2 the pure error of the replicate
    groups, at the force
    and moment resolutions divided by 1000 as they would be for kN, pooled with the unloaded rows of zero force
    about zero; rows of exactly zero displacement, a reference by definition, carry no noise) or, with no noise
    estimate, at least 5 % of the loaded rows' median displacement. Genuine
    reference rows (zero force, or a load cell's reading below the resolution with a displacement within the
    noise) pass. With some force columns above :data:`KN_MAX_FORCE` (in N) and others not (kN?), the rows classed
    unloaded that are pushed through the latter only (exactly zero in the former: a load cell's zero reading has
    some of every component) must deflect within :data:`KN_COMPLIANCE_FACTOR` of 1000 times
    what the compliance of the rows loaded through the former gives for their number. q_deg (N, n) [deg]; force,
    dp (N, d); moment (N, d_m) or None; target (N,) int."""
    fmag, dmag = np.linalg.norm(force, axis=1), np.linalg.norm(dp, axis=1)
    small = np.flatnonzero(unloaded & (fmag > 0))
    big = ~unloaded & (np.abs(force).max(axis=1) > force_res)
    top = np.abs(force).max(axis=0)
    kn, newton = (top > 0) & (top <= KN_MAX_FORCE), top > KN_MAX_FORCE  # columns with numbers typical of kN, of N
    scale = 1.0
    if newton.any():  # some columns in kN: the small rows pushed through them only, at 1000 times their number
        big &= np.all(np.abs(force[:, kn]) <= force_res, axis=1)  # the compliance from the other columns' loads
        small = small[~np.any(force[np.ix_(small, newton)] != 0, axis=1)]  # not a load cell's zero reading
        scale = 1000.0
    if small.size == 0 or not big.any():
        return
    compliance = float(np.median(dmag[big] / fmag[big]))
    ratio = float(np.median(dmag[small] / (compliance * scale * fmag[small]))) if compliance > 0 else 0.0
    if not 1 / KN_COMPLIANCE_FACTOR <= ratio <= KN_COMPLIANCE_FACTOR:
        return
    sigma2, df = _noise_at_kn_resolutions(q_deg, force, moment, dp, target, unloaded, angle_res, force_res,
                                          moment_res)
    noise = ""
    if df > 0 and sigma2 > 0:
        if not _beyond_noise(dmag[small], dp.shape[1], sigma2, df):
            return
        noise = f", beyond the noise of {np.sqrt(sigma2) * 1e6:.3g} um"
    elif np.median(dmag[small]) < 0.05 * np.median(dmag[big]):
        return
    cols = [c for c, k in zip(force_cols, kn) if k or scale == 1.0]
    others = [c for c, k in zip(force_cols, newton) if k]
    why = (f"every force is at most {fmag.max():g} N: the forces look like kN labelled N; give them in newtons "
           "(x 1000), or lower the force resolution" if scale == 1.0 else
           f"column(s) {', '.join(cols)} hold at most {np.abs(force[:, kn]).max():g} N while {', '.join(others)} "
           f"reach {top[newton].max():g} N: {', '.join(cols)} look{'s' if len(cols) == 1 else ''} like kN labelled "
           "N; give every force in newtons")
    raise InputError(
        f"{small.size} row(s) classed as unloaded ({_rows_text(small)}) carry forces of {fmag[small].min():g} to "
        f"{fmag[small].max():g} N, below the force resolution of {force_res:g} N, yet deflect as the loaded rows do "
        f"under {'such forces' if scale == 1.0 else '1000 times such forces'} ({np.median(dmag[small]) * 1e6:.3g} um "
        f"in the median, {ratio:.2g} times what the loaded rows' compliance gives{noise}): they are loads, not the "
        f"zero point, and {why}", source=source, field=f"columns {', '.join(cols)}")


def _noise_at_kn_resolutions(q_deg, force, moment, dp, target, unloaded, angle_res, force_res,
                             moment_res) -> tuple[float, int]:
    """(sigma^2 [m^2], df): the pure error of the replicate groups at the force and moment resolutions divided by
    1000 (as they would be for kN), pooled with the unloaded rows of zero force about zero (rows of exactly zero
    displacement, a reference by definition, carry no noise); (0, 0) where there is none."""
    d = dp.shape[1]
    zero_force = unloaded & (np.linalg.norm(force, axis=1) == 0)
    ref = zero_force & np.any(dp != 0, axis=1)  # reference rows that carry noise
    rest = np.flatnonzero(~zero_force)
    group = replicate_groups(q_deg[rest], force[rest], angle_res, force_res / 1000,
                             None if moment is None else moment[rest], moment_res / 1000, target[rest])
    sums = np.zeros((group.max(initial=-1) + 1, d))
    np.add.at(sums, group, dp[rest])
    means = sums / np.bincount(group, minlength=len(sums))[:, None]
    ss = float(np.sum((dp[rest] - means[group]) ** 2) + np.sum(dp[ref] ** 2))
    df = d * (len(rest) - len(means) + int(ref.sum()))
    return (ss / df, df) if df > 0 else (0.0, 0)


def _beyond_noise(dmag: np.ndarray, d: int, sigma2: float, df: int) -> bool:
    """Whether the median of the rows' ||dp||^2 / (d sigma^2) (dmag (m,) [m] their displacements' norms) is above
    what noise gives at a level of at most 1 %: Bonferroni over its order statistic through the Beta distribution
    at 0.5 % and the estimate sigma^2 ~ sigma^2 chi2(df) / df at 0.5 %."""
    from . import distributions as dist

    k = (dmag.size + 1) // 2  # the median's order statistic: F(X_(k)) ~ Beta(k, m - k + 1) under the noise
    median = dist.chi2_ppf(dist.beta_ppf(0.995, k, dmag.size - k + 1), d) / d  # of ||dp||^2 / (d sigma^2)
    return bool(np.sort(dmag**2)[k - 1] / (d * sigma2) > median / (dist.chi2_ppf(0.005, df) / df))


#: what a measured-data file beyond MAX_MEASURED_ROWS should do instead
ROWS_HINT = ("(MAX_MEASURED_ROWS: the analysis grows linearly with the rows, 2 x 10^5 rows of a 6-axis arm take "
             "about two minutes and 2.7 GB; docs/contracts.md, 'Limits'): average the replicates of each configuration "
             "and load, or analyse the log in parts")


def check_noise_levels(sigma_m_given: bool, sigma_rad_given: bool, source: str | None = None,
                       prefix: str = "") -> None:
    """Raise :class:`InputError` unless both noise levels (``sigma_m`` [m], ``sigma_rad`` [rad]) or neither are
    given, naming the missing one (``prefix``: where they are given, e.g. a config entry's path)."""
    if sigma_m_given != sigma_rad_given:
        raise InputError("expected both noise levels (sigma_m and sigma_rad) or neither: their ratio weighs the "
                         "rotation rows of data with orientation columns against the positions (the noise itself is "
                         "always estimated from the data)", source=source,
                         field=prefix + ("sigma_rad" if sigma_m_given else "sigma_m"))


#: the name pandas gives a column whose header cell is empty
_UNNAMED = re.compile(r"Unnamed: \d+")

#: characters no lab's CSV holds (C0 controls but tab, line feed and carriage return; DEL): a binary or damaged file
_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def _check_text(row: list[str], names: list[str], line_no: int, source: str) -> None:
    """Raise :class:`InputError` naming the row and column of the first control character in ``row`` (a NUL in a
    pose_id would otherwise make a configuration's rows two configurations, silently)."""
    if _CONTROL.search("".join(row)) is None:  # one search a row; the cell only when there is one
        return
    j, found = next((j, m) for j, m in enumerate(map(_CONTROL.search, row)) if m)
    where = f"row {line_no}" + (f" (data row {line_no - 2})" if line_no > 1 else "") + (
        f", column {names[j]}" if line_no > 1 and j < len(names) else "")
    raise InputError(f"a control character (U+{ord(found.group()):04X}) in a cell: expected text (numbers, labels), "
                     "not a binary or damaged file; remove it, or write the file again from its source", source=source,
                     field=where)


def _header(path, source: str, max_rows: int | None = None, hint: str = ROWS_HINT) -> list[str]:
    """The header row as the file writes it (pandas renames a repeated name 'dx_m' to 'dx_m.1'): raises
    :class:`InputError` for a control character in any cell (:func:`_check_text`), a column name given twice, a
    header with no comma but semicolons or tabs (a file separated by another character: a comma-separated file is
    expected), or a row with more or fewer fields than the header (pandas would take a surplus first field as the
    index and shift every column), or more than ``max_rows`` data rows (counted before anything is parsed)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            line = fh.readline()
            if line == "":
                raise InputError("the file is empty: expected a CSV table, a header row naming its columns and a "
                                 "row per reading", source=source)
        return _header_and_rows(path, line, source, max_rows, hint)
    except UnicodeDecodeError:
        raise _not_utf8(path, source) from None


def _not_utf8(path, source: str) -> InputError:
    """The error for a file that is not UTF-8 text, naming the row and byte where it stops being."""
    raw = Path(path).read_bytes()
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as err:
        row = raw.count(b"\n", 0, err.start) + 1
        if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):  # UTF-16's byte-order mark (Excel's "Unicode text")
            return InputError("not UTF-8 text: UTF-16 (the file begins with its byte-order mark, as Excel's "
                              "'Unicode text' writes it); save it as 'CSV UTF-8'", source=source, field="row 1")
        return InputError(f"not UTF-8 text: byte 0x{raw[err.start]:02x} (a file saved as Latin-1 or Windows-1252, "
                          "whose degree sign or accented letters UTF-8 cannot read?); save it as UTF-8",
                          source=source, field=f"row {row}")
    return InputError("not UTF-8 text", source=source)


def _header_and_rows(path, line: str, source: str, max_rows: int | None, hint: str) -> list[str]:
    """:func:`_header` from its first ``line`` on."""
    import csv
    from collections import Counter

    from ..limits import MAX_MEASURED_COLUMNS

    def unsplittable(err, row: int) -> InputError:  # csv's own errors (a field over its 128 KiB limit)
        return InputError(f"not a CSV row a reader can split ({err})", source=source, field=f"row {row}")

    if line.count(",") >= MAX_MEASURED_COLUMNS:
        raise InputError(f"more than {MAX_MEASURED_COLUMNS:,} columns in the header (the most read; a measured-data "
                         "file has a dozen or two): not a measured-data table", source=source, field="row 1")
    try:
        names = [c.strip() for c in next(csv.reader([line]), [])]
    except csv.Error as err:
        raise unsplittable(err, 1) from None
    seps = {";": "';' (semicolons)", "\t": "tabs"}
    seen = [sep for sep in seps if sep in line]
    if len(names) <= 1 and seen:
        sep = max(seen, key=line.count)
        raise InputError(f"missing columns: the header is one column separated by {seps[sep]} "
                         f"({line.strip()[:80]!r}), but the file must be comma-separated; save it as CSV with commas "
                         "(and a decimal point)", source=source)
    line_no, data_rows = 0, 0
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = csv.reader(fh)
        while True:
            try:
                row = next(rows, None)
            except csv.Error as err:
                raise unsplittable(err, line_no + 1) from None
            if row is None:
                break
            line_no += 1
            _check_text(row, names, line_no, source)
            filled = line_no > 1 and any(c.strip() for c in row)  # blank lines are not rows
            data_rows += filled
            if max_rows is not None and data_rows > max_rows:
                raise InputError(f"more than {max_rows:,} data rows {hint}", source=source)
            if filled and len(row) != len(names):
                r = line_no - 2
                if line.lstrip().startswith("#"):
                    raise InputError(f"the first line ({line.strip()[:60]!r}) is a comment, read as the header: "
                                     "comment lines are not read; remove them (the header must be the first line)",
                                     source=source, field="row 1")
                raise InputError(f"expected {len(names)} fields as in the header, got {len(row)}: a comma too "
                                 f"{'many' if len(row) > len(names) else 'few'} (a trailing comma, a decimal comma, "
                                 "a value or a header name missing?)", source=source,
                                 field=f"row {line_no} (data row {r})")
    counts = Counter(names)
    twice = sorted({c for c in names if counts[c] > 1}, key=names.index)
    if twice:
        where = "; ".join(f"{c} (header columns {', '.join(str(i + 1) for i, x in enumerate(names) if x == c)})"
                          for c in twice)
        raise InputError(f"column name(s) given more than once: {where}; give each quantity one column",
                         source=source, field=f"column {twice[0]}")
    return names


#: angles all within this magnitude [deg] over at least RADIANS_MIN_ROWS rows look like radians (a full turn in
#: radians, 2 pi: controllers that report 0 .. 2 pi, such as a Kinova's, as well as -pi .. pi)
RADIANS_MAX_DEG = 6.4
RADIANS_MIN_ROWS = 10


def looks_like_radians(q_deg: np.ndarray, robot: Robot) -> str | None:
    """Why the joint angles q_deg (N, n) [deg] look like radians (every angle within +-RADIANS_MAX_DEG deg over
    RADIANS_MIN_ROWS rows or more, of a robot whose joints range over more than ten times that), else None."""
    span = float(np.max(np.degrees(robot.joint_limits_rad[:, 1] - robot.joint_limits_rad[:, 0])))
    if (len(q_deg) >= RADIANS_MIN_ROWS and np.all(np.abs(q_deg) <= RADIANS_MAX_DEG) and np.ptp(q_deg) > 0
            and span > 10 * RADIANS_MAX_DEG):
        return (f"they are all within +-{RADIANS_MAX_DEG:g} deg over {len(q_deg)} rows while the robot's joints range "
                f"over up to {span:.0f} deg")
    return None


def check_angles(q_deg: np.ndarray, cols: list[str], robot: Robot, source: str, refuse: bool = True) -> list[str]:
    """Notes on joint angles outside the robot file's joint limits (rows and joints named), and on angles that
    :func:`looks_like_radians`: with ``refuse`` (a path to predict or compensate) an :class:`InputError`, else a
    note (measured data: poses within 3 degrees of a bent home pose are valid; the analysis refuses them when
    the model also misfits, :func:`stiffcal.measured.discrepancy.plausibility`)."""
    notes = []
    lims = np.degrees(robot.joint_limits_rad)
    why = looks_like_radians(q_deg, robot)
    if why and refuse:
        raise InputError(f"expected joint angles in degrees, but {why}: the angles look like radians; give them in "
                         "degrees (x 180/pi)", source=source, field=f"columns {', '.join(cols)}")
    if why:
        notes.append(f"the joint angles ({', '.join(cols)}) look like radians: {why}; if they are, give them in "
                     "degrees (x 180/pi)")
    if robot.has_joint_limits:
        tol = LIMIT_TOLERANCE_DEG
        for j, col in enumerate(cols):
            if j in robot.unlimited_joints:
                continue
            out = np.flatnonzero((q_deg[:, j] < lims[j, 0] - tol) | (q_deg[:, j] > lims[j, 1] + tol))
            if out.size:
                notes.append(f"{col} is outside the joint limits of robot {robot.source} ([{lims[j, 0]:g}, "
                             f"{lims[j, 1]:g}] deg) in {out.size} {_rows_text(out)}: check the robot file's "
                             "joint_limits_deg, the order of the joint columns and the angle unit")
    return notes


#: how far [deg] a logged angle may lie beyond a joint limit without a note: the digits a controller logs (a plan's
#: pose at a URDF limit of 3.05432619 rad = 174.99999 deg, logged as 175.0000, is at the limit, not beyond it)
LIMIT_TOLERANCE_DEG = 1e-3


#: exact copies of loaded rows refused as a log pasted twice: at least this many and this share of the loaded rows
PASTED_ROWS = (2, 0.05)


def _duplicate_notes(df, loaded: np.ndarray, displacement_columns: list[str], source: str) -> list[str]:
    """A note naming loaded rows that repeat an earlier row exactly in every column (a row pasted twice?);
    they are kept as replicates. Unloaded rows are left out: a reference row of zeros repeats naturally.
    Raises :class:`InputError` when the copies repeat a timestamp, or are a block (at least :data:`PASTED_ROWS`:
    two rows and 5 % of the loaded ones, 80 % of them at one distance from their originals; replicates printed at a
    coarse resolution coincide by chance, at scattered distances): no tracker reads the same displacement twice to
    the last digit, and kept as replicates the copies would make a noise estimate of zero spread (a log pasted
    twice gave a confident false cause)."""
    sub = df.iloc[loaded].apply(lambda c: c.str.strip())
    again = np.flatnonzero(sub.duplicated(keep="first").to_numpy())
    if again.size == 0:
        return []
    key = sub.apply(tuple, axis=1).to_numpy()
    first = {}
    for i, k in enumerate(key):
        first.setdefault(k, i)
    pairs = [(int(loaded[first[key[i]]]), int(loaded[i])) for i in again]
    text = "; ".join(f"row {b + 2} (data row {b}) repeats row {a + 2} (data row {a})" for a, b in pairs[:_MAX_LISTED])
    more = f" and {len(pairs) - _MAX_LISTED} more" if len(pairs) > _MAX_LISTED else ""
    timed = "timestamp_s" in df.columns
    shift = np.bincount([b - a for a, b in pairs]).max()  # a pasted block repeats rows at one distance
    if timed or (len(pairs) >= PASTED_ROWS[0] and len(pairs) >= PASTED_ROWS[1] * len(loaded)
                 and shift >= 0.8 * len(pairs)):
        when = ", the time included" if timed else ""
        raise InputError(f"expected each loaded row to be a reading of its own, but {len(pairs)} of the "
                         f"{len(loaded)} loaded rows repeat an earlier row exactly in every column{when} "
                         f"({text}{more}): exact copies of earlier readings (the same readings pasted twice, or "
                         "replicates written as their average?); no tracker reads the same displacement twice to the "
                         "last digit: remove the copies, or give every reading", source=source,
                         field=f"columns {', '.join(displacement_columns)}")
    return [f"{len(pairs)} loaded row(s) repeat an earlier row exactly in every column ({text}{more}): a row pasted "
            "twice? They are kept as replicates"]


def _targets(df, robot: Robot, source: str) -> tuple[np.ndarray, tuple[str, ...]]:
    """The ``target`` column as (N,) indices into the robot's target names (all the tool point without it)."""
    names = robot.target_names
    if "target" not in df.columns:
        return np.zeros(len(df), int), names
    raw = df["target"].str.strip().to_numpy()
    index = {t: i for i, t in enumerate(names)}
    bad = np.flatnonzero([t not in index for t in raw])
    if bad.size:
        r = int(bad[0])
        raise InputError(f"expected a target of robot {robot.source} ({', '.join(names)}: its targets and the tool "
                         f"point), got {raw[r]!r}", source=source, field=f"row {r + 2} (data row {r}), column target")
    return np.array([index[t] for t in raw], int), names
