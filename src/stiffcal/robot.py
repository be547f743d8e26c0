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
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
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


def as_xyz(v: np.ndarray) -> np.ndarray:
    """Lift planar vectors (..., 2) to (..., 3) with z = 0; spatial ones (..., 3) pass through."""
    v = np.asarray(v, float)
    return v if v.shape[-1] == 3 else np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)


def dh_link_transforms(dh: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Homogeneous transforms ``T_{i-1,i}`` of every link (module docstring, both conventions).

    dh: (n, 4) rows ``[a [m], alpha [rad], d [m], offset [rad]]``; q: (..., n) [rad].
    Returns (..., n, 4, 4).
    """
    a, alpha, d, off = (dh[:, j] for j in range(4))
    th = np.asarray(q, float) + off
    ct, st = np.cos(th), np.sin(th)
    ca, sa = np.broadcast_to(np.cos(alpha), th.shape), np.broadcast_to(np.sin(alpha), th.shape)
    a, d = np.broadcast_to(a, th.shape), np.broadcast_to(d, th.shape)
    zero, one = np.zeros_like(th), np.ones_like(th)
    if convention == "standard":
        rows = [[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [zero, sa, ca, d]]
    elif convention == "modified":
        rows = [[ct, -st, zero, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d]]
    else:
        raise ValueError(f"unknown DH convention {convention!r}")
    rows.append([zero, zero, zero, one])
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def dh_frames(dh: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Base-frame poses of frames 0..n, ``T_{0,i}``. dh: (n, 4); q: (..., n) [rad]. Returns (..., n+1, 4, 4)."""
    A = dh_link_transforms(dh, q, convention)
    T = [np.broadcast_to(np.eye(4), A.shape[:-3] + (4, 4))]
    for i in range(A.shape[-3]):
        T.append(T[-1] @ A[..., i, :, :])
    return np.stack(T, axis=-3)


def dh_tool_point(frames: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """Tool point in the base frame: frames (..., n+1, 4, 4), tool (3,) [m] in frame n. Returns (..., 3)."""
    T = frames[..., -1, :, :]
    return T[..., :3, :3] @ tool + T[..., :3, 3]


def dh_jacobian(dh: np.ndarray, tool: np.ndarray, q: np.ndarray, convention: str = "standard") -> np.ndarray:
    """Position Jacobian of the tool point of a revolute DH arm: column i is ``z_i x (p - o_i)`` for the
    axis ``z_i`` through ``o_i`` of joint i (frame i-1 in the standard convention, frame i in the modified).

    dh: (n, 4); tool: (3,) [m]; q: (..., n) [rad]. Returns (..., 3, n) [m/rad].
    """
    F = dh_frames(dh, q, convention)
    axes = F[..., :-1, :, :] if convention == "standard" else F[..., 1:, :, :]
    z, o = axes[..., :3, 2], axes[..., :3, 3]  # (..., n, 3)
    p = dh_tool_point(F, tool)
    return np.swapaxes(np.cross(z, p[..., None, :] - o), -1, -2)


@dataclass(frozen=True)
class Robot:
    """A serial robot read from a robot file (docs/contracts.md).

    Attributes: ``name``; ``kind`` ('planar' or 'spatial'); ``links_m`` (n,) [m] link lengths of a planar
    arm (for a spatial arm: the distances between consecutive joint axes' origins, for drawing and scale);
    ``joint_limits_rad`` (n, 2) [rad]; ``compliances`` (n,) [rad/(N m)] or None; ``source`` (the file it
    came from, for messages); for spatial arms ``dh`` (n, 4) ``[a, alpha, d, offset]`` [m, rad],
    ``convention`` ('standard' or 'modified') and ``tool_m`` (3,) [m] the measured point in the last frame;
    ``inert_joints`` (joints that never move the measured point, :func:`inert_joints`); ``reference`` (the
    file's ``source`` field: where the dimensions come from); ``targets`` {name: (3,) [m]}: further measured
    points (tracker targets) in the tip frame (:meth:`tool_frame`), beside the tool point ``"tool"``.
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
    targets: dict = field(default_factory=dict)

    @property
    def n_joints(self) -> int:
        return int(self.joint_limits_rad.shape[0])

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
        return self.n_joints + (self.kind == "spatial")

    def outside_limits(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., n) bool: angles outside the joint limits (all False without limits)."""
        lo, hi = self.joint_limits_rad.T
        q = np.asarray(q, float)
        return ((q < lo - 1e-9) | (q > hi + 1e-9)) & self.has_joint_limits

    @property
    def task_dim(self) -> int:
        """Number of measured Cartesian coordinates per pose (2 for planar arms, 3 for spatial ones)."""
        return 2 if self.kind == "planar" else 3

    @property
    def reach_m(self) -> float:
        """An upper bound on the distance from the base to the measured point [m]."""
        if self.kind == "planar":
            return float(self.links_m.sum())
        return float(np.abs(self.dh[:, 0]).sum() + np.abs(self.dh[:, 2]).sum() + np.linalg.norm(self.tool_m))

    def fk(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d) [m]."""
        if self.kind == "planar":
            return planar_fk(self.links_m, np.asarray(q, float))
        return dh_tool_point(dh_frames(self.dh, q, self.convention), self.tool_m)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(..., n) [rad] -> (..., d, n) [m/rad]."""
        if self.kind == "planar":
            return planar_jacobian(self.links_m, np.asarray(q, float))
        return dh_jacobian(self.dh, self.tool_m, q, self.convention)

    def link_points(self, q: np.ndarray) -> np.ndarray:
        """Points of the drawn arm, base first, measured point last: (..., n) [rad] -> (..., n + 1, 2) for a
        planar arm, (..., n + 2, 3) for a spatial one (base, frame origins 1..n, tool point) [m]."""
        if self.kind == "planar":
            return planar_link_points(self.links_m, np.asarray(q, float))
        F = dh_frames(self.dh, q, self.convention)
        return np.concatenate([F[..., :, :3, 3], dh_tool_point(F, self.tool_m)[..., None, :]], axis=-2)

    def scaled(self, factor: float) -> "Robot":
        """The same robot with every length multiplied by ``factor``."""
        dh = None if self.dh is None else self.dh * np.array([factor, 1.0, factor, 1.0])
        tool = None if self.tool_m is None else self.tool_m * factor
        return replace(self, links_m=self.links_m * factor, dh=dh, tool_m=tool)

    def joint_frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint axes in the base frame: (..., n) [rad] -> ``(origins (..., n, 3) [m], axes (..., n, 3))``,
        a point on each joint's axis and its unit direction (planar arms: z = 0 and every axis e_z).

        With :meth:`tool_frame` this gives the geometric Jacobian of any point t of the tip frame: linear
        rows ``axes x (p + R t - origins)``, angular rows ``axes`` (Siciliano et al., *Robotics*, eq. 3.30)."""
        q = np.asarray(q, float)
        if self.kind == "planar":
            pts = as_xyz(planar_link_points(self.links_m, q)[..., :-1, :])
            return pts, np.broadcast_to(np.array([0.0, 0.0, 1.0]), pts.shape)
        F = dh_frames(self.dh, q, self.convention)
        F = F[..., :-1, :, :] if self.convention == "standard" else F[..., 1:, :, :]
        return F[..., :3, 3], F[..., :3, 2]

    def tool_frame(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tip frame in the base frame: (..., n) [rad] -> ``(R (..., 3, 3), p (..., 3) [m])``, its rotation
        and origin. A point t given in the tip frame is at ``p + R t``; the tool point is t = ``tool_m``
        (planar arms: the tip frame sits at the end of the last link with x along it, the tool point at
        its origin; spatial DH arms: frame n)."""
        q = np.asarray(q, float)
        if self.kind == "planar":
            c = np.sum(q, axis=-1)
            ct, st, zero, one = np.cos(c), np.sin(c), np.zeros_like(c), np.ones_like(c)
            R = np.stack([np.stack([ct, -st, zero], -1), np.stack([st, ct, zero], -1),
                          np.stack([zero, zero, one], -1)], -2)
            return R, as_xyz(planar_fk(self.links_m, q))
        T = dh_frames(self.dh, q, self.convention)[..., -1, :, :]
        return T[..., :3, :3], T[..., :3, 3]

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


def planar_robot(links_m, name: str = "planar", joint_limits_deg=None) -> Robot:
    """Build a planar robot in memory (links in metres, optional (n, 2) limits in degrees)."""
    links = np.asarray(links_m, float)
    has = joint_limits_deg is not None
    lim = np.radians(np.asarray(joint_limits_deg, float)) if has else np.tile([-np.pi, np.pi], (links.size, 1))
    return Robot(name, "planar", links, lim, None, "<memory>", has)


def spatial_robot(dh_rows, tool_m=(0.0, 0.0, 0.0), name: str = "spatial", joint_limits_deg=None,
                  convention: str = "standard", compliances=None, source: str = "<memory>",
                  reference: str = "") -> Robot:
    """Build a spatial DH robot in memory. dh_rows: (n, 4) ``[a_m, alpha_deg, d_m, offset_deg]``."""
    dh = np.asarray(dh_rows, float) * np.array([1.0, np.pi / 180, 1.0, np.pi / 180])
    n = len(dh)
    has = joint_limits_deg is not None
    lim = np.radians(np.asarray(joint_limits_deg, float)) if has else np.tile([-np.pi, np.pi], (n, 1))
    robot = Robot(name, "spatial", np.zeros(n), lim, None if compliances is None else np.asarray(compliances, float),
                  source, has, dh, convention, np.asarray(tool_m, float), reference=reference)
    links = np.linalg.norm(np.diff(robot.link_points(np.zeros(n)), axis=0), axis=-1)
    inert = inert_joints(robot)
    if len(inert) == n:
        raise InputError("no joint moves the measured point: check dh and tool_m", source=source, field="tool_m")
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


def with_targets(robot: Robot, targets, src: str) -> Robot:
    """``robot`` with the robot file's ``targets`` {name: [x, y] (planar) or [x, y, z] [m] in the tip frame},
    checked: one coordinate per tip-frame axis of the arm, and no target named ``"tool"`` (the tool point's
    name). Planar targets are stored with z = 0."""
    out = {}
    d = 2 if robot.kind == "planar" else 3
    for name, xyz in (targets or {}).items():
        if name == TOOL_TARGET:
            raise InputError(f"the name '{TOOL_TARGET}' is the tool point's; give this target another name",
                             source=src, field=f"targets.{name}")
        if len(xyz) != d:
            raise InputError(f"expected {d} coordinates [m] in the tip frame for a {robot.kind} robot, got {len(xyz)}",
                             source=src, field=f"targets.{name}")
        out[str(name)] = as_xyz(np.asarray(xyz, float))
    return replace(robot, targets=out)


#: fields that only one kind of robot file may have
KIND_FIELDS = {"planar": ("links_m",), "spatial": ("dh", "dh_convention", "tool_m")}


def load_robot(path: str | Path) -> Robot:
    """Read and validate a robot file (planar or spatial; schema ``workflow/schemas/robot.schema.yaml``).

    Raises :class:`InputError` naming the file and the field for a missing or negative link length,
    an unknown ``kind``, a non-numeric value, joint limits or compliances that do not match the joints,
    or a tool point that no joint can move in some direction of space.
    """
    src = str(path)
    doc = read_yaml(path)
    if isinstance(doc, dict) and "kind" not in doc:  # the schema's other checks depend on it
        raise InputError("missing required field 'kind' (planar or spatial)", source=src, field="kind")
    validate(doc, "robot", src)
    for key in KIND_FIELDS["planar" if doc["kind"] == "spatial" else "spatial"]:
        if key in doc:
            raise InputError(f"'{key}' belongs to a {'planar' if key == 'links_m' else 'spatial'} robot, but this "
                             f"file says kind: {doc['kind']}; remove the field or change 'kind'", source=src, field=key)
    if doc["kind"] == "spatial":
        return with_targets(_load_spatial(doc, src), doc.get("targets"), src)
    links = np.asarray(doc["links_m"], float)
    limits, comp = _per_joint(doc, links.size, src, "link")
    return with_targets(replace(planar_robot(links, doc["name"], limits),
                                compliances=None if comp is None else np.asarray(comp, float),
                                source=src, reference=doc.get("source", "")), doc.get("targets"), src)


def _per_joint(doc: dict, n: int, src: str, what: str):
    """The optional per-joint fields (joint limits, compliances), checked against the n joints."""
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
    return limits, comp


def _load_spatial(doc: dict, src: str) -> Robot:
    """A validated spatial robot document -> :class:`Robot`."""
    rows = [[r["a_m"], r["alpha_deg"], r["d_m"], r.get("offset_deg", 0.0)] for r in doc["dh"]]
    limits, comp = _per_joint(doc, len(rows), src, "row of dh")
    return spatial_robot(rows, doc.get("tool_m", [0.0, 0.0, 0.0]), doc["name"], limits, doc["dh_convention"], comp,
                         src, doc.get("source", ""))
