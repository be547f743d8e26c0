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
    n, d = robot.n_joints, robot.task_dim
    if len(s["test_pose_deg"]) != n:
        raise InputError(f"expected {n} joint angles (robot {robot.source} has {n} joints), "
                         f"got {len(s['test_pose_deg'])}", source=source, field=f"{where}.test_pose_deg")
    if len(s["force_N"]) != d:
        raise InputError(f"expected {d} force components for a {robot.kind} robot, got {len(s['force_N'])}",
                         source=source, field=f"{where}.force_N")
    force = np.asarray(s["force_N"], float)
    if not np.any(force):
        raise InputError("expected a nonzero force: with F = 0 nothing deflects", source=source,
                         field=f"{where}.force_N")
    q = np.radians(np.asarray(s["test_pose_deg"], float))
    if robot.has_joint_limits:
        lo, hi = robot.joint_limits_rad.T
        out = np.flatnonzero((q < lo - 1e-9) | (q > hi + 1e-9))
        if out.size:
            j = int(out[0])
            raise InputError(f"expected q{j + 1} within the joint limits [{np.degrees(lo[j]):g}, {np.degrees(hi[j]):g}] "
                             f"deg of {robot.source}, got {s['test_pose_deg'][j]}", source=source,
                             field=f"{where}.test_pose_deg[{j}]")
    return Study(s["name"], robot, q, force, float(s["sigma_m"]), tuple(s["criteria"]), float(s["search_step_deg"]),
                 float(s["fig5_step_deg"]))


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
        too_few = [m for m in e["m_values"] if m * st.robot.task_dim < st.robot.n_joints]
        if too_few:
            raise InputError(f"expected m >= {-(-st.robot.n_joints // st.robot.task_dim)}: {too_few[0]} poses give "
                             f"{too_few[0] * st.robot.task_dim} equations for {st.robot.n_joints} compliances",
                             source=source, field=f"studies[{i}].m_values")
        out[e["name"]] = (st, e)
    return out
