"""The public Python API, for notebooks and scripts (``import stiffcal``), in the style of
``scipy.optimize.minimize``: one entry point per task, one result object, validation at the edge.

>>> import stiffcal
>>> robot = stiffcal.load_robot("config/robots/paper_2r.yaml")
>>> res = stiffcal.design(robot, test_pose_deg=[60, 30], force_N=[0, -1], experiments=3)
>>> res.O_t, res.chi, res.lower_bound, res.poses_deg          # doctest: +SKIP

Units at this edge, as in every file, table and command-line option: **angles in degrees** (every angle
argument and field ends in ``_deg``), lengths in metres, forces in newtons, ``sigma`` in the unit of the
measured displacement (1 reproduces the paper's numbers; 1e-5 for 10 micrometres). Inside the library
angles are radians. Bad input raises :class:`stiffcal.errors.InputError` naming the argument and what was
expected; the ``stiffcal`` command is a thin layer over these functions and prints the same message.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError, short_repr
from .jsonsafe import _json_number, json_safe  # noqa: F401  (re-exported: part of this module's API)
from .measured.results import DiscriminationPlan, Verdict
from .limits import (MAX_DESIGN_EXPERIMENTS, MAX_DISCRIMINATE_EXPERIMENTS, MAX_FORCE_N, MAX_MOMENT_NM, MIN_LOAD)
from .model.robot import MAX_JOINT_ANGLE_DEG, TOOL_TARGET, Robot, load_robot, round_within

__all__ = ["DesignResult", "design", "analyse_measurements", "load_robot", "float_list"]

#: the largest |value| accepted for a force [N] or sigma: beyond it squares overflow
MAX_MAGNITUDE = 1e100
#: the smallest sigma accepted: below it O_t underflows to zero
MIN_SIGMA = 1e-100


def _is_number(v) -> bool:
    """A real number: int, float or a numpy one; a bool is not a number here."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def float_list(value, field: str, size: int | None = None, limit: float = MAX_MAGNITUDE) -> np.ndarray:
    """A finite float vector from a flat list or tuple of numbers, a 1-D numeric array or a comma-separated
    string, every |value| <= ``limit``; a nested list, a bool, a string element or anything else is refused
    with an InputError naming ``field``."""
    if isinstance(value, str):
        parts = value.split(",")
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            raise InputError(f"expected comma-separated numbers, got {short_repr(value)}", field=field) from None
    else:
        if isinstance(value, np.ndarray) and value.ndim == 1:
            value = value.tolist()
        if not isinstance(value, (list, tuple)):
            raise InputError(f"expected a flat list of numbers, got {type(value).__name__} {short_repr(value)}",
                             field=field)
        for i, v in enumerate(value):
            if not _is_number(v):
                what = "a nested list" if isinstance(v, (list, tuple, np.ndarray)) else type(v).__name__
                raise InputError(f"expected a flat list of numbers (one per component), got {what} "
                                 f"{short_repr(v)}", field=f"{field}[{i}]")
        vals = [float(v) for v in value]
    arr = np.array(vals, float)
    if arr.size == 0:
        raise InputError("expected at least one number, got none", field=field)
    bad = np.flatnonzero(~np.isfinite(arr) | (np.abs(arr) > limit))
    if bad.size:
        raise InputError(f"expected finite numbers of magnitude at most {limit:g}, got "
                         f"{float(arr[bad[0]]):g}", field=f"{field}[{int(bad[0])}]")
    if size is not None and arr.size != size:
        raise InputError(f"expected {size} numbers, got {arr.size}", field=field)
    return arr


def positive_number(value, field: str, low: float = MIN_SIGMA, high: float = MAX_MAGNITUDE) -> float:
    """A finite number (or a string that reads as one: the command line's) in [low, high]; a bool is refused;
    InputError naming ``field``."""
    try:
        if not (_is_number(value) or isinstance(value, str)):
            raise TypeError
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", field=field) from None
    if not (math.isfinite(x) and low <= x <= high):
        raise InputError(f"expected a number in [{low:g}, {high:g}], got {value!r}", field=field)
    return x


def whole_number(value, field: str, low: int, high: int, bound: str | None = None) -> int:
    """An integer in [low, high] (a bool or a float with a fraction is refused); InputError naming ``field``.
    ``bound``: what the upper bound limits, for the message (docs/contracts.md, "Limits")."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) and not (
            isinstance(value, float) and value.is_integer()):
        raise InputError(f"expected a whole number, got {short_repr(value)}", field=field)
    if not low <= int(value) <= high:
        why = (f" (at most {high} {bound}: the work grows with them; docs/contracts.md, 'Limits')"
               if bound and int(value) > high else "")
        raise InputError(f"expected a whole number in [{low}, {high}]{why}, got {int(value)}", field=field)
    return int(value)


@dataclass(frozen=True)
class DesignResult:
    """What :func:`design` returns; :meth:`to_dict` is the JSON that ``stiffcal design`` prints.

    criterion, criterion_label; robot (its name); experiments M; poses_deg (M, n) [deg], each pose the
    representative of its symmetric copies; O_t (eq. 16) [unit of sigma squared]; O_t_star (eq. 17);
    chi = O_t*/O_t (eq. 27); cov_diag (n,) E[dk_i^2] (eq. 11) [(rad/(N m))^2 per sigma^2 unit], inf for
    a compliance the plan cannot identify; lower_bound: the certified lower bound on O_t of any M-pose plan
    (equivalence theorem; criterion 'ot' only, else None); gap = O_t / lower_bound - 1; lower_bound_converged:
    whether the approximate design behind the bound reached the equivalence theorem's tolerance (None without a
    bound; when False the bound is labelled not converged in ``notes``); optimal_set_deg
    (k, n): every equally optimal single pose (M = 1); degenerate: the criterion does not prefer any pose;
    approximate_design: support_deg (k, n), weights (k,), equivalence_gap, converged, region; notes; sigma, seed,
    test_pose_deg (n,), force_N (d,), moment_Nm (d_m,) or None, targets, orientation, sigma_rad, test_target,
    orientation_length_m: the inputs; joint_names (n,): the robot's joint names, in the order of every pose and
    of cov_diag. Every pose lies within the joint limits, written in the limits' own range (-229.51, not
    130.49, for a range of -230 to 50 deg). lower_bound_over: the set of plans ``lower_bound`` holds for;
    feasible_lower_bound, feasible_gap, feasible_lower_bound_over: in a cell, the bound exact over the finite
    set of feasible candidate poses and the plan's own (None without a cell); clearance_m (M,) [m] and closest:
    each pose's smallest distance over the cell's checked pairs and which pair (None and () without a cell);
    loads: the measurement loads as given (None: force_N in every measurement) and loads_N (L, w) their wrenches
    (a loading bar's at the tool, before it turns); cell: the cell's description; joint_limits_deg (n, 2) the
    limits the plan kept.
    """

    criterion: str
    criterion_label: str
    robot: str
    experiments: int
    poses_deg: np.ndarray
    O_t: float
    O_t_star: float
    chi: float
    cov_diag: np.ndarray
    lower_bound: float | None
    gap: float | None
    optimal_set_deg: np.ndarray
    degenerate: bool
    approximate_design: dict
    notes: tuple[str, ...]
    sigma: float
    seed: int
    test_pose_deg: np.ndarray
    force_N: np.ndarray = field(repr=False)
    joint_names: tuple[str, ...] = ()
    lower_bound_converged: bool | None = None
    moment_Nm: np.ndarray | None = None
    targets: tuple[str, ...] = ("tool",)
    orientation: bool = False
    sigma_rad: float | None = None
    test_target: str = "tool"
    orientation_length_m: float = 0.0
    lower_bound_over: str | None = None
    feasible_lower_bound: float | None = None
    feasible_gap: float | None = None
    feasible_lower_bound_over: str | None = None
    clearance_m: np.ndarray | None = None
    closest: tuple[str, ...] = ()
    loads: str | None = None
    loads_N: np.ndarray | None = None
    cell: str | None = None
    joint_limits_deg: np.ndarray | None = None

    def to_dict(self) -> dict:
        """The JSON object of ``stiffcal design``, strict JSON (:func:`json_safe`: inf as the string 'inf' in
        every field, poses rounded to 1e-6 deg)."""
        d = self.approximate_design
        return json_safe({
            "criterion": self.criterion, "criterion_label": self.criterion_label, "robot": self.robot,
            "joint_names": list(self.joint_names), "experiments": self.experiments,
            "poses_deg": round_within(self.poses_deg, self.joint_limits_deg).tolist(),
            "O_t": _json_number(self.O_t), "O_t_star": self.O_t_star, "chi": _json_number(self.chi),
            "cov_diag": [_json_number(v) for v in self.cov_diag],
            "lower_bound": self.lower_bound,
            "gap": None if self.gap is None else _json_number(self.gap),
            "lower_bound_converged": self.lower_bound_converged,
            "optimal_set_deg": round_within(self.optimal_set_deg, self.joint_limits_deg).tolist(),
            "degenerate": self.degenerate,
            "approximate_design": {"support_deg": round_within(d["support_deg"], self.joint_limits_deg).tolist(),
                                   "weights": np.round(d["weights"], 9).tolist(),
                                   "equivalence_gap": d["equivalence_gap"], "converged": d["converged"],
                                   "region": d["region"]},
            "notes": list(self.notes), "sigma": self.sigma, "seed": self.seed,
            "test_pose_deg": self.test_pose_deg.tolist(), "force_N": self.force_N.tolist(),
            "moment_Nm": None if self.moment_Nm is None else self.moment_Nm.tolist(),
            "targets": list(self.targets), "orientation": self.orientation, "sigma_rad": self.sigma_rad,
            "test_target": self.test_target, "orientation_length_m": self.orientation_length_m,
            "lower_bound_over": self.lower_bound_over, "feasible_lower_bound": self.feasible_lower_bound,
            "feasible_gap": None if self.feasible_gap is None else _json_number(self.feasible_gap),
            "feasible_lower_bound_over": self.feasible_lower_bound_over,
            "clearance_m": None if self.clearance_m is None else [round(float(c), 6) for c in self.clearance_m],
            "closest": list(self.closest), "loads": self.loads,
            "loads_N": None if self.loads_N is None else np.round(self.loads_N, 9).tolist(),
            "cell": self.cell,
            "joint_limits_deg": None if self.joint_limits_deg is None else np.round(self.joint_limits_deg, 9).tolist(),
        })


def _robot(robot) -> Robot:
    """A Robot, or the one read from a robot file's path; InputError naming the argument ``robot``."""
    if isinstance(robot, Robot):
        return robot
    if not isinstance(robot, (str, os.PathLike)):
        raise InputError(f"expected a Robot (stiffcal.load_robot) or the path of a robot file, got "
                         f"{type(robot).__name__} {short_repr(robot)}", field="robot")
    return load_robot(robot)


def _path(value, field: str, what: str) -> str | os.PathLike:
    """A file or directory path (str or os.PathLike); InputError naming ``field``."""
    if not isinstance(value, (str, os.PathLike)):
        hint = (" (write the table with df.to_csv(path, index=False) and give the path)"
                if type(value).__name__ == "DataFrame" else "")
        raise InputError(f"expected the path of {what} (a str or a path), got {type(value).__name__}{hint}",
                         field=field)
    return value


def _input_file(path):
    """``path`` if it is a regular file; a FIFO, a device or a directory is refused at once (never read: a FIFO
    blocks), and so is a missing file (:func:`stiffcal.safeio.regular_file`)."""
    from .safeio import regular_file

    regular_file(path)
    return path


def _flag(value, field: str) -> bool:
    """True or False (not a string: bool('no') is True); InputError naming ``field``."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"expected True or False, got {short_repr(value)}", field=field)
    return bool(value)


def design_estimate_s(robot: Robot, m: int, single: bool = True, n_loads: int = 1) -> list[tuple[str, float]]:
    """The stages of :func:`design` with a rough estimate of their seconds on one core of a 2-core machine like
    CI's (fitted to runs of 2-20-joint planar and 3-10-joint spatial arms, and of UR5, UR10, Panda and iiwa in
    cells under hanging masses: within a factor of about 3; the progress lines scale what is left by how the stages so
    far compared with their estimates). single: the single-pose search runs (one pose identifies every
    compliance); n_loads: the loads of every measurement pose (``loads``). In a cell the approximate design is
    computed twice (over the feasible poses, and over the joint space for the bound that holds for every plan)."""
    n = robot.n_joints
    if robot.planar:
        approx, plan = 0.3 + 0.75 * n, 19.0 * (n / 10) ** 3.85
    else:
        approx, plan = 1.5 + 30.0 * (n / 10) ** 8, 0.5 + 5.0 * (n / 10) ** 8
    approx *= (2.0 if robot.cell is not None else 1.0) * (1.5 if n_loads > 1 else 1.0)
    if robot.cell is not None and not robot.planar:  # every exchange step checks its poses against the meshes
        plan *= 6.0
    stages = [("single pose", 0.6 if single else 0.05), ("approximate design and certificate", approx)]
    return stages + ([(f"plan of {m} poses", plan + 0.01 * m)] if m > 1 else [])


def _stages(progress, stages):
    """The progress of :func:`design` on stderr (:class:`stiffcal.progress.Progress`): a bar on a terminal, a
    line every few seconds otherwise; ``progress`` False: nothing."""
    from .progress import Progress

    return Progress("design", stages, enabled=progress)


def design(robot, test_pose_deg, force_N=None, *, wrench=None, experiments: int = 1, criterion: str = "ot",
           sigma: float = 1.0, targets=None, orientation: bool = False, sigma_rad: float | None = None,
           test_target: str = "tool", orientation_length_m: float = 0.0, joint_limits_deg=None, loads=None,
           cell=None, candidates=None, seed: int = 0, progress: bool | None = None,
           cache_dir=None) -> DesignResult:
    """Optimal measurement poses for stiffness calibration at a test pose (the paper's method).

    robot: a :class:`~stiffcal.model.robot.Robot` or the path of a robot file (docs/contracts.md); test_pose_deg:
    (n,) the test pose q* [deg], within the joint limits; force_N: (d,) the force [N] at the tool point in every
    measurement and at the test pose (d = 2 for a planar arm, 3 for a spatial one); or instead wrench: the
    force followed by the moment [N m] about the tool point, ``(fx, fy, mz)`` for a planar arm, ``(fx, fy, fz,
    mx, my, mz)`` for a spatial one (eqs. 2-4 on the 6-D Jacobian, :mod:`stiffcal.model.observation`); not zero;
    experiments: the number of measurement poses M (enough equations for the compliances); criterion: one of
    ``ot a t d g mdc o1 o2 o3 o4`` (Table 1; 'ot' is the paper's test-pose criterion, eq. 16); sigma: the
    position noise standard deviation [m]; targets: the targets whose positions are measured at every pose
    (names of the robot file's ``targets`` and ``"tool"``; default the tool point); orientation: the tool's
    orientation is measured too, with the noise sigma_rad [rad] (weighted least squares); test_target: the
    target whose error O_t measures; orientation_length_m: a length scale [m] > 0 adds the tool's rotation
    to that error (``|dp|^2 + L^2 |dr|^2``); joint_limits_deg: (n, 2) [deg] replaces the robot file's limits;
    loads: the loads every measurement pose is measured under (the SPEC of ``discriminate``: 'hanging:M1,M2'
    [N] along the robot file's gravity, 'directions:K:M1,M2', 'forces:FX,FY,FZ;...', 'wrenches:FX,..,MZ;...',
    'bar:AX,AY,AZ:M1,M2'), force_N or wrench being then the test pose's load only (default: that load in every
    measurement too); cell: where the robot stands (a mapping of the cell's keys, a
    :class:`~stiffcal.model.workcell.WorkCell` or the path of a YAML file; replaces the robot file's ``cell``): every
    pose of the plan is feasible in it; candidates: the path of a CSV of candidate poses (columns q1_deg.. or
    the joint names in radians): the plan is chosen among those the cell allows, and the bound is exact over
    them; seed: seed of the random starts of M-pose plans (results are deterministic for a seed, whatever the
    BLAS thread count); progress: the progress on stderr, a bar on a terminal and a line every few seconds
    elsewhere, with an estimate of the time left (None or True; False: none; :mod:`stiffcal.progress`);
    cache_dir: a folder where the optimal approximate design and its certificate (the same for every M,
    criterion and seed) are kept and read back by later calls with the same inputs (None: computed afresh;
    :mod:`stiffcal.planning.designcache`; the result is the same either way, bit for bit).

    M = 1 is an exhaustive global search over one pose; M > 1 a Fedorov exchange over a candidate pool
    started from the rounded optimal approximate design, polished in the continuum. For 'ot', the
    equivalence theorem bounds O_t of any M-pose plan from below (``lower_bound``, ``gap``).
    Raises :class:`InputError` for bad arguments or a file that does not hold a valid robot.
    """
    from .threads import one_blas_thread

    inp = _design_inputs(robot, test_pose_deg, force_N, wrench, experiments, criterion, sigma, targets, orientation,
                         sigma_rad, test_target, orientation_length_m, joint_limits_deg, loads, cell, candidates, seed,
                         cache_dir)
    n_loads = 1 if inp.meas_loads is None else len(inp.meas_loads.wrenches)
    stages = design_estimate_s(inp.robot, inp.m, inp.m == 1, n_loads)
    with one_blas_thread(), _stages(progress if progress is None else _flag(progress, "progress"), stages) as bar:
        found = _search(inp, bar)
    return _design_result(inp, found)


@dataclass(frozen=True)
class _DesignInputs:
    """The checked arguments of :func:`design`: the placed robot, its study and the criterion's problem."""

    robot: Robot
    criterion: str
    m: int
    sigma: float
    seed: int
    q_t: np.ndarray
    force: np.ndarray
    moment: np.ndarray | None
    sensing: object
    test_target: str
    length: float
    meas_loads: object
    study: object
    base: object
    cache_dir: object


@dataclass(frozen=True)
class _Found:
    """What :func:`design`'s search found: the poses, the single pose's notes and optimal set, and the optimal
    approximate designs (over the candidates, and over the continuum where a cell restricts a continuous pool)."""

    poses: np.ndarray
    notes: list
    optimal_set: np.ndarray
    degenerate: bool
    approx: object
    continuum: object


def _design_inputs(robot, test_pose_deg, force_N, wrench, experiments, criterion, sigma, targets, orientation,
                   sigma_rad, test_target, orientation_length_m, joint_limits_deg, loads, cell, candidates, seed,
                   cache_dir) -> _DesignInputs:
    """:func:`design`'s arguments checked (InputError naming the argument) and its study built."""
    from .model import criteria
    from .model.observation import measurement_loads
    from .model.workcell import read_candidates
    from .planning.study import Study, check_sensing, check_test_inputs

    robot = _placed(_robot(robot), joint_limits_deg, cell)
    if criterion not in criteria.CRITERIA_KEYS:
        raise InputError(f"expected one of {', '.join(criteria.CRITERIA_KEYS)}, got {criterion!r}", field="criterion")
    force, moment, field_ = load_arguments(robot, force_N, wrench)
    q_t = check_test_inputs(robot, float_list(test_pose_deg, "test_pose_deg", limit=MAX_JOINT_ANGLE_DEG), force,
                            "test_pose_deg", field_, None, moment, field_)
    m = whole_number(experiments, "experiments", 1, MAX_DESIGN_EXPERIMENTS, "poses")
    sigma = positive_number(sigma, "sigma")
    sigma_rad = None if sigma_rad is None else positive_number(sigma_rad, "sigma_rad")
    seed = whole_number(seed, "seed", 0, 2**32 - 1)
    if cache_dir is not None:
        from .safeio import check_out_dir as check_dir

        if not str(_path(cache_dir, "cache_dir", "a folder for the cache")).strip():
            raise InputError("expected a folder for the cache, got an empty path", field="cache_dir")
        cache_dir = check_dir(cache_dir, field="cache_dir")
    if not isinstance(test_target, str):
        raise InputError(f"expected a target's name, got {short_repr(test_target)}", field="test_target")
    sensing, test_target, length = check_sensing(
        robot, [TOOL_TARGET] if targets is None else _names(targets, "targets"), _flag(orientation, "orientation"),
        sigma, sigma_rad, test_target, positive_number(orientation_length_m, "orientation_length_m", 0.0), "", None)
    meas_loads = None if loads is None else measurement_loads(robot, loads, "loads")
    pool = None if candidates is None else read_candidates(_path(candidates, "candidates", "a CSV of candidate poses"),
                                                           robot)
    study = Study(robot.name, robot, np.radians(q_t), force, sigma, (criterion,), 1.0, 1.0, moment, sensing,
                  test_target, length, meas_loads, pool)
    base = study.problem(criterion)
    base.check_test_load(field_)
    if m < base.min_poses:
        raise InputError(f"expected at least {base.min_poses} poses: {m} give {m * base.rows_per_pose} equations "
                         f"for {base.n_params} compliances", field="experiments")
    return _DesignInputs(robot, criterion, m, sigma, seed, q_t, force, moment, sensing, test_target, length,
                         meas_loads, study, base, cache_dir)


def _search(inp: _DesignInputs, bar) -> _Found:
    """:func:`design`'s computation, ``bar`` advanced after each stage: the single-pose search (M = 1), the
    optimal approximate design and its certificate (cached in ``cache_dir``), the M-pose plan (M > 1)."""
    from .planning.certificate import unconstrained
    from .planning.designcache import cached_design, cached_pool
    from .planning.plans import best_plan
    from .planning.problem import optimal_single_pose

    study, base, m, cache_dir = inp.study, inp.base, inp.m, inp.cache_dir
    notes, optimal_set, degenerate = [], np.zeros((0, inp.robot.n_joints)), False
    continuum = None
    if m == 1:
        _check_single_pose_identifies(base)
        res1 = optimal_single_pose(base)
        notes, degenerate, optimal_set = list(res1.notes), res1.degenerate, res1.optimal_set_deg
        poses = res1.pose_deg[None, :]
    bar.advance()
    approx = cached_design(study.problem("ot"), cache_dir)
    if approx.exact_over_candidates and inp.robot.cell is not None and base.continuous:
        continuum = cached_design(unconstrained(study.problem("ot")), cache_dir)
    bar.advance()
    if m > 1:
        pool = None if cache_dir is None else cached_pool(study.problem("ot"), cache_dir)
        poses = best_plan(study.problem(inp.criterion, m), approx, seed=inp.seed, pool=pool).poses_deg
        bar.advance()
    return _Found(poses, notes, optimal_set, degenerate, approx, continuum)


def _ot_bound(inp: _DesignInputs, found: _Found):
    """(lower_bound, over, feasible_lower_bound, feasible_over, converged) of an O_t plan (the equivalence
    theorem's bound on O_t of every M-pose plan, and what it is over); None for the other criteria."""
    approx, continuum, m, sigma = found.approx, found.continuum, inp.m, inp.sigma
    bound = feasible_bound = over = feasible_over = None
    converged = approx.converged
    if inp.criterion == "ot":
        if continuum is not None:
            bound, converged = continuum.lower_bound(m, sigma), continuum.converged
            over = "every plan within the joint limits, so every plan the cell allows (the cell ignored: valid, loose)"
            # the joint-space bound holds for these plans too: where the design over the feasible candidates stopped
            # short of its optimum (its bound below the other by up to its gap), the larger of the two
            feasible_bound = max(approx.bound_with(inp.study.problem("ot"), np.radians(found.poses), m, sigma), bound)
            feasible_over = (f"every plan of the {approx.n_candidates} feasible pool poses, the feasible search "
                             "points, the maxima of phi found from them and this plan's poses (exact over these; not "
                             "a bound for plans of other feasible poses)")
        elif approx.region == "candidate poses":
            bound = approx.lower_bound(m, sigma)
            over = f"every plan of the {approx.n_candidates} candidate poses the cell allows (exact)"
        else:
            bound = approx.lower_bound(m, sigma)
            over = "every plan within the joint limits"
    return bound, over, feasible_bound, feasible_over, converged


def _singular_plan_note(inp: _DesignInputs, summ, ot: float) -> list[str]:
    """A note when the plan does not identify the compliances the model keeps (an infinite O_t or variance): a
    criterion such as T (the trace of M, whatever its rank) can be best at a singular plan (a fresh user's Baxter:
    two identical poses, every variance 'inf', and no word)."""
    from .model import criteria

    names = [n for j, n in zip(inp.robot.joint_columns("E_dk"), inp.robot.joint_names)
             if j in summ and not np.isfinite(float(summ[j]))]
    kept = [inp.robot.joint_names[j] for j in inp.base.params]
    unseen = [n for n in names if n in kept]
    if np.isfinite(ot) and not unseen:
        return []
    what = f"the compliances of joint(s) {', '.join(unseen)}" if unseen else "every compliance"
    return [f"the plan's {inp.m} pose(s) do not identify {what} (the information matrix is singular: O_t and those "
            f"variances are infinite); criterion {criteria.label(inp.criterion)} need not identify the model (T "
            "maximises the trace of M, whatever its rank): take more poses, or criterion ot, d or a"]


def _ot_star_note(base, ot_star: float) -> list[str]:
    """A note when O_t* (eq. 17: every measurement at the test pose; ``ot_star``, :meth:`Problem.ot_star`) is inf: the
    measurement loads at the test pose cannot give its deflection under the test load, so chi = O_t* / O_t is inf
    too (a fresh user read "chi: inf" as infinitely better)."""
    if base.loads is None or np.isfinite(ot_star):
        return []
    return [f"O_t_star and chi are inf: measured at the test pose itself, the loads {base.loads.spec} cannot give its "
            "deflection under the test load (it is not a combination of theirs), so the paper's reference O_t* "
            "(eq. 17) does not exist here; compare O_t with lower_bound instead"]


#: poses of a plan within this many degrees of each other in every joint are copies of one configuration
COPY_TOL_DEG = 1e-4


def merged_copies(poses_deg: np.ndarray) -> np.ndarray:
    """(M, n) [deg]: the plan's poses with each one within :data:`COPY_TOL_DEG` of an earlier pose in every joint
    replaced by that pose: the polish moves copies of one configuration apart by round-off (a fresh user's D-optimal
    plan printed one pose as 9.172572, 9.172573 and 9.172574 deg, and the note on repeats stayed silent)."""
    out = np.array(poses_deg, float, copy=True)
    for i in range(1, len(out)):
        near = np.flatnonzero(np.abs(out[:i] - out[i]).max(axis=1) < COPY_TOL_DEG)
        if near.size:
            out[i] = out[near[0]]
    return out


def repeated_poses_note(poses_deg: np.ndarray) -> list[str]:
    """A note where the plan (poses_deg (M, n) [deg]) repeats a configuration: each repeat is a visit of its own (the
    robot leaving and returning), and the analysis tells visits apart by a ``visit`` column or the row order (a fresh
    user measured a plan's repeats back to back without one: 17 visits read for 24)."""
    _, first, counts = np.unique(merged_copies(poses_deg), axis=0, return_index=True, return_counts=True)
    repeated = [(int(i) + 1, int(c)) for i, c in sorted(zip(first, counts)) if c > 1]
    if not repeated:
        return []
    which = ", ".join(f"pose {i} x{c}" for i, c in repeated[:6]) + (" ..." if len(repeated) > 6 else "")
    return [f"the plan repeats {len(repeated)} configuration(s) ({which}): measure each repeat as a visit of its own "
            "(the robot leaving the configuration and returning to it: replicates), and log a visit column, or measure "
            "the repeats apart in the session: rows of one configuration measured back to back without a visit column "
            "are read as one visit"]




def _design_result(inp: _DesignInputs, found: _Found) -> DesignResult:
    """The :class:`DesignResult` of the plan found: its summary, bound, notes and clearance in the cell."""
    from .model import criteria
    from .model.workcell import cell_notes, test_pose_note
    from .planning.problem import plan_summary, unidentified_notes, weak_compliance_notes

    robot, base, approx, continuum = inp.robot, inp.base, found.approx, found.continuum
    poses = merged_copies(found.poses)
    summ = plan_summary(inp.study, poses)
    bound, over, feasible_bound, feasible_over, converged = _ot_bound(inp, found)
    notes = found.notes + unidentified_notes(robot, base)
    if not converged:
        notes.append((continuum or approx).convergence_note())
    if continuum is not None and not approx.converged:
        notes.append("over its feasible candidates, " + approx.convergence_note())
    notes += [d.near_singular_note() for d in (continuum, approx) if d is not None and d.near_singular]
    clear, closest, near = _clearances(robot, np.radians(poses))
    notes += cell_notes(robot, np.radians(poses), base.hang_offset) + near
    notes += test_pose_note(robot, base, np.radians(inp.q_t))
    ot = float(summ["O_t"])
    ot_star = base.ot_star(inp.m)
    cov_diag = np.array([float(summ[e]) for e in robot.joint_columns("E_dk")])
    notes += _singular_plan_note(inp, summ, ot) + _ot_star_note(base, ot_star)
    notes += weak_compliance_notes(robot, cov_diag) if inp.criterion == "ot" else []  # L-optimality's blind spot
    notes += repeated_poses_note(poses)
    meas_loads, sensing = inp.meas_loads, inp.sensing
    return DesignResult(
        criterion=inp.criterion, criterion_label=criteria.label(inp.criterion), robot=robot.name, experiments=inp.m,
        poses_deg=np.asarray(poses, float), O_t=ot, O_t_star=ot_star,
        chi=float(summ["chi"]), cov_diag=cov_diag,
        lower_bound=bound, gap=None if bound is None else ot / bound - 1.0,
        optimal_set_deg=np.asarray(found.optimal_set, float).reshape(-1, robot.n_joints),
        degenerate=bool(found.degenerate),
        approximate_design={"support_deg": approx.support_deg, "weights": approx.weights,
                            "equivalence_gap": approx.equivalence_gap, "converged": approx.converged,
                            "region": approx.region},
        notes=tuple(notes), sigma=inp.sigma, seed=inp.seed, test_pose_deg=inp.q_t, force_N=inp.force,
        joint_names=robot.joint_names, lower_bound_converged=None if bound is None else converged,
        moment_Nm=inp.moment, targets=sensing.targets, orientation=sensing.orientation, sigma_rad=sensing.sigma_rad,
        test_target=inp.test_target, orientation_length_m=inp.length, lower_bound_over=over,
        feasible_lower_bound=feasible_bound, feasible_gap=None if feasible_bound is None else ot / feasible_bound - 1.0,
        feasible_lower_bound_over=feasible_over, clearance_m=clear, closest=closest,
        loads=None if meas_loads is None else meas_loads.spec,
        loads_N=None if meas_loads is None else meas_loads.wrenches,
        cell=None if robot.cell is None else robot.cell.describe(),
        joint_limits_deg=robot.limits_deg)


def _cell_value(cell):
    """The ``cell`` argument: a mapping, a WorkCell, or the path of a YAML file (str or path)."""
    from .model.workcell import WorkCell

    if isinstance(cell, (dict, WorkCell)):
        return cell
    if isinstance(cell, (str, os.PathLike)):
        return os.fspath(cell)
    raise InputError(f"expected a cell: a mapping of its keys or the path of a YAML file holding them, got "
                     f"{type(cell).__name__} {short_repr(cell)}", field="cell")


def _check_single_pose_identifies(problem, samples: int = 256) -> None:
    """Refuse (InputError) a criterion that needs the inverse of the information matrix when no single pose
    identifies every compliance: at 256 random poses within the limits the rows of a pose never reach full rank
    (e.g. every joint axis through one point: the measured point then moves on a sphere, two directions for three
    compliances). The single-pose search would find no finite value anywhere."""
    from .model import criteria

    if problem.criterion not in criteria.NEEDS_INVERSE or problem.rows_per_pose < problem.n_params:
        return  # the search says so itself (too few equations), or the criterion is finite without an inverse
    lo, hi = problem.robot.joint_limits_rad.T
    q = np.random.default_rng(0).uniform(lo, hi, (samples, problem.robot.n_joints))
    A = problem.rows(q)
    s = np.linalg.svd(A, compute_uv=False)
    full = s[:, -1] > 1e-9 * np.maximum(s[:, 0], 1e-300)
    if not full.any():
        raise InputError(f"criterion {criteria.label(problem.criterion)} is infinite at every pose: no single pose "
                         f"identifies all {problem.n_params} compliances (the rows of one pose never reach full rank, "
                         "e.g. every joint axis meets in one point); use at least 2 poses", field="experiments")


def _names(value, field: str) -> list[str]:
    """A list of names from a list or a comma-separated string; InputError naming ``field``."""
    if isinstance(value, str):
        value = value.split(",")
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise InputError(f"expected a list of names (strings) or comma-separated names, got {short_repr(value)}",
                         field=field)
    names = [v.strip() for v in value]
    if not names or not all(names):
        raise InputError(f"expected comma-separated names, got {value!r}", field=field)
    return names


def load_arguments(robot: Robot, force_N, wrench, required: bool = True):
    """``(force (d,), moment (d_m,) or None, field)`` from ``force_N`` (d,) or ``wrench`` (d + d_m,) [N, N m], one
    of them (or neither when not ``required``: (None, None, 'force_N')); InputError naming the argument."""
    from .model.observation import force_dim, wrench_dim

    if force_N is not None and wrench is not None:
        raise InputError("expected the force or the wrench, not both", field="wrench")
    if wrench is not None:
        w = float_list(wrench, "wrench", limit=math.inf)  # the physical range is check_load's
        d, dw = force_dim(robot), wrench_dim(robot)
        if w.size != dw:
            names = "fx, fy, mz" if robot.planar else "fx, fy, fz, mx, my, mz"
            raise InputError(f"expected {dw} wrench components ({names}) for a {robot.kind} robot, got {w.size}",
                             field="wrench")
        check_load(w[:d], w[d:], "wrench")
        return w[:d], w[d:], "wrench"
    if force_N is None:
        if required:
            raise InputError("expected the force (force_N) or the wrench", field="force_N")
        return None, None, "force_N"
    force = float_list(force_N, "force_N", limit=math.inf)
    check_load(force, None, "force_N")
    return force, None, "force_N"


def check_load(force: np.ndarray, moment: np.ndarray | None, field: str, moment_field: str | None = None) -> None:
    """A load within the physical range (:mod:`stiffcal.limits`): every force component at most
    :data:`~stiffcal.limits.MAX_FORCE_N` [N], every moment component at most
    :data:`~stiffcal.limits.MAX_MOMENT_NM` [N m], and the load as a whole (a zero load is left to the callers'
    own, more specific, message) either zero or at least :data:`~stiffcal.limits.MIN_LOAD`; InputError naming
    ``field`` and the component (a moment's components ``moment_field[i]``, or, without it, ``field[d + i]``: a
    wrench's)."""
    parts = [(np.asarray(force, float), MAX_FORCE_N, "N", field, 0)]
    if moment is not None and np.size(moment):
        parts.append((np.asarray(moment, float), MAX_MOMENT_NM, "N m", moment_field or field,
                      0 if moment_field else np.size(force)))
    for values, high, unit, name, start in parts:
        big = np.flatnonzero(np.abs(values) > high)
        if big.size:
            raise InputError(f"expected at most {high:g} {unit} in magnitude (the physical range of loads; "
                             f"docs/contracts.md, 'Limits'), got {float(values[big[0]]):g}",
                             field=f"{name}[{start + int(big[0])}]")
    size = math.hypot(*(float(x) for v, *_ in parts for x in v))  # no underflow of tiny components
    if 0.0 < size < MIN_LOAD:
        raise InputError(f"expected a load of at least {MIN_LOAD:g} N (N m) in magnitude (the physical range of "
                         f"loads; docs/contracts.md, 'Limits'), got {size:g}", field=field)


def check_out_dir(out, field: str | None = None) -> Path:
    """An output directory that can be written (:func:`stiffcal.safeio.check_out_dir`: not empty, a directory or
    not existing, no folder on its way is a file, and its nearest existing folder is writable), checked before any
    work; InputError naming ``out`` (and ``field``, the option or argument) otherwise."""
    from .safeio import check_out_dir as check

    return check(out, field)


def analyse_measurements(robot, data, *, alpha: float = 0.01, test_pose_deg=None, force_N=None, wrench=None,
                         out=None, label: str | None = None, angle_resolution_deg: float | None = None,
                         force_resolution_N: float | None = None, moment_resolution_Nm: float | None = None,
                         sigma_m: float | None = None, sigma_rad: float | None = None, joint_limits_deg=None,
                         cell=None, figures: bool = True) -> Verdict:
    """What the stiffness model gets wrong in measured deflections (``stiffcal discrepancy``).

    robot: a Robot or a robot file; data: the measured-data CSV (docs/measured-data.md); alpha: family-wise
    false-alarm rate, in (0, 1); test_pose_deg (n,) [deg] and force_N (d,) [N] or wrench (d + d_m,) [N, N m]:
    the test pose and its load for the predicted compensation error (give the pose and one load, or neither);
    out: a directory for ``verdict.json``, ``calibrated.yaml`` and the figures
    (:func:`stiffcal.measured.discrepancy.run`; None: nothing is written); figures: False writes the two files
    without the figures; label: the data set's name in the figures' titles (default the file's name). The files are
    written to a temporary directory and moved into ``out`` only when everything succeeded; an earlier run's files
    there that this run does not write (its figures, after ``figures=False``) are then removed.
    angle_resolution_deg [deg], force_resolution_N [N], moment_resolution_Nm [N m]: joint angles and loads
    that agree within these are one configuration and one load (encoder and load-cell resolution; defaults
    0.01 deg, 0.5 N and 0.05 N m, docs/measured-data.md). sigma_m [m] and sigma_rad [rad]: the noise levels
    of positions and rotations, whose ratio weights the rotation rows (both or neither; default: estimated
    from the data). joint_limits_deg (n, 2) [deg] and cell (as :func:`design`): where the robot stands, for the
    verdict's O_t-optimal plan of the extended model (``optimal_plan_extended_deg``: every pose feasible).

    Returns the :class:`stiffcal.measured.results.Verdict` (docs/measured-data.md: cause, causes,
    indistinguishable_from, p_value, structure, nominal, extended, gain, outlier_rows, notes, ...; a read-only
    mapping, and ``to_dict()`` the JSON of ``verdict.json``), with the same fields whether or not ``out`` is given
    (``calibrated_model`` None when nothing is written). Raises :class:`InputError` for bad arguments or data.
    """
    from .measured import discrepancy
    from .measured.measurements import check_noise_levels

    robot = _placed(_robot(robot), joint_limits_deg, cell)
    data = _input_file(_path(data, "data", "a measured-data CSV"))
    if out is not None:
        out = check_out_dir(_path(out, "out", "an output directory"))
    alpha = positive_number(alpha, "alpha", 1e-12, 1 - 1e-12)
    res = _resolutions(angle_resolution_deg, force_resolution_N, moment_resolution_Nm)
    check_noise_levels(sigma_m is not None, sigma_rad is not None)
    sig = (None, None) if sigma_m is None else (positive_number(sigma_m, "sigma_m"),
                                                 positive_number(sigma_rad, "sigma_rad"))
    qt, ft = _test_pose(robot, test_pose_deg, force_N, wrench)
    if out is None:
        return discrepancy.analysed(robot, str(data), alpha, qt, ft, res, *sig)[0]
    return _written_whole(out, lambda tmp: discrepancy.run(robot, str(data), tmp, alpha, qt, ft, label, *res, *sig,
                                                           figures=bool(figures)), discrepancy.RUN_FILES)


def _placed(robot: Robot, joint_limits_deg=None, cell=None) -> Robot:
    """``robot`` with the joint limits and the cell given as arguments (None keeps the robot file's)."""
    from .model.robot import narrowed_limits
    from .model.workcell import with_cell

    if joint_limits_deg is not None:
        robot = narrowed_limits(robot, joint_limits_deg, None, "joint_limits_deg")
    if cell is not None:
        robot = with_cell(robot, _cell_value(cell), None, "cell")
    return robot


def _resolutions(angle_resolution_deg, force_resolution_N, moment_resolution_Nm=None) -> tuple[float, float, float]:
    """The encoder, load-cell and moment resolutions [deg, N, N m] (docs/measured-data.md), defaults filled in,
    checked."""
    from .measured import measurements as M

    return (M.ANGLE_RESOLUTION_DEG if angle_resolution_deg is None
            else positive_number(angle_resolution_deg, "angle_resolution_deg", 1e-12, 360.0),
            M.FORCE_RESOLUTION_N if force_resolution_N is None
            else positive_number(force_resolution_N, "force_resolution_N", 1e-12, MAX_FORCE_N),
            M.MOMENT_RESOLUTION_NM if moment_resolution_Nm is None
            else positive_number(moment_resolution_Nm, "moment_resolution_Nm", 1e-12, MAX_MOMENT_NM))


def _test_pose(robot: Robot, test_pose_deg, force_N, wrench=None):
    """(test pose (n,) [rad], its load: the force (d,) [N] or the wrench (d + d_m,) [N, N m]) from degrees,
    newtons and newton metres; the pose and a load both or neither; checked."""
    from .planning.study import check_test_inputs

    force, moment, field_ = load_arguments(robot, force_N, wrench, required=False)
    if (test_pose_deg is None) != (force is None):
        raise InputError("expected both the test pose and its force (or wrench), or neither", field="test_pose_deg")
    if test_pose_deg is None:
        return None, None
    qt = np.radians(check_test_inputs(robot, float_list(test_pose_deg, "test_pose_deg", limit=MAX_JOINT_ANGLE_DEG),
                                      force, "test_pose_deg", field_, None, moment, field_))
    return qt, (force if moment is None else np.r_[force, moment])


def _written_whole(out, write, owned: tuple[str, ...] = ()) -> dict:
    """Run ``write(directory)`` into a temporary directory beside ``out`` and move its files into ``out`` only
    when it succeeded (no partial output); the files named in ``owned`` (every file ``write`` may write) that it
    did not write this time are then removed from ``out``, so that ``out`` holds one run's results (never a verdict
    beside the figures or the calibrated model of another data set); other files are left alone. Returns what
    ``write`` returns."""
    out = check_out_dir(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        result = write(str(tmp))
        out.mkdir(exist_ok=True)
        written = sorted(tmp.iterdir())
        for f in written:
            f.replace(out / f.name)
        for name in sorted(set(owned) - {f.name for f in written}):
            (out / name).unlink(missing_ok=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return result


def plan_discrimination(robot, data, experiments, *, loads: str | None = None, repeats=1, weight=0.5,
                        truth: str = "best", alpha=0.01, test_pose_deg=None, force_N=None, out=None,
                        angle_resolution_deg=None, force_resolution_N=None, seed=0, joint_limits_deg=None,
                        cell=None) -> DiscriminationPlan:
    """The next experiment that tells a verdict's rival causes apart (``stiffcal discriminate``; issue 18,
    :mod:`stiffcal.measured.discrimination`): the M-point plan (poses within the joint limits, loads from ``loads``)
    that maximises the T-criterion of the rivals (Atkinson & Fedorov 1975), its predicted power, its
    efficiency against the equivalence-theorem bound, and a compound plan with the extended model's O_t.

    robot: a Robot or a robot file; data: the measured-data CSV; experiments: M (whole number >= 1); loads: a
    load set ('hanging:M1,M2' [N], 'directions:K:M1,M2', 'forces:FX,FY;...', 'wrenches:...', 'bar:AX,AY,AZ:M1,M2';
    default the data's loads, or a loading bar's masses at the lever the data's moments give);
    repeats: times each point is measured; weight: kappa of the discrimination in the compound plan, in [0, 1];
    truth: 'best' (the best-fitting model as the truth) or 'each'; alpha: family-wise rate; test_pose_deg (n,)
    [deg] and force_N (d,) [N]: for the compound plan's O_t; out: a directory for plan.json and plan.png/svg
    (None: nothing written; files moved in only on success); resolutions as :func:`analyse_measurements`;
    joint_limits_deg and cell (as :func:`design`): every measurement of every plan is feasible in the cell, with
    a hanging mass's cable free.
    Returns the :class:`stiffcal.measured.results.DiscriminationPlan` (plan.json's fields, docs/measured-data.md; a
    read-only mapping, ``to_dict()`` the JSON), the same whether or not ``out`` is given (the data's own loads,
    with a loading bar's moments, in both). Raises :class:`InputError` for bad arguments or data.
    """
    from .measured import discrimination

    robot = _placed(_robot(robot), joint_limits_deg, cell)
    data = _input_file(_path(data, "data", "a measured-data CSV"))
    if out is not None:
        out = check_out_dir(_path(out, "out", "an output directory"))
    if loads is not None and not isinstance(loads, str):
        raise InputError(f"expected a load set such as 'hanging:100,300', got {short_repr(loads)}", field="loads")
    experiments = whole_number(experiments, "experiments", 1, MAX_DISCRIMINATE_EXPERIMENTS, "measurements")
    repeats = whole_number(repeats, "repeats", 1, 1000)
    seed = whole_number(seed, "seed", 0, 2**32 - 1)
    weight = positive_number(weight, "weight", 0.0, 1.0)
    alpha = positive_number(alpha, "alpha", 1e-12, 1 - 1e-12)
    if truth not in ("best", "each"):
        raise InputError(f"expected 'best' or 'each', got {truth!r}", field="truth")
    res = _resolutions(angle_resolution_deg, force_resolution_N)
    qt, ft = _test_pose(robot, test_pose_deg, force_N)

    def write(directory):
        return discrimination.run(robot, str(data), directory, experiments, loads, repeats, weight, truth, alpha,
                                  qt, ft, *res[:2], seed)

    if out is not None:
        return _written_whole(out, write)
    return discrimination.planned(robot, str(data), experiments, loads, repeats, weight, truth, alpha, qt, ft,
                                  *res[:2], seed)


def predict_deflection(robot, poses, *, out=None, orientation: bool = False) -> dict:
    """The calibrated model's deflection at given poses under given loads (``stiffcal predict``;
    :func:`stiffcal.measured.calibrated.predict`).

    robot: a calibrated robot file (``calibrated.yaml`` of ``stiffcal discrepancy``) or Robot (one with only
    ``compliances_rad_per_Nm`` predicts with those, no extension, no interval); poses: a CSV of poses and loads
    (:func:`stiffcal.measured.calibrated.read_poses`); out: a CSV to write (the poses with ``dx_m`` .. and their
    standard deviations ``sd_dx_m`` ..; None: nothing written); orientation: predict the tool's rotation too.
    Returns ``{"rows", "causes", "max_deflection_m", "max_sd_m", "n_undetermined", "out", "notes"}``; raises
    :class:`InputError`."""
    from .measured import calibrated as C

    robot = _robot(robot)
    pf = C.read_poses(_input_file(_path(poses, "poses", "a CSV of poses and loads")), robot)
    out_path = None if out is None else _out_file(out, "out")
    pred = C.predict(robot, pf.q, pf.load, pf.target, _flag(orientation, "orientation"))
    if out_path is not None:
        _write_whole(out_path, C.prediction_csv(robot, pf, pred))
    size = np.linalg.norm(pred.displacement, axis=1)
    return json_safe({"rows": len(pf.q), "causes": list(pred.causes), "max_deflection_m": float(size.max()),
                      "max_sd_m": float(np.linalg.norm(pred.sd, axis=1).max()),
                      "n_undetermined": _undetermined(pred.determined),
                      "out": None if out_path is None else str(out_path), "notes": [*pf.notes, *pred.notes]})


def compensate_path(robot, path, *, out=None) -> dict:
    """Compensate a path with the calibrated model (``stiffcal compensate``;
    :func:`stiffcal.measured.calibrated.compensate`): for every row of ``path`` (a CSV of poses and loads) the
    predicted deflection of the tool point, the corrected target and the corrected joint angles (iterated, and first
    order), and the predicted residual error. out: a CSV to write (None: nothing written). Returns ``{"rows",
    "causes", "max_deflection_m", "max_residual_m", "max_first_order_residual_m", "max_band95_m", "converged",
    "n_undetermined", "out", "notes"}``; raises :class:`InputError`."""
    from .measured import calibrated as C

    robot = _robot(robot)
    pf = C.read_poses(_input_file(_path(path, "path", "a CSV of poses and loads")), robot)
    if pf.target is not None and np.any(pf.target != 0):
        raise InputError("a path is compensated at the tool point: remove the target column (or give 'tool')",
                         field="path")
    out_path = None if out is None else _out_file(out, "out")
    comp = C.compensate(robot, pf.q, pf.load)
    if out_path is not None:
        _write_whole(out_path, C.compensation_csv(robot, pf, comp))
    return json_safe({"rows": len(pf.q), "causes": list(_calibration_causes(robot)),
                      "max_deflection_m": float(np.linalg.norm(comp.deflection, axis=1).max()),
                      "max_residual_m": float(comp.residual_m.max()),
                      "max_first_order_residual_m": float(comp.first_order_residual_m.max()),
                      "max_band95_m": float(comp.band95_m.max()),
                      "converged": bool(comp.converged.all()), "n_undetermined": _undetermined(comp.determined),
                      "out": None if out_path is None else str(out_path),
                      "notes": [*pf.notes, *comp.notes]})


def _undetermined(determined: np.ndarray | None) -> int:
    """The rows whose prediction rests on parameters the calibration's data did not determine (their sd and band
    do not hold the model's error there)."""
    return 0 if determined is None else int(np.count_nonzero(~np.asarray(determined, bool)))


def _calibration_causes(robot: Robot) -> tuple:
    cal = getattr(robot, "calibration", None)
    return () if cal is None else cal.causes


def _out_file(out, field: str) -> Path:
    """An output file path whose folder can be written (checked before any work); an existing target that is not a
    regular file (a folder, a FIFO, a device such as /dev/full) is refused: the write would replace it."""
    from .safeio import file_kind

    path = Path(_path(out, field, "an output file"))
    if path.is_dir():
        raise InputError(f"expected a file to write, got the folder {path}", field=field)
    if os.path.lexists(path):
        what = file_kind(path.stat().st_mode) if path.exists() else "a broken symbolic link"
        if what:
            raise InputError(f"expected a file to write, but {path} is {what}: it would be replaced", field=field)
    check_out_dir(path.parent if str(path.parent) else Path("."))
    return path


def _write_whole(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it (no partial output)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


def _next_round_robot(prior, robot, joint_limits_deg, cell):
    """(the prior, the robot the next round measures with the prior's calibration, placed in its limits and cell,
    notes) of :func:`plan_next_round`; the prior's cell when neither the robot nor ``cell`` gives one."""
    from dataclasses import replace

    from .measured import calibrated as C

    prior = _robot(prior)
    if getattr(prior, "calibration", None) is None:
        raise InputError("expected a calibrated robot file (DIR/calibrated.yaml of stiffcal discrepancy): this one has "
                         "no calibration section", source=prior.source, field="prior")
    robot = prior if robot is None else _robot(robot)
    if robot is not prior:
        if robot.joint_names != prior.joint_names:
            raise InputError(f"the prior is a calibration of another robot: joints {', '.join(prior.joint_names)} "
                             f"against {', '.join(robot.joint_names)} of the robot", source=prior.source,
                             field="prior")
        robot = replace(robot, calibration=C.from_dict(prior.calibration.to_dict(), robot, prior.source))
    notes = []
    if cell is None and robot.cell is None and prior.cell is not None:  # the prior's cell, not none at all
        robot = replace(robot, cell=prior.cell)
        notes.append(f"the robot file has no cell: the prior's ({prior.cell.describe()}) is the next round's; "
                     "give --cell to plan in another")
    if joint_limits_deg is None and robot is not prior and prior.has_joint_limits:
        robot, note = _within_prior_limits(robot, prior)
        notes += note
    return prior, _placed(robot, joint_limits_deg, cell), notes


def _within_prior_limits(robot, prior):
    """(``robot`` within the prior's joint limits too, notes): a next round measured by another robot file
    stays where the prior's data were taken unless ``joint_limits_deg`` is given."""
    import numpy as np

    from .model.robot import narrowed_limits

    own = np.degrees(robot.joint_limits_rad)
    both = np.column_stack([np.maximum(own[:, 0], prior.limits_deg[:, 0]),
                            np.minimum(own[:, 1], prior.limits_deg[:, 1])])
    if np.any(both[:, 0] >= both[:, 1]):
        joints = [robot.joint_names[j] for j in np.flatnonzero(both[:, 0] >= both[:, 1])]
        return robot, [f"the prior's joint limits and the robot file's do not overlap (joints {', '.join(joints)}): "
                       "the next round plans within the robot file's"]
    if np.allclose(both, own, rtol=0, atol=1e-9):
        return robot, []
    joints = [robot.joint_names[j] for j in np.flatnonzero(np.any(np.abs(both - own) > 1e-9, axis=1))]
    return narrowed_limits(robot, both, prior.source, "joint_limits_deg"), [
        f"the prior's joint limits narrow the robot file's (joints {', '.join(joints)}): the next round plans within "
        "them; give --joint-limits-deg to plan within others"]


def _root(ot: float) -> float:
    """sqrt(O_t) [m] of an O_t [m^2]: inf for inf (written "inf", docs/contracts.md), 0 for a round-off below zero."""
    return math.sqrt(max(ot, 0.0)) if math.isfinite(ot) else math.inf


def plan_next_round(prior, test_pose_deg, force_N=None, *, wrench=None, experiments: int = 1,
                    sigma_m: float | None = None, joint_limits_deg=None, cell=None, seed: int = 0,
                    robot=None, loads: str | None = None) -> dict:
    """The next round's plan (``stiffcal design --prior``; :func:`stiffcal.measured.calibrated.next_round`): M more
    poses of the tool point's position under the test load (or each measured under ``loads``, the SPEC of
    :func:`design`'s: the lab's hanging masses, their cable free in the cell), O_t-optimal for the calibrated model
    with the information its data already hold added, with the certified lower bound over every M-pose plan of the
    candidate poses.

    prior: a calibrated robot file (``calibrated.yaml`` of ``stiffcal discrepancy``) or a Robot with a
    calibration; test_pose_deg (n,) [deg]; force_N (d,) [N] or wrench (d + d_m,) [N, N m]: the test load, used in
    every new measurement; experiments: M; sigma_m [m]: the new readings' noise (default the calibration's);
    joint_limits_deg, cell: as :func:`design`; robot: the robot the next round measures (a Robot or a robot file
    with the prior's joint names: its kinematics, limits and cell, with the prior's calibration; default the
    prior's own file). Returns the JSON of docs/contracts.md ("The calibrated model"):
    ``poses_deg``, ``O_t``, ``O_t_prior``, ``O_t_fresh``, ``lower_bound``, ``gap``, ... [m^2]. Raises
    :class:`InputError` for bad arguments or a robot without a calibration."""
    from .measured import calibrated as C
    from .model.observation import measurement_loads
    from .planning.study import check_test_inputs
    from .threads import one_blas_thread

    prior, robot, inherited = _next_round_robot(prior, robot, joint_limits_deg, cell)
    force, moment, field_ = load_arguments(robot, force_N, wrench)
    q_t = check_test_inputs(robot, float_list(test_pose_deg, "test_pose_deg", limit=MAX_JOINT_ANGLE_DEG), force,
                            "test_pose_deg", field_, None, moment, field_)
    m = whole_number(experiments, "experiments", 1, MAX_DESIGN_EXPERIMENTS, "poses")
    sigma = None if sigma_m is None else positive_number(sigma_m, "sigma_m")
    seed = whole_number(seed, "seed", 0, 2**32 - 1)
    load = np.r_[force, [] if moment is None else moment]
    meas_loads = None if loads is None else measurement_loads(robot, loads, "loads")
    with one_blas_thread():
        nr = C.next_round(robot, np.radians(q_t), load, m, sigma, seed=seed, loads=meas_loads)
    clear, closest, near = _clearances(robot, nr.poses)
    return json_safe({
        "robot": robot.name, "prior": prior.source, "experiments": m, "causes": list(nr.causes),
        "joint_names": list(robot.joint_names),
        "poses_deg": round_within(np.degrees(nr.poses), robot.limits_deg).tolist(),
        "O_t": nr.O_t, "O_t_prior": nr.O_t_prior, "O_t_fresh": nr.O_t_fresh,
        "rms_m": _root(nr.O_t), "rms_prior_m": _root(nr.O_t_prior), "rms_fresh_m": _root(nr.O_t_fresh),
        "lower_bound": nr.lower_bound,
        "gap": nr.O_t / nr.lower_bound - 1.0 if nr.lower_bound > 0 else None,
        "lower_bound_over": f"every plan of {m} of the {nr.pool_size} candidate poses, with the old information added"
                            + ("" if meas_loads is None else f", each pose measured under the loads {meas_loads.spec}"),
        "loads": None if meas_loads is None else meas_loads.spec,
        "approximate_design": {"support_deg": round_within(np.degrees(nr.support), robot.limits_deg).tolist(),
                               "weights": nr.weights.tolist(), "equivalence_gap": nr.equivalence_gap},
        "parameter_names": list(nr.names), "cov_diag": nr.cov_diag.tolist(), "sigma_m": nr.sigma_m, "seed": seed,
        "test_pose_deg": q_t.tolist(), "force_N": force.tolist(),
        "moment_Nm": None if moment is None else np.asarray(moment).tolist(),
        "clearance_m": None if clear is None else [round(float(c), 6) for c in clear],
        "closest": list(closest), "notes": inherited + list(nr.notes) + near})


def _clearances(robot: Robot, q: np.ndarray) -> tuple[np.ndarray | None, tuple, list[str]]:
    """(each pose's smallest distance (M,) [m] over the cell's checked pairs, the closest pair of each, the notes of
    the poses within 1 mm of contact) of the poses q (M, n) [rad]; (None, (), []) without a cell."""
    from .model.workcell import clearance, contact_note

    if robot.cell is None:
        return None, (), []
    c, names = clearance(robot, q)
    return c, tuple(names), contact_note(c, names)
