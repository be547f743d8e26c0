"""A truth simulator of measured deflections, written from the physics and independent of the analysis.

It does not use :mod:`stiffcal.discrepancy` (nor its regressors): joint deflections come from torque-
deflection laws solved per joint, link bending from integrating the beam curvature along each link,
and the measuring system adds noise, a bias, a drift or blunders. Used to make the example data set and
by the tests that hide an effect and require the analysis to find it.

Units: angles rad, forces N, lengths m, joint compliances rad/(N m), link bending compliances
1/(E I) in 1/(N m^2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .robot import Robot

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
    """

    k: np.ndarray
    coupling: np.ndarray | None = None
    tau_max: np.ndarray | None = None
    gap: np.ndarray | None = None
    tau_gap: float = 0.5
    link_bending: np.ndarray | None = None
    offset: np.ndarray | None = None
    drift: np.ndarray | None = None
    extra: dict = field(default_factory=dict)


def joint_torques(robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """tau = J^T F: (N, n) [N m] for q (N, n) [rad], force (N, d) [N]."""
    return np.einsum("ndj,nd->nj", robot.jacobian(q), force)


def joint_deflections(truth: Truth, tau: np.ndarray) -> np.ndarray:
    """dq (N, n) [rad] from the joint torque-deflection laws."""
    k = np.asarray(truth.k, float)
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
    """End-effector displacement (N, 2) [m] of Euler-Bernoulli links bending under the end-effector force.

    A curvature kappa(s) = c m(s) at arc length s of a link (m the bending moment there, from the force
    at the end effector) turns everything beyond s by kappa ds about that point; integrated along each
    link by Gauss-Legendre quadrature.
    """
    pts = robot.link_points(q)  # (N, n + 1, 2)
    pe = pts[:, -1, :]
    out = np.zeros_like(pe)
    for i in range(robot.n_joints):
        a, b = pts[:, i, :], pts[:, i + 1, :]
        L = np.linalg.norm(b - a, axis=-1)
        for xg, wg in zip(_GL_X, _GL_W):
            t = 0.5 * (xg + 1.0)
            x = a + t * (b - a)
            r = pe - x
            moment = r[:, 0] * force[:, 1] - r[:, 1] * force[:, 0]  # z . (r x F)
            turn = np.stack([-r[:, 1], r[:, 0]], axis=-1)  # z x r
            out += (0.5 * wg * L * c[i] * moment)[:, None] * turn
    return out


def simulate(robot: Robot, truth: Truth, q: np.ndarray, force: np.ndarray, sigma: float,
             rng: np.random.Generator, blunders: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Measured displacements dp (N, d) [m]: the physics of ``truth`` plus N(0, sigma^2) noise per
    coordinate; blunders {row: (d,) extra error [m]} adds gross errors."""
    tau = joint_torques(robot, q, force)
    dq = joint_deflections(truth, tau)
    dp = np.einsum("ndj,nj->nd", robot.jacobian(q), dq)
    if truth.link_bending is not None:
        dp = dp + link_bending_displacement(robot, q, force, np.asarray(truth.link_bending, float))
    if truth.offset is not None:
        dp = dp + np.asarray(truth.offset, float)
    if truth.drift is not None:
        dp = dp + np.arange(len(q))[:, None] * np.asarray(truth.drift, float)
    dp = dp + rng.normal(0.0, sigma, dp.shape)
    for row, err in (blunders or {}).items():
        dp[row] += err
    return dp


def random_experiment(robot: Robot, rng: np.random.Generator, n_poses: int = 30, replicates: int = 3,
                      force_N: tuple[float, float] = (100.0, 400.0)):
    """(q (N, n) [rad], force (N, 2) [N], pose_id (N,)): random poses within the joint limits, each with a
    random force (magnitude in force_N, any direction), measured ``replicates`` times."""
    lims = robot.joint_limits_rad
    q = rng.uniform(lims[:, 0], lims[:, 1], (n_poses, robot.n_joints))
    mag = rng.uniform(*force_N, n_poses)
    ang = rng.uniform(-np.pi, np.pi, n_poses)
    f = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=-1)
    idx = np.repeat(np.arange(n_poses), replicates)
    return q[idx], f[idx], idx
