"""A truth simulator of measured deflections, written from the physics and independent of the analysis.

It does not use :mod:`stiffcal.discrepancy` (nor its regressors): joint deflections come from torque-
deflection laws solved per joint, link bending from integrating the beam curvature along each link,
and the measuring system adds noise, a bias, a drift or blunders. Used to make the example data set and
by the tests that hide an effect and require the analysis to find it.

Units: angles rad, forces N, moments N m, lengths m, joint compliances rad/(N m), link bending compliances
1/(E I) in 1/(N m^2).

Loads are applied at the tool point (``tool_m``; the end of the last link of a planar arm): a force and,
optionally, a moment about that point. The tracker measures the displacement of a target (the tool point,
or a target of the robot file's ``targets``, rigidly attached to the tip frame) and, optionally, the
small-angle rotation of the tool; every joint deflection dq_j turns everything beyond joint j about its axis
(``joint_frames``), and every element ds of a bending link turns everything beyond it by the curvature.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .robot import TOOL_TARGET, Robot, as_xyz
from .stiffness import random_directions

#: Gauss-Legendre nodes for the curvature integral along a link (exact for the quadratic integrand)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class Truth:
    """The hidden physics. k: (n,) joint compliances [rad/(N m)]; the rest default to 'absent'.

    coupling: (n, n) symmetric off-diagonal joint compliances (diagonal ignored);
    tau_max: (n,) softening joints, dq = k tau / sqrt(1 - (tau / tau_max)^2) [N m];
    gap: (n,) backlash, an extra dq = gap/2 tanh(tau / tau_gap) [rad];
    link_bending: (n,) 1/(E I) of each link [1/(N m^2)];
    offset: (d,) constant bias of the measuring system [m];
    drift: (d,) drift of the measuring system per measurement (row order) [m];
    modulation: (n,) relative change of each joint's compliance with its own angle,
    k_i (1 + modulation_i cos q_i) (a gear whose stiffness varies over its turn; outside the catalogue);
    """

    k: np.ndarray
    coupling: np.ndarray | None = None
    tau_max: np.ndarray | None = None
    gap: np.ndarray | None = None
    tau_gap: float = 0.5
    link_bending: np.ndarray | None = None
    offset: np.ndarray | None = None
    drift: np.ndarray | None = None
    modulation: np.ndarray | None = None
    extra: dict = field(default_factory=dict)


def joint_torques(robot: Robot, q: np.ndarray, force: np.ndarray, moment: np.ndarray | None = None) -> np.ndarray:
    """tau = J^T F (+ a^T M): (N, n) [N m] for q (N, n) [rad], force (N, d) [N] and moment (N, d_m) [N m]
    (d_m = 1 planar, 3 spatial) about the tool point: the virtual work of the load through a unit rotation
    of each joint, from the joint axes (:meth:`Robot.joint_frames`)."""
    tau = np.einsum("ndj,nd->nj", robot.jacobian(q), force)
    if moment is None or not np.any(moment):
        return tau
    axes = robot.joint_frames(q)[1]  # (N, n, 3): a unit rotation of joint j turns the tool by a_j
    return tau + np.einsum("njd,nd->nj", axes, _moment3(robot, moment))


def _moment3(robot: Robot, moment: np.ndarray) -> np.ndarray:
    """(N, d_m) -> (N, 3): a planar arm's moment about z as a 3-D vector."""
    moment = np.asarray(moment, float)
    return np.column_stack([np.zeros((len(moment), 2)), moment]) if robot.kind == "planar" else moment


def target_world(robot: Robot, q: np.ndarray, target: np.ndarray | None, names) -> np.ndarray:
    """(N, 3) [m]: the base-frame position of each row's target (``target`` (N,) indices into the target
    ``names`` of the robot; None: the tool point)."""
    R, p = robot.tool_frame(q)
    names = tuple(names) if names is not None else (TOOL_TARGET,)
    pts = np.array([robot.target_point(t) for t in names])
    t = np.zeros(len(q), int) if target is None else np.asarray(target, int)
    return p + np.einsum("nij,nj->ni", R, pts[t])


def joint_motion(robot: Robot, q: np.ndarray, dq: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(displacement (N, 3) [m] of points (N, 3), rotation (N, 3) [rad] of the tool)`` of small joint
    rotations dq (N, n): joint j turns everything beyond it by dq_j about its axis."""
    origins, axes = robot.joint_frames(q)
    turn = axes * dq[:, :, None]  # (N, n, 3)
    return np.cross(turn, points[:, None, :] - origins).sum(axis=1), turn.sum(axis=1)


def joint_deflections(truth: Truth, tau: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
    """dq (N, n) [rad] from the joint torque-deflection laws (q (N, n) [rad] for ``modulation``)."""
    k = np.asarray(truth.k, float)
    if truth.modulation is not None:
        k = k * (1.0 + np.asarray(truth.modulation, float) * np.cos(q))
    dq = k * tau
    if truth.tau_max is not None:
        dq = k * tau / np.sqrt(1.0 - (tau / np.asarray(truth.tau_max, float)) ** 2)
    if truth.coupling is not None:
        C = np.array(truth.coupling, float)
        np.fill_diagonal(C, 0.0)
        dq = dq + tau @ C.T
    if truth.gap is not None:
        dq = dq + 0.5 * np.asarray(truth.gap, float) * np.tanh(tau / truth.tau_gap)
    return dq


def link_bending_displacement(robot: Robot, q: np.ndarray, force: np.ndarray, c: np.ndarray) -> np.ndarray:
    """End-effector displacement (N, d) [m] of Euler-Bernoulli links bending under the end-effector force.

    Link i is the segment between consecutive points of ``robot.link_points`` (n segments for a planar arm;
    n + 1 for a spatial one, the last to the tool point). A curvature vector kappa(s) = c M_perp(s) at arc
    length s (M_perp the bending part of the moment r x F of the end-effector force about that point, i.e.
    without the torsion about the link) turns everything beyond s by kappa ds; integrated along each link
    by Gauss-Legendre quadrature. c: (segments,) [1/(N m^2)].
    """
    pe = as_xyz(robot.link_points(q))[:, -1, :]
    return link_bending_motion(robot, q, force, c, None, pe)[0][:, : robot.task_dim]


def link_bending_motion(robot: Robot, q: np.ndarray, force: np.ndarray, c: np.ndarray, moment: np.ndarray | None,
                        points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(displacement (N, 3) [m] of points (N, 3) rigidly attached to the tool, rotation (N, 3) [rad] of the
    tool)`` of Euler-Bernoulli links bending under the force (N, d) and the moment (N, d_m) at the tool point
    (:func:`link_bending_displacement`; the moment about a point x of a link is (p_tool - x) x F + M)."""
    pts = as_xyz(robot.link_points(q))
    F = as_xyz(force)
    M_tool = np.zeros_like(F) if moment is None else _moment3(robot, moment)
    pe = pts[:, -1, :]
    disp, rot = np.zeros_like(pe), np.zeros_like(pe)
    for i in range(pts.shape[1] - 1):
        a, b = pts[:, i, :], pts[:, i + 1, :]
        L = np.linalg.norm(b - a, axis=-1)
        if c[i] == 0 or not np.any(L > 0):
            continue
        u = (b - a) / np.where(L > 0, L, 1.0)[:, None]
        for xg, wg in zip(_GL_X, _GL_W):
            x = a + 0.5 * (xg + 1.0) * (b - a)
            M = np.cross(pe - x, F) + M_tool
            M_perp = M - np.einsum("nd,nd->n", M, u)[:, None] * u
            kappa = (0.5 * wg * L * c[i])[:, None] * M_perp  # the turn of the element ds at x
            disp += np.cross(kappa, points - x)
            rot += kappa
    return disp, rot


def physics(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray,
            order: np.ndarray | None = None, moment: np.ndarray | None = None, target: np.ndarray | None = None,
            target_names=None, orientation: bool = False) -> np.ndarray:
    """Noise-free measured displacements (N, d) [m] of ``truth``: joint laws, link bending, and the measuring
    system's offset and drift (``order`` (N,): the time order of each row, default the row index).

    With a ``moment`` (N, d_m) [N m] about the tool point, rows of other targets (``target`` (N,) indices into
    ``target_names``) or ``orientation``: (N, d (+ d_r)), the displacement of each row's target and the
    tool's rotation [rad] (planar: about z). ``offset`` and ``drift`` act on the positions."""
    if (moment is None or not np.any(moment)) and target is None and not orientation:
        tau = joint_torques(robot, q, force)
        dq = joint_deflections(truth, tau, q)
        dp = np.einsum("ndj,nj->nd", robot.jacobian(q), dq)
        if truth.link_bending is not None:
            dp = dp + link_bending_displacement(robot, q, force, np.asarray(truth.link_bending, float))
    else:
        dq = joint_deflections(truth, joint_torques(robot, q, force, moment), q)
        pts = target_world(robot, q, target, target_names)
        disp, rot = joint_motion(robot, q, dq, pts)
        if truth.link_bending is not None:
            bd, br = link_bending_motion(robot, q, force, np.asarray(truth.link_bending, float), moment, pts)
            disp, rot = disp + bd, rot + br
        d = robot.task_dim
        dp = np.hstack([disp[:, :d], (rot[:, 2:] if d == 2 else rot)]) if orientation else disp[:, :d]
    d = robot.task_dim
    if truth.offset is not None:
        dp[:, :d] = dp[:, :d] + np.asarray(truth.offset, float)
    if truth.drift is not None:
        t = np.arange(len(q)) if order is None else np.asarray(order, float)
        dp[:, :d] = dp[:, :d] + t[:, None] * np.asarray(truth.drift, float)
    return dp


def simulate(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray, sigma,
             rng: np.random.Generator, blunders: dict[int, np.ndarray] | None = None,
             order: np.ndarray | None = None, moment: np.ndarray | None = None, target: np.ndarray | None = None,
             target_names=None, orientation: bool = False, sigma_rad=None) -> np.ndarray:
    """Measured displacements dp (N, d) [m]: :func:`physics` plus N(0, sigma^2) noise per coordinate (sigma
    [m] a scalar or one per row, (N,)); blunders {row: (d,) extra error [m]} adds gross errors. With the
    orientation (N, d + d_r): the rotation gets N(0, sigma_rad^2) noise [rad] (a scalar or one per row)."""
    dp = physics(robot, truth, q, force, order, moment, target, target_names, orientation)
    sig = np.reshape(np.broadcast_to(sigma, (len(q),)), (-1, 1))
    if orientation:
        sig = np.hstack([np.repeat(sig, robot.task_dim, 1),
                         np.repeat(np.reshape(np.broadcast_to(sigma_rad, (len(q),)), (-1, 1)),
                                   dp.shape[1] - robot.task_dim, 1)])
    dp = dp + rng.normal(0.0, 1.0, dp.shape) * sig
    for row, err in (blunders or {}).items():
        dp[row] += err
    return dp


def random_experiment(robot: Robot, rng: np.random.Generator, n_poses: int = 30, replicates: int = 3,
                      force_N: tuple[float, float] = (100.0, 400.0)):
    """(q (N, n) [rad], force (N, d) [N], pose_id (N,)): random poses within the joint limits, each with a
    random force (magnitude in force_N, any direction in the plane or in space), measured ``replicates`` times."""
    lims = robot.joint_limits_rad
    q = rng.uniform(lims[:, 0], lims[:, 1], (n_poses, robot.n_joints))
    mag = rng.uniform(*force_N, n_poses)
    f = mag[:, None] * random_directions(rng, n_poses, robot.task_dim)
    idx = np.repeat(np.arange(n_poses), replicates)
    return q[idx], f[idx], idx


# --- measurement protocols of calibration labs ---------------------------------------------------------

@dataclass(frozen=True)
class Protocol:
    """How a lab loads and measures the robot.

    loads: ``"hanging"`` (weights hanging on the tool: the force along gravity, -y for a planar arm in a
    vertical plane, -z for a spatial one, one magnitude per mass), ``"directions"`` (pushes in ``n_directions``
    directions equally spaced in the plane, from a random start per configuration, at every magnitude),
    ``"pushes3d"`` (``n_directions`` random 3-D directions per configuration at every magnitude) or
    ``"random"`` (one random direction and magnitude per configuration); magnitudes_N [N]; repeats: how
    often the load sequence is measured at each configuration (1: no replicates); interleaved: the whole
    plan is measured once, then repeated (replicates far apart in time) instead of repeating the load
    sequence on the spot; unloaded_rows: an unloaded reference row (zero force, zero displacement) logged
    before every loaded one; tracker_m: the tracker's position [m] in the robot's frame, the noise growing
    with the distance to it as sigma_m + sigma_per_m * distance [m] (a laser tracker's MPE has that form);
    pose_id: whether the log numbers the configurations; lever_m: the loads hang from a loading bar, applied
    at this distance [m] from the tool point along a random horizontal direction per configuration (in the
    plane for a planar arm), so that each carries the moment r x F about the tool point (0: at the tool point);
    targets: the targets the tracker measures, one row each per reading (the robot file's ``targets``, ``tool``
    the tool point); orientation: a 6-DoF tracker logs the tool's rotation too, with the noise sigma_rad [rad];
    reference: ``"reading"`` (every displacement is taken from its own unloaded reading: independent errors,
    unloaded rows logged as exactly zero) or ``"configuration"`` (every displacement of a configuration is
    taken from one unloaded reading, whose error enters all of them; unloaded rows are then further readings
    from it, logged with their noise).
    """

    name: str
    loads: str = "hanging"
    magnitudes_N: tuple[float, ...] = (147.1, 294.2, 490.3, 784.5)
    n_directions: int = 4
    repeats: int = 2
    interleaved: bool = False
    unloaded_rows: bool = False
    sigma_m: float = 1e-5
    sigma_per_m: float = 0.0
    tracker_m: tuple[float, ...] = (2.5, 0.5, 0.0)
    lever_m: float = 0.0
    targets: tuple[str, ...] = (TOOL_TARGET,)
    orientation: bool = False
    sigma_rad: float = 1e-5
    reference: str = "reading"


@dataclass(frozen=True)
class LabLog:
    """A simulated measurement log: one row per reading, in time order. q (N, n) [rad]; force (N, d) [N];
    config (N,) int (the configuration each row belongs to); loaded (N,) bool (False: an unloaded reference
    row); sigma (N,) [m] the noise of each row; moment (N, d_m) [N m] or None; target (N,) int into
    target_names, or None (the tool point); orientation: the rotation is logged, with the noise sigma_rad [rad]."""

    q: np.ndarray
    force: np.ndarray
    config: np.ndarray
    loaded: np.ndarray
    sigma: np.ndarray
    moment: np.ndarray | None = None
    target: np.ndarray | None = None
    target_names: tuple[str, ...] = (TOOL_TARGET,)
    orientation: bool = False
    sigma_rad: float = 1e-5
    shared_reference: bool = False


def _gravity(d: int) -> np.ndarray:
    return np.array([0.0, -1.0]) if d == 2 else np.array([0.0, 0.0, -1.0])


def configuration_loads(protocol: Protocol, d: int, rng: np.random.Generator) -> np.ndarray:
    """(L, d) [N]: the load sequence of one configuration (:class:`Protocol`)."""
    mags = np.asarray(protocol.magnitudes_N, float)
    if protocol.loads == "hanging":
        return mags[:, None] * _gravity(d)
    if protocol.loads == "random":
        return rng.uniform(mags.min(), mags.max()) * random_directions(rng, 1, d)
    if protocol.loads == "directions":
        start = rng.uniform(-np.pi, np.pi)
        ang = start + 2 * np.pi * np.arange(protocol.n_directions) / protocol.n_directions
        u = np.stack([np.cos(ang), np.sin(ang)], -1)
        if d == 3:  # pushes in the horizontal plane
            u = np.concatenate([u, np.zeros((len(u), 1))], -1)
    elif protocol.loads == "pushes3d":
        u = random_directions(rng, protocol.n_directions, d)
    else:
        raise ValueError(f"unknown load protocol {protocol.loads!r}")
    return (u[:, None, :] * mags[None, :, None]).reshape(-1, d)


def lab_log(robot: Robot, protocol: Protocol, rng: np.random.Generator, n_configs: int = 40) -> LabLog:
    """The rows a lab following ``protocol`` logs at ``n_configs`` random configurations within the joint
    limits (time order; see :class:`Protocol`)."""
    lims = robot.joint_limits_rad
    d = robot.task_dim
    configs = rng.uniform(lims[:, 0], lims[:, 1], (n_configs, robot.n_joints))
    per = [configuration_loads(protocol, d, rng) for _ in range(n_configs)]
    levers = _levers(protocol, d, rng, n_configs)
    once = [(c, f) for c in range(n_configs) for f in per[c]]
    if protocol.interleaved:
        seq = once * protocol.repeats
    else:
        seq = [(c, f) for c in range(n_configs) for _ in range(protocol.repeats) for f in per[c]]
    names = robot.target_names
    targets = [names.index(t) for t in protocol.targets]
    rows = []
    for c, f in seq:
        for t in targets:  # the tracker measures each target in turn under the same load
            if protocol.unloaded_rows:
                rows.append((c, np.zeros(d), False, t))
            rows.append((c, f, True, t))
    config = np.array([r[0] for r in rows])
    force = np.array([r[1] for r in rows])
    loaded = np.array([r[2] for r in rows])
    target = np.array([r[3] for r in rows])
    q = configs[config]
    moment = None
    if levers is not None:
        moment = np.cross(as_xyz(levers[config]), as_xyz(force))
        moment = moment[:, 2:] if d == 2 else moment
    tracker = as_xyz(np.asarray(protocol.tracker_m, float)[:d])
    plain = tuple(protocol.targets) == (TOOL_TARGET,)
    where = as_xyz(robot.fk(q)) if plain else target_world(robot, q, target, names)
    dist = np.linalg.norm(where - tracker, axis=-1)
    if protocol.reference not in ("reading", "configuration"):
        raise ValueError(f"unknown reference {protocol.reference!r}")
    return LabLog(q, force, config, loaded, protocol.sigma_m + protocol.sigma_per_m * dist, moment,
                  None if plain else target, names, protocol.orientation, protocol.sigma_rad,
                  protocol.reference == "configuration")


def _levers(protocol: Protocol, d: int, rng: np.random.Generator, n_configs: int) -> np.ndarray | None:
    """(n_configs, d) [m]: the loading bar of each configuration (:class:`Protocol`), or None without one."""
    if protocol.lever_m == 0:
        return None
    ang = rng.uniform(-np.pi, np.pi, n_configs)
    bar = np.stack([np.cos(ang), np.sin(ang)], -1) * protocol.lever_m
    if d == 2:  # in the arm's vertical plane: along x, to either side
        return np.column_stack([np.sign(bar[:, 0]) * protocol.lever_m, np.zeros(n_configs)])
    return np.column_stack([bar, np.zeros(n_configs)])


def measure(robot: Robot, truth: Truth, log: LabLog, rng: np.random.Generator,
            blunders: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Displacements (N, d) [m] of every row of ``log``: loaded rows from :func:`simulate` (the drift runs
    in time order over all rows), unloaded reference rows exactly zero (the log's reference). With a shared
    reference (``log.shared_reference``) every row of a configuration (and target) less the error of one
    reference reading there, and the unloaded rows their own noise less it. With the orientation logged:
    (N, d + d_r), the rotation [rad] after the displacement."""
    dp = simulate(robot, truth, log.q, log.force, log.sigma, rng, blunders, order=np.arange(len(log.q)),
                  moment=log.moment, target=log.target, target_names=log.target_names, orientation=log.orientation,
                  sigma_rad=log.sigma_rad)
    if not log.shared_reference:
        dp[~log.loaded] = 0.0
        return dp
    dp[~log.loaded] = rng.normal(0.0, 1.0, (int(np.sum(~log.loaded)), dp.shape[1])) * log.sigma[~log.loaded, None]
    target = np.zeros(len(dp), int) if log.target is None else log.target
    key = np.unique(np.column_stack([log.config, target]), axis=0, return_inverse=True)[1].ravel()
    first = np.array([np.flatnonzero(key == k)[0] for k in range(key.max() + 1)])
    ref = rng.normal(0.0, 1.0, (len(first), robot.task_dim)) * log.sigma[first, None]
    dp[:, : robot.task_dim] -= ref[key]
    return dp


def lab_csv(robot: Robot, log: LabLog, dp: np.ndarray, pose_id: bool = True) -> str:
    """The log as the measured-data CSV a lab would write (``pose_id`` numbering the configurations from 1,
    when asked), angles to 1e-4 deg, forces to 0.01 N, moments to 1e-4 N m, displacements to 1e-9 m and
    rotations to 1e-12 rad as trackers print them; with the log's moments (``mx_Nm``.. or ``mz_Nm``), targets
    (``target``) and orientation (``rx_rad``.. or ``rz_rad``) columns when it has them."""
    n, d = robot.n_joints, robot.task_dim
    axes = "xyz"[:d]
    rot_axes = "z" if d == 2 else "xyz"
    head = (["pose_id"] if pose_id else []) + [f"q{i + 1}_deg" for i in range(n)] + [f"f{a}_N" for a in axes] \
        + ([f"m{a}_Nm" for a in rot_axes] if log.moment is not None else []) \
        + (["target"] if log.target is not None else []) + [f"d{a}_m" for a in axes] \
        + ([f"r{a}_rad" for a in rot_axes] if log.orientation else [])
    lines = [",".join(head)]
    qd = np.degrees(log.q)
    for r in range(len(qd)):
        cells = ([str(int(log.config[r]) + 1)] if pose_id else []) + [f"{v:.4f}" for v in qd[r]] \
            + [f"{v:.2f}" for v in log.force[r]] \
            + ([f"{v:.4f}" for v in log.moment[r]] if log.moment is not None else []) \
            + ([log.target_names[log.target[r]]] if log.target is not None else []) \
            + [f"{v:.9e}" for v in dp[r, :d]] + ([f"{v:.12e}" for v in dp[r, d:]] if log.orientation else [])
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"
