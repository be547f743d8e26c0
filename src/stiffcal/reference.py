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
