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
    """Build the :class:`Study` of a validated config dict; paths are relative to ``root``."""
    s = {**DEFAULTS, **config["study"]}
    robot = load_robot(Path(root) / s["robot"])
    n, d = robot.n_joints, robot.task_dim
    if len(s["test_pose_deg"]) != n:
        raise InputError(f"expected {n} joint angles (robot {robot.source} has {n} joints), "
                         f"got {len(s['test_pose_deg'])}", source=source, field="study.test_pose_deg")
    if len(s["force_N"]) != d:
        raise InputError(f"expected {d} force components for a {robot.kind} robot, got {len(s['force_N'])}",
                         source=source, field="study.force_N")
    force = np.asarray(s["force_N"], float)
    if not np.any(force):
        raise InputError("expected a nonzero force: with F = 0 nothing deflects", source=source,
                         field="study.force_N")
    return Study(s["name"], robot, np.radians(np.asarray(s["test_pose_deg"], float)), force,
                 float(s["sigma_m"]), tuple(s["criteria"]), float(s["search_step_deg"]),
                 float(s["fig5_step_deg"]))
