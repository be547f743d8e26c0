"""The optimal approximate design for O_t and a certified lower bound on O_t for ANY plan of M poses.

O_t (eq. 16) is an L-optimality criterion: with ``W = A_t^T A_t`` and the information of a plan
``sum_i A_i^T A_i = M * M(xi)``, where ``M(xi) = sum_j w_j A(x_j)^T A(x_j)`` is the information matrix of
the plan seen as a probability measure xi over poses, ``O_t = sigma^2 Phi(xi) / M`` with
``Phi(xi) = trace(W M(xi)^-1)``. Every M-pose plan is one such measure (weights 1/M), so
``O_t >= sigma^2 Phi* / M`` where ``Phi*`` is the minimum of Phi over ALL measures: the optimal
approximate design.

Bound (general equivalence theorem)
-----------------------------------
Phi is convex and homogeneous of degree -1 in M. Its directional derivative towards a one-point measure
at pose x is ``phi(x, xi) - Phi(xi)`` with ``phi(x, xi) = || A(x) M(xi)^-1 A_t^T ||_F^2``. Convexity gives,
for any xi and any scaling t > 0, ``Phi* >= 2 Phi(t xi) - max_x phi(x, t xi)``; the best t yields

    Phi* >= Phi(xi)^2 / max_x phi(x, xi)                                    (the bound used here)

which is tight exactly at the optimum, where ``max_x phi = Phi`` (Kiefer-Wolfowitz equivalence theorem).
So any good design xi certifies how far any plan can be from optimal. The maximum over poses is over the
whole joint space, found by the same exhaustive grid + polish as the single-pose search
(:func:`stiffcal.design.grid_minimise`) or, for 4+ joints, by a dense scrambled-Sobol sample + polish
(:func:`stiffcal.design.sampled_minimise`); the bound is as reliable as that global maximisation.

Algorithm
---------
1. multiplicative algorithm (Silvey-Titterington-Torsney; exponent 1/2, monotone for this class, Yu 2010)
   on a candidate pool of poses (a grid over one symmetry cell of the joint space when the arm has
   full-turn joints: the other cells hold poses with identical information);
2. the weighted pool is merged into clusters; clusters lighter than ``min_mass`` are dropped; poses and
   weights are polished jointly in the continuum (L-BFGS-B);
3. vertex direction: the pose maximising phi joins the support and the design is re-polished, until the
   equivalence gap is below ``target_gap``; the bound is computed from the final design.

For 4+ joints (a sampled joint space) steps 2-3 are replaced by pool augmentation (:func:`_sampled_design`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .design import (Problem, angle_diff, global_minimise, is_sampled, joint_grids, sample_joint_space, sampled_minimise,
                     wrap_deg, _is_full_turn)
from .robot import Robot
from .stiffness import pose_information


#: candidate pool of a sampled joint space (4+ joints): 2**POOL_LOG2 scrambled-Sobol poses
POOL_LOG2 = 13


def has_planar_symmetry(robot: Robot, problem: Problem | None = None) -> bool:
    """Whether a pose's half-turn and mirror copies carry the same information (planar arm, no limits, and
    for ``problem`` no moment and no measured target beside the last link's line: :attr:`Problem.symmetric`)."""
    return robot.kind == "planar" and robot.n_joints >= 2 and all(
        _is_full_turn(lo, hi) for lo, hi in robot.joint_limits_rad) and (problem is None or problem.symmetric)


def candidate_pool(robot: Robot, step_deg: float, problem: Problem | None = None) -> np.ndarray:
    """Candidate poses [rad], (N, n): a grid over the joint space, restricted to one symmetry cell
    (q1 in [-90, 90), first nonzero of q2..qn >= 0) when the arm is planar and every joint turns fully
    (both the half-turn and the mirror copy of a pose carry the same information). For 4+ joints
    (:func:`stiffcal.design.is_sampled`): ``2**POOL_LOG2`` scrambled-Sobol poses within the limits."""
    if is_sampled(robot, step_deg):
        return sample_joint_space(robot, POOL_LOG2, seed=0)
    grids = joint_grids(robot, step_deg)
    q = np.stack(np.meshgrid(*grids, indexing="ij"), -1).reshape(-1, robot.n_joints)
    if not has_planar_symmetry(robot, problem):
        return q
    eps = 1e-12
    rest = q[:, 1:]
    nz = np.abs(rest) > eps
    first = np.where(nz.any(1), rest[np.arange(len(q)), np.argmax(nz, axis=1)], 0.0)
    keep = (q[:, 0] >= -np.pi / 2 - eps) & (q[:, 0] < np.pi / 2 - eps) & (first >= -eps)
    return q[keep]


def default_pool_step(n: int) -> float:
    """Grid step [deg] that keeps the pool near 10^4-10^5 poses: 2 deg for 2 joints, coarser beyond."""
    return float(max(2.0, np.ceil(360.0 / 120_000 ** (1.0 / n))))


def check_identifiable(problem: Problem, P: np.ndarray) -> None:
    """Raise :class:`InputError` when no plan over the joint space can identify every compliance with this
    force: the information summed over a pool covering the joint space (P: (N, n, n), its poses'
    information matrices) is singular. Names the joints of the
    combination that no pose excites (e.g. a vertical axis 1 under a vertical force: no torque about it)."""
    from .errors import InputError
    from .stiffness import spectral

    w, V, null = spectral(P.mean(axis=0))
    if not np.any(null) and w[0] > 1e-12 * w[-1]:
        return
    v = V[:, 0]
    joints = [int(problem.params[j]) + 1 for j in np.flatnonzero(np.abs(v) > 0.1 * np.abs(v).max())]
    what = (f"the compliance of joint {joints[0]}" if len(joints) == 1 else
            "a combination of the compliances of joints " + ", ".join(map(str, joints)))
    raise InputError(f"{what} cannot be identified with the force {problem.force.tolist()} N at any pose: the force "
                     "never loads it (zero torque about that axis, or the same effect as other joints); use a force "
                     "with another direction", source=problem.robot.source)


def _phi_design(W, M):
    Minv = np.linalg.inv(M)
    return float(np.trace(W @ Minv)), Minv


@dataclass
class ApproximateDesign:
    """The optimal approximate design for O_t and its certificate.

    support_deg: (k, n) poses [deg]; weights: (k,) summing to 1; phi: Phi(xi) = trace(W M(xi)^-1)
    (O_t of one pose-equivalent with sigma = 1); max_phi: max over poses of phi(x, xi);
    phi_lower: the certified lower bound Phi(xi)^2 / max_phi on Phi*; iterations of step 1.
    """

    support_deg: np.ndarray
    weights: np.ndarray
    phi: float
    max_phi: float
    phi_lower: float
    iterations: int

    @property
    def equivalence_gap(self) -> float:
        """max_x phi(x, xi) / Phi(xi) - 1: zero exactly at the optimum (equivalence theorem)."""
        return self.max_phi / self.phi - 1.0

    def lower_bound(self, m: int, sigma: float = 1.0) -> float:
        """Certified lower bound on O_t (eq. 16) for any plan of m poses."""
        return sigma**2 * self.phi_lower / m


def _info(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Per-pose information A^T A for poses q (..., n) [rad] -> (..., n, n)."""
    return pose_information(problem.rows(q))


def multiplicative(P: np.ndarray, W: np.ndarray, iters: int = 3000, tol: float = 1e-7, w0: np.ndarray | None = None):
    """Multiplicative algorithm for min trace(W M(w)^-1) over weights on a pool.

    P: (N, n, n) pool information matrices; W: (n, n); w0: starting weights (default uniform).
    Returns (w (N,), iterations used). Stops when max_i phi_i / Phi - 1 < tol (equivalence theorem on the pool).
    """
    N = P.shape[0]
    w = np.full(N, 1.0 / N) if w0 is None else np.asarray(w0, float) / np.sum(w0)
    it = 0
    n = P.shape[-1]
    P2 = P.reshape(N, n * n)  # matrix-vector products (BLAS) instead of einsum
    for it in range(1, iters + 1):
        M = (w @ P2).reshape(n, n)
        Phi, Minv = _phi_design(W, M)
        B = Minv @ W @ Minv
        phi = P2 @ B.T.ravel()
        if phi.max() / Phi - 1.0 < tol:
            break
        w = w * np.sqrt(np.maximum(phi, 0.0))
        w /= w.sum()
    return w, it


def _cluster(points: np.ndarray, weights: np.ndarray, radius: float):
    """Greedy clustering of weighted support points (rad, wrapped distances): heaviest first."""
    order = np.argsort(-weights, kind="stable")
    centers, masses = [], []
    for i in order:
        p = points[i]
        for c in range(len(centers)):
            d = angle_diff(p, centers[c])
            if np.all(np.abs(d) <= radius):
                masses[c] += weights[i]
                break
        else:
            centers.append(p.copy())
            masses.append(weights[i])
    return np.array(centers), np.array(masses)


def _polish_design(problem: Problem, W, X0: np.ndarray, w0: np.ndarray):
    """Jointly polish support poses X (k, n) [rad] and weights (softmax) to minimise Phi."""
    k, n = X0.shape

    def unpack(z):
        X = z[: k * n].reshape(k, n)
        logits = z[k * n:]
        w = np.exp(logits - logits.max())
        return X, w / w.sum()

    def f(z):
        X, w = unpack(z)
        M = np.einsum("k,kij->ij", w, _info(problem, X))
        try:
            val = float(np.trace(W @ np.linalg.inv(M)))
        except np.linalg.LinAlgError:
            return np.inf
        return val if np.isfinite(val) and val > 0 else np.inf

    z0 = np.concatenate([X0.ravel(), np.log(np.maximum(w0, 1e-12))])
    lims = problem.robot.joint_limits_rad
    bounds = [(None, None) if _is_full_turn(*lims[j % n]) else tuple(lims[j % n]) for j in range(k * n)]
    bounds += [(-30.0, 30.0)] * k
    res = minimize(f, z0, method="L-BFGS-B", bounds=bounds, options=dict(maxiter=500, ftol=1e-15, gtol=1e-12))
    if res.fun <= f(z0):
        return unpack(res.x)
    return X0, w0


def merge_support(X: np.ndarray, w: np.ndarray, tol_deg: float = 0.05, min_weight: float = 1e-6):
    """Merge support points closer than ``tol_deg`` on every joint (summing their weights) and drop
    weights below ``min_weight``; the design's information matrix changes only by that much.
    X: (k, n) [rad]; w: (k,). Returns (X, w) with w summing to 1."""
    keep = w >= min_weight
    C, m = _cluster(X[keep], w[keep], radius=np.radians(tol_deg))
    return C, m / m.sum()


def approximate_design(problem: Problem, pool_step_deg: float | None = None, search_step_deg: float | None = None,
                       iters: int = 300, min_mass: float = 0.02, vertex_steps: int = 6,
                       target_gap: float = 1e-7) -> ApproximateDesign:
    """Optimal approximate design for O_t of ``problem`` and its certified bound (module docstring).

    pool_step_deg: candidate grid step (default :func:`default_pool_step`); search_step_deg: grid step of
    the maximisation of phi over the whole joint space (default: the pool step, at most 2 deg);
    min_mass: clusters lighter than this are dropped before polishing; vertex_steps: at most this many
    times, the pose maximising phi joins the support and the design is re-polished (vertex direction)
    while the equivalence gap exceeds ``target_gap``.
    """
    robot = problem.robot
    step = pool_step_deg or default_pool_step(robot.n_joints)
    s_step = search_step_deg or min(step, 2.0)
    At = problem.At
    W = At.T @ At
    pool = candidate_pool(robot, step, problem)
    P = _info(problem, pool)
    check_identifiable(problem, P)
    if is_sampled(robot, step):
        return _sampled_design(problem, W, pool, P, iters, target_gap)
    w, it = multiplicative(P, W, iters)
    sig = w >= 1e-3 * w.max()
    X, m = _cluster(pool[sig], w[sig], radius=max(4 * np.radians(step), np.radians(8.0)))
    heavy = m >= min_mass * m.sum()
    X, wts = merge_support(*_polish_design(problem, W, X[heavy], m[heavy] / m[heavy].sum()))
    for _ in range(vertex_steps + 1):
        M = np.einsum("k,kij->ij", wts, _info(problem, X))
        Phi, Minv = _phi_design(W, M)
        xs, fs = global_minimise(_neg_phi(problem, Minv @ At.T), robot, s_step, n_refine=8)
        max_phi = max(-float(fs[0]), Phi)  # max_x phi >= Phi always (the mean of phi under xi is Phi)
        if max_phi / Phi - 1.0 <= target_gap:
            break
        keep = wts >= 1e-6
        X, wts = merge_support(*_polish_design(problem, W, np.vstack([X[keep], xs[:1]]),
                                               np.append(wts[keep] * 0.9, 0.1) / (wts[keep].sum() * 0.9 + 0.1)))
    order = np.argsort(-wts, kind="stable")
    return ApproximateDesign(wrap_deg(np.degrees(X[order])), wts[order], Phi, max_phi, Phi**2 / max_phi, it)


def _neg_phi(problem: Problem, C: np.ndarray):
    """q (..., n) [rad] -> -phi(q, xi) = -||A(q) M(xi)^-1 A_t^T||_F^2, with C = M(xi)^-1 A_t^T (n, d)."""
    def f(q):
        return -np.sum((problem.rows(q) @ C) ** 2, axis=(-2, -1))
    return f


def _max_phi(problem: Problem, W, X: np.ndarray, w: np.ndarray, n_refine: int, xatol: float):
    """(Phi(xi), max_x phi(x, xi), maximisers (k, n) [rad]) of the design (X, w), the maximum by
    :func:`stiffcal.design.sampled_minimise` started also from the support."""
    Phi, Minv = _phi_design(W, np.einsum("k,kij->ij", w, _info(problem, X)))
    xs, fs = sampled_minimise(_neg_phi(problem, Minv @ problem.At.T), problem.robot, n_refine, extra_starts=X,
                              xatol=xatol)
    return Phi, max(-float(fs[0]), Phi), xs


def _sampled_design(problem: Problem, W, pool: np.ndarray, P: np.ndarray, iters: int, target_gap: float,
                    rounds: int = 12, add: int = 4) -> ApproximateDesign:
    """The approximate design for 4+ joints (sampled joint space), by pool augmentation:

    1. multiplicative algorithm on a scrambled-Sobol pool of ``2**POOL_LOG2`` poses;
    2. the maximisers of phi(x, xi) over the joint space (Sobol sample + polish) join the pool and the
       multiplicative algorithm resumes from the current weights, until the equivalence gap is below
       ``target_gap`` or ``rounds`` are done (each round can only lower Phi);
    3. the support is merged and polished jointly (poses and weights), and the bound is computed from the
       final design with a fresh maximisation of phi.
    """
    w, it = multiplicative(P, W, iters)
    for _ in range(rounds):
        sup = w >= 1e-3 * w.max()
        Phi, max_phi, xs = _max_phi(problem, W, pool[sup], w[sup] / w[sup].sum(), 6, 1e-6)
        if max_phi / Phi - 1.0 <= target_gap:
            break
        pool = np.vstack([pool, xs[:add]])
        P = np.concatenate([P, _info(problem, xs[:add])])
        w, used = multiplicative(P, W, iters, w0=np.append(w, np.full(len(xs[:add]), 0.05 / add)))
        it += used
    keep = w >= 1e-4 * w.max()
    X, wts = merge_support(pool[keep], w[keep] / w[keep].sum(), tol_deg=2.0)
    X, wts = merge_support(*_polish_design(problem, W, X, wts))
    Phi, max_phi, _ = _max_phi(problem, W, X, wts, 16, 1e-10)
    order = np.argsort(-wts, kind="stable")
    return ApproximateDesign(wrap_deg(np.degrees(X[order])), wts[order], Phi, max_phi, Phi**2 / max_phi, it)
