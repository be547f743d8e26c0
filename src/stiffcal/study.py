"""A study: the robot, test pose, force and noise that one section of the report is about, read from
the validated config (``config/config.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .criteria import CRITERIA_KEYS
from .design import Problem
from .errors import InputError
from .robot import Robot, load_robot
from .validation import read_yaml, validate

DEFAULTS = {"sigma_m": 1.0, "criteria": list(CRITERIA_KEYS[1:]) + ["ot"], "search_step_deg": 1.0,
            "fig5_step_deg": 1.0}


@dataclass(frozen=True)
class Study:
    """name; robot; test_pose: (n,) [rad]; force: (d,) [N]; sigma [m]; criteria keys; grid steps [deg]."""

    name: str
    robot: Robot
    test_pose: np.ndarray
    force: np.ndarray
    sigma: float
    criteria: tuple[str, ...]
    search_step_deg: float
    fig5_step_deg: float

    def problem(self, criterion: str, m: int = 1) -> Problem:
        return Problem(self.robot, self.force, criterion, m, self.test_pose, None, self.sigma)


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
    s = {**DEFAULTS, **entry}
    robot = load_robot(Path(root) / s["robot"])
    force = np.asarray(s["force_N"], float)
    q = np.radians(check_test_inputs(robot, s["test_pose_deg"], force, f"{where}.test_pose_deg", f"{where}.force_N",
                                     source))
    return Study(s["name"], robot, q, force, float(s["sigma_m"]), tuple(s["criteria"]), float(s["search_step_deg"]),
                 float(s["fig5_step_deg"]))


def check_test_inputs(robot: Robot, q_deg, force: np.ndarray, pose_field: str, force_field: str,
                      source: str | None = None) -> np.ndarray:
    """The test pose (one angle per joint, within the joint limits) and force (one component per measured
    coordinate, nonzero) of a study or a CLI call; raises :class:`InputError` naming ``source`` and the
    field. Returns the test pose (n,) [deg]."""
    q_deg = np.asarray(q_deg, float)
    n, d = robot.n_joints, robot.task_dim
    if q_deg.size != n:
        raise InputError(f"expected {n} joint angles (robot {robot.source} has {n} joints), got {q_deg.size}",
                         source=source, field=pose_field)
    if np.size(force) != d:
        raise InputError(f"expected {d} force components for a {robot.kind} robot, got {np.size(force)}",
                         source=source, field=force_field)
    if not np.any(force):
        raise InputError("expected a nonzero force: with F = 0 nothing deflects", source=source, field=force_field)
    out = np.flatnonzero(robot.outside_limits(np.radians(q_deg)))
    if out.size:
        j = int(out[0])
        lo, hi = np.degrees(robot.joint_limits_rad[j])
        raise InputError(f"expected {robot.joint_columns('q')[j]} within the joint limits [{lo:g}, {hi:g}] deg of "
                         f"{robot.source}, got {q_deg[j]:g}", source=source, field=f"{pose_field}[{j}]")
    return q_deg


#: defaults of an entry of config ``studies`` (design studies for any robot)
DESIGN_DEFAULTS = {"sigma_m": 1.0, "m_values": [2, 3, 4, 5, 6, 7, 8], "draw_m": None}


def design_studies(config: dict, root: str | Path = ".", source: str = "config") -> dict[str, tuple[Study, dict]]:
    """The design studies of config ``studies``: name -> (Study, entry with defaults filled in)."""
    out = {}
    for i, entry in enumerate(config.get("studies", []) or []):
        e = {**DESIGN_DEFAULTS, **entry}
        if e["name"] in out:
            raise InputError(f"expected unique study names, got {e['name']!r} twice", source=source,
                             field=f"studies[{i}].name")
        st = study_from_entry({k: e[k] for k in ("name", "robot", "test_pose_deg", "force_N", "sigma_m")},
                              root, source, f"studies[{i}]")
        if e["draw_m"] is None:
            e["draw_m"] = max(e["m_values"])
        if e["draw_m"] not in e["m_values"]:
            raise InputError(f"expected one of m_values {e['m_values']}, got {e['draw_m']}", source=source,
                             field=f"studies[{i}].draw_m")
        too_few = [m for m in e["m_values"] if m < st.robot.min_poses]
        if too_few:
            raise InputError(f"expected m >= {st.robot.min_poses}: {too_few[0]} poses give "
                             f"{too_few[0] * st.robot.task_dim} equations for {st.robot.n_params} compliances",
                             source=source, field=f"studies[{i}].m_values")
        out[e["name"]] = (st, e)
    return out
