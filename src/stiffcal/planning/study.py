"""A study: the robot, test pose, force and noise that one section of the report is about, read from
the validated config (``config/config.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..model.criteria import CRITERIA_KEYS
from ..planning.problem import Problem
from ..errors import InputError
from ..model.observation import Loads, Sensing, measurement_loads, moment_dim
from ..model.robot import TOOL_TARGET, Robot, load_config_robot
from ..validation import read_yaml, validate

#: the keys of a study entry (``study`` or an item of ``studies``) that say what is loaded and measured, with
#: their defaults: a force only, the tool point's position, its error at the test pose (the paper's study)
SENSING_DEFAULTS = {"moment_Nm": None, "targets": [TOOL_TARGET], "orientation": False, "sigma_rad": None,
                    "test_target": TOOL_TARGET, "orientation_length_m": 0.0}
#: the keys every computation of a study's plans depends on
PROBLEM_KEYS = ("test_pose_deg", "force_N", "sigma_m", *SENSING_DEFAULTS)
#: the keys of a design study (config ``studies``) that say where the robot stands and what the lab applies, with
#: their defaults: the robot file's joint limits and cell, the test force in every measurement, the joint space
CELL_DEFAULTS = {"joint_limits_deg": None, "cell": None, "loads": None, "candidates": None}
#: the keys every computation of a design study's plans depends on
DESIGN_KEYS = (*PROBLEM_KEYS, *CELL_DEFAULTS)

DEFAULTS = {"sigma_m": 1.0, "criteria": list(CRITERIA_KEYS[1:]) + ["ot"], "search_step_deg": 1.0,
            "fig5_step_deg": 1.0, **SENSING_DEFAULTS}


@dataclass(frozen=True)
class Study:
    """name; robot; test_pose: (n,) [rad]; force: (d,) [N]; sigma [m] (position noise); criteria keys; grid
    steps [deg]; moment: (d_m,) [N m] about the tool point, or None; sensing: what is measured
    (:class:`stiffcal.model.observation.Sensing`, None: the tool point's position); test_target and length_m: where
    and how O_t measures the error at the test pose (:class:`stiffcal.planning.problem.Problem`); loads: the measurement
    loads (:class:`stiffcal.model.observation.Loads`; None: the force and moment, in every measurement and at the
    test pose); candidates: the only poses a plan may use (N, n) [rad] (a candidate file), or None."""

    name: str
    robot: Robot
    test_pose: np.ndarray
    force: np.ndarray
    sigma: float
    criteria: tuple[str, ...]
    search_step_deg: float
    fig5_step_deg: float
    moment: np.ndarray | None = None
    sensing: Sensing | None = None
    test_target: str = TOOL_TARGET
    length_m: float = 0.0
    loads: Loads | None = None
    candidates: np.ndarray | None = None

    def problem(self, criterion: str, m: int = 1) -> Problem:
        return Problem(self.robot, self.force, criterion, m, self.test_pose, None, self.sigma, self.moment,
                       None, self.sensing, self.test_target, self.length_m, self.loads, self.candidates)


def load_config(path: str | Path) -> dict:
    """Read and validate the workflow config; raise :class:`InputError` naming the file and field."""
    doc = read_yaml(path)
    validate(doc, "config", str(path))
    return doc


def study_from_config(config: dict, root: str | Path = ".", source: str = "config") -> Study:
    """Build the paper's :class:`Study` (config ``study``) of a validated config dict; paths are relative
    to ``root``."""
    return study_from_entry(config["study"], root, source, "study")


def study_from_entry(entry: dict, root: str | Path = ".", source: str = "config", where: str = "study") -> Study:
    """Build a :class:`Study` from one validated config entry (``study`` or an item of ``studies``).

    Checks what the schema cannot: one test-pose angle per joint, within the joint limits; one force
    component per measured coordinate; a nonzero force. ``where`` names the entry in messages."""
    s = {**DEFAULTS, **CELL_DEFAULTS, **entry}
    robot = load_config_robot(root, s["robot"], source, f"{where}.robot")
    if s["joint_limits_deg"] is not None:
        from ..model.robot import narrowed_limits

        robot = narrowed_limits(robot, s["joint_limits_deg"], source, f"{where}.joint_limits_deg")
    if s["cell"] is not None:
        from ..model.workcell import with_cell

        robot = with_cell(robot, s["cell"], source, f"{where}.cell", root)
    loads = None if s["loads"] is None else measurement_loads(robot, s["loads"], f"{where}.loads", source)
    candidates = None
    if s["candidates"] is not None:
        from ..model.workcell import read_candidates

        candidates = read_candidates(Path(root) / s["candidates"], robot)
    force = np.asarray(s["force_N"], float)
    moment = None if s["moment_Nm"] is None else np.asarray(s["moment_Nm"], float)
    q = np.radians(check_test_inputs(robot, s["test_pose_deg"], force, f"{where}.test_pose_deg", f"{where}.force_N",
                                     source, moment, f"{where}.moment_Nm"))
    sensing, target, length = check_sensing(robot, s["targets"], s["orientation"], float(s["sigma_m"]), s["sigma_rad"],
                                            s["test_target"], s["orientation_length_m"], where, source)
    study = Study(s["name"], robot, q, force, float(s["sigma_m"]), tuple(s["criteria"]), float(s["search_step_deg"]),
                  float(s["fig5_step_deg"]), moment, sensing, target, length, loads, candidates)
    study.problem("ot").check_test_load(f"{where}.force_N", source)
    return study


def check_sensing(robot: Robot, targets, orientation: bool, sigma_m: float, sigma_rad, test_target: str,
                  length_m: float, where: str = "", source: str | None = None):
    """``(Sensing, test_target, length_m)`` of a study or a CLI call, checked: known targets (the robot file's
    ``targets`` and ``"tool"``), each once, the orientation noise when the orientation is measured, a known test
    target and a length scale >= 0. Raises :class:`InputError` naming ``source`` and the field (prefixed by
    ``where``)."""
    pre = f"{where}." if where else ""
    sensing = Sensing(tuple(str(t) for t in targets), bool(orientation), sigma_m,
                      None if sigma_rad is None else float(sigma_rad))
    sensing.check(robot, pre, source)
    if test_target not in robot.target_names:
        raise InputError(f"expected a target of robot {robot.source} ({', '.join(robot.target_names)}), got "
                         f"{test_target!r}", source=source, field=f"{pre}test_target")
    if not (np.isfinite(length_m) and length_m >= 0):
        raise InputError(f"expected a length >= 0 [m], got {length_m}", source=source,
                         field=f"{pre}orientation_length_m")
    return sensing, str(test_target), float(length_m)


def _chain_text(robot: Robot) -> str:
    """For a URDF arm: ': j1, j2, ... from base to tip frame', and how to choose another tip (a gripper's joint in
    the chain guessed from a URDF: a fresh user's Z1 had 7 joints where they expected 6)."""
    info = robot.urdf_info
    if not info:
        return ""
    return (f": {', '.join(map(str, robot.joint_names))}, from {info['base_frame']} to {info['tip_frame']}; a robot "
            "file's tip_frame (or load_robot(path, tip_frame=...)) ends the arm at another link")


def check_test_inputs(robot: Robot, q_deg, force: np.ndarray, pose_field: str, force_field: str,
                      source: str | None = None, moment: np.ndarray | None = None,
                      moment_field: str = "moment_Nm") -> np.ndarray:
    """The test pose (one angle per joint, within the joint limits), force (one component per measured
    coordinate) and moment (optional: one component per rotation coordinate, 1 planar, 3 spatial), not both
    zero, of a study or a CLI call; raises :class:`InputError` naming ``source`` and the field. Returns the test
    pose (n,) [deg]."""
    q_deg = np.asarray(q_deg, float)
    n, d, dm = robot.n_joints, robot.task_dim, moment_dim(robot)
    if q_deg.size != n:
        raise InputError(f"expected {n} joint angles (robot {robot.source} has {n} joints{_chain_text(robot)}), got "
                         f"{q_deg.size}", source=source, field=pose_field)
    if np.size(force) != d:
        raise InputError(f"expected {d} force components for a {robot.kind} robot, got {np.size(force)}",
                         source=source, field=force_field)
    if moment is not None and np.size(moment) != dm:
        raise InputError(f"expected {dm} moment component{'s' * (dm > 1)} for a {robot.kind} robot "
                         f"({'mz' if dm == 1 else 'mx, my, mz'}), got {np.size(moment)}", source=source,
                         field=moment_field)
    if not np.any(force) and (moment is None or not np.any(moment)):
        raise InputError("expected a nonzero force or moment: with no load nothing deflects", source=source,
                         field=force_field)
    out = np.flatnonzero(robot.outside_limits(np.radians(q_deg)))
    if out.size:
        j = int(out[0])
        lo, hi = np.degrees(robot.joint_limits_rad[j])
        raise InputError(f"expected {robot.joint_columns('q')[j]} within the joint limits [{lo:g}, {hi:g}] deg of "
                         f"{robot.source}, got {q_deg[j]:g}", source=source, field=f"{pose_field}[{j}]")
    check_load_bends(robot, np.radians(q_deg), force if moment is None else np.r_[force, moment], force_field, source)
    return q_deg


#: a joint torque below this fraction of |load| times the arm's reach is zero (rounding of sines and cosines)
ZERO_TORQUE = 1e-12


def check_load_bends(robot: Robot, q: np.ndarray, load: np.ndarray, field: str, source: str | None = None) -> None:
    """Refuse a load that produces no joint torque at the test pose q (n,) [rad]: ``tau = J_W^T W`` (eqs. 2-4;
    ``load`` the force (d,) or the wrench [N, N m]) is 0, e.g. a force along the straight arm. Nothing deflects
    there, A_t = 0 and O_t (eq. 16) is 0 for every plan: the problem has no answer. Raises :class:`InputError`
    naming ``source`` and ``field``."""
    from ..model.observation import as_wrench, tool_twists, torques

    tau = torques(robot, q, load)
    scale = np.linalg.norm(as_wrench(robot, load)) * max(1.0, float(np.abs(tool_twists(robot, q)[0]).max()))
    if np.all(np.abs(tau) <= ZERO_TORQUE * scale):
        raise InputError("expected a load that bends the arm at the test pose, but it produces no joint torque there "
                         "(tau = J^T F = 0: its line of action passes through every joint axis, e.g. a force along "
                         "the straight arm), so nothing deflects at the test pose and O_t is 0 for every plan; "
                         "change the force direction or the test pose", source=source, field=field)


#: defaults of an entry of config ``studies`` (design studies for any robot)
DESIGN_DEFAULTS = {"sigma_m": 1.0, "m_values": [2, 3, 4, 5, 6, 7, 8], "draw_m": None, **SENSING_DEFAULTS,
                   **CELL_DEFAULTS}


def design_studies(config: dict, root: str | Path = ".", source: str = "config") -> dict[str, tuple[Study, dict]]:
    """The design studies of config ``studies``: name -> (Study, entry with defaults filled in)."""
    out = {}
    for i, entry in enumerate(config.get("studies", []) or []):
        e = {**DESIGN_DEFAULTS, **entry}
        if e["name"] in out:
            raise InputError(f"expected unique study names, got {e['name']!r} twice", source=source,
                             field=f"studies[{i}].name")
        st = study_from_entry({k: e[k] for k in ("name", "robot", *DESIGN_KEYS)}, root, source, f"studies[{i}]")
        if e["draw_m"] is None:
            e["draw_m"] = max(e["m_values"])
        if e["draw_m"] not in e["m_values"]:
            raise InputError(f"expected one of m_values {e['m_values']}, got {e['draw_m']}", source=source,
                             field=f"studies[{i}].draw_m")
        prob = st.problem("ot")
        too_few = [m for m in e["m_values"] if m < prob.min_poses]
        if too_few:
            raise InputError(f"expected m >= {prob.min_poses}: {too_few[0]} poses give "
                             f"{too_few[0] * prob.rows_per_pose} equations for {prob.n_params} compliances",
                             source=source, field=f"studies[{i}].m_values")
        if prob.candidates is not None and len(prob.candidates) < prob.min_poses:  # as the design job would say
            raise InputError(f"expected at least {prob.min_poses} candidate poses: {len(prob.candidates)} give "
                             f"{len(prob.candidates) * prob.rows_per_pose} equations for {prob.n_params} compliances",
                             source=source, field=f"studies[{i}].candidates")
        out[e["name"]] = (st, e)
    return out
