"""A truth simulator of measured deflections, written from the physics and independent of the analysis.

It does not use :mod:`stiffcal.measured.discrepancy` (nor its regressors): joint deflections come from torque-
deflection laws solved per joint on the total torque (the load's and, when the robot file gives masses, the
arm's own weight), link bending from integrating the beam curvature along each link, and the lab is
simulated as it is: a tracker takes *readings* (positions of targets, with noise that grows with the distance
to the tracker, a drift, a bias, blunders), and every logged row is the difference of two readings, the
loaded one and the protocol's unloaded reference reading (:class:`Protocol`: one reference per load, per
visit, or per configuration with later visits measured against it, the robot returning to the configuration
within its pose repeatability). Used to make the example data sets and by the tests and the rate matrix
that hide an effect and require the analysis to find it.

Units: angles rad, forces N, moments N m, lengths m, joint compliances rad/(N m), link bending compliances
1/(E I) in 1/(N m^2), times s.

Loads are applied at the tool point (``tool_m``; the end of the last link of a planar arm): a force and,
optionally, a moment about that point. The tracker measures the position of a target (the tool point, or a
target of the robot file's ``targets``, rigidly attached to the tip frame) and, optionally, the small-angle
rotation of the tool; every joint deflection dq_j turns everything beyond joint j about its axis
(``joint_frames``), and every element ds of a bending link turns everything beyond it by the curvature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..model.robot import TOOL_TARGET, Robot, as_xyz
from ..model.stiffness import random_directions

#: Gauss-Legendre nodes for the curvature integral along a link (exact for the quadratic integrand)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class Truth:
    """The hidden physics. k: (n,) joint compliances [rad/(N m)]; the rest default to 'absent'.

    coupling: (n, n) symmetric off-diagonal joint compliances (diagonal ignored);
    tau_max: (n,) softening joints, dq = k tau / sqrt(1 - (tau / tau_max)^2) [N m];
    gap: (n,) backlash, an extra dq = gap/2 tanh(tau / tau_gap) [rad];
    link_bending: (n,) 1/(E I) of each link [1/(N m^2)];
    offset: (d,) constant bias of the measuring system on the loaded readings [m] (a target nest that shifts
    when the load goes on);
    drift: (d,) drift of the measuring system [m/s] over the campaign's clock (:func:`lab_log`'s times; per row
    index for rows simulated without a log, :func:`physics`);
    modulation: (n,) relative change of each joint's compliance with its own angle,
    k_i (1 + modulation_i cos q_i) (a gear whose stiffness varies over its turn; outside the catalogue);
    load_tilt: (3,) [rad] the real load is the logged one turned by this small rotation vector (a pulley or a
    hanging fixture that does not pull where the log says; outside the catalogue);
    held_gap: (n,) [rad] a backlash held by friction (outside the catalogue): the gear rests on one flank of its
    gap and moves to the other only when the total torque passes ``held_torque`` (n,) [N m] towards it, so an
    unloaded reading after a load keeps the jump (:func:`gear_sides`); the joint's offset is held_gap/2 times
    the side (+-1). Needs a :class:`LabLog` (the readings' order); :func:`deflection` ignores it.
    base_tilt: (c [rad/(N m)], h [m]) a compliant base (outside the catalogue: a pedestal, a floor, a mobile
    platform): the whole robot tilts about the horizontal axes through a pivot h below the base origin by c times the
    horizontal part of the load's moment about that pivot (:func:`base_tilt_motion`; spatial arms); (c_x, c_y, h) a
    base compliant by c_x about the horizontal axis along the base's x (:func:`horizontal_axes`) and by c_y about the
    one across it (a plate stiffer one way, a pedestal on rails).
    The joint laws act on the total torque, the load's plus the arm's own weight (:func:`self_weight_torques`),
    and a row's deflection is the difference between the loaded and the unloaded state at the same pose.
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
    load_tilt: np.ndarray | None = None
    held_gap: np.ndarray | None = None
    held_torque: np.ndarray | None = None
    base_tilt: tuple[float, ...] | None = None
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


def self_weight_torques(robot: Robot, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """(N, n) [N m]: the torques the arm's own weight (and the payload) applies at each joint, tau = -dV/dq
    with the potential V(q) = -sum_b m_b g . p_b(q) of the robot file's point masses
    (:attr:`Robot.masses`), by central differences of V (independent of the analysis's cross-product
    formula). Zero without masses."""
    q = np.atleast_2d(np.asarray(q, float))
    masses = robot.masses
    if masses is None:
        return np.zeros(q.shape)
    g = np.asarray(masses.gravity_m_s2, float)

    def potential(x):
        return -np.einsum("...bk,b,k->...", robot.mass_positions(x), masses.kg, as_xyz(g))

    out = np.empty(q.shape)
    for j in range(q.shape[1]):
        e = np.zeros(q.shape[1])
        e[j] = step
        out[:, j] = -(potential(q + e) - potential(q - e)) / (2 * step)
    return out


def _moment3(robot: Robot, moment: np.ndarray) -> np.ndarray:
    """(N, d_m) -> (N, 3): a planar arm's moment about z as a 3-D vector."""
    moment = np.asarray(moment, float)
    return np.column_stack([np.zeros((len(moment), 2)), moment]) if robot.planar else moment


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
    """dq (N, n) [rad] from the joint torque-deflection laws at the torques tau (N, n) [N m] (q (N, n) [rad]
    for ``modulation``)."""
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


def loaded_deflections(truth: Truth, tau_load: np.ndarray, tau_weight: np.ndarray, q: np.ndarray) -> np.ndarray:
    """dq (N, n) [rad] of the loaded state relative to the unloaded one at the same pose: the joint laws at
    the total torque tau_weight + tau_load less those at the own weight's tau_weight (a gap preloaded by the
    weight jumps only when the load reverses the total torque)."""
    if not np.any(tau_weight):
        return joint_deflections(truth, tau_load, q)
    return joint_deflections(truth, tau_weight + tau_load, q) - joint_deflections(truth, tau_weight, q)


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


def _tilted(robot: Robot, truth: Truth, force: np.ndarray, moment: np.ndarray | None = None):
    """(force, moment): the real load of a logged one, the force (N, d) turned by ``truth.load_tilt`` (small
    rotation vector) and, for a spatial arm's moment (N, 3) of a mass on a loading bar (the bar level, its lever r
    normal to the force: r = F x M / |F|^2), the moment of the turned force about the tool point, r x F_real (a
    planar arm's in-plane lever normal to the force keeps its moment under an in-plane turn)."""
    if truth.load_tilt is None:
        return force, moment
    turn = np.cross(np.asarray(truth.load_tilt, float), as_xyz(force))
    real = (as_xyz(force) + turn)[:, : robot.task_dim]
    if moment is None or robot.task_dim != 3 or not np.any(moment):
        return real, moment
    f2 = np.einsum("ni,ni->n", force, force)
    lever = np.cross(force, moment) / np.where(f2 > 0, f2, 1.0)[:, None]
    return real, moment + np.cross(lever, turn)


def base_tilt_motion(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray, moment: np.ndarray | None,
                     points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(displacement (N, 3) [m] of points (N, 3), rotation (N, 3) [rad])`` of a robot on a compliant base
    (``truth.base_tilt`` = (c, h)): the base turns by w = c P M about the pivot p0 = -h u below its origin (u the up
    direction, minus the robot file's gravity; P the projection on the horizontal plane; with (c_x, c_y, h),
    w = c_x (M . e1) e1 + c_y (M . e2) e2, :func:`horizontal_axes`), M = (x - p0) x F + M_tool
    the load's moment about the pivot (x the tool point, F (N, 3) [N], M_tool (N, 3) [N m] about the tool point),
    and every point p moves by w x (p - p0): a rigid rotation of the whole arm on a rotational spring at its
    foot."""
    if robot.task_dim != 3:
        raise ValueError("a compliant base (Truth.base_tilt) needs a spatial arm")
    *c, h = (float(v) for v in truth.base_tilt)
    up, e1, e2 = horizontal_axes(robot)
    pivot = -h * up
    x = target_world(robot, q, None, None)
    M = np.cross(x - pivot, as_xyz(force)) + (0.0 if moment is None or not np.any(moment) else _moment3(robot, moment))
    cx, cy = (c[0], c[0]) if len(c) == 1 else c
    turn = cx * np.outer(M @ e1, e1) + cy * np.outer(M @ e2, e2)
    return np.cross(turn, points - pivot), turn


def horizontal_axes(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(up, e1, e2), unit (3,) each in the base frame: up = minus the robot file's gravity, e1 the base's x axis made
    horizontal (its y axis where x is nearly vertical), e2 = up x e1: the axes of a compliant base's
    ``Truth.base_tilt`` = (c_x, c_y, h)."""
    up = -np.asarray(robot.gravity, float)
    up = up / np.linalg.norm(up)
    x = np.eye(3)[0] if abs(up[0]) < 0.9 else np.eye(3)[1]
    e1 = x - (x @ up) * up
    e1 /= np.linalg.norm(e1)
    return up, e1, np.cross(up, e1)


def deflection(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray, moment: np.ndarray | None = None,
               target: np.ndarray | None = None, target_names=None, orientation: bool = False) -> np.ndarray:
    """Noise-free deflection (N, d (+ d_r)) [m (, rad)] of the robot between the unloaded and the loaded
    state at poses q (N, n) under force (N, d) (and moment (N, d_m)), at each row's target (``target`` (N,)
    indices into ``target_names``; None: the tool point), with the tool's rotation after the position when
    ``orientation``: joint laws on the total torque (:func:`loaded_deflections`), link bending, a compliant base,
    the load's tilt. No measuring-system effect (offset, drift)."""
    q = np.asarray(q, float)
    force, moment = _tilted(robot, truth, np.asarray(force, float), moment)
    tau = joint_torques(robot, q, force, moment)
    dq = loaded_deflections(truth, tau, self_weight_torques(robot, q), q)
    plain = (moment is None or not np.any(moment)) and target is None and not orientation
    if plain:
        dp = np.einsum("ndj,nj->nd", robot.jacobian(q), dq)
        if truth.link_bending is not None:
            dp = dp + link_bending_displacement(robot, q, force, np.asarray(truth.link_bending, float))
        if truth.base_tilt is not None:
            dp = dp + base_tilt_motion(robot, truth, q, force, moment, target_world(robot, q, None, None))[0]
        return dp
    pts = target_world(robot, q, target, target_names)
    disp, rot = joint_motion(robot, q, dq, pts)
    if truth.link_bending is not None:
        bd, br = link_bending_motion(robot, q, force, np.asarray(truth.link_bending, float), moment, pts)
        disp, rot = disp + bd, rot + br
    if truth.base_tilt is not None:
        bd, br = base_tilt_motion(robot, truth, q, force, moment, pts)
        disp, rot = disp + bd, rot + br
    d = robot.task_dim
    return np.hstack([disp[:, :d], (rot[:, 2:] if d == 2 else rot)]) if orientation else disp[:, :d]


def physics(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray,
            order: np.ndarray | None = None, moment: np.ndarray | None = None, target: np.ndarray | None = None,
            target_names=None, orientation: bool = False) -> np.ndarray:
    """Noise-free measured displacements (N, d (+ d_r)) of rows each taken from its own unloaded reading:
    :func:`deflection` plus the measuring system's offset and drift (``order`` (N,): the time order of each
    row, default the row index). ``offset`` and ``drift`` act on the positions."""
    dp = deflection(robot, truth, q, force, moment, target, target_names, orientation)
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
    """Measured displacements dp (N, d) [m] of independent rows: :func:`physics` plus N(0, sigma^2) noise per
    coordinate (sigma [m] a scalar or one per row, (N,)); blunders {row: (d,) extra error [m]} adds gross
    errors. With the orientation (N, d + d_r): the rotation gets N(0, sigma_rad^2) noise [rad]. (A lab's log,
    whose rows share reference readings, is :func:`lab_log` and :func:`measure`.)"""
    dp = physics(robot, truth, q, force, order, moment, target, target_names, orientation)
    dp = dp + rng.normal(0.0, 1.0, dp.shape) * _noise_scale(robot, dp.shape[1], sigma, sigma_rad, len(q))
    for row, err in (blunders or {}).items():
        dp[row] += err
    return dp


def _noise_scale(robot: Robot, width: int, sigma, sigma_rad, n: int) -> np.ndarray:
    """(n, width): the noise of every component (positions sigma, rotations sigma_rad)."""
    sig = np.reshape(np.broadcast_to(sigma, (n,)), (-1, 1))
    d = robot.task_dim
    if width == d:
        return sig
    rot = np.reshape(np.broadcast_to(sigma_rad, (n,)), (-1, 1))
    return np.hstack([np.repeat(sig, d, 1), np.repeat(rot, width - d, 1)])


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

REFERENCES = ("reading", "visit", "configuration")
LOADS = ("hanging", "directions", "pushes3d", "random", "gauge")


@dataclass(frozen=True)
class Protocol:
    """How a lab loads and measures the robot.

    Loads: ``loads`` = ``"hanging"`` (masses hanging on the tool: the force along gravity, -y for a planar arm
    in a vertical plane, -z for a spatial one, one magnitude per mass; with ``lever_m`` from a loading bar),
    ``"directions"`` (pushes in ``n_directions`` directions equally spaced in the plane, from a random start per
    configuration, at every magnitude), ``"pushes3d"`` (``n_directions`` random 3-D directions per
    configuration at every magnitude), ``"random"`` (one random direction and magnitude per configuration) or
    ``"gauge"`` (a hand-held force gauge pushing along +-x, +-y (+-z) of the base frame, each push its own
    force within +-``gauge_spread`` of the magnitude, the gauge's zero reading logged with the unloaded rows:
    forces of about ``gauge_zero_N``, below a load cell's resolution; ``gauge_angle_deg`` > 0: the hand holds the
    gauge off the axis it logs, each push turned by a random angle of that RMS [deg] about a random axis normal to
    it, its magnitude the one logged; ``gauge_each_push`` (default): every visit and repeat pushes anew, its forces
    drawn again (a hand reaching 300 N +- the spread each time: two pushes are replicates only by chance, within
    the force resolution), else the configuration's pushes are read again as they were on every visit and repeat
    (an actuator's: replicates)); magnitudes_N [N]; lever_m: the loads
    hang from a loading bar at this distance [m] from the tool point (a random horizontal direction per
    configuration; a planar arm: along x), ``bar_sides`` 2: on both ends of the bar (moments of both signs).

    Visits: ``passes`` visits of every configuration (the later ones of ``revisit_fraction`` of them), each
    pass in a new random order when ``shuffle``; the robot returns to a configuration within its pose
    repeatability ``repeatability_m`` (RMS distance of the tool point [m]; a random joint error per visit);
    ``relabel``: later visits get new pose_id labels (R1, R2, ..., as a lab that numbers its poses per pass);
    repeats: how often the load sequence is measured on the spot in a visit; interleaved: the whole plan is
    measured ``repeats`` times, pass after pass in the same order (replicates far apart in time) instead of
    repeating the load sequence on the spot.

    References: every logged displacement is a loaded (or unloaded) reading less the protocol's unloaded
    reference reading of the same target: ``reference`` = ``"reading"`` (each load its own unloaded reading
    just before it: independent rows), ``"visit"`` (one unloaded reading at the start of each visit, shared by
    the visit's loads) or ``"configuration"`` (one at the first visit of each configuration; the later visits
    are measured against it, so their rows carry the pose error of the return and the reference's error).
    zero_rows: the reference reading is logged as a row of exact zeros (the reference itself);
    unloaded_rows: an unloaded reading is logged before every loaded one (for ``"reading"`` it is the load's
    reference, logged as zeros; else a reading against the reference, with its noise); return_to_zero: an
    unloaded reading at the end of every visit, against the reference. With ``"configuration"`` the start of a
    later visit is logged as an unloaded row against the reference when the lab logs unloaded rows at all.

    Tracker: noise per reading sigma_m + sigma_per_m * (distance to ``tracker_m``) [m] (a laser tracker's MPE
    has that form); targets: the targets it measures, one row each per reading (the robot file's
    ``targets``, ``tool`` the tool point); orientation: a 6-DoF tracker logs the tool's rotation too, noise
    sigma_rad [rad] per reading; pose_id (in :func:`lab_csv`): the log numbers the configurations;
    timestamps: the log has a ``timestamp_s`` column (readings 12-45 s apart, 60-150 s between visits).
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
    bar_sides: int = 1
    targets: tuple[str, ...] = (TOOL_TARGET,)
    orientation: bool = False
    sigma_rad: float = 1e-5
    reference: str = "reading"
    passes: int = 1
    revisit_fraction: float = 1.0
    shuffle: bool = False
    relabel: bool = False
    zero_rows: bool = False
    return_to_zero: bool = False
    repeatability_m: float = 0.0
    gauge_spread: float = 0.05
    gauge_zero_N: float = 0.15
    gauge_angle_deg: float = 0.0
    gauge_each_push: bool = True
    timestamps: bool = False


@dataclass(frozen=True)
class LabLog:
    """A simulated measurement log: one row per logged reading and target, in time order.

    Rows: q (N, n) [rad] the commanded joint angles; force (N, d) [N] the logged force (moment (N, d_m)
    [N m] or None); config (N,) int; visit (N,) int; loaded (N,) bool (False: an unloaded row); sigma (N,)
    [m] the noise of the row's reading; target (N,) int into target_names, or None (the tool point);
    orientation: the rotation is logged, noise sigma_rad [rad]; time_s (N,); label (N,) str: the pose_id a
    lab would write; reading (N,) int: the reading each row logs; reference (N,) int: the reading it is
    taken from (the row is reading - reference); exact (N,) bool: the row is the reference reading itself,
    logged as zeros.

    Readings (R of them): r_q (R, n) [rad], r_force (R, d) [N] the load really applied (r_moment (R, d_m) or
    None), r_target (R,) int, r_visit (R,) int, r_loaded (R,) bool, r_sigma (R,) [m], r_order (R,) int (time
    order), r_time (R,) [s] its time; visit_config (V,) int; visit_scale (V,) [rad]: the standard deviation of
    each visit's joint error (the robot's pose repeatability: :func:`measure` draws N(0, visit_scale_v^2) per
    joint and visit); timestamps: the log has times to write; gauge_angle_rad [rad]: the RMS angle by which the
    hand turned each push off its logged direction (``Protocol.gauge_angle_deg``; the turned loads are r_force)."""

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
    visit: np.ndarray | None = None
    time_s: np.ndarray | None = None
    label: np.ndarray | None = None
    reading: np.ndarray | None = None
    reference: np.ndarray | None = None
    exact: np.ndarray | None = None
    r_q: np.ndarray | None = None
    r_force: np.ndarray | None = None
    r_moment: np.ndarray | None = None
    r_target: np.ndarray | None = None
    r_visit: np.ndarray | None = None
    r_loaded: np.ndarray | None = None
    r_sigma: np.ndarray | None = None
    r_order: np.ndarray | None = None
    r_time: np.ndarray | None = None
    visit_config: np.ndarray | None = None
    visit_scale: np.ndarray | None = None
    timestamps: bool = False
    gauge_angle_rad: float = 0.0

    @property
    def noisy(self) -> np.ndarray:
        """(N,) bool: the rows that carry noise (every row but the exact-zero reference rows)."""
        return ~self.exact


def _gravity(d: int) -> np.ndarray:
    return np.array([0.0, -1.0]) if d == 2 else np.array([0.0, 0.0, -1.0])


def configuration_loads(protocol: Protocol, d: int, rng: np.random.Generator) -> np.ndarray:
    """(L, d) [N]: the load sequence of one configuration (:class:`Protocol`), before a loading bar's sides."""
    mags = np.asarray(protocol.magnitudes_N, float)
    if protocol.loads == "hanging":
        return mags[:, None] * _gravity(d)
    if protocol.loads == "random":
        return rng.uniform(mags.min(), mags.max()) * random_directions(rng, 1, d)
    if protocol.loads == "gauge":
        axes = np.vstack([np.eye(d), -np.eye(d)])[np.argsort(rng.uniform(size=2 * d))]
        size = mags[None, :, None] * (1 + protocol.gauge_spread * rng.uniform(-1, 1, (2 * d, len(mags), 1)))
        return (axes[:, None, :] * size).reshape(-1, d)
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


def _bars(protocol: Protocol, d: int, rng: np.random.Generator, n_configs: int) -> list[np.ndarray] | None:
    """Per configuration the loading bar's lever arms (sides, d) [m] from the tool point, or None without one."""
    if protocol.lever_m == 0:
        return None
    out = []
    for _ in range(n_configs):
        ang = rng.uniform(-np.pi, np.pi)
        if d == 2:  # in the arm's vertical plane: along x
            bar = np.array([np.sign(np.cos(ang)) * protocol.lever_m, 0.0])
        else:
            bar = np.array([np.cos(ang), np.sin(ang), 0.0]) * protocol.lever_m
        out.append(np.stack([bar, -bar])[: max(1, protocol.bar_sides)])
    return out


def _visit_plan(protocol: Protocol, rng: np.random.Generator, n_configs: int) -> list[tuple[int, int]]:
    """The visits in time order: (configuration, pass)."""
    passes = protocol.repeats if protocol.interleaved else protocol.passes
    out = []
    for p in range(max(1, passes)):
        configs = np.arange(n_configs)
        if p > 0 and protocol.revisit_fraction < 1:
            configs = np.sort(rng.choice(n_configs, max(1, int(round(protocol.revisit_fraction * n_configs))),
                                         replace=False))
        if protocol.shuffle:
            configs = rng.permutation(configs)
        out += [(int(c), p) for c in configs]
    return out


class _Readings:
    """Builds the readings and the rows of a log (:func:`lab_log`)."""

    def __init__(self, n_targets: int):
        self.n_targets = n_targets
        self.readings: list[tuple] = []  # (visit, target, force, moment, loaded, order)
        self.rows: list[tuple] = []      # (reading, reference reading, exact, logged force)
        self.order = 0

    def read(self, visit: int, force, moment, loaded: bool) -> list[int]:
        """One reading of every target under one load (one time step); returns their indices."""
        idx = []
        for t in range(self.n_targets):
            idx.append(len(self.readings))
            self.readings.append((visit, t, force, moment, loaded, self.order))
        self.order += 1
        return idx

    def log(self, readings: list[int], references: list[int], exact: bool = False, logged_force=None) -> None:
        for r, ref in zip(readings, references):
            self.rows.append((r, ref, exact, logged_force))


def lab_log(robot: Robot, protocol: Protocol, rng: np.random.Generator, n_configs: int = 40) -> LabLog:
    """The rows a lab following ``protocol`` logs at ``n_configs`` random configurations within the joint
    limits (time order; see :class:`Protocol`)."""
    if protocol.reference not in REFERENCES:
        raise ValueError(f"unknown reference {protocol.reference!r}")
    lims = robot.joint_limits_rad
    d, n = robot.task_dim, robot.n_joints
    configs = rng.uniform(lims[:, 0], lims[:, 1], (n_configs, n))
    per = [configuration_loads(protocol, d, rng) for _ in range(n_configs)]
    bars = _bars(protocol, d, rng, n_configs)
    dm = 1 if d == 2 else 3
    if bars is not None:  # every mass on every side of the bar: force and moment r x F about the tool point
        loads = []
        for c in range(n_configs):
            F = np.repeat(per[c], len(bars[c]), axis=0)
            r = np.tile(bars[c], (len(per[c]), 1))
            M = np.cross(as_xyz(r), as_xyz(F))
            loads.append((F, M[:, 2:] if d == 2 else M))
    else:
        loads = [(per[c], None) for c in range(n_configs)]
    names = robot.target_names
    targets = [names.index(t) for t in protocol.targets]
    rd = _Readings(len(targets))
    visits = _visit_plan(protocol, rng, n_configs)
    logs_unloaded = protocol.zero_rows or protocol.unloaded_rows or protocol.return_to_zero
    reference_of: dict[int, list[int]] = {}
    zero = (np.zeros(d), None if bars is None else np.zeros(dm))
    for v, (c, p) in enumerate(visits):
        ref = None
        if protocol.reference == "visit" or (protocol.reference == "configuration" and c not in reference_of):
            ref = rd.read(v, *zero, False)
            if protocol.zero_rows:
                rd.log(ref, ref, exact=True)
            if protocol.reference == "configuration":
                reference_of[c] = ref
        elif protocol.reference == "configuration":
            ref = reference_of[c]
            if logs_unloaded:  # the later visit's start, against the configuration's reference
                rd.log(rd.read(v, *zero, False), ref)
        F, M = loads[c]
        for r in range(1 if protocol.interleaved else protocol.repeats):
            again = r > 0 or any(c == c0 for c0, _ in visits[:v])
            if protocol.loads == "gauge" and protocol.gauge_each_push and again:
                F = configuration_loads(protocol, d, rng)  # pushed anew
            for i in range(len(F)):
                load = (_held_off(F[i], protocol.gauge_angle_deg, rng), None if M is None else M[i])
                if protocol.reference == "reading":
                    ref = rd.read(v, *zero, False)
                    if protocol.unloaded_rows or protocol.zero_rows:
                        rd.log(ref, ref, exact=True)
                elif protocol.unloaded_rows:
                    rd.log(rd.read(v, *zero, False), ref)
                rd.log(rd.read(v, *load, True), ref, logged_force=F[i] if protocol.gauge_angle_deg else None)
        if protocol.return_to_zero and protocol.reference != "reading":
            logged = None
            if protocol.loads == "gauge":  # the gauge's own zero reading, below a load cell's resolution
                logged = rng.normal(0.0, protocol.gauge_zero_N, d)
            rd.log(rd.read(v, *zero, False), ref, logged_force=logged)
    return _assemble(robot, protocol, rng, configs, visits, rd, [names[t] for t in targets], names, bars is not None)


def _held_off(force: np.ndarray, angle_deg: float, rng: np.random.Generator) -> np.ndarray:
    """The force (d,) [N] a hand applies when it means ``force``: turned by a normal random angle of RMS
    ``angle_deg`` about a random axis normal to it (in the plane for a planar arm); ``force`` itself for 0."""
    if not angle_deg:
        return force
    d = len(force)
    axis = np.array([0.0, 0.0, 1.0]) if d == 2 else random_directions(rng, 1, 3)[0]
    turn = np.cross(axis, as_xyz(force))
    norm = np.linalg.norm(turn)
    if norm == 0:
        return force
    angle = np.radians(angle_deg) * rng.normal()
    real = as_xyz(force) * np.cos(angle) + turn / norm * np.linalg.norm(force) * np.sin(angle)
    return real[:d]


def _assemble(robot, protocol, rng, configs, visits, rd: _Readings, measured, names, has_moment) -> LabLog:
    """The :class:`LabLog` of the readings and rows :func:`lab_log` built."""
    d = robot.task_dim
    dm = 1 if d == 2 else 3
    R = rd.readings
    r_visit = np.array([r[0] for r in R])
    r_target = np.array([names.index(measured[r[1]]) for r in R])
    r_force = np.array([r[2] for r in R], float).reshape(-1, d)
    r_moment = np.array([np.zeros(dm) if r[3] is None else r[3] for r in R], float) if has_moment else None
    r_loaded = np.array([r[4] for r in R])
    r_order = np.array([r[5] for r in R])
    visit_config = np.array([c for c, _ in visits])
    r_q = configs[visit_config[r_visit]]
    plain = tuple(protocol.targets) == (TOOL_TARGET,)
    tracker = as_xyz(np.asarray(protocol.tracker_m, float)[:d])
    where = as_xyz(robot.fk(r_q)) if plain else target_world(robot, r_q, r_target, names)
    r_sigma = protocol.sigma_m + protocol.sigma_per_m * np.linalg.norm(where - tracker, axis=-1)
    scale = np.zeros(len(visits))
    if protocol.repeatability_m > 0:  # RMS distance of the tool point = the repeatability
        J = robot.jacobian(configs[visit_config])
        scale = protocol.repeatability_m / np.sqrt(np.einsum("vdj,vdj->v", J, J))
    reading = np.array([r[0] for r in rd.rows])
    reference = np.array([r[1] for r in rd.rows])
    exact = np.array([r[2] for r in rd.rows])
    force = r_force[reading].copy()
    for i, row in enumerate(rd.rows):
        if row[3] is not None:
            force[i] = row[3]
    # times: readings 12-45 s apart, 60-150 s more between visits
    steps = rng.uniform(12.0, 45.0, r_order.max() + 1)
    starts = np.array([r_order[r_visit == v].min() for v in range(len(visits))])
    steps[starts[1:]] += rng.uniform(60.0, 150.0, len(starts) - 1)
    clock = 300.0 + np.cumsum(steps)
    config = visit_config[r_visit[reading]]
    first_pass = {}
    labels = []
    for v, (c, p) in enumerate(visits):
        first_pass.setdefault(c, v)
    relabels = {}
    for row_visit, c in zip(r_visit[reading], config):
        if protocol.relabel and first_pass[c] != row_visit:
            relabels.setdefault(int(row_visit), f"R{len(relabels) + 1}")
            labels.append(relabels[int(row_visit)])
        else:
            labels.append(str(int(c) + 1))
    return LabLog(configs[config], force, config, r_loaded[reading], r_sigma[reading],
                  None if r_moment is None else r_moment[reading], None if plain else r_target[reading], names,
                  protocol.orientation, protocol.sigma_rad, r_visit[reading], clock[r_order[reading]],
                  np.array(labels), reading, reference, exact, r_q, r_force, r_moment, r_target, r_visit, r_loaded,
                  r_sigma, r_order, clock[r_order], visit_config, scale, protocol.timestamps,
                  float(np.radians(protocol.gauge_angle_deg)))


def _reading_motion(robot: Robot, log: LabLog, dq: np.ndarray) -> np.ndarray:
    """(R, d (+ d_r)): the motion of every reading's target (and the tool's rotation) under joint errors dq
    (R, n) [rad] (linear: a pose repeatability of micrometres)."""
    pts = target_world(robot, log.r_q, log.r_target, log.target_names)
    disp, rot = joint_motion(robot, log.r_q, dq, pts)
    d = robot.task_dim
    return np.hstack([disp[:, :d], (rot[:, 2:] if d == 2 else rot)]) if log.orientation else disp[:, :d]


def gear_sides(robot: Robot, truth: Truth, log: LabLog) -> np.ndarray:
    """(R, n): the flank (+1 or -1) each joint's gear rests on at every reading of ``log`` under a backlash held by
    friction (``truth.held_gap``, ``truth.held_torque``). At the start of a visit the weight's torque sets the
    flank where it exceeds the friction torque; elsewhere the gear is on its + flank (every configuration is
    approached from the same side: the drive's last motion pushes the gear there). Reading by reading in time
    order, a total torque (the weight's plus the load's, :func:`joint_torques` of the real, tilted load) beyond
    +-held_torque moves the gear to that flank; a smaller one leaves it where it was, so the unloaded reading
    after a load keeps the load's flank while its weight cannot bring it back."""
    hold = np.broadcast_to(np.asarray(truth.held_torque, float), (robot.n_joints,))
    weight = self_weight_torques(robot, log.r_q)
    load = np.zeros_like(weight)
    on = log.r_loaded
    if on.any():
        load[on] = joint_torques(robot, log.r_q[on], *_tilted(robot, truth, log.r_force[on],
                                                              None if log.r_moment is None else log.r_moment[on]))
    push = np.sign(weight + load) * (np.abs(weight + load) > hold)  # (R, n): where the torque moves the gear
    start = np.where(np.abs(weight) > hold, np.sign(weight), 1.0)
    sides = np.empty_like(weight)
    side = None
    previous = -1
    for r in np.lexsort((np.arange(len(log.r_q)), log.r_order, log.r_visit)):
        if log.r_visit[r] != previous:
            side, previous = start[r], log.r_visit[r]
        side = np.where(push[r] != 0, push[r], side)
        sides[r] = side
    return sides


def reading_means(robot: Robot, truth: Truth, log: LabLog) -> np.ndarray:
    """(R, d (+ d_r)): every reading's noise-free value less the target's unloaded position at its commanded
    pose, without the pose errors of the returns: the deflection of a loaded reading (:func:`deflection`), the
    measuring system's offset (loaded readings) and drift (over the clock of the readings, [s]), and the offset of
    a backlash held by friction (every reading, :func:`gear_sides`)."""
    width = robot.task_dim * 1 + ((1 if robot.task_dim == 2 else 3) if log.orientation else 0)
    out = np.zeros((len(log.r_q), width))
    on = log.r_loaded
    if on.any():
        target = None if log.target is None else log.r_target[on]
        out[on] = deflection(robot, truth, log.r_q[on], log.r_force[on],
                             None if log.r_moment is None else log.r_moment[on], target, log.target_names,
                             log.orientation)
    d = robot.task_dim
    if truth.offset is not None:
        out[on, :d] += np.asarray(truth.offset, float)
    if truth.drift is not None:
        out[:, :d] += log.r_time[:, None] * np.asarray(truth.drift, float)
    if truth.held_gap is not None:
        out += _reading_motion(robot, log, 0.5 * np.asarray(truth.held_gap, float) * gear_sides(robot, truth, log))
    return out


def row_means(robot: Robot, truth: Truth, log: LabLog) -> np.ndarray:
    """(N, d (+ d_r)): the noise-free value of every logged row (reading less its reference)."""
    m = reading_means(robot, truth, log)
    return m[log.reading] - m[log.reference]


def measure(robot: Robot, truth: Truth, log: LabLog, rng: np.random.Generator,
            blunders: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Displacements (N, d) [m] of every row of ``log``: each reading the target's position (its deflection
    under the load, the return's pose error, the tracker's offset, drift and noise), each row its reading
    less its reference reading (exact zeros for the reference rows themselves); the returns' joint errors
    are drawn here (:class:`LabLog`); blunders {row: (d,) error
    [m]} added to the rows. With the orientation logged: (N, d + d_r), the rotation [rad] after the
    displacement."""
    value = reading_means(robot, truth, log)
    dq = rng.normal(0.0, 1.0, (len(log.visit_config), robot.n_joints)) * log.visit_scale[:, None]
    value += _reading_motion(robot, log, dq[log.r_visit])
    value += rng.normal(0.0, 1.0, value.shape) * _noise_scale(robot, value.shape[1], log.r_sigma, log.sigma_rad,
                                                              len(value))
    dp = value[log.reading] - value[log.reference]
    dp[log.exact] = 0.0
    for row, err in (blunders or {}).items():
        dp[row] += err
    return dp


def _turn_deflections(robot: Robot, log: LabLog, k: np.ndarray) -> np.ndarray:
    """(R, w, A): the deflection of every reading (its target, and the rotation when logged) per radian of its
    load turned about each axis a normal to the plane (A = 1, planar) or x, y, z (A = 3), the joints' compliances
    ``k`` (n,) [rad/(N m)] acting on the turned force a x F (linear; the moment, if any, not turned)."""
    d = robot.task_dim
    axes = [np.array([0.0, 0.0, 1.0])] if d == 2 else list(np.eye(3))
    moment = None if log.r_moment is None else np.zeros_like(log.r_moment)
    target = None if log.target is None else log.r_target
    cols = [deflection(robot, Truth(k), log.r_q, np.cross(a, as_xyz(log.r_force))[:, :d], moment, target,
                       log.target_names, log.orientation) for a in axes]
    return np.stack(cols, -1)


def row_covariance(robot: Robot, log: LabLog, k: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The true covariance of the noisy rows (every row but the exact-zero references), configuration by
    configuration: a list of ``(rows (k,), Sigma (k w, k w))`` with w the components of a row, ordered row by
    row. Rows are D times the readings, whose noise is independent (sigma per reading) and whose return
    errors J dq_v are shared by the readings of a visit (dq_v ~ N(0, s_v^2 I), s_v = ``visit_scale``),
    so Sigma = D Sigma_readings D^T.

    k (n,) [rad/(N m)], the joints' compliances: with a gauge held off its axis (``log.gauge_angle_rad``), the
    covariance about the deflections of the logged loads over the hand's turns too (each loaded reading's own,
    theta^2 / k_a sum_a t_a t_a^T, t_a its deflection per radian of the load turned about axis a,
    :func:`_turn_deflections`, k_a = 1 planar, 2 spatial: the axes normal to the force); None: given the turns
    (the log's r_force, as :func:`measure` simulates a fixed log)."""
    width = robot.task_dim + ((1 if robot.task_dim == 2 else 3) if log.orientation else 0)
    noise = _noise_scale(robot, width, log.r_sigma, log.sigma_rad, len(log.r_q)) ** 2
    turn = None
    if k is not None and log.gauge_angle_rad > 0:
        turn = _turn_deflections(robot, log, np.asarray(k, float))
        turn *= log.gauge_angle_rad / np.sqrt(1.0 if robot.task_dim == 2 else 2.0)
    J = None
    if np.any(log.visit_scale):
        n = robot.n_joints
        J = np.stack([_reading_motion(robot, log, np.tile(np.eye(n)[j], (len(log.r_q), 1))) for j in range(n)], -1)
        J *= log.visit_scale[log.r_visit][:, None, None]
    out = []
    for c in np.unique(log.config):
        rows = np.flatnonzero((log.config == c) & ~log.exact)
        if rows.size == 0:
            continue
        used = np.unique(np.concatenate([log.reading[rows], log.reference[rows]]))
        pos = {int(r): i for i, r in enumerate(used)}
        D = np.zeros((len(rows), len(used)))
        D[np.arange(len(rows)), [pos[int(r)] for r in log.reading[rows]]] += 1.0
        D[np.arange(len(rows)), [pos[int(r)] for r in log.reference[rows]]] -= 1.0
        S = np.zeros((len(used), width, len(used), width))
        S[np.arange(len(used)), :, np.arange(len(used)), :] = np.eye(width)[None] * noise[used][:, :, None]
        if J is not None:
            Ju = J[used]  # (u, w, n)
            same = log.r_visit[used][:, None] == log.r_visit[used][None, :]
            S += np.einsum("awj,bvj,ab->awbv", Ju, Ju, same)
        if turn is not None:
            S[np.arange(len(used)), :, np.arange(len(used)), :] += np.einsum("uwa,uva->uwv", turn[used], turn[used])
        S = S.reshape(len(used) * width, len(used) * width)
        Dw = np.kron(D, np.eye(width))
        out.append((rows, Dw @ S @ Dw.T))
    return out


def lab_csv(robot: Robot, log: LabLog, dp: np.ndarray, pose_id: bool = True, timestamps: bool | None = None) -> str:
    """The log as the measured-data CSV a lab would write (``pose_id`` the log's labels, when asked; a
    ``timestamp_s`` column when the protocol logs times or ``timestamps``), angles to 1e-4 deg, forces to
    0.01 N, moments to 1e-4 N m, displacements to 1e-9 m and rotations to 1e-12 rad as trackers print them;
    with the log's moments (``mx_Nm``.. or ``mz_Nm``), targets (``target``) and orientation (``rx_rad``.. or
    ``rz_rad``) columns when it has them."""
    n, d = robot.n_joints, robot.task_dim
    axes = "xyz"[:d]
    rot_axes = "z" if d == 2 else "xyz"
    times = log.timestamps if timestamps is None else timestamps
    head = (["pose_id"] if pose_id else []) + (["timestamp_s"] if times else []) \
        + [f"q{i + 1}_deg" for i in range(n)] + [f"f{a}_N" for a in axes] \
        + ([f"m{a}_Nm" for a in rot_axes] if log.moment is not None else []) \
        + (["target"] if log.target is not None else []) + [f"d{a}_m" for a in axes] \
        + ([f"r{a}_rad" for a in rot_axes] if log.orientation else [])
    lines = [",".join(head)]
    qd = np.degrees(log.q)
    labels = log.label if log.label is not None else np.array([str(int(c) + 1) for c in log.config])
    for r in range(len(qd)):
        cells = ([str(labels[r])] if pose_id else []) + ([f"{log.time_s[r]:.1f}"] if times else []) \
            + [f"{v:.4f}" for v in qd[r]] + [f"{v:.2f}" for v in log.force[r]] \
            + ([f"{v:.4f}" for v in log.moment[r]] if log.moment is not None else []) \
            + ([log.target_names[log.target[r]]] if log.target is not None else []) \
            + [f"{v:.9e}" for v in dp[r, :d]] + ([f"{v:.12e}" for v in dp[r, d:]] if log.orientation else [])
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


# --- the effects a case can hide: a registry (a catalogue cause, or an effect outside the catalogue) ------------

@dataclass(frozen=True)
class Effect:
    """One effect the simulator can hide in a log, an entry of :data:`EFFECTS`: ``name`` (a catalogue cause's
    name, :data:`stiffcal.model.catalogue.CATALOGUE`, or an effect outside the catalogue); ``field``: the
    :class:`Truth` field that holds it; ``unit(robot, k, rng, log) -> Truth``: a truth with the compliances k and
    the effect at an arbitrary size (the rate matrix scales it to a displacement it draws); ``inverse``: the field
    is a limit that the effect grows as it shrinks (a softening joint's tau_max), so :meth:`scaled` divides it and
    the effect's displacement is not linear in the factor (the rate matrix then searches the factor), else the
    displacement is linear in the field (multiplied)."""
    name: str
    field: str
    unit: Callable
    inverse: bool = False

    def scaled(self, truth: Truth, s: float) -> Truth:
        """``truth`` with this effect s times as strong (the field times s, or divided by s when ``inverse``)."""
        value = getattr(truth, self.field)
        return replace(truth, **{self.field: value / s if self.inverse else value * s})


def _load_torques(robot: Robot, log: LabLog) -> np.ndarray:
    on = log.loaded
    return joint_torques(robot, log.q[on], log.force[on], None if log.moment is None else log.moment[on])


def _coupled_pair(robot: Robot, k: np.ndarray, rng: np.random.Generator, log: LabLog) -> Truth:
    n = robot.n_joints
    i, j = sorted(rng.choice(n, 2, replace=False))
    c = np.zeros((n, n))
    c[i, j] = c[j, i] = 0.1 * np.sqrt(k[i] * k[j]) * rng.choice([-1.0, 1.0])
    return Truth(k, coupling=c)


def _softening(robot: Robot, k: np.ndarray, rng: np.random.Generator, log: LabLog) -> Truth:
    weight = self_weight_torques(robot, log.q)
    tau = np.abs(np.vstack([_load_torques(robot, log) + weight[log.loaded], weight])).max(axis=0)  # the largest
    return Truth(k, tau_max=np.maximum(tau, 1e-9) / 0.3)


def _tilt(robot: Robot, k: np.ndarray, rng: np.random.Generator, log: LabLog) -> Truth:
    """A pulley or a fixture that pulls a few degrees off the logged direction."""
    axis = random_directions(rng, 1, 3)[0] if robot.task_dim == 3 else np.array([0.0, 0.0, 1.0])
    return Truth(k, load_tilt=axis * np.radians(1.0))


def _friction_held(robot: Robot, k: np.ndarray, rng: np.random.Generator, log: LabLog) -> Truth:
    """Friction of a fifth of the joint's typical load torque holds the gear."""
    held = np.maximum(0.2 * np.median(np.abs(_load_torques(robot, log)), axis=0), 1e-9)
    return Truth(k, held_gap=np.full(robot.n_joints, 1e-5), held_torque=held)


#: the effects a case can hide, the catalogue's causes first (in the catalogue's order), then those outside it
EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("link_compliance", "link_bending",
           lambda robot, k, rng, log: Truth(k, link_bending=np.full(robot.n_segments, 1e-7))),
    Effect("joint_coupling", "coupling", _coupled_pair),
    Effect("nonlinear_joint_stiffness", "tau_max", _softening, inverse=True),
    Effect("backlash", "gap", lambda robot, k, rng, log: Truth(k, gap=np.full(robot.n_joints, 1e-5))),
    Effect("measurement_offset", "offset",
           lambda robot, k, rng, log: Truth(k, offset=random_directions(rng, 1, robot.task_dim)[0] * 1e-5)),
    Effect("drift", "drift",
           lambda robot, k, rng, log: Truth(k, drift=random_directions(rng, 1, robot.task_dim)[0] * 1e-7)),
    Effect("modulation", "modulation", lambda robot, k, rng, log: Truth(
        k, modulation=rng.uniform(0.05, 0.15, robot.n_joints) * rng.choice([-1.0, 1.0], robot.n_joints))),
    Effect("tilted_load", "load_tilt", _tilt),
    Effect("held_backlash", "held_gap", _friction_held),
)}
