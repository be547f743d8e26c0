"""Slow, independent reference solvers for checking fast ones (tests and ``benchmarks/``).

They use only eq. 16 evaluated by plain linear algebra on the robot's Jacobian, none of the reductions of
:mod:`stiffcal.maps`, so agreement between the two is evidence, not a tautology.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from .robot import planar_robot
from .stiffness import observation_matrix


def _setup(b: float, force: np.ndarray, qt_deg):
    robot = planar_robot([1.0, b])
    At = observation_matrix(robot.jacobian(np.radians(np.asarray(qt_deg, float))), force)
    return robot, At.T @ At


def ot_plain(robot, q_deg: np.ndarray, S: np.ndarray, force: np.ndarray, max_cond: float = 1e8) -> np.ndarray:
    """O_t / sigma^2 = tr(M^-1 S) of single measurement poses q_deg (N, 2) [deg] by a plain solve; +inf
    for plans with cond(M) >= max_cond (whose round-off would give meaningless values)."""
    A = observation_matrix(robot.jacobian(np.radians(np.atleast_2d(q_deg))), force)
    M = np.einsum("ndi,ndj->nij", A, A)
    ok = np.linalg.cond(M) < max_cond
    out = np.full(len(M), np.inf)
    out[ok] = np.einsum("nii->n", np.linalg.solve(M[ok], np.broadcast_to(S, M[ok].shape)))
    return out


def brute_force_cell(b: float, force: np.ndarray, qt_deg, step_deg: float = 1.0, polish: int = 3) -> float:
    """min O_t over one measurement pose: every pose of a step_deg grid over the whole joint space, then
    Nelder-Mead from the ``polish`` best grid poses."""
    robot, S = _setup(b, force, qt_deg)
    g = np.arange(-180.0, 180.0, step_deg)
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    vals = ot_plain(robot, Q, S, force)
    best = float(vals.min())
    for i in np.argsort(vals)[:polish]:
        with np.errstate(invalid="ignore"):
            r = minimize(lambda q: ot_plain(robot, q, S, force)[0], Q[i], method="Nelder-Mead",
                         options=dict(xatol=1e-9, fatol=1e-15, maxiter=4000))
        best = min(best, float(r.fun))
    return best


def naive_cell(b: float, force: np.ndarray, qt_deg, starts: int = 10, seed: int = 0) -> float:
    """The naive method of issue 4: a multi-start local search (Nelder-Mead from random poses)."""
    robot, S = _setup(b, force, qt_deg)
    rng = np.random.default_rng(seed)
    best = np.inf
    for q0 in rng.uniform(-180.0, 180.0, (starts, 2)):
        with np.errstate(invalid="ignore"):  # a simplex may touch a singular plan (+inf)
            r = minimize(lambda q: ot_plain(robot, q, S, force)[0], q0, method="Nelder-Mead",
                         options=dict(xatol=1e-8, fatol=1e-13, maxiter=2000))
        best = min(best, float(r.fun))
    return best


# --- long-double references for the maps (issue 16): eq. 16 by explicit 2 x 2 algebra in 80-bit precision --

def _observation_ld(b: float, force: np.ndarray, q_deg) -> tuple[np.ndarray, np.ndarray]:
    """A = J diag(J^T F) (eq. 4) and det A of the arm (1, b) at poses q_deg (N, 2) [deg], in long double;
    det A = tau1 tau2 det J with det J = b sin q2 (a product: no cancellation next to singular poses)."""
    L = np.longdouble
    q = np.radians(np.atleast_2d(np.asarray(q_deg, L)))
    F = np.asarray(force, L)
    c1, s1, c12, s12 = np.cos(q[:, 0]), np.sin(q[:, 0]), np.cos(q.sum(1)), np.sin(q.sum(1))
    J = np.empty((len(q), 2, 2), L)
    J[:, 0, 0], J[:, 1, 0], J[:, 0, 1], J[:, 1, 1] = -(s1 + b * s12), c1 + b * c12, -b * s12, b * c12
    tau = np.einsum("ndi,d->ni", J, F)
    return J * tau[:, None, :], tau[:, 0] * tau[:, 1] * b * np.sin(q[:, 1])


def ot_long_double(b: float, force: np.ndarray, qt_deg, q_deg) -> np.ndarray:
    """O_t / sigma^2 = ||A_t A^-1||_F^2 (eq. 16, one measurement pose; l1 = 1) for measurement poses q_deg
    (N, 2) [deg] and the test pose qt_deg (2,), in long double with A^-1 = adj(A) / det A; +inf where
    det A = 0. Independent of the reduction of :mod:`stiffcal.maps`."""
    At, _ = _observation_ld(b, force, qt_deg)
    A, det = _observation_ld(b, force, q_deg)
    adj = np.empty_like(A)
    adj[:, 0, 0], adj[:, 1, 1], adj[:, 0, 1], adj[:, 1, 0] = A[:, 1, 1], A[:, 0, 0], -A[:, 0, 1], -A[:, 1, 0]
    G = np.einsum("ij,njk->nik", At[0], adj)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.einsum("nij,nij->n", G, G) / (det * det)
    return np.where(det != 0, out, np.inf)


def brute_force_cell_ld(b: float, force: np.ndarray, qt_deg, step_deg: float = 2.0, polish: int = 6) -> float:
    """min O_t / sigma^2 over one measurement pose: every pose of a step_deg grid over the whole joint space,
    then Nelder-Mead from the ``polish`` best grid poses, all evaluated by :func:`ot_long_double`."""
    g = np.arange(-180.0, 180.0, step_deg) + step_deg / 3   # off the singular lines q2 = 0, 180
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    vals = ot_long_double(b, force, qt_deg, Q).astype(float)
    best = float(vals.min())
    for i in np.argsort(vals)[:polish]:
        with np.errstate(invalid="ignore", over="ignore"):
            r = minimize(lambda q: float(ot_long_double(b, force, qt_deg, q)[0]), Q[i], method="Nelder-Mead",
                         options=dict(xatol=1e-11, fatol=1e-17, maxiter=20000, maxfev=40000))
        best = min(best, float(r.fun))
    return best


def brute_force_pair(b: float, force: np.ndarray, qt_deg, step_deg: float = 6.0, polish: int = 8) -> float:
    """min O_t / sigma^2 over plans of two measurement poses (l1 = 1): every pair of poses of a step_deg grid
    over the whole joint space, then Nelder-Mead in the four joint angles from the ``polish`` best pairs;
    eq. 16 by a plain solve on the stacked observation matrices."""
    robot, S = _setup(b, force, qt_deg)
    g = np.arange(-180.0, 180.0, step_deg) + step_deg / 3
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    A = observation_matrix(robot.jacobian(np.radians(Q)), force)
    M = np.einsum("ndi,ndj->nij", A, A)
    m = np.stack([M[:, 0, 0], M[:, 0, 1], M[:, 1, 1]], -1)
    best = []
    for i in range(len(Q)):                      # row i against every j >= i
        t = m[i] + m[i:]
        det = t[:, 0] * t[:, 2] - t[:, 1] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(det > 1e-12 * t[:, 0] * t[:, 2], (S[0, 0] * t[:, 2] - 2 * S[0, 1] * t[:, 1] + S[1, 1] * t[:, 0]) / det,
                         np.inf)
        k = np.argsort(v)[:2]
        best += [(v[j], i, i + j) for j in k]
    best.sort()

    def plan_ot(x):
        Ap = observation_matrix(robot.jacobian(np.radians(x.reshape(2, 2))), force).reshape(4, 2)
        Mp = Ap.T @ Ap
        if np.linalg.cond(Mp) > 1e12:
            return np.inf
        return float(np.trace(np.linalg.solve(Mp, S)))

    out = best[0][0]
    for _, i, j in best[:polish]:
        with np.errstate(invalid="ignore", over="ignore"):
            r = minimize(plan_ot, np.concatenate([Q[i], Q[j]]), method="Nelder-Mead",
                         options=dict(xatol=1e-9, fatol=1e-15, maxiter=20000, maxfev=40000))
        out = min(out, float(r.fun))
    return out
