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
So any design xi certifies how far any plan can be from optimal, and a good one nearly tightly. The maximum
over poses is over the whole joint space (:class:`PhiSearch`): an exhaustive grid with limits included for
up to 3 joints, else 2**15 scrambled-Sobol poses plus as many on the faces of the joint-limit box; the
best points, the best point of every one of ~729 cells of the joint space climbed by exact coordinate
ascent (phi is a trigonometric polynomial of degree 4 in each joint: :func:`coordinate_ascent`), and the
design's support are polished by Newton's method (:func:`newton_maximise`). The bound is as reliable as
that global maximisation; the tests compare it with independent random searches of 200,000-500,000 poses
and an independent design.

Algorithm (column generation with exact weights)
------------------------------------------------
1. multiplicative algorithm (Silvey-Titterington-Torsney; exponent 1/2, Yu 2010) for ``iters`` steps on a
   candidate pool (a grid over one symmetry cell of the joint space, or 8192 Sobol poses for 4+ joints);
   its heaviest poses start the support;
2. the optimal weights on the support (:func:`optimal_weights`, a projected Newton method: exact to
   the equivalence theorem on those poses), poses of zero weight dropped;
3. the local maxima of phi from the best search points and from every support pose join the support with
   weight 0 when above Phi (poses that coincide or carry the same information, e.g. symmetric copies,
   merge), and step 2 repeats: Phi never increases;
4. when the equivalence gap is at most ``target_gap`` (1e-6), a thorough search (more starts, climbing from
   every cell) confirms it; if it finds a higher maximum, step 3 goes on. The final search certifies.

A design counts as converged when its equivalence gap is at most :data:`EQUIVALENCE_TOL` (1e-3, the bound
then within 0.1 % of Phi*); otherwise the outputs label the bound as not converged (it still holds).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .problem import (SAMPLES_LOG2, Problem, angle_diff, grid_local_minima, into_limits, is_sampled, joint_grids,
                     joint_space_pool, sample_joint_space, _is_full_turn, _turn_start)
from ..model.robot import Robot
from ..model.stiffness import pose_information
from ..threads import single_threaded


#: candidate pool of a sampled joint space (4+ joints): 2**POOL_LOG2 scrambled-Sobol poses
POOL_LOG2 = 13


def has_planar_symmetry(robot: Robot, problem: Problem | None = None) -> bool:
    """Whether a pose's half-turn and mirror copies carry the same information (planar arm, no limits, and
    for ``problem`` no moment and no measured target beside the last link's line: :attr:`Problem.symmetric`)."""
    return robot.planar and robot.n_joints >= 2 and robot.cell is None and all(
        _is_full_turn(lo, hi) for lo, hi in robot.joint_limits_rad) and (problem is None or problem.symmetric)


def candidate_pool(robot: Robot, step_deg: float, problem: Problem | None = None) -> np.ndarray:
    """Candidate poses [rad], (N, n): a grid over the joint space, restricted to one symmetry cell
    (q1 in [-90, 90), first nonzero of q2..qn >= 0) when the arm is planar and every joint turns fully
    (both the half-turn and the mirror copy of a pose carry the same information). For 4+ joints
    (:func:`stiffcal.planning.problem.is_sampled`): ``2**POOL_LOG2`` scrambled-Sobol poses within the limits. With a
    candidate file (``problem.candidates``) its poses. In a cell (:mod:`stiffcal.model.workcell`) only the feasible
    poses (:meth:`stiffcal.planning.problem.Problem.feasible`); :class:`InputError` when none is."""
    if problem is not None and problem.candidates is not None:
        return _feasible_only(problem.candidates, robot, problem, "of the candidate file")
    q = joint_space_pool(robot, step_deg, POOL_LOG2)
    if is_sampled(robot, step_deg) or not has_planar_symmetry(robot, problem):
        return _feasible_only(q, robot, problem)
    eps = 1e-12
    rest = q[:, 1:]
    nz = np.abs(rest) > eps
    first = np.where(nz.any(1), rest[np.arange(len(q)), np.argmax(nz, axis=1)], 0.0)
    keep = (q[:, 0] >= -np.pi / 2 - eps) & (q[:, 0] < np.pi / 2 - eps) & (first >= -eps)
    return q[keep]


def _feasible_only(q: np.ndarray, robot: Robot, problem: Problem | None, what: str = "of the candidate pool"):
    """The poses q (N, n) [rad] the robot can take in its cell (all of them without a cell)."""
    if robot.cell is None:
        return q
    from ..errors import InputError
    from ..model.workcell import feasible, no_pose_reason

    ok = problem.feasible(q) if problem is not None else feasible(robot, q)
    if not ok.any():
        hint = no_pose_reason(robot, q, problem.hang_offset if problem is not None else None)
        raise InputError(f"none of the {len(q)} poses {what} can be taken in the cell ({robot.cell.describe()}): "
                         f"{hint}", source=robot.cell.source, field="cell")
    return q[ok]


def default_pool_step(n: int) -> float:
    """Grid step [deg] that keeps the pool near 10^4-10^5 poses: 2 deg for 2 joints, coarser beyond."""
    return float(max(2.0, np.ceil(360.0 / 120_000 ** (1.0 / n))))


def check_identifiable(problem: Problem, P: np.ndarray) -> None:
    """Raise :class:`InputError` when no plan over the joint space can identify every compliance with this
    force: the information summed over a pool covering the joint space (P: (N, n, n), its poses'
    information matrices) is singular. Names the joints of the
    combination that no pose excites (e.g. a vertical axis 1 under a vertical force: no torque about it)."""
    from ..errors import InputError
    from ..model.stiffness import spectral

    w, V, null = spectral(P.mean(axis=0))
    if not np.any(null) and w[0] > 1e-12 * w[-1]:
        return
    v = V[:, 0]
    joints = [problem.robot.joint_names[int(problem.params[j])]
              for j in np.flatnonzero(np.abs(v) > 0.1 * np.abs(v).max())]
    what = (f"the compliance of joint {joints[0]}" if len(joints) == 1 else
            "a combination of the compliances of joints " + ", ".join(map(str, joints)))
    load = (f"the loads {problem.loads.spec}" if problem.loads is not None else
            f"the force {problem.force.tolist()} N")
    why = "the loads never load it there (zero torque about that axis, or the same effect as other joints)"
    if problem.candidates is not None:  # a fresh user's one-pose candidate file was told to change the load
        rows = len(P) * problem.rows_per_pose * (1 if problem.loads is None else len(problem.loads.wrenches))
        where = (f"at the {len(P)} pose(s) of the candidate file (--candidates, `candidates`)"
                 + ("" if problem.robot.cell is None else " that the cell allows"))
        if rows < problem.n_params:
            where, why = f"{where}, {rows} equation(s) for {problem.n_params} compliances", "too few poses"
        cure = "give the candidate file more poses (of other configurations), or a load with another direction"
    else:
        where = "at any pose" if problem.robot.cell is None else "at any pose the cell allows"
        cure = "use a load with another direction"
    raise InputError(f"{what} cannot be identified with {load} {where}: {why}; {cure}", source=problem.robot.source)


#: eigenvalues of a design's information matrix below this fraction of its largest are zero to working precision
#: (its inverse has no correct digit along them: :func:`_phi_design`)
SINGULAR_RTOL = 1e-12
#: ... and below this one nearly so (:func:`_phi_design` with ``near``)
NEAR_SINGULAR_RTOL = 1e-8
#: the share of Phi the nearly singular directions W does not weigh may carry and still be left out of G
NEAR_SINGULAR_SHARE = 1e-4


def _phi_design(W: np.ndarray, M: np.ndarray, near: bool = False) -> tuple[float, np.ndarray]:
    """(Phi, G): Phi(xi) = trace(W G) of a design's information M (n, n), W (n, n) = A_t^T A_t, and G (n, n) the
    inverse of M that phi(x, xi) = ||A(x) G A_t^T||_F^2 uses. The certified bound Phi^2 / max_x phi holds with any
    G (Cauchy-Schwarz: for every design eta, trace(W G)^2 <= Phi(eta) sum_x eta(x) ||A(x) G A_t^T||^2;
    :meth:`ApproximateDesign.bound_with`); G is chosen to make it tight. G = M^-1, except where M is singular to
    working precision (eigenvalues at most :data:`SINGULAR_RTOL` of the largest) in directions W does not weigh
    (the test pose's deflection does not depend on them; e.g. the compliance of a joint that the test load does not
    turn, which the design then leaves unloaded): G is then the pseudo-inverse on the other directions. That is
    the design's Phi, taken as singular (a singular optimal design: Pukelsheim, *Optimal Design of Experiments*,
    1993, whose general equivalence theorem holds with a generalised inverse of M), where M^-1 has no correct digit
    along those directions and sends phi, and the bound, astray.

    With ``near`` also where M is nearly singular (eigenvalues at most :data:`NEAR_SINGULAR_RTOL` of the largest)
    in directions W does not weigh that carry at most :data:`NEAR_SINGULAR_SHARE` of Phi: a design that gives
    them ever less information gains ever less, while phi there, the slope, grows as 1 / eigenvalue^2 (a 7-axis
    arm under loads in its plane stopped at an equivalence gap of 1e6, its bound 1e-6 of the plan's; the second
    pass of :func:`approximate_design`)."""
    ev, V = np.linalg.eigh(M)
    if ev[-1] > 0:
        weight = np.einsum("ik,ij,jk->k", V, W, V)  # W's weight on each eigenvector
        negligible = SINGULAR_RTOL * float(np.trace(W))
        tiny = ev <= SINGULAR_RTOL * ev[-1]
        if near:
            drop = ev <= NEAR_SINGULAR_RTOL * ev[-1]
            share = float(np.sum(weight[drop & ~tiny] / ev[drop & ~tiny]))
            if drop.any() and weight[drop].sum() <= negligible and share <= NEAR_SINGULAR_SHARE * float(
                    np.sum(weight[~drop] / ev[~drop])):
                return _truncated(W, V, ev, drop)
        if tiny.any() and weight[tiny].sum() <= negligible:
            return _truncated(W, V, ev, tiny)
    Minv = np.linalg.inv(M)
    return float(np.trace(W @ Minv)), Minv


def _truncated(W: np.ndarray, V: np.ndarray, ev: np.ndarray, drop: np.ndarray) -> tuple[float, np.ndarray]:
    """(trace(W G), G): G the inverse of V diag(ev) V^T on the eigenvectors not dropped (``drop`` (n,) bool)."""
    G = (V[:, ~drop] / ev[~drop]) @ V[:, ~drop].T
    return float(np.trace(W @ G)), G


#: equivalence gap max_x phi / Phi - 1 up to which an approximate design counts as converged (its bound is
#: then within 0.1 % of the best possible, Phi* >= Phi (1 - gap))
EQUIVALENCE_TOL = 1e-3


@dataclass
class ApproximateDesign:
    """The optimal approximate design for O_t and its certificate.

    support_deg: (k, n) poses [deg]; weights: (k,) summing to 1; phi: Phi(xi) = trace(W M(xi)^-1)
    (O_t of one pose-equivalent with sigma = 1); max_phi: max over poses of phi(x, xi);
    phi_lower: the certified lower bound Phi(xi)^2 / max_phi on Phi*; iterations of step 1; near_singular: phi
    and Phi leave out the nearly singular directions the test pose does not need (:func:`_phi_design` with
    ``near``).
    """

    support_deg: np.ndarray
    weights: np.ndarray
    phi: float
    max_phi: float
    phi_lower: float
    iterations: int
    region: str = "joint space"
    n_candidates: int = 0
    near_singular: bool = False

    @property
    def exact_over_candidates(self) -> bool:
        """The maximum of phi (and so the bound) is over a finite set of feasible candidate poses, exactly (a cell
        or a candidate file), not over the whole joint space (:attr:`region` says which)."""
        return self.region != "joint space"

    def bound_with(self, problem: Problem, poses_rad: np.ndarray, m: int, sigma: float = 1.0) -> float:
        """The lower bound on O_t of m-pose plans over the candidate set with the poses ``poses_rad`` (k, n) added
        (a plan's own poses, polished off the candidates): phi's maximum taken over both."""
        X = np.radians(np.asarray(self.support_deg, float))
        M = np.einsum("k,kij->ij", np.asarray(self.weights, float), _info(problem, X))
        C = _phi_design(problem.At.T @ problem.At, M, self.near_singular)[1] @ problem.At.T
        extra = float(np.max(np.sum((problem.rows(np.atleast_2d(poses_rad)) @ C) ** 2, axis=(-2, -1)),
                             initial=0.0))
        return sigma**2 * self.phi**2 / max(self.max_phi, extra) / m

    @property
    def equivalence_gap(self) -> float:
        """max_x phi(x, xi) / Phi(xi) - 1: zero exactly at the optimum (equivalence theorem)."""
        return self.max_phi / self.phi - 1.0

    @property
    def converged(self) -> bool:
        """Whether the equivalence gap is within :data:`EQUIVALENCE_TOL`. The bound holds either way (for any
        design); when False it may be far below the best possible (the design is not near the optimum)."""
        return bool(self.equivalence_gap <= EQUIVALENCE_TOL)

    def convergence_note(self) -> str | None:
        """One sentence for the outputs when the design did not converge (None when it did)."""
        if self.converged:
            return None
        return (f"the optimal approximate design did not converge (equivalence gap {self.equivalence_gap:.2e} > "
                f"{EQUIVALENCE_TOL:g}): the lower bound is NOT CONVERGED; it still holds for every plan but may be "
                f"up to {100 * self.equivalence_gap / (1 + self.equivalence_gap):.2g} % below the best possible O_t")

    def near_singular_note(self) -> str:
        """One sentence for the outputs of a design whose phi leaves out nearly singular directions
        (:attr:`near_singular`)."""
        return (f"the optimal approximate design over the {self.region} leaves some compliances nearly unloaded "
                "that the test pose's deflection does not depend on (its information there at most "
                f"{NEAR_SINGULAR_RTOL:g} of its largest): its certificate leaves them out (phi with a generalised "
                f"inverse; at most {NEAR_SINGULAR_SHARE:g} of Phi), which gave a tighter bound than the plain inverse")

    def lower_bound(self, m: int, sigma: float = 1.0) -> float:
        """Certified lower bound on O_t (eq. 16) for any plan of m poses."""
        return sigma**2 * self.phi_lower / m


def _info(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Per-pose information A^T A for poses q (..., n) [rad] -> (..., n, n)."""
    return pose_information(problem.rows(q))


@functools.lru_cache(maxsize=None)
def _triu(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row and column indices of the upper triangle of an n x n matrix, row by row, and the weights
    (1 on the diagonal, 2 off it); computed once per n (:func:`vech` runs in every exchange step)."""
    i, j = np.triu_indices(n)
    return i, j, np.where(i == j, 1.0, 2.0)


def vech(M: np.ndarray) -> np.ndarray:
    """Upper-triangle entries of symmetric matrices (..., n, n) -> (..., n(n+1)/2), row by row."""
    i, j, _ = _triu(M.shape[-1])
    return M[..., i, j]


def _vech2(M: np.ndarray) -> np.ndarray:
    """:func:`vech` with doubled off-diagonal entries, so that ``trace(P B) = vech(P) . _vech2(B)``."""
    i, j, two = _triu(M.shape[-1])
    return M[..., i, j] * two


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


def _damped_newton_step(P: np.ndarray, w: np.ndarray, phi: np.ndarray, viol: np.ndarray, Phi: float,
                        Minv: np.ndarray, B: np.ndarray, mu: float, tol: float, value) -> tuple[np.ndarray, float, bool]:
    """One projected, Levenberg-Marquardt-damped Newton step of :func:`optimal_weights` with Armijo
    backtracking: (weights, damping mu, whether a step was accepted); mu grows by 100 after a failure (up to
    1e10) and shrinks by 10 after a full step."""
    k = len(w)
    drop = (w <= 1e-12) & (viol < 0)
    F = np.flatnonzero(~drop & ((w > 0) | (viol > tol)))
    H = 2.0 * (P[F] @ Minv).reshape(len(F), -1) @ np.swapaxes(P[F] @ B, -1, -2).reshape(len(F), -1).T
    H = 0.5 * (H + H.T)
    D = np.diag(np.maximum(np.diag(H), 1e-300))
    one = np.ones((len(F), 1))
    while mu < 1e10:
        step = np.zeros(k)
        K = np.block([[H + mu * D, one], [one.T, np.zeros((1, 1))]])
        try:
            step[F] = np.linalg.solve(K, np.append(phi[F], 0.0))[:len(F)]
        except np.linalg.LinAlgError:  # poses that add nothing make H singular: damp more
            mu *= 100
            continue
        for a in 0.5 ** np.arange(6):
            trial = np.where(drop, 0.0, np.maximum(w + a * step, 0.0))
            trial /= trial.sum()
            decrease = phi @ trial - Phi  # first-order decrease of Phi towards trial
            if decrease > 0 and value(trial) <= Phi - 1e-4 * decrease:
                return trial, (mu / 10 if a == 1.0 else mu), True
        mu *= 100
    return w, mu, False


def optimal_weights(P: np.ndarray, W: np.ndarray, w0: np.ndarray | None = None, tol: float = 1e-9,
                    max_iter: int = 500, near: bool = False) -> np.ndarray:
    """The optimal weights of an approximate design on a fixed set of k poses: min ``Phi(w) =
    trace(W M(w)^-1)``, ``M(w) = sum_i w_i P_i``, over the simplex (a convex problem).

    Projected Newton method with Levenberg-Marquardt damping (Bertsekas 1982; Newton steps for design
    weights: Yang, Biedermann & Tang 2013, JASA 108:1411): on the poses of positive weight and those with
    ``phi_i > Phi`` (which would gain weight), the step under ``sum w = 1`` with the exact gradient
    ``-phi_i = -trace(P_i B)``, ``B = M^-1 W M^-1``, and Hessian ``H_ij = 2 trace(P_i M^-1 P_j B)`` plus
    ``mu diag(H)``, projected onto ``w >= 0`` (a pose of tiny weight and ``phi_i < Phi`` drops to 0) and
    accepted by backtracking (Armijo); mu shrinks after full steps and grows after failures, so the step
    turns from Newton's into a scaled gradient step where the quadratic model fails (near-duplicate poses
    make H nearly singular). Where no step lowers Phi, a vertex-direction step (Fedorov-Wynn) towards the
    pose of largest phi_i with an exact line search. Stops when ``max_i phi_i / Phi - 1 <= tol`` (the
    equivalence theorem on the k poses) or when no step lowers Phi (round-off).

    P: (k, n, n); W: (n, n); w0: (k,) starting weights (default uniform; M(w0) must be nonsingular); near: Phi
    as :func:`_phi_design` with ``near`` gives it. Returns w (k,), summing to 1.
    """
    from scipy.optimize import minimize_scalar

    k, n = P.shape[0], P.shape[-1]
    P2 = P.reshape(k, n * n)
    w = np.full(k, 1.0 / k) if w0 is None else np.maximum(np.asarray(w0, float), 0.0) / np.sum(w0)

    def value(v):
        try:
            val = _phi_design(W, (v @ P2).reshape(n, n), near)[0]
        except np.linalg.LinAlgError:
            return np.inf
        return val if np.isfinite(val) and val > 0 else np.inf

    mu = 1e-8
    for _ in range(max_iter):
        Phi, Minv = _phi_design(W, (w @ P2).reshape(n, n), near)
        B = Minv @ W @ Minv
        phi = P2 @ B.ravel()
        viol = phi / Phi - 1.0
        if viol.max() <= tol:
            break
        w, mu, accepted = _damped_newton_step(P, w, phi, viol, Phi, Minv, B, mu, tol, value)
        if not accepted:
            e = -w.copy()
            e[int(np.argmax(phi))] += 1.0
            with np.errstate(invalid="ignore", over="ignore"):  # Phi = inf where M is singular: inf - inf inside
                res = minimize_scalar(lambda t: value(w + t * e), bounds=(0.0, 1.0), method="bounded",
                                      options=dict(xatol=1e-12))
            if not res.fun < Phi:
                break
            w = np.maximum(w + float(res.x) * e, 0.0)
            w /= w.sum()
            mu = 1e-8
    return w


def _ascent_step(v: np.ndarray, h: float, n: int, pi: np.ndarray, pj: np.ndarray, Xa: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray) -> np.ndarray:
    """Newton's ascent step (k, n) of :func:`newton_maximise` from the function's values ``v`` (k, 1 + 2n + 2 n(n-1)/2)
    on the central-difference stencil (step ``h``; ``pi``, ``pj`` the pairs of the mixed differences): the
    Hessian's eigenvalues made negative, the joints at a limit with the gradient pointing out held."""
    npair = len(pi)
    f0, fp, fm = v[:, 0], v[:, 1:1 + n], v[:, 1 + n:1 + 2 * n]
    pp, mm = v[:, 1 + 2 * n:1 + 2 * n + npair], v[:, 1 + 2 * n + npair:]
    g = (fp - fm) / (2 * h)
    H = np.empty((len(v), n, n))
    H[:, np.arange(n), np.arange(n)] = (fp - 2 * f0[:, None] + fm) / h**2
    off = (pp + mm - fp[:, pi] - fm[:, pi] - fp[:, pj] - fm[:, pj] + 2 * f0[:, None]) / (2 * h**2)
    H[:, pi, pj] = off
    H[:, pj, pi] = off
    held = ((Xa <= lo + 1e-12) & (g < 0)) | ((Xa >= hi - 1e-12) & (g > 0))
    g = np.where(held, 0.0, g)
    H = np.where(held[:, :, None] | held[:, None, :], 0.0, H)
    H[:, np.arange(n), np.arange(n)] = np.where(held, -1.0, H[:, np.arange(n), np.arange(n)])
    lam, Vec = np.linalg.eigh(H)
    lam = np.maximum(np.abs(lam), 1e-10 * np.abs(lam).max(axis=1, keepdims=True) + 1e-300)
    return np.einsum("kij,kj->ki", Vec, np.einsum("kji,kj->ki", Vec, g) / lam)


def newton_maximise(fun, robot: Robot, X0: np.ndarray, h: float = 1e-4, max_iter: int = 100,
                    xtol: float = 1e-9, drop_below: float = -np.inf, feasible=None):
    """Local maxima of a smooth batched function ``fun`` (q (k, n) [rad] -> (k,)) from every start X0 (k, n)
    at once: Newton's method with central-difference gradient and Hessian (1 + n^2 evaluations per start and
    step, in one call of ``fun``), the Hessian's eigenvalues made negative (ascent), a trust radius per
    start, within the joint limits (projected: a joint at a limit with the gradient pointing out is held).
    Joints with a full turn of range are free. A start stops at a step shorter than ``xtol`` [rad] (the value
    is then exact to about its square), after 4 steps while below ``drop_below``, or when it comes within
    1e-3 rad (every joint) of another start still climbing (which goes on to their common maximum). With
    ``feasible`` (q (k, n) -> (k,) bool, a cell), a step to a pose that cannot be taken is refused like one that
    does not climb (the trust radius shrinks), so every start stays feasible. Returns (X (k, n),
    f (k,)) in the order of X0, each never worse than its start.
    """
    X = np.array(X0, float)
    k, n = X.shape
    lims = robot.joint_limits_rad
    free = np.array([_is_full_turn(lo, hi) for lo, hi in lims])
    lo = np.where(free, -np.inf, lims[:, 0])
    hi = np.where(free, np.inf, lims[:, 1])
    X = np.clip(X, lo, hi)
    E = h * np.eye(n)
    pi, pj = np.triu_indices(n, 1)
    stencil = np.vstack([np.zeros(n), E, -E, E[pi] + E[pj], -(E[pi] + E[pj])])
    f = np.asarray(fun(X), float)
    radius = np.full(k, 0.5)
    active = np.isfinite(f)
    for it in range(max_iter):
        if it == 4:
            active &= f >= drop_below
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        Xa = X[idx]
        v = np.asarray(fun((Xa[:, None, :] + stencil).reshape(-1, n)), float).reshape(len(idx), -1)
        f0 = v[:, 0]
        step = _ascent_step(v, h, n, pi, pj, Xa, lo, hi)
        norm = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, radius[idx] / np.maximum(norm, 1e-300))[:, None]
        Xn = np.clip(Xa + step, lo, hi)
        moved = np.linalg.norm(Xn - Xa, axis=1)
        fn = np.asarray(fun(Xn), float)
        better = fn > f0
        if feasible is not None and better.any():
            better[better] = feasible(Xn[better])
        X[idx[better]] = Xn[better]
        f[idx[better]] = fn[better]
        radius[idx] = np.where(better, np.maximum(radius[idx], 2 * moved), radius[idx] / 4)
        active[idx[(moved < xtol) | (radius[idx] < 1e-12)]] = False
        idx = np.flatnonzero(active)  # starts that met another one on the way up follow it no further
        active[idx[_meets_earlier(X[idx], 1e-3)]] = False
    return X, f


def _meets_earlier(X: np.ndarray, tol: float) -> np.ndarray:
    """Indices j of the poses X (k, n) [rad] within ``tol`` (every joint, modulo 2 pi) of some X[i], i < j:
    the pairs close on the first joint are found first, then checked on all."""
    i, j = np.nonzero(np.triu(np.abs(angle_diff(X[:, None, 0], X[None, :, 0])) < tol, 1))
    return np.unique(j[np.all(np.abs(angle_diff(X[i], X[j])) < tol, axis=1)])


class PhiSearch:
    """The global maximisation of ``phi(x, xi) = ||A(x) M(xi)^-1 A_t^T||_F^2`` over the whole joint space,
    behind the certificate (module docstring).

    phi is evaluated at every node of a grid over the joint space (:func:`stiffcal.planning.problem.joint_grids` at
    ``step_deg``, limits included) or, where that grid would be too large (:func:`stiffcal.planning.problem.is_sampled`),
    at ``2**15`` scrambled-Sobol poses plus, for joints with limits, as many poses on the faces of the box:
    the same poses with each limited joint moved to its lower or upper limit with probability 1/6 each (the
    maxima of phi often lie on the limits, where a sample of the interior is thin). The pose information
    matrices there are computed once, so each evaluation is one matrix-vector product. The best grid local
    maxima (or best samples, from each of the two samples, at least 10 deg apart) and any extra starts are
    polished by :func:`newton_maximise`.
    """

    def __init__(self, problem: Problem, step_deg: float):
        robot = problem.robot
        self.problem, self.robot = problem, robot
        self.sampled = is_sampled(robot, step_deg)
        if self.sampled:
            Q = sample_joint_space(robot, SAMPLES_LOG2, seed=1)
            lo, hi = robot.joint_limits_rad.T
            limited = ~np.array([_is_full_turn(a, b) for a, b in robot.joint_limits_rad])
            groups = [Q]
            if limited.any():
                u = np.random.default_rng(2).uniform(size=Q.shape)
                groups.append(np.where(limited & (u < 1 / 6), lo, np.where(limited & (u > 5 / 6), hi, Q)))
            self.Q = np.vstack(groups)
            self.group = np.repeat(np.arange(len(groups)), len(Q))
            self.shape = None
        else:
            grids = joint_grids(robot, step_deg)
            self.shape = tuple(len(g) for g in grids)
            self.Q = np.stack(np.meshgrid(*grids, indexing="ij"), -1).reshape(-1, robot.n_joints)
            self.group = np.zeros(len(self.Q), int)
        self.V = np.concatenate([vech(_info(problem, self.Q[i:i + 8192])) for i in range(0, len(self.Q), 8192)])
        # in a cell: which search points the robot can take (1, 0; -1 not checked yet: a sample is checked lazily,
        # best points first, since only the best feasible ones are used)
        self.ok = None
        if robot.cell is not None:
            self.ok = np.full(len(self.Q), -1, np.int8)
            if not self.sampled:
                self.ok[:] = problem.feasible(self.Q)

    def feasible_in_order(self, order: np.ndarray, count: int) -> np.ndarray:
        """The first ``count`` indices of ``order`` (into the search points) whose poses are feasible, checked
        lazily in chunks; every index of ``order`` without a cell."""
        order = np.asarray(order, int)
        if self.ok is None:
            return order[:count]
        out, pos = [], 0
        while len(out) < count and pos < len(order):
            chunk = order[pos:pos + 512]
            pos += 512
            unknown = chunk[self.ok[chunk] < 0]
            if unknown.size:
                self.ok[unknown] = self.problem.feasible(self.Q[unknown])
            out.extend(chunk[self.ok[chunk] == 1][:count - len(out)].tolist())
        return np.array(out, int)

    def max_feasible(self, phi: np.ndarray) -> float:
        """The largest phi over the feasible search points."""
        best = self.feasible_in_order(np.argsort(-phi, kind="stable"), 1)
        return float(phi[best[0]]) if best.size else -np.inf

    def cell_best(self, phi: np.ndarray, cells: int = 729) -> np.ndarray:
        """Indices of the search point of largest phi in each cell of a partition of the joint space into about
        ``cells`` boxes (equal bins of every joint's range): starts spread over the whole joint space."""
        lo, hi = self.robot.joint_limits_rad.T
        n = self.robot.n_joints
        bins = max(2, int(np.floor(cells ** (1.0 / n) + 1e-9)))
        span = np.minimum(hi - lo, 2 * np.pi)
        start = np.where(hi - lo > 2 * np.pi, _turn_start(lo, hi), lo)
        b = np.clip(np.floor(np.mod(self.Q - start, 2 * np.pi) / span * bins), 0, bins - 1).astype(int)
        cell = b @ bins ** np.arange(n)
        order = np.lexsort((-phi, cell))
        return order[np.r_[True, cell[order][1:] != cell[order][:-1]]]

    def starts(self, phi: np.ndarray, n_refine: int, min_separation_deg: float = 10.0) -> np.ndarray:
        """The starting poses (k, n) [rad] for the polish, from phi at every search point."""
        if not self.sampled:
            periodic = [_is_full_turn(lo, hi) for lo, hi in self.robot.joint_limits_rad]
            if self.ok is not None:
                phi = np.where(self.ok == 1, phi, -np.inf)
            mask = grid_local_minima(-phi.reshape(self.shape), periodic).ravel()
            cand = np.flatnonzero(mask)
            return self.Q[cand[np.argsort(-phi[cand], kind="stable")[:n_refine]]]
        chosen = []
        sep = np.radians(min_separation_deg)
        groups = np.unique(self.group)
        per = -(-n_refine // len(groups))
        for k in groups:
            idx = np.flatnonzero(self.group == k)
            cand = self.Q[self.feasible_in_order(idx[np.argsort(-phi[idx], kind="stable")], 8 * per)]
            mine: list[int] = []
            for i in range(len(cand)):  # greedily, each more than sep from every one taken (on some joint)
                if len(mine) == per:
                    break
                if np.any(np.abs(angle_diff(cand[i], cand[mine])) > sep, axis=-1).all():
                    mine.append(i)
            chosen.append(cand[mine])
        return np.vstack(chosen)

    def maximise(self, Minv: np.ndarray, extra_starts: np.ndarray, n_refine: int = 32, climb: int = 0,
                 n_climbed: int = 64, xtol: float = 1e-9, drop_below: float = -np.inf):
        """Polished local maxima of phi for a design with ``M(xi)^-1 = Minv``: Newton (:func:`newton_maximise`)
        from the ``n_refine`` best search points, from ``extra_starts`` (k, n) [rad] and, with ``climb`` > 0,
        from the ``n_climbed`` best distinct results of ``climb`` sweeps of :func:`coordinate_ascent` started
        at the best search point of every cell of :meth:`cell_best` and at the extra starts; xtol, drop_below: see :func:`newton_maximise`. Returns (xs, phi)
        of the search-point starts (best first), then (xs, phi) of the extra starts (in their order)."""
        C = Minv @ self.problem.At.T
        phi = self.V @ _vech2(C @ C.T)
        starts = self.starts(phi, n_refine)
        extra = np.atleast_2d(extra_starts).reshape(-1, self.robot.n_joints)
        rows = self.problem.rows
        feasible = None
        if self.ok is not None:  # in a cell: no climbing (it does not know the cell), Newton steps stay feasible
            climb, feasible = 0, self.problem.feasible

        def fun(q):
            return np.sum((rows(q) @ C) ** 2, axis=(-2, -1))
        if climb:
            Xc, fc = coordinate_ascent(fun, self.robot, np.vstack([self.Q[self.cell_best(phi)], extra]),
                                       sweeps=int(climb))
            _, first = np.unique(np.round(np.degrees(Xc)), axis=0, return_index=True)
            first = first[np.argsort(-fc[first], kind="stable")[:n_climbed]]
            starts = np.vstack([starts, Xc[first]])
        X, f = newton_maximise(fun, self.robot, np.vstack([starts, extra]), xtol=xtol, drop_below=drop_below,
                               feasible=feasible)
        k = len(starts)
        order = np.argsort(-f[:k], kind="stable")
        return X[:k][order], f[:k][order], X[k:], f[k:]


def coordinate_ascent(fun, robot: Robot, X0: np.ndarray, sweeps: int = 2, step_deg: float = 0.5):
    """Exact coordinate ascent of phi from every start X0 (k, n) [rad] at once: each joint in turn is set to
    the global maximum of phi along that joint within its range.

    phi is a trigonometric polynomial of degree at most 4 in each joint angle: turning joint j rotates every
    axis and point beyond it rigidly, so the Jacobian is linear in ``(cos q_j, sin q_j)``, the observation
    matrix ``A = J diag(J^T F)`` quadratic and ``phi = ||A C||_F^2`` quartic. Nine equally spaced values
    therefore determine phi along the joint exactly (a discrete Fourier transform), and its maximum over the
    joint's range (one turn for full-turn joints) is taken on a ``step_deg`` grid of that exact polynomial
    (the current angle included, so phi never decreases). fun: q (k, n) [rad] -> (k,).
    Returns (X (k, n), phi (k,)).
    """
    X = np.array(X0, float)
    k, n = X.shape
    theta = 2 * np.pi * np.arange(9) / 9
    harmonics = np.arange(5)
    lims = robot.joint_limits_rad
    for _ in range(sweeps):
        for j in range(n):
            lo, hi = lims[j]
            if _is_full_turn(lo, hi):
                start = float(_turn_start(lo, hi))
                grid = start + np.radians(np.arange(0.0, 360.0, step_deg))
            else:
                grid = np.linspace(lo, hi, int(np.ceil(np.degrees(hi - lo) / step_deg)) + 1)
            Q = np.repeat(X[:, None, :], 9, axis=1)
            Q[:, :, j] = theta
            c = np.fft.rfft(np.asarray(fun(Q.reshape(-1, n)), float).reshape(k, 9), axis=1) / 9
            h = harmonics[1:, None]
            vals = c[:, :1].real + 2 * (c[:, 1:].real @ np.cos(h * grid) - c[:, 1:].imag @ np.sin(h * grid))
            now = c[:, 0].real + 2 * np.sum(c[:, 1:].real * np.cos(h.T * X[:, j:j + 1])
                                            - c[:, 1:].imag * np.sin(h.T * X[:, j:j + 1]), axis=1)
            best = np.argmax(vals, axis=1)
            X[:, j] = np.where(vals[np.arange(k), best] > now, grid[best], X[:, j])
    return X, np.asarray(fun(X), float)


@single_threaded
def approximate_design(problem: Problem, pool_step_deg: float | None = None, search_step_deg: float | None = None,
                       iters: int = 100, target_gap: float = 1e-6, max_rounds: int = 60, n_refine: int = 16,
                       n_certify: int = 256) -> ApproximateDesign:
    """Optimal approximate design for O_t of ``problem`` and its certified bound (module docstring).

    pool_step_deg: candidate grid step of the starting pool (default :func:`default_pool_step`);
    search_step_deg: grid step of the maximisation of phi over the whole joint space (default: the pool
    step, at most 2 deg; 4+ joints sample it instead); iters: multiplicative iterations on the pool;
    target_gap: stop when the equivalence gap is at most this; max_rounds: at most this many rounds of
    optimal weights + global maximisation of phi; n_refine: search points polished in each round;
    n_certify: search points polished in the thorough search that certifies the final design (and confirms
    that the target gap is reached), which also climbs from every cell of the joint space
    (:meth:`PhiSearch.maximise` with ``climb``).

    In a cell (:mod:`stiffcal.model.workcell`) the design is over the poses the robot can take: the feasible pool,
    the feasible search points and the maxima of phi reached from them by Newton steps that stay feasible (no
    climbing: the coordinate ascent does not know the cell); its maximum of phi, and so its bound, is exact over
    that finite set of feasible candidates (``region``), not over the feasible continuum (a plan of other feasible
    poses may do better; the bound over the whole joint space, :func:`unconstrained`, holds for every plan).
    With a candidate file (``problem.candidates``) the design is over those poses alone, and the bound exact
    for every plan of them (:func:`_candidate_design`).
    """
    robot = problem.robot
    step = pool_step_deg or default_pool_step(robot.n_joints)
    At = problem.At
    W = At.T @ At
    pool = candidate_pool(robot, step, problem)
    P = _info(problem, pool)
    check_identifiable(problem, P)
    if not problem.continuous:
        return _candidate_design(problem, pool, P, W, target_gap, max_rounds)
    search = PhiSearch(problem, search_step_deg or min(step, 2.0))
    if robot.cell is not None:
        return _feasible_design(problem, pool, P, W, search, iters, max(target_gap, FEASIBLE_TARGET_GAP), max_rounds)
    w, it = multiplicative(P, W, iters)
    top = np.argsort(-w, kind="stable")[:MAX_START_SUPPORT]
    top = top[w[top] >= 1e-3 * w[top[0]]]
    rounds = functools.partial(_column_generation, problem, W, search, target_gap=target_gap, max_rounds=max_rounds,
                               n_refine=n_refine, n_certify=n_certify)

    def design(X, P, w, near=False):
        X, w, Phi, gap = rounds(X, P, w, near=near)
        return _design_of(robot, X, w, Phi, Phi * (1.0 + gap), it, near_singular=near)
    return _second_pass(problem, W, design(pool[top], P[top], w[top] / w[top].sum()), design)


def _second_pass(problem: Problem, W: np.ndarray, first: ApproximateDesign, design) -> ApproximateDesign:
    """``first``, or where it did not converge and leaves directions the test pose does not need nearly singular
    (:func:`_phi_design` with ``near``), the design of a second pass from its support (``design(X (k, n) [rad],
    P (k, n, n), w (k,), near=True)``, phi without the slope of those directions) when its bound is higher."""
    X = np.radians(first.support_deg)
    if first.converged or not _nearly_singular(W, problem, X, first.weights):
        return first
    second = design(X, _info(problem, X), first.weights, near=True)
    return second if second.phi_lower > first.phi_lower else first


def _design_of(robot: Robot, X: np.ndarray, w: np.ndarray, Phi: float, max_phi: float, it: int,
               *args, **kwargs) -> ApproximateDesign:
    """The :class:`ApproximateDesign` of the support X (k, n) [rad] with weights w (k,), its Phi and max_x phi (its
    bound Phi^2 / max_phi); further arguments as the class's after ``iterations``."""
    return ApproximateDesign(into_limits(robot, np.degrees(X)), w, Phi, max_phi, Phi**2 / max_phi, it, *args,
                             **kwargs)


def _nearly_singular(W: np.ndarray, problem: Problem, X: np.ndarray, w: np.ndarray) -> bool:
    """Whether the design of poses X (k, n) [rad] and weights w (k,) has nearly singular directions that W does not
    weigh (:func:`_phi_design` leaves them out with ``near`` and not without)."""
    M = np.einsum("k,kij->ij", w, _info(problem, X))
    return _phi_design(W, M, True)[0] != _phi_design(W, M)[0]


def _column_generation(problem: Problem, W: np.ndarray, search: "PhiSearch", X: np.ndarray, PS: np.ndarray,
                       wS: np.ndarray, target_gap: float, max_rounds: int, n_refine: int, n_certify: int,
                       near: bool = False):
    """The rounds of :func:`approximate_design` from the support X (k, n) [rad] (information PS (k, n, n)) with
    weights wS (k,): optimal weights, then the maxima of phi over the joint space join the support, until the
    equivalence gap is at most ``target_gap`` or ``max_rounds``; with ``near`` (:func:`_phi_design`) also when Phi
    stalls (:func:`_stalled`) far from the optimum after a thorough search. Returns (X, w, Phi, gap), the support
    by falling weight."""
    early, history, stalls = False, [], 0
    for rnd in range(max_rounds):
        wS = optimal_weights(PS, W, wS, near=near)
        keep = wS > MIN_WEIGHT
        X, PS, wS = X[keep], PS[keep], wS[keep] / wS[keep].sum()
        Phi, Minv = _phi_design(W, np.einsum("k,kij->ij", wS, PS), near)
        history.append(Phi)
        found = search.maximise(Minv, X, n_refine, climb=int(rnd == 0), xtol=1e-5, drop_below=0.8 * Phi)
        gap = _gap(found, Phi)
        # the thorough search certifies the final design (and confirms the target gap); a lighter one runs once
        # as soon as the design is near optimal, to bring in the regions the quick searches missed, and a thorough
        # one where Phi stalls far from the optimum (up to MAX_STALLS times)
        last = gap <= target_gap or rnd == max_rounds - 1
        stall = near and gap > EQUIVALENCE_TOL and _stalled(history)
        if last or stall or (gap <= EQUIVALENCE_TOL and not early):
            early = True
            found = search.maximise(Minv, X, n_certify if last or stall else 4 * n_refine,
                                    climb=2 if last or stall else 1, drop_below=0.5 * Phi)
            gap = _gap(found, Phi)
            stalls += stall
            if gap <= target_gap or rnd == max_rounds - 1 or stalls > MAX_STALLS:
                break
            history = [] if stall else history
        X, wS, PS = _grow_support(problem, W, X, wS, Phi, found, near)
    order = np.argsort(-wS, kind="stable")
    return X[order], wS[order], Phi, gap


#: rounds over which Phi falling by less than STALL_RTOL of itself counts as a stall (:func:`_column_generation`
#: with ``near``), and the thorough searches after stalls before the design ends there (its bound holds, with the
#: note that it did not converge)
STALL_ROUNDS = 5
STALL_RTOL = 1e-9
MAX_STALLS = 2


def _stalled(history: list[float]) -> bool:
    """Whether Phi (``history``, one value a round) fell by less than :data:`STALL_RTOL` of itself over the last
    :data:`STALL_ROUNDS` rounds: the poses that join the support no longer lower it."""
    return len(history) > STALL_ROUNDS and history[-1 - STALL_ROUNDS] - history[-1] < STALL_RTOL * history[-1]


def _grow_support(problem: Problem, W: np.ndarray, X: np.ndarray, wS: np.ndarray, Phi: float,
                  found, singular: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X, w, P) of the support after a search of phi (``found``: :meth:`PhiSearch.maximise`'s grid and local
    maxima): a support pose whose maximum of phi is near (within MOVE_DEG) moves there when that lowers Phi at
    the same weights; the other maxima above Phi (at most MAX_NEW, the highest) join with weight 0 (the weights
    step brings them in); poses that coincide or carry the same information merge. ``singular``: Phi as
    :func:`_phi_design` with ``near`` gives it."""
    xg, fg, xm, fm = found
    near = np.all(np.abs(angle_diff(xm, X)) <= np.radians(MOVE_DEG), axis=1)
    moved = np.where(near[:, None], xm, X)
    P_moved = _info(problem, moved)
    if _phi_design(W, np.einsum("k,kij->ij", wS, P_moved), singular)[0] < Phi:
        X, fm = moved, np.where(near, -np.inf, fm)
    xs, fs = np.vstack([xm, xg]), np.concatenate([fm, fg])
    best = np.argsort(-fs, kind="stable")[:MAX_NEW]
    new = xs[best[fs[best] > Phi]]
    X, wS = _merge(problem, np.vstack([X, new]), np.append(wS, np.zeros(len(new))))
    return X, wS, _info(problem, X)


def _feasible_design(problem: Problem, pool: np.ndarray, P: np.ndarray, W: np.ndarray, search: "PhiSearch",
                     iters: int, target_gap: float, max_rounds: int, n_refine: int = 24) -> ApproximateDesign:
    """The optimal approximate design over the poses a cell allows (column generation with exact weights, as
    :func:`approximate_design`, on a candidate set that stays feasible): the candidates are the feasible pool
    poses, the feasible search points (:class:`PhiSearch`: a grid, or 2**15 Sobol poses and as many on the faces
    of the joint-limit box; checked lazily, best phi first, so that only the few that matter are checked) and
    every local maximum of phi reached from the best of them and from the support by Newton steps that stay
    feasible (:func:`newton_maximise` with ``feasible``). phi is known at every candidate exactly (the pool's and
    the search points' information computed once), so the maximum over them, and the bound, is exact for every
    plan of these poses (:meth:`ApproximateDesign.bound_with` adds a plan's own, polished, poses); a plan of
    other feasible poses could do better (the feasible continuum is not searched exhaustively: no climbing,
    which does not know the cell)."""
    w, it = multiplicative(P, W, iters)
    top = np.argsort(-w, kind="stable")[:MAX_START_SUPPORT]
    top = top[w[top] >= 1e-3 * w[top[0]]]
    rounds = functools.partial(_feasible_rounds, problem, pool, P, W, search, target_gap=target_gap,
                               max_rounds=max_rounds, n_refine=n_refine)

    def design(X, P, w, near=False):
        X, w, Phi, top_max, n_found = rounds(X, P, w, near=near)
        return _design_of(problem.robot, X, w, Phi, top_max, it, "feasible candidates",
                          len(pool) + len(search.Q) + n_found, near_singular=near)
    return _second_pass(problem, W, design(pool[top], P[top], w[top] / w[top].sum()), design)


def _feasible_rounds(problem: Problem, pool: np.ndarray, P: np.ndarray, W: np.ndarray, search: "PhiSearch",
                     X: np.ndarray, PS: np.ndarray, wS: np.ndarray, target_gap: float, max_rounds: int, n_refine: int,
                     near: bool = False):
    """The rounds of :func:`_feasible_design` from the support X (k, n) [rad] (information PS (k, n, n)) with
    weights wS (k,); ``near`` as :func:`_phi_design`'s (and then ending once Phi stalls, :func:`_stalled`).
    Returns (X, w, Phi, the largest phi over the candidates, the number of maxima of phi found), the support by
    falling weight."""
    robot, n = problem.robot, problem.robot.n_joints
    P2 = P.reshape(len(P), -1)
    found = np.zeros((0, n))  # the maxima of phi found so far: candidates too
    rows, history = problem.rows, []
    for _ in range(max_rounds):
        wS = optimal_weights(PS, W, wS, near=near)
        keep = wS > MIN_WEIGHT
        X, PS, wS = X[keep], PS[keep], wS[keep] / wS[keep].sum()
        Phi, Minv = _phi_design(W, np.einsum("k,kij->ij", wS, PS), near)
        history.append(Phi)
        B = Minv @ W @ Minv
        C = Minv @ problem.At.T

        def fun(q, C=C):
            return np.sum((rows(q) @ C) ** 2, axis=(-2, -1))

        phi_pool = P2 @ B.ravel()
        phi_q = search.V @ _vech2(B)
        best_q = search.feasible_in_order(np.argsort(-phi_q, kind="stable"), MAX_NEW)
        best_p = np.argsort(-phi_pool, kind="stable")[:MAX_NEW]
        cand = np.vstack([pool[best_p], search.Q[best_q], found]).reshape(-1, n)
        fc = np.concatenate([phi_pool[best_p], phi_q[best_q], fun(found) if len(found) else np.zeros(0)])
        starts = cand[np.argsort(-fc, kind="stable")[:n_refine]]
        xm, fm = newton_maximise(fun, robot, np.vstack([starts, X]), xtol=1e-6, drop_below=0.8 * Phi,
                                 feasible=problem.feasible)
        up = fm > Phi * (1 + 1e-9)
        if up.any():  # the new maxima join the candidates; the best MAX_FOUND of them (by phi now) are kept
            found = np.vstack([xm[up], found])
            found = found[np.r_[True, ~_meets_earlier_mask(found, 1e-6)[1:]]] if len(found) > 1 else found
            if len(found) > MAX_FOUND:
                found = found[np.argsort(-fun(found), kind="stable")[:MAX_FOUND]]
        top_max = max(float(phi_pool.max()), float(phi_q[best_q[0]]) if best_q.size else -np.inf,
                      float(fm.max(initial=-np.inf)), float(fc.max(initial=-np.inf)), Phi)
        if top_max / Phi - 1.0 <= target_gap or (near and _stalled(history)):
            break
        xs, fs = np.vstack([cand, xm]), np.concatenate([fc, fm])
        pick = np.argsort(-fs, kind="stable")[:MAX_NEW]
        new = xs[pick[fs[pick] > Phi]]
        X, wS = _merge(problem, np.vstack([X, new]), np.append(wS, np.zeros(len(new))))
        PS = _info(problem, X)
    order = np.argsort(-wS, kind="stable")
    return X[order], wS[order], Phi, top_max, len(found)


def _meets_earlier_mask(X: np.ndarray, tol: float) -> np.ndarray:
    """(k,) bool: poses X (k, n) [rad] within ``tol`` (every joint, modulo 2 pi) of an earlier one."""
    out = np.zeros(len(X), bool)
    out[_meets_earlier(X, tol)] = True
    return out


def _candidate_design(problem: Problem, pool: np.ndarray, P: np.ndarray, W: np.ndarray, target_gap: float,
                      max_rounds: int) -> ApproximateDesign:
    """The optimal approximate design over a finite set of candidate poses (a candidate file): the
    multiplicative algorithm on the whole set, then exact weights on its support with the candidates of
    largest phi brought in (column generation) until the equivalence gap over the set, computed at every
    candidate, is at most ``target_gap``. The bound is exact for every plan of these poses."""
    P2 = P.reshape(len(P), -1)
    w, it = multiplicative(P, W, 3000, tol=target_gap)
    top = np.argsort(-w, kind="stable")[:MAX_START_SUPPORT]
    S, wS = top[w[top] >= 1e-6 * w[top[0]]], None
    wS = w[S] / w[S].sum()
    for _ in range(max_rounds):
        wS = optimal_weights(P[S], W, wS)
        keep = wS > MIN_WEIGHT
        S, wS = S[keep], wS[keep] / wS[keep].sum()
        Phi, Minv = _phi_design(W, np.einsum("k,kij->ij", wS, P[S]))
        phi = P2 @ (Minv @ W @ Minv).ravel()
        if phi.max() / Phi - 1.0 <= target_gap:
            break
        new = np.setdiff1d(np.argsort(-phi, kind="stable")[:MAX_NEW], S)
        new = new[phi[new] > Phi]
        if not new.size:
            break
        S, wS = np.concatenate([S, new]), np.append(wS, np.zeros(len(new)))
    max_phi = max(float(phi.max()), Phi)
    order = np.argsort(-wS, kind="stable")
    return ApproximateDesign(into_limits(problem.robot, np.degrees(pool[S[order]])), wS[order], Phi, max_phi,
                             Phi**2 / max_phi, it, "candidate poses", len(pool))


def unconstrained(problem: Problem) -> Problem:
    """The same problem without the robot's cell and without a candidate file: its approximate design bounds O_t
    of every plan within the joint limits, so of every plan the cell allows too (a valid bound for the feasible
    continuum; loose by what the cell excludes)."""
    from dataclasses import replace

    return replace(problem, robot=replace(problem.robot, cell=None), candidates=None)


def _gap(found, Phi: float) -> float:
    """max_x phi / Phi - 1 from :meth:`PhiSearch.maximise`'s maxima; max_x phi >= Phi always (the mean of phi
    under xi is Phi), so the gap is never negative."""
    xg, fg, xm, fm = found
    return max(float(fg.max(initial=Phi)), float(fm.max(initial=Phi)), Phi) / Phi - 1.0


#: a support pose moves to the maximum of phi found from it when that is this close on every joint [deg]
MOVE_DEG = 1.0
#: at most this many maxima of phi (the highest) join the support in a round
MAX_NEW = 32
#: poses of smaller weight leave the design (before its maximum of phi is sought, so the bound stays exact)
MIN_WEIGHT = 1e-9
#: at most this many poses of the multiplicative algorithm's pool weights start the support
MAX_START_SUPPORT = 200
#: in a cell, at most this many maxima of phi found by the feasible Newton steps stay among the candidates
MAX_FOUND = 256
#: in a cell, the equivalence gap over the feasible candidates at which the design stops (its bound is exact
#: over them whatever the gap; a tighter design only tightens that bound, by at most the gap)
FEASIBLE_TARGET_GAP = 1e-5


def _merge(problem: Problem, X: np.ndarray, w: np.ndarray, pose_tol: float = 1e-6, info_rtol: float = 1e-9):
    """Merge poses X (k, n) [rad] with weights w (k,) that coincide (every joint within pose_tol, modulo
    2 pi) or carry the same information (symmetric copies: ``||P_i - P_j|| <= info_rtol ||P_i||``): the
    first of each group keeps the summed weight. Returns (X, w)."""
    P = vech(_info(problem, X))
    scale = np.linalg.norm(P, axis=1)
    same = np.all(np.abs(angle_diff(X[:, None, :], X[None, :, :])) <= pose_tol, axis=-1)
    same |= np.linalg.norm(P[:, None, :] - P[None, :, :], axis=-1) <= info_rtol * np.maximum(scale[:, None], scale)
    first = np.argmax(same, axis=1)  # the first pose equal to each (itself when none before)
    groups = np.unique(first)
    return X[groups], np.array([w[first == g].sum() for g in groups])
