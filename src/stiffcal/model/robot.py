"""Robot description, forward kinematics and Jacobian, batched over arrays of poses (paper eqs. 1, 18, 20).

Conventions
-----------
* Joint angles are radians inside the library, degrees only at the edges (files, CLI, tables).
* A batch of poses is an array ``q`` of shape ``(..., n)``; every function broadcasts over ``...``.
* Planar arm (``kind: planar``, docs/contracts.md): revolute joints about z, joint i at the base of
  link i, ``q_i`` relative to link i-1 (``q_1`` from the base x axis), so link k points along the
  absolute angle ``c_k = q_1 + ... + q_k``. Measured coordinates: x, y (d = 2).
* Spatial serial arm (``kind: spatial``): revolute joints given by a Denavit-Hartenberg table, in the
  *standard* convention (Denavit & Hartenberg 1955; Spong, Hutchinson & Vidyasagar, *Robot Modeling and
  Control*, sec. 3.2), ``T_{i-1,i} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)`` with
  ``theta_i = q_i + offset_i`` and joint i turning about ``z_{i-1}``; or the *modified* convention
  (Craig, *Introduction to Robotics*, sec. 3.4), ``T_{i-1,i} = Rot_x(alpha_{i-1}) Trans_x(a_{i-1})
  Rot_z(theta_i) Trans_z(d_i)`` with joint i turning about ``z_i`` (row i of the file then holds
  ``a_{i-1}, alpha_{i-1}, d_i, offset_i``, as Craig's tables print them). The measured point is the tool
  point ``tool_m`` given in the last frame. Measured coordinates: x, y, z (d = 3).
* URDF arm (``kind: urdf``): the revolute and continuous joints of a URDF between a base frame and a tip
  frame (:mod:`stiffcal.model.urdf`, read with Pinocchio), held as a :class:`Chain` of fixed transforms and joint
  axes; the measured point is ``tool_m`` in the tip frame. Measured coordinates: x, y, z (d = 3).
* Every robot names its joints (``joint_names``: the URDF's joint names, or ``joint_names:`` of a planar or
  DH file, default "1".."n"); tables, plans and verdicts name joints by :meth:`Robot.joint_columns`
  (``q1_deg`` for the default names, ``q_<name>_deg`` otherwise).
* Whatever the kind, :meth:`Robot.joint_frames` and :meth:`Robot.tool_frame` give every joint's axis and the
  tip frame in the base frame, so the Jacobian of any point t given in the tip frame is
  ``J_lin = axes x (p + R t - origins)`` and the angular one is the axes.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, short_repr
from ..limits import MAX_JOINTS, MIN_LINK_M, TOOL_LENGTHS
from ..validation import read_yaml, validate

#: the smallest joint compliance accepted [rad/(N m)]
MIN_COMPLIANCE = 1e-12


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
    p = np.empty(c.shape[:-1] + (2, c.shape[-1]))  # rows: l_k cos c_k, l_k sin c_k
    np.multiply(links, np.cos(c), out=p[..., 0, :])
    np.multiply(links, np.sin(c), out=p[..., 1, :])
    # reverse cumulative sums (contribution of links j..n to column j), added from the last link as
    # np.cumsum of the reversed rows adds them: the same numbers
    s = p.copy()
    for j in range(c.shape[-1] - 2, -1, -1):
        np.add(s[..., j + 1], p[..., j], out=s[..., j])
    J = np.empty_like(s)
    np.negative(s[..., 1, :], out=J[..., 0, :])
    J[..., 1, :] = s[..., 0, :]
    return J


def planar_link_points(links: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Joint and end-effector positions for drawing the arm.

    links: (n,) [m]; q: (..., n) [rad]. Returns (..., n + 1, 2): base, joints 2..n, end effector [m].
    """
    c = np.cumsum(q, axis=-1)
    seg = np.stack([links * np.cos(c), links * np.sin(c)], axis=-1)
    zero = np.zeros(seg.shape[:-2] + (1, 2))
    return np.concatenate([zero, np.cumsum(seg, axis=-2)], axis=-2)


def as_xyz(v: np.ndarray) -> np.ndarray:
    """Lift planar vectors (..., 2) to (..., 3) with z = 0; spatial ones (..., 3) pass through."""
    v = np.asarray(v, float)
    return v if v.shape[-1] == 3 else np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)


def dh_link_transforms(dh: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Homogeneous transforms ``T_{i-1,i}`` of every link (module docstring, both conventions).

    dh: (n, 4) rows ``[a [m], alpha [rad], d [m], offset [rad]]``; q: (..., n) [rad].
    Returns (..., n, 4, 4).
    """
    if convention not in ("standard", "modified"):
        raise ValueError(f"unknown DH convention {convention!r}")
    a, alpha, d, off = (dh[:, j] for j in range(4))
    th = np.asarray(q, float) + off
    ct, st = np.cos(th), np.sin(th)
    ca, sa = np.cos(alpha), np.sin(alpha)
    T = np.zeros(th.shape + (4, 4))  # filled entry by entry (one array, no stacking: small batches are common)
    T[..., 0, 0], T[..., 1, 1] = ct, ct * ca
    if convention == "standard":
        T[..., 0, 1], T[..., 0, 2], T[..., 0, 3] = -st * ca, st * sa, a * ct
        T[..., 1, 0], T[..., 1, 2], T[..., 1, 3] = st, -ct * sa, a * st
        T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = sa, ca, d
    else:
        T[..., 0, 1], T[..., 0, 3] = -st, a
        T[..., 1, 0], T[..., 1, 2], T[..., 1, 3] = st * ca, -sa, -sa * d
        T[..., 2, 0], T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = st * sa, ct * sa, ca, ca * d
    T[..., 3, 3] = 1.0
    return T


def dh_frames(dh: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Base-frame poses of frames 0..n, ``T_{0,i}``. dh: (n, 4); q: (..., n) [rad]. Returns (..., n+1, 4, 4)."""
    A = dh_link_transforms(dh, q, convention)
    n = A.shape[-3]
    T = np.empty(A.shape[:-3] + (n + 1, 4, 4))
    T[..., 0, :, :] = np.eye(4)
    for i in range(n):
        np.matmul(T[..., i, :, :], A[..., i, :, :], out=T[..., i + 1, :, :])
    return T


def dh_tool_point(frames: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """Tool point in the base frame: frames (..., n+1, 4, 4), tool (3,) [m] in frame n. Returns (..., 3)."""
    T = frames[..., -1, :, :]
    return T[..., :3, :3] @ tool + T[..., :3, 3]


def rotation_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices about a unit ``axis`` (3,) by ``angle`` (...) [rad] (Rodrigues' formula).
    Returns (..., 3, 3)."""
    x, y, z = np.asarray(axis, float)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


@dataclass(frozen=True)
class Chain:
    """A serial chain of revolute joints as fixed transforms and joint axes (the form of a URDF: each joint
    placed in the previous frame, then turning about its axis).

    placements: (n, 4, 4) transform from the frame of joint i-1 after its rotation (for i = 1: the base
    frame) to the frame of joint i; axes: (n, 3) unit axis of joint i in its own frame; tip: (4, 4) from the
    frame of joint n after its rotation to the tip frame. Lengths in metres. The pose of the tip frame is
    ``placements[0] Rot(axes[0], q_1) ... placements[n-1] Rot(axes[n-1], q_n) tip``.
    """

    placements: np.ndarray
    axes: np.ndarray
    tip: np.ndarray


def chain_frames(chain: Chain, q: np.ndarray):
    """Joint axes and tip frame of a :class:`Chain` in the base frame, batched over poses.

    q: (..., n) [rad]. Returns ``(origins (..., n, 3) [m], axes (..., n, 3) unit, R_tip (..., 3, 3),
    p_tip (..., 3) [m])``: a point of each joint's axis (its frame origin), the axis direction, and the
    rotation and origin of the tip frame.
    """
    q = np.asarray(q, float)
    R = np.broadcast_to(np.eye(3), q.shape[:-1] + (3, 3))
    p = np.zeros(q.shape[:-1] + (3,))
    origins, axes = [], []
    for i in range(q.shape[-1]):
        P = chain.placements[i]
        p = p + R @ P[:3, 3]
        R = R @ P[:3, :3]
        origins.append(p)
        axes.append(R @ chain.axes[i])
        R = R @ rotation_about(chain.axes[i], q[..., i])
    return np.stack(origins, axis=-2), np.stack(axes, axis=-2), R @ chain.tip[:3, :3], p + R @ chain.tip[:3, 3]


def chain_link_frames(chain: Chain, q: np.ndarray):
    """The frame of every joint of a :class:`Chain` after its rotation, in the base frame: q (..., n) [rad] ->
    ``(R (..., n, 3, 3), p (..., n, 3) [m])`` (for a URDF, Pinocchio's joint frames)."""
    q = np.asarray(q, float)
    R = np.broadcast_to(np.eye(3), q.shape[:-1] + (3, 3))
    p = np.zeros(q.shape[:-1] + (3,))
    Rs, ps = [], []
    for i in range(q.shape[-1]):
        P = chain.placements[i]
        p = p + R @ P[:3, 3]
        R = R @ P[:3, :3] @ rotation_about(chain.axes[i], q[..., i])
        Rs.append(R)
        ps.append(p)
    return np.stack(Rs, axis=-3), np.stack(ps, axis=-2)


def dh_jacobian(dh: np.ndarray, tool: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Position Jacobian of the tool point of a revolute DH arm: column i is ``z_i x (p - o_i)`` for the
    axis ``z_i`` through ``o_i`` of joint i (frame i-1 in the standard convention, frame i in the modified).

    dh: (n, 4); tool: (3,) [m]; q: (..., n) [rad]. Returns (..., 3, n) [m/rad].
    """
    F = dh_frames(dh, q, convention)
    axes = F[..., :-1, :, :] if convention == "standard" else F[..., 1:, :, :]
    z, o = axes[..., :3, 2], axes[..., :3, 3]  # (..., n, 3)
    p = dh_tool_point(F, tool)
    return cross_columns(z, p[..., None, :] - o)


def cross_columns(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``np.swapaxes(np.cross(u, v), -1, -2)`` for u, v (..., n, 3): the same products and differences, so the
    same numbers in the same memory layout (a view of (..., n, 3)), in fewer array operations. Returns
    (..., 3, n)."""
    u, v = np.broadcast_arrays(u, v)
    out = np.empty(u.shape)
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.subtract(u[..., i] * v[..., j], u[..., j] * v[..., i], out=out[..., k])
    return np.swapaxes(out, -1, -2)


@dataclass(frozen=True)
class MassModel:
    """The arm's own weight as point masses rigidly attached to the frames that move with the joints:
    kg (B,) [kg]; link (B,) int, the frame each is attached to (0-based joint j: the frame that moves with joints
    1..j+1, :meth:`Robot.link_frames`; n: the tip frame of :meth:`Robot.tool_frame`); com_m (B, 3) [m] each
    mass's centre in its frame; gravity_m_s2 (3,) [m/s^2] the gravitational acceleration in the base frame.
    From a URDF's inertias (:func:`stiffcal.model.urdf.read_chain`) or the robot file's ``link_masses_kg``,
    ``link_coms_m``, ``payload_kg``, ``payload_com_m`` and ``gravity`` (docs/contracts.md)."""

    kg: np.ndarray
    link: np.ndarray
    com_m: np.ndarray
    gravity_m_s2: np.ndarray


@dataclass(frozen=True)
class Robot:
    """A serial robot read from a robot file (docs/contracts.md).

    Attributes: ``name``; ``kind`` ('planar', 'spatial' or 'urdf'); ``links_m`` (n,) [m] link lengths of a
    planar arm (for a spatial arm: the distances between consecutive points of :meth:`link_points`, for
    drawing and scale); ``joint_limits_rad`` (n, 2) [rad]; ``compliances`` (n,) [rad/(N m)] or None;
    ``source`` (the file it came from, for messages); for spatial arms ``dh`` (n, 4) ``[a, alpha, d, offset]``
    [m, rad], ``convention`` ('standard' or 'modified') and ``tool_m`` (3,) [m] the measured point in the last
    frame (for URDF arms: in the tip frame); ``inert_joints`` (joints that never move the measured point,
    :func:`inert_joints`); ``reference`` (the file's ``source`` field: where the dimensions come from);
    ``joint_names`` (n,) str (default "1".."n"); for URDF arms ``chain`` (:class:`Chain`) and ``urdf`` (the
    URDF file); ``targets`` {name: (3,) [m]}: further measured points (tracker targets) in the tip frame
    (:meth:`tool_frame`), beside the tool point ``"tool"``; ``masses`` (:class:`MassModel`) the arm's own weight,
    or None (no self-weight torques, :meth:`gravity_torques`); ``calibration``
    (:class:`stiffcal.model.calibration.Calibration`): the model a calibration identified (a calibrated.yaml), or
    None; gravity: the unit direction of gravity in the base frame (robot-file key ``gravity``; default -y for a planar
    arm in its vertical plane, -z for a spatial one), along which hanging masses pull and the arm's own weight
    acts; cell: the :class:`stiffcal.model.workcell.WorkCell` the robot stands in (None: every pose within the joint
    limits can be taken); urdf_info: for a URDF arm read from a file, where its chain comes from (``path``,
    ``base_frame``, ``tip_frame``, the moving ``joints``, the ``held`` angles [rad]), for its collision geometry.
    """

    name: str
    kind: str
    links_m: np.ndarray
    joint_limits_rad: np.ndarray
    compliances: np.ndarray | None = None
    source: str = "<memory>"
    has_joint_limits: bool = field(default=False)
    dh: np.ndarray | None = None
    convention: str = "standard"
    tool_m: np.ndarray | None = None
    inert_joints: tuple[int, ...] = ()
    reference: str = ""
    joint_names: tuple[str, ...] = ()
    chain: Chain | None = None
    urdf: str = ""
    targets: dict = field(default_factory=dict)
    unlimited_joints: tuple[int, ...] = ()
    masses: MassModel | None = None
    calibration: object = None
    gravity: tuple[float, ...] = ()
    cell: object = field(default=None, compare=False)
    urdf_info: dict | None = field(default=None, compare=False)

    def __repr__(self) -> str:
        """One line (the dataclass's repr printed every array of the chain, its masses and calibration)."""
        extras = [x for x, on in (("masses", self.masses is not None), ("calibrated", self.calibration is not None),
                                  ("cell", self.cell is not None)) if on]
        return (f"Robot({self.name!r}, kind={self.kind!r}, joints={list(self.joint_names)}, source={self.source!r}"
                + "".join(f", {x}" for x in extras) + ")")

    def __post_init__(self):
        if not self.joint_names:
            object.__setattr__(self, "joint_names", default_joint_names(self.n_joints))
        if not self.gravity:
            object.__setattr__(self, "gravity", (0.0, -1.0) if self.planar else (0.0, 0.0, -1.0))

    @property
    def kind_spec(self) -> "RobotKind":
        """This robot's kind in the registry :data:`ROBOT_KINDS`."""
        return ROBOT_KINDS[self.kind]

    @property
    def planar(self) -> bool:
        """True for an arm that moves in a plane (a 2-D task space: x, y and the rotation about z)."""
        return ROBOT_KINDS[self.kind].task_dim == 2

    @property
    def n_joints(self) -> int:
        return int(self.joint_limits_rad.shape[0])

    def joint_columns(self, prefix: str, suffix: str = "") -> list[str]:
        """Per-joint names of table columns and labels: ``prefix + i + suffix`` for the default joint names
        "1".."n" (``q1_deg``, ``E_dk1``), ``prefix + '_' + name + suffix`` for named joints (``q_a1_deg``)."""
        default = self.joint_names == default_joint_names(self.n_joints)
        return [f"{prefix}{name if default else '_' + name}{suffix}" for name in self.joint_names]

    @property
    def params(self) -> np.ndarray:
        """Indices of the joints whose compliance moves the measured point at some pose (the model's
        parameters); a joint whose axis passes through the measured point at every pose is left out."""
        return np.array([j for j in range(self.n_joints) if j not in self.inert_joints], int)

    @property
    def n_params(self) -> int:
        return self.n_joints - len(self.inert_joints)

    def model_jacobian(self, q: np.ndarray) -> np.ndarray:
        """The Jacobian's columns of the model's parameters: (..., n) [rad] -> (..., d, n_params) [m/rad]."""
        J = self.jacobian(q)
        return J[..., self.params] if self.inert_joints else J

    @property
    def min_poses(self) -> int:
        """Fewest measurement poses that give as many equations as compliances: ceil(n_params / d)."""
        return -(-self.n_params // self.task_dim)

    @property
    def n_segments(self) -> int:
        """Straight segments of the drawn arm (:meth:`link_points`): n links, plus the tool for a spatial arm."""
        return self.n_joints + self.kind_spec.tool_segment

    @property
    def limits_deg(self) -> np.ndarray | None:
        """(n, 2) [deg]: the joint limits, None for a robot file without limits (what printed poses keep within,
        :func:`round_within`)."""
        return np.degrees(self.joint_limits_rad) if self.has_joint_limits else None

    @property
    def limited(self) -> np.ndarray:
        """(n,) bool: the joints that have limits (a file without limits has none; a URDF's continuous joints,
        ``unlimited_joints``, turn endlessly and have none either)."""
        out = np.full(self.n_joints, bool(self.has_joint_limits))
        out[list(self.unlimited_joints)] = False
        return out

    def outside_limits(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., n) bool: angles outside the joint limits (always False for a joint without
        limits, :attr:`limited`)."""
        lo, hi = self.joint_limits_rad.T
        q = np.asarray(q, float)
        return ((q < lo - 1e-9) | (q > hi + 1e-9)) & self.limited

    @property
    def task_dim(self) -> int:
        """Number of measured Cartesian coordinates per pose (2 for planar arms, 3 for spatial ones)."""
        return self.kind_spec.task_dim

    @property
    def reach_m(self) -> float:
        """An upper bound on the distance from the base to the measured point [m]."""
        return float(self.kind_spec.reach(self))

    def fk(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d) [m]."""
        return self.kind_spec.fk(self, np.asarray(q, float))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d, n) [m/rad]."""
        return self.kind_spec.jacobian(self, np.asarray(q, float))

    def link_points(self, q: np.ndarray) -> np.ndarray:
        """Points of the drawn arm, base first, measured point last: (..., n) [rad] -> (..., n + 1, 2) for a
        planar arm, (..., n + 2, 3) for a spatial one (base, frame origins 1..n, tool point; for a URDF arm:
        base, the origins of joints 2..n, the tip frame's origin, tool point) [m]."""
        return self.kind_spec.link_points(self, np.asarray(q, float))

    def scaled(self, factor: float) -> "Robot":
        """The same robot with every length multiplied by ``factor``."""
        dh = None if self.dh is None else self.dh * np.array([factor, 1.0, factor, 1.0])
        tool = None if self.tool_m is None else self.tool_m * factor
        chain = None
        if self.chain is not None:
            placements, tip = self.chain.placements.copy(), self.chain.tip.copy()
            placements[:, :3, 3] *= factor
            tip[:3, 3] *= factor
            chain = Chain(placements, self.chain.axes, tip)
        return replace(self, links_m=self.links_m * factor, dh=dh, tool_m=tool, chain=chain)

    def joint_frames(self, q: np.ndarray):
        """Every joint's axis in the base frame: (..., n) [rad] -> ``(origins (..., n, 3) [m], axes (..., n, 3))``,
        ``origins`` a point of each axis, ``axes`` unit vectors (planar arms: z = 0 and e_z).

        With :meth:`tool_frame` this gives the geometric Jacobian of any point t of the tip frame: linear
        rows ``axes x (p + R t - origins)``, angular rows ``axes`` (Siciliano et al., *Robotics*, eq. 3.30)."""
        return self.kind_spec.joint_frames(self, np.asarray(q, float))

    def tool_frame(self, q: np.ndarray):
        """The tip frame in the base frame: (..., n) [rad] -> ``(R (..., 3, 3), p (..., 3) [m])``, its rotation and
        origin; a point t given in the tip frame (``tool_m``, a target) is at ``p + R t``. Planar arms: the
        frame at the end of the last link, x along that link; spatial arms: the last DH frame."""
        return self.kind_spec.tool_frame(self, np.asarray(q, float))

    def link_frames(self, q: np.ndarray):
        """The frame that moves with each joint, in the base frame: (..., n) [rad] -> ``(R (..., n, 3, 3),
        o (..., n, 3) [m])``: for a planar arm the frame at joint j with x along link j; for a DH arm frame j
        (after joint j's transform, either convention); for a URDF arm joint j's own frame after its rotation
        (Pinocchio's joint frame). Frame j turns with joints 1..j."""
        return self.kind_spec.link_frames(self, np.asarray(q, float))

    def mass_positions(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., B, 3) [m]: the base-frame position of every point mass of :attr:`masses`."""
        m = self.masses
        R, o = self.link_frames(q)
        Rt, pt = self.tool_frame(q)
        R = np.concatenate([R, Rt[..., None, :, :]], axis=-3)[..., m.link, :, :]
        o = np.concatenate([o, pt[..., None, :]], axis=-2)[..., m.link, :]
        return o + np.einsum("...bij,bj->...bi", R, m.com_m)

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., n) [N m]: the torques the arm's own weight applies at the joints (tau = J^T F
        of every point mass's weight m_b g, as a load's tau; Siciliano et al., *Robotics*, eq. 7.39); zeros
        without :attr:`masses`. The backlash and nonlinear-stiffness causes act on this plus the load's torque."""
        q = np.asarray(q, float)
        if self.masses is None:
            return np.zeros(q.shape)
        m = self.masses
        origins, axes = self.joint_frames(q)  # (..., n, 3)
        P = self.mass_positions(q)  # (..., B, 3)
        weight = m.kg[:, None] * as_xyz(np.asarray(m.gravity_m_s2, float))[None, :]  # (B, 3)
        lever = P[..., None, :, :] - origins[..., :, None, :]  # (..., n, B, 3)
        moment = np.cross(lever, weight)  # about each joint's axis point
        carried = m.link[None, :] >= np.arange(self.n_joints)[:, None]  # (n, B): mass b turns with joint j
        return np.einsum("...jbk,...jk,jb->...j", moment, axes, carried)

    @property
    def target_names(self) -> tuple[str, ...]:
        """Names of the points whose position can be measured: ``"tool"`` (the tool point, where the load is
        applied) first, then the file's ``targets`` in their order."""
        return (TOOL_TARGET,) + tuple(self.targets)

    def target_point(self, name: str) -> np.ndarray:
        """(3,) [m]: the point ``name`` (:attr:`target_names`) in the tip frame of :meth:`tool_frame`."""
        if name == TOOL_TARGET:
            return np.zeros(3) if self.tool_m is None else np.asarray(self.tool_m, float)
        return np.asarray(self.targets[name], float)


def default_joint_names(n: int) -> tuple[str, ...]:
    """The joint names of a robot file without ``joint_names``: "1" .. "n" (columns ``q1_deg`` .. ``qn_deg``)."""
    return tuple(str(i + 1) for i in range(n))


#: widest joint limit accepted [deg]: data sheets give ranges beyond a turn (ABB axis 6: +-400 deg); a joint
#: that turns endlessly is given without limits (or +-720, which holds every pose twice over)
MAX_JOINT_ANGLE_DEG = 720.0
#: what a joint name may hold: it becomes part of column names (``q_<name>_deg``) and CSV headers
JOINT_NAME = re.compile(r"^[A-Za-z0-9_.:/-]+$")


def check_joint_names(names, n: int, source: str, field: str = "joint_names") -> tuple[str, ...]:
    """Validated joint names (n,): unique, made of letters, digits and ``_ . : / -``, and a name of digits
    only must be its own joint's number (so that ``q3_deg`` always means joint 3). Raises :class:`InputError`
    naming ``source`` and ``field``."""
    names = tuple(str(v) for v in names)
    if len(names) != n:
        raise InputError(f"expected {n} names (one per joint), got {len(names)}", source=source, field=field)
    for i, name in enumerate(names):
        if not JOINT_NAME.match(name):
            raise InputError(f"expected a name of letters, digits and _ . : / - (it names table columns such as "
                             f"q_<name>_deg), got {name!r}", source=source, field=f"{field}[{i}]")
        if name.isdigit() and name != str(i + 1):
            raise InputError(f"a joint name of digits only must be the joint's own number ({i + 1}), got {name!r}",
                             source=source, field=f"{field}[{i}]")
        if name in names[:i]:
            raise InputError(f"expected unique joint names, got {name!r} twice", source=source, field=f"{field}[{i}]")
    return names


def planar_robot(links_m, name: str = "planar", joint_limits_deg=None, joint_names=()) -> Robot:
    """Build a planar robot in memory (links in metres, optional (n, 2) limits in degrees, optional names)."""
    links = np.asarray(links_m, float)
    has = joint_limits_deg is not None
    lim = np.radians(np.asarray(joint_limits_deg, float)) if has else np.tile([-np.pi, np.pi], (links.size, 1))
    return Robot(name, "planar", links, lim, None, "<memory>", has, joint_names=tuple(joint_names))


def spatial_robot(dh_rows, tool_m=(0.0, 0.0, 0.0), name: str = "spatial", joint_limits_deg=None,
                  convention: str = "standard", compliances=None, source: str = "<memory>",
                  reference: str = "", joint_names=()) -> Robot:
    """Build a spatial DH robot in memory. dh_rows: (n, 4) ``[a_m, alpha_deg, d_m, offset_deg]``."""
    dh = np.asarray(dh_rows, float) * np.array([1.0, np.pi / 180, 1.0, np.pi / 180])
    n = len(dh)
    has = joint_limits_deg is not None
    lim = np.radians(np.asarray(joint_limits_deg, float)) if has else np.tile([-np.pi, np.pi], (n, 1))
    robot = Robot(name, "spatial", np.zeros(n), lim, None if compliances is None else np.asarray(compliances, float),
                  source, has, dh, convention, np.asarray(tool_m, float), reference=reference,
                  joint_names=tuple(joint_names))
    return _with_geometry(robot, "check dh and tool_m", "dh", "the dh table's a_m and d_m and tool_m")


def chain_robot(chain: Chain, tool_m, joint_limits_rad, joint_names, name: str = "urdf", compliances=None,
                source: str = "<memory>", reference: str = "", urdf: str = "", has_joint_limits: bool = True,
                unlimited_joints: tuple[int, ...] = ()) -> Robot:
    """Build a URDF arm (``kind: urdf``) in memory from its :class:`Chain` (:func:`stiffcal.model.urdf.read_chain`).
    tool_m: (3,) [m] the measured point in the tip frame; joint_limits_rad: (n, 2) (a full turn [-pi, pi] for
    the joints of ``unlimited_joints``, continuous joints, which have no limits)."""
    robot = Robot(name, "urdf", np.zeros(len(chain.axes)), np.asarray(joint_limits_rad, float),
                  None if compliances is None else np.asarray(compliances, float), source, has_joint_limits,
                  tool_m=np.asarray(tool_m, float), reference=reference, joint_names=tuple(joint_names), chain=chain,
                  urdf=urdf, unlimited_joints=tuple(int(j) for j in unlimited_joints))
    return _with_geometry(robot, "check base_frame, tip_frame, the joints and tool_m", "urdf",
                          "the URDF's joint origins and tool_m")


def _with_geometry(robot: Robot, advice: str, field_: str, lengths: str) -> Robot:
    """A spatial robot with its drawn link lengths and inert joints filled in; refused (naming the robot file's
    ``field_``, and ``lengths``, what gives its lengths) if it has more than :data:`~stiffcal.limits.MAX_JOINTS`
    joints, if its lengths are below the physical range (the measured point within
    :data:`~stiffcal.limits.MIN_LINK_M` of the base whatever the pose), or if no joint moves the measured point
    (``advice``: what to check)."""
    n = robot.n_joints
    if n > MAX_JOINTS:
        raise InputError(f"{n} joints: expected at most {MAX_JOINTS} (docs/contracts.md, 'Limits')",
                         source=robot.source, field=field_)
    if robot.reach_m < MIN_LINK_M:
        raise InputError(f"the arm's lengths add up to {robot.reach_m:g} m: expected at least {MIN_LINK_M:g} m (the "
                         f"physical range of lengths; docs/contracts.md, 'Limits'); check {lengths}",
                         source=robot.source, field=field_)
    links = np.linalg.norm(np.diff(robot.link_points(np.zeros(n)), axis=0), axis=-1)
    if robot.tool_m is not None:
        check_tool_length(float(np.linalg.norm(robot.tool_m)), float(links[:-1].sum()), robot.source, "tool_m")
    inert = inert_joints(robot)
    if len(inert) == n:
        raise InputError(f"no joint moves the measured point: {advice}", source=robot.source, field="tool_m")
    return replace(robot, links_m=links, inert_joints=inert)


def inert_joints(robot: Robot, samples: int = 512, seed: int = 0) -> tuple[int, ...]:
    """Joints whose Jacobian column vanishes at every one of ``samples`` random poses (the joint's axis
    passes through the measured point, e.g. joint 6 of a spherical wrist with the point on the flange
    axis): their compliance never deflects the measured point, so position measurements cannot identify it
    and the deflection model does not need it."""
    lo, hi = robot.joint_limits_rad.T
    q = np.random.default_rng(seed).uniform(lo, hi, (samples, robot.n_joints))
    col = np.abs(robot.jacobian(q)).max(axis=(0, 1))
    return tuple(int(j) for j in np.flatnonzero(col <= 1e-12 * max(robot.reach_m, 1e-300)))


#: the name of the tool point among the measured targets (``tool_m``; the end of the last link of a planar arm)
TOOL_TARGET = "tool"


def check_tool_length(length: float, arm: float, source: str | None, field_: str, what: str = "",
                      origin: str = "the tip frame") -> None:
    """Refuse a tool point, target or loading bar (``what``, to begin the message) ``length`` [m] from ``origin``
    that is more than :data:`~stiffcal.limits.TOOL_LENGTHS` times the arm's own length ``arm`` [m], naming
    ``field_`` of ``source``."""
    if arm > 0 and length > TOOL_LENGTHS * arm:
        raise InputError(f"{what}{length:.4g} m from {origin}, more than {TOOL_LENGTHS:g} times the arm's own "
                         f"length ({arm:.3g} m): lengths are in metres (millimetres given?)", source=source,
                         field=field_)


def own_length(robot: Robot) -> float:
    """[m] the arm's own length: its links (a spatial arm's joint origins from the base, the tool left out)."""
    links = np.asarray(robot.links_m, float)
    return float(links.sum() if robot.planar else links[:-1].sum())


def with_targets(robot: Robot, targets, src: str) -> Robot:
    """``robot`` with the robot file's ``targets`` {name: [x, y] (planar) or [x, y, z] [m] in the tip frame},
    checked: one coordinate per tip-frame axis of the arm, and no target named ``"tool"`` (the tool point's
    name). Planar targets are stored with z = 0."""
    out = {}
    d = robot.task_dim
    for name, xyz in (targets or {}).items():
        if name == TOOL_TARGET:
            raise InputError(f"the name '{TOOL_TARGET}' is the tool point's; give this target another name",
                             source=src, field=f"targets.{name}")
        if len(xyz) != d:
            raise InputError(f"expected {d} coordinates [m] in the tip frame for a {robot.kind} robot, got {len(xyz)}",
                             source=src, field=f"targets.{name}")
        out[str(name)] = as_xyz(np.asarray(xyz, float))
        if d == 3 and robot.links_m is not None and len(robot.links_m) > 1:
            check_tool_length(float(np.linalg.norm(out[str(name)])), float(np.sum(robot.links_m[:-1])), src,
                              f"targets.{name}")
    return replace(robot, targets=out)


def load_config_robot(root: str | Path, path: str, source: str, field: str) -> Robot:
    """:func:`load_robot` of the robot file ``path`` (relative to ``root``) that the config ``source`` names in
    ``field``: a path that names nothing is refused naming the config and the field (the file's own errors name
    the file)."""
    full = Path(root) / path
    if not os.path.lexists(full):
        raise InputError(f"expected a robot file, but {path} does not exist", source=source, field=field)
    return load_robot(full)


def _link_masses(robot: Robot, doc: dict, src: str) -> tuple[list, list, list]:
    """(kg, link index, centre of mass (3,) [m] in the link's frame) of each link from ``link_masses_kg`` and
    ``link_coms_m`` (empty lists when not given); InputError naming the field."""
    n = robot.n_joints
    if "link_masses_kg" not in doc:
        if "link_coms_m" in doc:
            raise InputError("link_coms_m needs link_masses_kg: give the mass of each link", source=src,
                             field="link_coms_m")
        return [], [], []
    masses = doc["link_masses_kg"]
    if len(masses) != n:
        raise InputError(f"expected {n} masses [kg] (one per link), got {len(masses)}", source=src,
                         field="link_masses_kg")
    coms = doc.get("link_coms_m")
    if coms is None and not robot.planar:
        raise InputError("expected link_coms_m beside link_masses_kg: the centre of mass of each link, [x, y, z] "
                         "[m] in its DH frame", source=src, field="link_coms_m")
    if coms is not None and len(coms) != n:
        raise InputError(f"expected {n} centres of mass (one per link), got {len(coms)}", source=src,
                         field="link_coms_m")
    kg, link, com = [], [], []
    for j in range(n):
        if robot.planar:
            c = robot.links_m[j] / 2 if coms is None else coms[j]
            if isinstance(c, list):
                if len(c) != 2:
                    raise InputError(f"expected [x, y] [m] (x along the link), got {len(c)} numbers", source=src,
                                     field=f"link_coms_m[{j}]")
                xyz = [c[0], c[1], 0.0]
            else:
                xyz = [float(c), 0.0, 0.0]
        else:
            if not isinstance(coms[j], list) or len(coms[j]) != 3:
                raise InputError("expected [x, y, z] [m] in the link's DH frame", source=src,
                                 field=f"link_coms_m[{j}]")
            xyz = coms[j]
        kg.append(float(masses[j]))
        link.append(j)
        com.append(np.asarray(xyz, float))
    return kg, link, com


def _payload_mass(robot: Robot, doc: dict, src: str) -> tuple[list, list, list]:
    """([kg], [n], [centre of mass (3,) [m] in the tip frame]) of ``payload_kg`` and ``payload_com_m`` (default
    the tool point); empty lists when not given; InputError naming the field."""
    if "payload_kg" not in doc:
        if "payload_com_m" in doc:
            raise InputError("payload_com_m needs payload_kg: give the payload's mass", source=src,
                             field="payload_com_m")
        return [], [], []
    pc = doc.get("payload_com_m")
    if pc is not None and len(pc) != robot.task_dim:
        raise InputError(f"expected {robot.task_dim} coordinates [m] in the tip frame, got {len(pc)}", source=src,
                         field="payload_com_m")
    return ([float(doc["payload_kg"])], [robot.n_joints],
            [robot.target_point(TOOL_TARGET) if pc is None else as_xyz(np.asarray(pc, float))])


def load_robot(path: str | Path, base_frame: str | None = None, tip_frame: str | None = None) -> Robot:
    """Read and validate a robot file (a kind of :data:`ROBOT_KINDS`; schema ``schemas/robot.schema.yaml``), or a
    URDF itself (a path ending in ``.urdf``: the arm from ``base_frame`` to ``tip_frame``, each guessed when not
    given, :func:`stiffcal.model.urdf.chain_frames`: the root link, and the end of the longest chain of revolute joints
    or the flange its tool frames hang from; no tool offset, masses from the URDF's inertias).

    Raises :class:`InputError` naming the file and the field for a missing or negative link length,
    an unknown ``kind``, a non-numeric value, joint limits, names or compliances that do not match the
    joints, a field of another kind, a URDF that cannot be read or has no chain from ``base_frame`` to
    ``tip_frame`` (:func:`stiffcal.model.urdf.read_chain`), or a tool point that no joint can move.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"expected the path of a robot file (a str or a path), got {type(path).__name__} "
                         f"{short_repr(path)}", field="path")
    src = str(path)
    if src.lower().endswith(".urdf"):
        from .urdf import chain_frames

        base, tip = chain_frames(path, base_frame, tip_frame, src)
        return _load_urdf({"name": Path(src).stem, "kind": "urdf", "urdf": Path(src).name, "base_frame": base,
                           "tip_frame": tip}, src)
    if base_frame is not None or tip_frame is not None:
        raise InputError("base_frame and tip_frame are for a URDF path; a robot file names its own frames",
                         source=src, field="tip_frame" if tip_frame is not None else "base_frame")
    doc = read_yaml(path)
    _check_robot_document(doc, src)
    robot = ROBOT_KINDS[doc["kind"]].load(doc, src)
    robot = with_targets(robot, doc.get("targets"), src)
    if "gravity" in doc:
        robot = with_gravity(robot, doc["gravity"], src)
    robot = with_masses(robot, doc, src)
    if "cell" in doc:
        from .workcell import parse_cell

        robot = replace(robot, cell=parse_cell(doc["cell"], robot, src, Path(src).parent))
    if "calibration" in doc:
        from ..model.calibration import from_dict

        robot = replace(robot, calibration=from_dict(doc["calibration"], robot, src))
    return robot


def _check_robot_document(doc, src: str) -> None:
    """A robot file's document checked against the schema and its ranges; InputError naming the field for a
    missing ``kind``, too many joints, or a field of another kind."""
    if isinstance(doc, dict) and "kind" not in doc:  # the schema's other checks depend on it
        raise InputError(f"missing required field 'kind' ({', '.join(ROBOT_KINDS)})", source=src, field="kind")
    for key in ("links_m", "dh", "joints"):  # before the schema: its message would not say why
        if isinstance(doc, dict) and isinstance(doc.get(key), list) and len(doc[key]) > MAX_JOINTS:
            raise InputError(f"{len(doc[key])} joints: expected at most {MAX_JOINTS} (every industrial arm has at most "
                             "7; the design's searches grow exponentially with the joints; docs/contracts.md, "
                             "'Limits')", source=src, field=key)
    validate(doc, "robot", src)
    check_ranges(doc, src)
    for key, kinds in FIELD_KINDS.items():
        if key in doc and doc["kind"] not in kinds:
            raise InputError(f"'{key}' belongs to a {' or '.join(kinds)} robot, but this file says kind: "
                             f"{doc['kind']}; remove the field or change 'kind'", source=src, field=key)


def _load_planar(doc: dict, src: str) -> Robot:
    """The planar arm of a validated robot file (``links_m``)."""
    links = np.asarray(doc["links_m"], float)
    limits, comp, names = _per_joint(doc, links.size, src, "link")
    return replace(planar_robot(links, doc["name"], limits, names),
                   compliances=None if comp is None else np.asarray(comp, float), source=src,
                   reference=doc.get("source", ""))


#: standard gravity [m/s^2] (ISO 80000-3), the size of the arm's own weight along the robot file's ``gravity``
STANDARD_GRAVITY_M_S2 = 9.80665
#: default gravitational acceleration in the base frame [m/s^2]: a planar arm in a vertical plane (-y), a
#: spatial arm standing on the floor (-z)
GRAVITY_M_S2 = {2: (0.0, -STANDARD_GRAVITY_M_S2), 3: (0.0, 0.0, -STANDARD_GRAVITY_M_S2)}


def with_masses(robot: Robot, doc: dict, src: str, urdf_masses: MassModel | None = None) -> Robot:
    """``robot`` with its own weight (:class:`MassModel`) from the robot file (docs/contracts.md, "The arm's
    own weight"): ``link_masses_kg`` (one per link) and ``link_coms_m`` (planar: the distance of each link's
    centre of mass from its joint along the link, default half the link; spatial: [x, y, z] in frame i),
    ``payload_kg`` and ``payload_com_m`` (the tool and fixture, in the tip frame; default the tool point), standard
    gravity along the robot's ``gravity`` direction (default -y planar, -z spatial); for a URDF arm the URDF's
    inertias (``urdf_masses``, or the robot's own) and the payload; ``self_weight: false`` leaves every mass
    out. No mass given: None (the analysis then knows no self-weight torque)."""
    d = robot.task_dim
    urdf_masses = urdf_masses if urdf_masses is not None else robot.masses
    if doc.get("self_weight", True) is False:
        return replace(robot, masses=None)
    kg, link, com = [], [], []
    if urdf_masses is not None:
        kg, link, com = list(urdf_masses.kg), list(urdf_masses.link), list(urdf_masses.com_m)
    for part in (_link_masses(robot, doc, src), _payload_mass(robot, doc, src)):
        kg, link, com = kg + part[0], link + part[1], com + part[2]
    g = STANDARD_GRAVITY_M_S2 * np.asarray(robot.gravity, float) if robot.gravity else np.asarray(GRAVITY_M_S2[d])
    kg = np.asarray(kg, float)
    if kg.size == 0 or not np.any(kg > 0):
        return replace(robot, masses=None)
    keep = kg > 0
    model = MassModel(kg[keep], np.asarray(link, int)[keep], np.asarray(com, float).reshape(-1, 3)[keep],
                      as_xyz(np.asarray(g, float)))
    return replace(robot, masses=model)


def check_ranges(doc: dict, src: str) -> None:
    """The physical ranges the schema cannot say (:mod:`stiffcal.limits`): planar links at least
    :data:`~stiffcal.limits.MIN_LINK_M` long, compliances at least :data:`MIN_COMPLIANCE`; InputError naming the
    field."""
    for i, v in enumerate(doc.get("links_m") or []):
        if v < MIN_LINK_M:
            raise InputError(f"expected a link length of at least {MIN_LINK_M:g} m (the physical range of lengths; "
                             f"docs/contracts.md, 'Limits'), got {v:g}", source=src, field=f"links_m[{i}]")
    for i, v in enumerate(doc.get("compliances_rad_per_Nm") or []):
        if v < MIN_COMPLIANCE:
            raise InputError(f"expected a compliance of at least {MIN_COMPLIANCE:g} rad/(N m) (the physical range: "
                             f"a stiffer joint does not deflect measurably), got {v:g}", source=src,
                             field=f"compliances_rad_per_Nm[{i}]")


def with_gravity(robot: Robot, gravity, src: str, field: str = "gravity") -> Robot:
    """``robot`` with the direction of gravity ``gravity`` (2 components planar, 3 spatial; normalised)."""
    g = np.asarray(gravity, float)
    d = robot.task_dim
    if g.shape != (d,) or not np.linalg.norm(g) > 0:
        raise InputError(f"expected a nonzero direction of {d} components for a {robot.kind} robot, got "
                         f"{np.asarray(gravity).tolist()}", source=src, field=field)
    return replace(robot, gravity=tuple(float(v) for v in g / np.linalg.norm(g)))


def round_within(deg, limits_deg, decimals: int = 6) -> np.ndarray:
    """Joint angles deg (..., n) [deg] rounded to ``decimals``, a value the rounding would put past its joint's limit
    (limits_deg (n, 2) [deg], or None) held at the limit rounded inward: a pose at a limit is printed within it
    (a controller checks its limits strictly). -0.0 is written 0.0."""
    out = np.round(np.asarray(deg, float), decimals)
    if limits_deg is not None:
        f = 10.0 ** decimals
        lim = np.asarray(limits_deg, float)
        out = np.clip(out, np.ceil(lim[:, 0] * f - 1e-6) / f, np.floor(lim[:, 1] * f + 1e-6) / f)
    return out + 0.0


def narrowed_limits(robot: Robot, limits_deg, src: str | None, field: str = "joint_limits_deg",
                    within_urdf: bool = True) -> Robot:
    """``robot`` with the joint limits ``limits_deg`` (n [lower, upper] pairs [deg], within +-720); with
    ``within_urdf`` (always, but for a robot file's own first limits), each within the robot's limits of that
    joint where it has any (a URDF's, or the robot file's: limits given in a robot file over a URDF, in a study or
    on the command line narrow them, never widen them: a plan beyond the arm's own limits cannot be run). Raises
    :class:`InputError` naming ``src`` and ``field``."""
    if isinstance(limits_deg, np.ndarray):
        limits_deg = limits_deg.tolist()
    if not isinstance(limits_deg, (list, tuple)) or len(limits_deg) != robot.n_joints:
        raise InputError(f"expected {robot.n_joints} [lower, upper] pairs (one per joint: "
                         f"{', '.join(robot.joint_names)}), got {short_repr(limits_deg)}", source=src, field=field)
    lim = []
    for j, pair in enumerate(limits_deg):
        if isinstance(pair, np.ndarray):
            pair = pair.tolist()
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise InputError(f"expected [lower, upper] in degrees, got {short_repr(pair)}", source=src,
                             field=f"{field}[{j}]")
        for k, v in enumerate(pair):
            if not isinstance(v, (int, float, np.integer, np.floating)) or isinstance(v, (bool, np.bool_)) \
                    or not np.isfinite(v):
                raise InputError(f"expected a finite number of degrees, got {short_repr(v)}", source=src,
                                 field=f"{field}[{j}][{k}]")
        lo, hi = float(pair[0]), float(pair[1])
        if not -MAX_JOINT_ANGLE_DEG <= lo < hi <= MAX_JOINT_ANGLE_DEG:
            raise InputError(f"expected -{MAX_JOINT_ANGLE_DEG:g} <= lower < upper <= {MAX_JOINT_ANGLE_DEG:g} deg, got "
                             f"[{lo:g}, {hi:g}]", source=src, field=f"{field}[{j}]")
        if within_urdf and robot.limited[j]:
            ulo, uhi = np.degrees(robot.joint_limits_rad[j])
            whose = "URDF" if robot.kind == "urdf" else "robot file's"
            if lo < ulo - 1e-9 or hi > uhi + 1e-9:
                raise InputError(f"expected limits within joint {robot.joint_names[j]}'s {whose} limits [{ulo:g}, "
                                 f"{uhi:g}] deg (joint_limits_deg narrows them, never widens them), got [{lo:g}, "
                                 f"{hi:g}]", source=src, field=f"{field}[{j}]")
        lim.append((lo, hi))
    return replace(robot, joint_limits_rad=np.radians(np.array(lim)), has_joint_limits=True, unlimited_joints=())


def robot_inputs(path: str | Path, cell: bool = False) -> list[str]:
    """The files a robot file reads besides itself: its URDF (``kind: urdf``), with a cell (the robot file's own, or
    ``cell`` True: one given beside it, a design study's ``cell:``) the URDF's collision meshes
    (:func:`stiffcal.model.urdf.collision_meshes`, absolute paths), and its cell's SRDF (or a cell file's SRDF), the
    others as paths relative to where ``path`` is relative to; nothing for a file that cannot be read (loading it
    reports why).
    The workflow lists them as inputs, so that editing a URDF or a mesh reruns the jobs of its robot (a fresh user's
    study with its cell in the config listed no mesh: an edited mesh reran nothing and the archive held none)."""
    try:
        doc = read_yaml(path)
    except InputError:
        return []
    out = []
    own = (doc.get("cell") if "kind" in doc else doc) if isinstance(doc, dict) else None  # a robot file or a cell file
    if isinstance(doc, dict) and doc.get("kind") == "urdf" and isinstance(doc.get("urdf"), str):
        out.append(str(Path(path).parent / doc["urdf"]))
        if cell or isinstance(own, dict):  # a cell reads the URDF's collision meshes
            from .urdf import collision_meshes

            out += collision_meshes(out[0])
    if isinstance(own, dict) and isinstance(own.get("srdf"), str):
        out.append(str(Path(path).parent / own["srdf"]))
    return out


def _per_joint(doc: dict, n: int, src: str, what: str):
    """The optional per-joint fields (joint limits, compliances, joint names), checked against the n joints."""
    limits = doc.get("joint_limits_deg")
    if limits is not None:
        if len(limits) != n:
            raise InputError(f"expected {n} [lower, upper] pairs (one per {what}), got {len(limits)}",
                             source=src, field="joint_limits_deg")
        for i, (lo, hi) in enumerate(limits):
            if not lo < hi:
                raise InputError(f"expected lower < upper, got [{lo}, {hi}]", source=src,
                                 field=f"joint_limits_deg[{i}]")
    comp = doc.get("compliances_rad_per_Nm")
    if comp is not None and len(comp) != n:
        raise InputError(f"expected {n} values (one per {what}), got {len(comp)}", source=src,
                         field="compliances_rad_per_Nm")
    names = check_joint_names(doc["joint_names"], n, src) if "joint_names" in doc else ()
    return limits, comp, names


def _load_spatial(doc: dict, src: str) -> Robot:
    """A validated spatial robot document -> :class:`Robot`."""
    rows = [[r["a_m"], r["alpha_deg"], r["d_m"], r.get("offset_deg", 0.0)] for r in doc["dh"]]
    limits, comp, names = _per_joint(doc, len(rows), src, "row of dh")
    return spatial_robot(rows, doc.get("tool_m", [0.0, 0.0, 0.0]), doc["name"], limits, doc["dh_convention"], comp,
                         src, doc.get("source", ""), names)


def _load_urdf(doc: dict, src: str) -> Robot:
    """A validated URDF robot document -> :class:`Robot` (the chain read by :func:`stiffcal.model.urdf.read_chain`)."""
    from .urdf import read_chain

    urdf = Path(src).parent / doc["urdf"]
    arm = read_chain(urdf, doc["base_frame"], doc["tip_frame"], doc.get("joints"), doc.get("fixed_joints_deg"), src)
    comp = doc.get("compliances_rad_per_Nm")
    if comp is not None and len(comp) != len(arm.names):
        raise InputError(f"expected {len(arm.names)} values (one per joint: {', '.join(arm.names)}), got {len(comp)}",
                         source=src, field="compliances_rad_per_Nm")
    names = check_joint_names(arm.names, len(arm.names), str(urdf), "joint names")
    robot = chain_robot(arm.chain, doc.get("tool_m", [0.0, 0.0, 0.0]), arm.limits_rad, names, doc["name"], comp, src,
                        doc.get("source", ""), str(doc["urdf"]), arm.has_limits, arm.unlimited)
    robot = replace(robot, masses=arm.masses, urdf_info={"path": str(urdf.resolve()), "base_frame": doc["base_frame"],
                                                      "tip_frame": doc["tip_frame"], "joints": list(arm.names),
                                                      "held": dict(arm.held)})
    if "joint_limits_deg" in doc:
        robot = narrowed_limits(robot, doc["joint_limits_deg"], src, within_urdf=True)
    return robot



# --- the robot kinds: the registry ------------------------------------------------------------------------------

@dataclass(frozen=True)
class RobotKind:
    """One robot kind, an entry of the registry :data:`ROBOT_KINDS` (the robot file's ``kind``): ``name``;
    ``task_dim`` (2: an arm in a plane, its task space x, y and the rotation about z; 3: a spatial arm);
    ``fields``: the robot-file fields that belong to this kind (besides the common ones; the schema
    ``robot.schema.yaml`` gives their types, :data:`FIELD_KINDS` refuses them in a file of another kind);
    ``load(doc, src) -> Robot``: the robot of a validated robot file; ``tool_segment``: the drawn arm ends with a
    segment from the last frame to the measured point; and its kinematics, each ``(robot, q (..., n) [rad])``:
    ``fk`` -> (..., d) [m], ``jacobian`` -> (..., d, n) [m/rad], ``link_points`` (:meth:`Robot.link_points`),
    ``joint_frames``, ``tool_frame``, ``link_frames`` (the methods of :class:`Robot` of the same names), and
    ``reach(robot)`` [m]. docs/extending.md, "A robot kind", says what a new kind touches."""

    name: str
    task_dim: int
    fields: tuple[str, ...]
    load: Callable
    tool_segment: bool
    fk: Callable
    jacobian: Callable
    link_points: Callable
    joint_frames: Callable
    tool_frame: Callable
    link_frames: Callable
    reach: Callable


def _planar_tool_frame(robot: Robot, q: np.ndarray):
    return rotation_about(np.array([0.0, 0.0, 1.0]), q.sum(axis=-1)), as_xyz(planar_fk(robot.links_m, q))


def _planar_joint_frames(robot: Robot, q: np.ndarray):
    origins = as_xyz(planar_link_points(robot.links_m, q)[..., :-1, :])
    return origins, np.broadcast_to([0.0, 0.0, 1.0], origins.shape)


def _planar_link_frames(robot: Robot, q: np.ndarray):
    origins = as_xyz(planar_link_points(robot.links_m, q)[..., :-1, :])
    return rotation_about(np.array([0.0, 0.0, 1.0]), np.cumsum(q, axis=-1)), origins


def _dh_joint_frames(robot: Robot, q: np.ndarray):
    F = dh_frames(robot.dh, q, robot.convention)
    F = F[..., :-1, :, :] if robot.convention == "standard" else F[..., 1:, :, :]
    return F[..., :3, 3], F[..., :3, 2]


def _dh_tool_frame(robot: Robot, q: np.ndarray):
    T = dh_frames(robot.dh, q, robot.convention)[..., -1, :, :]
    return T[..., :3, :3], T[..., :3, 3]


def _dh_link_frames(robot: Robot, q: np.ndarray):
    F = dh_frames(robot.dh, q, robot.convention)[..., 1:, :, :]
    return F[..., :3, :3], F[..., :3, 3]


def _dh_link_points(robot: Robot, q: np.ndarray):
    F = dh_frames(robot.dh, q, robot.convention)
    return np.concatenate([F[..., :, :3, 3], dh_tool_point(F, robot.tool_m)[..., None, :]], axis=-2)


def _chain_fk(robot: Robot, q: np.ndarray):
    R, p = chain_frames(robot.chain, q)[2:]
    return p + R @ robot.tool_m


def _chain_jacobian(robot: Robot, q: np.ndarray):
    origins, axes, R, p = chain_frames(robot.chain, q)
    point = R @ robot.tool_m + p
    return np.swapaxes(np.cross(axes, point[..., None, :] - origins), -1, -2)


def _chain_link_points(robot: Robot, q: np.ndarray):
    origins, _, R, p = chain_frames(robot.chain, q)
    base = np.zeros(origins.shape[:-2] + (1, 3))
    return np.concatenate([base, origins[..., 1:, :], p[..., None, :], (R @ robot.tool_m + p)[..., None, :]], axis=-2)


def _chain_reach(robot: Robot) -> float:
    steps = np.concatenate([robot.chain.placements[:, :3, 3], robot.chain.tip[None, :3, 3]])
    return float(np.linalg.norm(steps, axis=1).sum() + np.linalg.norm(robot.tool_m))


#: the robot kinds by name (the robot file's ``kind``; the schema's enum is checked against it by the tests)
ROBOT_KINDS = {k.name: k for k in (
    RobotKind("planar", 2, ("links_m", "joint_limits_deg", "joint_names", "link_masses_kg", "link_coms_m"),
              _load_planar, False,
              fk=lambda r, q: planar_fk(r.links_m, q), jacobian=lambda r, q: planar_jacobian(r.links_m, q),
              link_points=lambda r, q: planar_link_points(r.links_m, q), joint_frames=_planar_joint_frames,
              tool_frame=_planar_tool_frame, link_frames=_planar_link_frames,
              reach=lambda r: float(r.links_m.sum())),
    RobotKind("spatial", 3, ("dh", "dh_convention", "tool_m", "joint_limits_deg", "joint_names", "link_masses_kg",
                             "link_coms_m"),
              _load_spatial, True,
              fk=lambda r, q: dh_tool_point(dh_frames(r.dh, q, r.convention), r.tool_m),
              jacobian=lambda r, q: dh_jacobian(r.dh, r.tool_m, q, r.convention), link_points=_dh_link_points,
              joint_frames=_dh_joint_frames, tool_frame=_dh_tool_frame, link_frames=_dh_link_frames,
              reach=lambda r: float(np.abs(r.dh[:, 0]).sum() + np.abs(r.dh[:, 2]).sum() + np.linalg.norm(r.tool_m))),
    RobotKind("urdf", 3, ("urdf", "base_frame", "tip_frame", "joints", "fixed_joints_deg", "tool_m",
                          "joint_limits_deg"),
              _load_urdf, True, fk=_chain_fk, jacobian=_chain_jacobian, link_points=_chain_link_points,
              joint_frames=lambda r, q: chain_frames(r.chain, q)[:2],
              tool_frame=lambda r, q: chain_frames(r.chain, q)[2:],
              link_frames=lambda r, q: chain_link_frames(r.chain, q), reach=_chain_reach),
)}

#: the kinds of robot file that may have each kind-specific field (from :data:`ROBOT_KINDS`)
FIELD_KINDS = {f: tuple(k.name for k in ROBOT_KINDS.values() if f in k.fields)
               for f in dict.fromkeys(f for k in ROBOT_KINDS.values() for f in k.fields)}
