"""Robot description, forward kinematics and Jacobian, batched over arrays of poses (paper eqs. 1, 18, 20).

Conventions
-----------
* Joint angles are radians inside the library, degrees only at the edges (files, CLI, tables).
* A batch of poses is an array ``q`` of shape ``(..., n)``; every function broadcasts over ``...``.
* Planar arm: revolute joints about z, joint i at the base of link i, ``q_i`` relative to link i-1
  (``q_1`` from the base x axis), so link k points along the absolute angle ``c_k = q_1 + ... + q_k``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .validation import read_yaml, validate


def planar_fk(links: np.ndarray, q: np.ndarray) -> np.ndarray:
    """End-effector position of a planar serial arm (eq. 18 for n = 2).

    links: (n,) link lengths [m]; q: (..., n) joint angles [rad]. Returns (..., 2) position [m].
    """
    c = np.cumsum(q, axis=-1)
    return np.stack([(links * np.cos(c)).sum(-1), (links * np.sin(c)).sum(-1)], axis=-1)


def planar_jacobian(links: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Position Jacobian d p / d q of a planar serial arm (eq. 20 in the base frame).

    Column j is z x (p - o_j): the sum over links k >= j of l_k [-sin c_k, cos c_k].
    links: (n,) [m]; q: (..., n) [rad]. Returns (..., 2, n) [m/rad].
    """
    c = np.cumsum(q, axis=-1)
    px = links * np.cos(c)
    py = links * np.sin(c)
    # reverse cumulative sums: contribution of links j..n to column j
    jx = -np.flip(np.cumsum(np.flip(py, -1), -1), -1)
    jy = np.flip(np.cumsum(np.flip(px, -1), -1), -1)
    return np.stack([jx, jy], axis=-2)


def planar_link_points(links: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Joint and end-effector positions for drawing the arm.

    links: (n,) [m]; q: (..., n) [rad]. Returns (..., n + 1, 2): base, joints 2..n, end effector [m].
    """
    c = np.cumsum(q, axis=-1)
    seg = np.stack([links * np.cos(c), links * np.sin(c)], axis=-1)
    zero = np.zeros(seg.shape[:-2] + (1, 2))
    return np.concatenate([zero, np.cumsum(seg, axis=-2)], axis=-2)


@dataclass(frozen=True)
class Robot:
    """A serial robot read from a robot file (DESIGN.md contract).

    Attributes: ``name``; ``kind`` ('planar'); ``links_m`` (n,) [m]; ``joint_limits_rad`` (n, 2) [rad];
    ``compliances`` (n,) [rad/(N m)] or None; ``source`` (the file it came from, for messages).
    """

    name: str
    kind: str
    links_m: np.ndarray
    joint_limits_rad: np.ndarray
    compliances: np.ndarray | None = None
    source: str = "<memory>"
    has_joint_limits: bool = field(default=False)

    @property
    def n_joints(self) -> int:
        return int(self.links_m.shape[0])

    @property
    def task_dim(self) -> int:
        """Number of measured Cartesian coordinates per pose (2 for planar arms)."""
        return 2

    def fk(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d) [m]."""
        return planar_fk(self.links_m, np.asarray(q, float))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d, n) [m/rad]."""
        return planar_jacobian(self.links_m, np.asarray(q, float))

    def link_points(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., n + 1, d) [m]."""
        return planar_link_points(self.links_m, np.asarray(q, float))

    def scaled(self, factor: float) -> "Robot":
        """The same robot with every link length multiplied by ``factor``."""
        return Robot(self.name, self.kind, self.links_m * factor, self.joint_limits_rad,
                     self.compliances, self.source, self.has_joint_limits)


def planar_robot(links_m, name: str = "planar", joint_limits_deg=None) -> Robot:
    """Build a planar robot in memory (links in metres, optional (n, 2) limits in degrees)."""
    links = np.asarray(links_m, float)
    has = joint_limits_deg is not None
    lim = np.radians(np.asarray(joint_limits_deg, float)) if has else np.tile([-np.pi, np.pi], (links.size, 1))
    return Robot(name, "planar", links, lim, None, "<memory>", has)


def load_robot(path: str | Path) -> Robot:
    """Read and validate a robot file.

    Raises :class:`InputError` naming the file and the field for a missing or negative link length,
    an unknown ``kind``, a non-numeric value, or joint limits that do not match the joints.
    """
    src = str(path)
    doc = read_yaml(path)
    validate(doc, "robot", src)
    links = np.asarray(doc["links_m"], float)
    n = links.size
    limits = doc.get("joint_limits_deg")
    if limits is not None:
        if len(limits) != n:
            raise InputError(f"expected {n} [lower, upper] pairs (one per link), got {len(limits)}",
                             source=src, field="joint_limits_deg")
        for i, (lo, hi) in enumerate(limits):
            if not lo < hi:
                raise InputError(f"expected lower < upper, got [{lo}, {hi}]", source=src,
                                 field=f"joint_limits_deg[{i}]")
    comp = doc.get("compliances_rad_per_Nm")
    if comp is not None and len(comp) != n:
        raise InputError(f"expected {n} values (one per joint), got {len(comp)}", source=src,
                         field="compliances_rad_per_Nm")
    robot = planar_robot(links, doc["name"], limits)
    return Robot(robot.name, doc["kind"], robot.links_m, robot.joint_limits_rad,
                 None if comp is None else np.asarray(comp, float), src, robot.has_joint_limits)
