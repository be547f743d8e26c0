"""Plans of M measurement poses (eqs. 11, 16 summed over poses; Tables 4-5).

Global optimisation of an M-pose plan
-------------------------------------
The plan's information matrix is a sum over poses, so a plan is improved one pose at a time
(Fedorov's exchange): with the other M - 1 poses fixed, the best replacement for pose j is found over a
whole candidate pool at once (vectorised), and passes repeat until no pose changes. Every exchanged plan
is then ranked, and the ``n_polish`` best are polished in the continuum (L-BFGS-B on all M n angles). Starts: the rounding of the optimal
approximate design (:mod:`stiffcal.certificate`), the best single pose repeated (plan (i)), and
``n_starts`` random plans drawn from the pool with the given seed, so the result is deterministic for a
seed. The certificate bounds how far the result can be from the true optimum; the tests compare it with
a brute force.

Symmetric optima
----------------
Each pose's information is unchanged by the half-turn and mirror copies of that pose (see
:mod:`stiffcal.design`), independently for every pose of a plan. A plan is reported with each pose
replaced by its representative copy (:func:`stiffcal.design.representative`) and the poses sorted, so
plans equal up to symmetry print identically. Joint limits break the symmetry: then poses are kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from . import criteria
from .certificate import ApproximateDesign, candidate_pool, default_pool_step, has_planar_symmetry
from .design import Problem, _is_full_turn, into_limits, plan_loss, representative, wrap_deg
from .stiffness import information_matrix, pose_information


@dataclass
class PlanResult:
    """poses_deg: (m, n) canonical plan; loss: minimised criterion; starts: number of starts tried;
    distinct_optima: how many starts reached the optimum (to 1e-9) with a different canonical plan."""

    poses_deg: np.ndarray
    loss: float
    starts: int
    distinct_optima: int = 1
    notes: list[str] = field(default_factory=list)


def symmetric_copies(robot, pose_deg: np.ndarray, force: np.ndarray) -> np.ndarray:
    """The half-turn and mirror copies of one pose (4, n) [deg] (only valid for full-turn joints)."""
    phi = np.degrees(np.arctan2(force[1], force[0]))
    mirror = np.concatenate([[2 * phi - pose_deg[0]], -pose_deg[1:]])
    base = np.array([pose_deg, mirror])
    turned = base.copy()
    turned[:, 0] += 180.0
    return wrap_deg(np.concatenate([base, turned]))


def canonical_plan(problem: Problem, plan_deg: np.ndarray) -> np.ndarray:
    """Each pose replaced by its representative symmetric copy (planar arms without limits only), poses
    sorted (by q1, then q2, ...)."""
    robot = problem.robot
    plan = into_limits(robot, np.atleast_2d(plan_deg))
    if has_planar_symmetry(robot, problem):
        plan = np.array([representative(symmetric_copies(robot, p, problem.force)) for p in plan])
    order = np.lexsort(plan.T[::-1])
    return plan[order]


def _plan_A(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Stacked observation rows of poses q (..., n) [rad] -> (..., r, p) (:meth:`Problem.rows`)."""
    return problem.rows(q)


def ot_exchange_values(M_rest: np.ndarray, pool_A: np.ndarray, At: np.ndarray, sigma: float) -> np.ndarray | None:
    """O_t (eq. 16) of ``M_rest + A_c^T A_c`` for every candidate c, by the Woodbury identity.

    ``(R^-1 + A^T A)^-1 = R - R A^T (I + A R A^T)^-1 A R`` with ``R = M_rest^-1``, so
    ``O_t(c) = sigma^2 [trace(W R) - trace(S_c^-1 G_c)]``, ``S_c = I + A_c R A_c^T``,
    ``G_c = A_c R W R A_c^T``, ``W = A_t^T A_t``: d x d work per candidate, no eigen-decomposition.
    M_rest: (n, n); pool_A: (N, d, n). Returns (N,), or None when M_rest is singular or ill conditioned
    (eigenvalue ratio below ``1e-8``, where R would be inaccurate): the caller then uses the general path.
    """
    w = np.linalg.eigvalsh(M_rest)
    if not w[0] > 1e-8 * w[-1]:
        return None
    R = np.linalg.inv(M_rest)
    W = At.T @ At
    AR = pool_A @ R  # (N, d, n)
    S = np.eye(pool_A.shape[1]) + AR @ np.swapaxes(pool_A, -1, -2)
    G = AR @ W @ np.swapaxes(AR, -1, -2)
    return sigma**2 * (np.trace(W @ R) - np.einsum("nij,nji->n", np.linalg.inv(S), G))


def exchange(problem: Problem, plan: np.ndarray, pool: np.ndarray, pool_A: np.ndarray, max_passes: int = 30):
    """Fedorov exchange of an m-pose plan (m, n) [rad] over a pool (N, n) with rows pool_A (N, d, n).

    Candidates are scored from information matrices (``M_rest + A_c^T A_c``), O(N n^2) per step; only
    G-optimality, which needs the rows themselves, stacks them. Returns the improved plan and its loss.
    """
    m = plan.shape[0]
    d, n = pool_A.shape[-2:]
    key = problem.criterion
    pool_P = pose_information(pool_A)
    A = _plan_A(problem, plan)  # (m, d, n)
    best = float(criteria.loss(key, A.reshape(m * d, n), m, problem.At, problem.sigma))
    for _ in range(max_passes):
        changed = False
        for j in range(m):
            others = np.delete(A, j, axis=0)
            M_rest = information_matrix(others)
            vals = ot_exchange_values(M_rest, pool_A, problem.At, problem.sigma) if key == "ot" else None
            if vals is None:
                rows = None
                if key == "g":
                    rows = np.concatenate([np.broadcast_to(others.reshape(1, -1, n), (len(pool), (m - 1) * d, n)),
                                           pool_A], axis=1)
                vals = criteria.loss_from_info(key, M_rest[None] + pool_P, m, problem.At, problem.sigma, rows)
            c = int(np.argmin(vals))
            if vals[c] < best * (1 - 1e-12) - 1e-300:
                best = float(vals[c])
                plan = plan.copy()
                plan[j] = pool[c]
                A = A.copy()
                A[j] = pool_A[c]
                changed = True
        if not changed:
            break
    return plan, best


def polish(problem: Problem, plan: np.ndarray, free: np.ndarray | None = None):
    """L-BFGS-B on the free joint angles of every pose of plan (m, n) [rad]. Returns (plan, loss)."""
    m, n = plan.shape
    free = np.ones(n, bool) if free is None else np.asarray(free, bool)
    lims = problem.robot.joint_limits_rad

    def full(z):
        q = plan.copy()
        q[:, free] = z.reshape(m, free.sum())
        return q

    def f(z):
        return float(plan_loss(problem, full(z)))

    z0 = plan[:, free].ravel()
    f0 = f(z0)
    if not np.isfinite(f0):
        return plan, f0
    bounds = [(None, None) if _is_full_turn(*lims[j]) else tuple(lims[j]) for j in np.flatnonzero(free)] * m
    res = minimize(f, z0, method="L-BFGS-B", bounds=bounds, options=dict(maxiter=2000, ftol=1e-15, gtol=1e-11))
    if np.isfinite(res.fun) and res.fun <= f0:
        return full(res.x), float(res.fun)
    return plan, f0


def merge_repeats(plan_deg: np.ndarray, tol_deg: float = 1e-3) -> np.ndarray:
    """Plan (m, n) [deg] with poses closer than tol_deg (every joint) made identical (the first of each group).

    The continuous polish leaves a repeated pose of the optimum as two poses a round-off apart; the caller
    keeps the merged plan only when its loss is no worse.
    """
    out = np.array(plan_deg, float)
    for i in range(1, len(out)):
        close = np.flatnonzero(np.all(np.abs(wrap_deg(out[:i] - out[i])) < tol_deg, axis=1))
        if close.size:
            out[i] = out[close[0]]
    return out


def round_design(design: ApproximateDesign, m: int) -> np.ndarray:
    """Efficient rounding (Pukelsheim & Rieder 1992) of an approximate design to m poses [deg]."""
    w = design.weights
    k = len(w)
    counts = np.ceil((m - 0.5 * k) * w).astype(int).clip(min=0)
    while counts.sum() < m:
        counts[np.argmin(counts / w)] += 1
    while counts.sum() > m:
        j = np.argmax(np.where(counts > 0, (counts - 1) / w, -np.inf))
        counts[j] -= 1
    return np.repeat(design.support_deg, counts, axis=0)


def optimise_plan(problem: Problem, pool: np.ndarray | None = None, free: np.ndarray | None = None,
                  starts: list[np.ndarray] | None = None, n_starts: int = 16, seed: int = 0,
                  pool_step_deg: float | None = None, canonical: bool = True, n_polish: int = 4) -> PlanResult:
    """Globally optimise the m-pose plan of ``problem`` (module docstring).

    pool: candidate poses (N, n) [rad] (default: :func:`candidate_pool`); free: which joints the continuous
    polish may move (default all; plans (ii)-(iii) fix some); starts: extra starting plans [deg];
    canonical: report each pose as its representative symmetric copy (False keeps the poses as found,
    e.g. when some joints are held fixed, which the symmetric copies would change); n_polish: how many
    of the best exchanged plans are polished in the continuum.
    """
    m = problem.m
    rng = np.random.default_rng(seed)
    if pool is None:
        pool = candidate_pool(problem.robot, pool_step_deg or default_pool_step(problem.robot.n_joints), problem)
    pool_A = _plan_A(problem, pool)
    inits = [np.radians(np.atleast_2d(s)) for s in (starts or [])]
    inits += [pool[rng.choice(len(pool), m, replace=len(pool) < m)] for _ in range(n_starts)]
    exchanged = [exchange(problem, init, pool, pool_A) for init in inits]
    order = np.argsort([v for _, v in exchanged], kind="stable")[:n_polish]
    results = [polish(problem, exchanged[i][0], free)[::-1] for i in order]
    vals = np.array([r[0] for r in results])
    best_i = int(np.argmin(vals))
    best_val, best_plan = results[best_i]
    def canon_of(plan):
        if canonical:
            return canonical_plan(problem, np.degrees(plan))
        q = into_limits(problem.robot, np.degrees(plan))
        return q[np.lexsort(q.T[::-1])]

    canon = canon_of(best_plan)
    merged = merge_repeats(canon)
    merged_val = float(plan_loss(problem, np.radians(merged)))
    if merged_val <= best_val * (1 + 1e-10):
        canon, best_val = merged, merged_val
    near = [canon_of(p) for v, p in results if v <= best_val * (1 + 1e-9) + 1e-300]
    distinct = len({tuple(np.round(c, 3).ravel()) for c in near})
    return PlanResult(canon, float(best_val), len(inits), distinct)
