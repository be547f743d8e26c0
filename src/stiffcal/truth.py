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

from .robot import Robot, as_xyz
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
    """End-effector displacement (N, d) [m] of Euler-Bernoulli links bending under the end-effector force.

    Link i is the segment between consecutive points of ``robot.link_points`` (n segments for a planar arm;
    n + 1 for a spatial one, the last to the tool point). A curvature vector kappa(s) = c M_perp(s) at arc
    length s (M_perp the bending part of the moment r x F of the end-effector force about that point, i.e.
    without the torsion about the link) turns everything beyond s by kappa ds; integrated along each link
    by Gauss-Legendre quadrature. c: (segments,) [1/(N m^2)].
    """
    pts = as_xyz(robot.link_points(q))  # (N, segments + 1, 3)
    F = as_xyz(force)
    pe = pts[:, -1, :]
    out = np.zeros_like(pe)
    for i in range(pts.shape[1] - 1):
        a, b = pts[:, i, :], pts[:, i + 1, :]
        L = np.linalg.norm(b - a, axis=-1)
        if c[i] == 0 or not np.any(L > 0):
            continue
        u = (b - a) / np.where(L > 0, L, 1.0)[:, None]
        for xg, wg in zip(_GL_X, _GL_W):
            x = a + 0.5 * (xg + 1.0) * (b - a)
            r = pe - x
            M = np.cross(r, F)
            M_perp = M - np.einsum("nd,nd->n", M, u)[:, None] * u
            out += (0.5 * wg * L * c[i])[:, None] * np.cross(M_perp, r)
    return out[:, : robot.task_dim]


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
    """(q (N, n) [rad], force (N, d) [N], pose_id (N,)): random poses within the joint limits, each with a
    random force (magnitude in force_N, any direction in the plane or in space), measured ``replicates`` times."""
    lims = robot.joint_limits_rad
    q = rng.uniform(lims[:, 0], lims[:, 1], (n_poses, robot.n_joints))
    mag = rng.uniform(*force_N, n_poses)
    f = mag[:, None] * random_directions(rng, n_poses, robot.task_dim)
    idx = np.repeat(np.arange(n_poses), replicates)
    return q[idx], f[idx], idx
