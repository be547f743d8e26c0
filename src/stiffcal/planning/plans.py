"""Plans of M measurement poses (eqs. 11, 16 summed over poses; Tables 4-5).

Global optimisation of an M-pose plan
-------------------------------------
The plan's information matrix is a sum over poses, so a plan is improved one pose at a time
(Fedorov's exchange): with the other M - 1 poses fixed, the best replacement for pose j is found over a
whole candidate pool at once, and passes repeat until no pose changes. For O_t (and A-optimality) every
candidate is scored in closed form from quantities of the pool computed once (:func:`exchange_scores`:
the adjugate formula for up to 3 parameters, the Woodbury identity with the pool's quadratic forms
beyond), a few vector operations per step for the whole pool, with exactly the values (and so the plans)
of a general inverse of every candidate's information matrix; D and T likewise (:func:`closed_form_scores`:
the determinant lemma, traces). The same engine serves any linear model
(:func:`fedorov_exchange`); a slot holding the same point as one already verified since the last change is
not rescored, so a converged plan of M poses at k distinct points costs k scorings a pass. Every distinct
exchanged plan is then polished in the continuum (L-BFGS-B on all M n angles, with the gradient of O_t
from one batched evaluation of the rows whatever M: :func:`l_criterion_gradient`), roughly, and the best
``N_FINISH`` to convergence; the L-BFGS-B runs of all plans go in lockstep (:func:`lbfgsb_lockstep`:
scipy's routine for each, the points they ask for evaluated in one batch), so a step costs one
evaluation of the rows for all starts. Starts: the roundings of the optimal approximate design
(:func:`design_starts`, :mod:`stiffcal.planning.certificate`), the best single pose repeated (plan (i)), and
``n_starts`` random plans drawn from the pool with the given seed, so the result is deterministic for a
seed. The certificate bounds how far the result can be from the true optimum; the tests compare it with
a brute force.

Symmetric optima
----------------
Each pose's information is unchanged by the half-turn and mirror copies of that pose (see
:mod:`stiffcal.planning.problem`), independently for every pose of a plan. A plan is reported with each pose
replaced by its representative copy (:func:`stiffcal.planning.problem.representative`) and the poses sorted, so
plans equal up to symmetry print identically. Joint limits break the symmetry: then poses are kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize

from ..model import criteria
from .certificate import ApproximateDesign, candidate_pool, default_pool_step, has_planar_symmetry, vech
from .problem import Problem, _is_full_turn, angle_diff, into_limits, plan_loss, representative, wrap_deg
from ..model.stiffness import pose_information, spectral
from ..threads import single_threaded


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


def information_symmetries(problem: Problem, n_probe: int = 16, rtol: float = 1e-9) -> np.ndarray:
    """The joint-space symmetries of a spatial arm's problem: maps q -> s * q + c (signs s, offsets c [deg],
    returned as (k, 2, n), the identity first) under which every pose carries the same information, so that
    plans differing by them have the same O_t. Tried: q_1 kept or mirrored through the vertical plane of the
    force (s_1 = -1, c_1 = 2 phi, phi the force's azimuth about the base z axis), and every other joint
    kept, negated, turned by a half turn or both, which covers the mirror of an arm symmetric about its
    plane and the wrist flip (q4 + 180, -q5, q6 + 180) of a spherical wrist. A map is kept when the per-pose
    information of ``n_probe`` random poses agrees to ``rtol``. Planar arms: :func:`symmetric_copies`."""
    from itertools import product

    robot, force = problem.robot, np.asarray(problem.force, float)
    identity = np.array([[np.ones(robot.n_joints), np.zeros(robot.n_joints)]])
    if robot.planar or force.shape != (3,):
        return identity
    phi = np.degrees(np.arctan2(force[1], force[0]))
    first = [(1.0, 0.0), (-1.0, 2 * phi)]
    rest = [(1.0, 0.0), (-1.0, 0.0), (1.0, 180.0), (-1.0, 180.0)]
    maps = np.array([np.array(c).T for c in product(first, *[rest] * (robot.n_joints - 1))])  # (K, 2, n)
    q = np.random.default_rng(0).uniform(-180.0, 180.0, (n_probe, robot.n_joints))
    info = pose_information(_plan_A(problem, np.radians(q)))
    for probes in (slice(0, 1), slice(None)):  # screened on one pose, the survivors checked on all
        copies = q[probes] * maps[:, None, 0] + maps[:, None, 1]  # (K, probes, n)
        diff = np.abs(pose_information(_plan_A(problem, np.radians(copies))) - info[probes])
        maps = maps[(diff <= rtol * np.abs(info).max()).all(axis=(1, 2, 3))]
    return maps


def canonical_plan(problem: Problem, plan_deg: np.ndarray, symmetries: np.ndarray | None = None) -> np.ndarray:
    """Each pose replaced by its representative copy (:func:`stiffcal.planning.problem.representative`) among its
    symmetric copies within the joint limits (planar arms without limits: the half-turn and mirror copies;
    spatial arms: :func:`information_symmetries`, or ``symmetries`` when given), poses sorted (by q1, then
    q2, ...)."""
    robot = problem.robot
    plan = into_limits(robot, np.atleast_2d(plan_deg))
    if has_planar_symmetry(robot, problem):
        plan = np.array([representative(into_limits(robot, symmetric_copies(robot, p, problem.force))) for p in plan])
    elif not robot.planar:
        maps = information_symmetries(problem) if symmetries is None else symmetries
        if len(maps) > 1:
            copies = into_limits(robot, plan[:, None] * maps[:, 0] + maps[:, 1])  # (m, K, n)
            inside = ~robot.outside_limits(np.radians(copies)).any(axis=-1)
            if robot.cell is not None:  # a copy the cell does not allow is no copy (the pose itself always is)
                inside &= problem.feasible(np.radians(copies))
            plan = np.array([representative(c[ok]) for c, ok in zip(copies, inside)])
    order = np.lexsort(plan.T[::-1])
    return plan[order]


def _plan_A(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Stacked observation rows of poses q (..., n) [rad] -> (..., r, p) (:meth:`Problem.rows`)."""
    return problem.rows(q)


# ---------------------------------------------------------------------------------------------------
# Scoring every candidate of a pool at once for an L-optimality criterion (O_t, eq. 16; A-optimality)

def _inverse_traces(S, G, dim: int, norm: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``(trace(S^-1 G), ||S^-1||_F)`` for batches of symmetric dim x dim matrices given by their upper
    triangles, component first: S (dim(dim+1)/2, ...), G the same or (dim(dim+1)/2,) for one G (so each
    component of a batch is one contiguous vector): the adjugate formula ``S^-1 = adj(S) / det(S)`` for
    dim <= 3, ``numpy.linalg.inv`` beyond (which raises ``LinAlgError`` for an exactly singular S). A singular
    S gives inf or nan. ``norm=False`` skips the norm (None) where it is not needed."""
    if dim == 1:
        return G[0] / S[0], 1.0 / np.abs(S[0]) if norm else None
    if dim == 2:
        a, b, c = S[0], S[1], S[2]
        det = a * c - b * b
        num = G[0] * c - 2.0 * G[1] * b + G[2] * a
        return num / det, np.sqrt(a * a + 2 * b * b + c * c) / np.abs(det) if norm else None
    if dim == 3:
        a, b, c, d, e, f = S[:6]
        A11, A12, A13 = d * f - e * e, c * e - b * f, b * e - c * d
        A22, A23, A33 = a * f - c * c, b * c - a * e, a * d - b * b
        det = a * A11 + b * A12 + c * A13
        num = G[0] * A11 + G[3] * A22 + G[5] * A33 + 2.0 * (G[1] * A12 + G[2] * A13 + G[4] * A23)
        if not norm:
            return num / det, None
        return num / det, np.sqrt(A11**2 + A22**2 + A33**2 + 2 * (A12**2 + A13**2 + A23**2)) / np.abs(det)
    inv = np.linalg.inv(_full_symmetric(S, dim))
    return (np.einsum("...ij,...ji->...", inv, _full_symmetric(G, dim)),
            np.linalg.norm(inv, axis=(-2, -1)) if norm else None)


def _full_symmetric(v, dim: int) -> np.ndarray:
    """Symmetric dim x dim matrices (..., dim, dim) from their upper triangles, component first
    (dim(dim+1)/2, ...)."""
    iu = np.triu_indices(dim)
    v = np.moveaxis(np.asarray(v), 0, -1)
    out = np.zeros(v.shape[:-1] + (dim, dim))
    out[(..., *iu)] = v
    out[(..., iu[1], iu[0])] = v
    return out


@dataclass(frozen=True)
class PoolForms:
    """A candidate pool prepared once for exchange scoring (:func:`exchange_scores`).

    info: (K, p, p) information matrices ``X_c^T X_c`` of the candidates; vech: (p(p+1)/2, K) their upper
    triangles, component first; quad: (p(p+1)/2, q_d K) with ``(vech(R) @ quad).reshape(q_d, K)`` the upper
    triangles (q_d = d(d+1)/2 entries, component first) of ``X_c R X_c^T`` for any symmetric R, for the
    Woodbury identity when p > 3 (else None), of the regressors scaled by ``unit`` (p,) (``X_c diag(unit)``, the
    pool's parameters to a unit mean information: the Woodbury algebra's round-off grows with the square of
    M_rest's condition in the coordinates it is done in, and compliances of a base and a wrist joint put 1e5
    into it that the scaling takes out); d: rows per candidate; max_trace: the largest trace of a candidate's
    information matrix.
    """

    info: np.ndarray
    vech: np.ndarray
    quad: np.ndarray | None
    d: int
    max_trace: float = 0.0
    unit: np.ndarray | None = None


#: the quadratic forms of :func:`pool_forms` are built only within this many bytes (they and their temporaries take
#: about twice it): a fresh user's extended model of three causes on a 6-axis arm, 4096 candidates under three loads
#: (p about 40, 9 rows a candidate), took 3.2 GB and 75 s of an analysis for them; beyond, the exchange scores every
#: candidate by the direct path (:func:`exchange_scores`), whose memory is the pool's information matrices alone
QUAD_MAX_BYTES = 256e6


def _quad_bytes(k: int, d: int, p: int) -> float:
    """Bytes of :func:`pool_forms`' quadratic forms for k candidates of d rows and p parameters."""
    return 8.0 * k * (d * (d + 1) // 2) * (p * (p + 1) // 2)


def pool_forms(X: np.ndarray | None = None, info: np.ndarray | None = None) -> PoolForms:
    """Precompute the quadratic forms of a candidate pool: from its regressors X (K, d, p) or, without
    them, its information matrices info (K, p, p) (factored as ``X_c = sqrt(Lambda) V^T`` on their rank)."""
    if info is None:
        info = pose_information(X)
    p = info.shape[-1]
    quad, d = None, 0
    unit = None
    if p > 3 and _quad_bytes(len(info), p if X is None else X.shape[-2], p) <= QUAD_MAX_BYTES:
        if X is None:
            lam, V = np.linalg.eigh(info)
            rank = int(np.max(np.sum(lam > p * np.finfo(float).eps * np.maximum(lam[:, -1:], 0.0), axis=1)))
            X = np.swapaxes(V[..., -rank:] * np.sqrt(np.maximum(lam[:, None, -rank:], 0.0)), -1, -2)
        mean = np.einsum("kii->i", info) / len(info)
        unit = np.where(mean > 0, 1.0 / np.sqrt(np.where(mean > 0, mean, 1.0)), 1.0)
        X = X * unit
        d = X.shape[-2]
        (i, j), (a, b) = np.triu_indices(d), np.triu_indices(p)
        # coefficient of R_ab (a <= b) in (X R X^T)_ij: X_ia X_jb + X_ib X_ja, halved on the diagonal a = b
        coef = X[:, i][:, :, a] * X[:, j][:, :, b] + X[:, i][:, :, b] * X[:, j][:, :, a]
        coef[..., a == b] *= 0.5
        quad = np.ascontiguousarray(np.transpose(coef, (2, 1, 0))).reshape(len(a), -1)  # (q_p, q_d K)
    elif X is not None:
        d = X.shape[-2]
    return PoolForms(info, np.ascontiguousarray(vech(info).T), quad, d,
                     float(np.einsum("kii->k", info).max(initial=0.0)), unit)


def _general_scores(M: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """``trace(X_t M^-1 X_t^T)`` of information matrices M (K, p, p) by their eigen-decomposition, +inf
    where M is singular (:func:`stiffcal.model.criteria.loss_from_info`)."""
    return criteria.loss_from_info("ot", M, 1, Xt, 1.0)


#: eigenvalue ratio of the information of the other poses above which the Woodbury identity is used
WOODBURY_MIN_RATIO = 1e-8
#: a Woodbury score below this times kappa^2 trace(W R) (kappa: the condition of the other poses' information)
#: may have lost more than about 1e-9 of its value to cancellation (1e9 eps, :func:`_woodbury_scores`)
WOODBURY_CANCELLATION = 1e9 * np.finfo(float).eps
#: a candidate whose information matrix M_c has ``1 / (||M_c^-1||_F trace M_c)`` (a lower bound on its
#: eigenvalue ratio) at most this is rescored by the general path
DIRECT_MIN_RATIO = 1e-7


def exchange_scores(forms: PoolForms, M_rest: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """``trace(X_t (M_rest + X_c^T X_c)^-1 X_t^T)`` for every candidate c of a pool (O_t / sigma^2 of
    eq. 16 with the other poses' information M_rest, when X_t = A_t), +inf where that matrix is singular.

    forms: :func:`pool_forms` of the pool (K candidates); M_rest: (p, p), or (S, p, p) for S plans at once
    (each row as for that M_rest alone); Xt: (d_t, p). Returns (K,) or (S, K).

    * p > 3 and M_rest well conditioned (Woodbury): with ``R = M_rest^-1`` and ``W = X_t^T X_t``,
      ``(M_rest + X_c^T X_c)^-1 = R - R X_c^T S_c^-1 X_c R``, ``S_c = I + X_c R X_c^T``, so the score is
      ``trace(W R) - trace(S_c^-1 X_c R W R X_c^T)``; the d x d matrices S_c and ``X_c R W R X_c^T`` are
      linear in R and RWR, hence one matrix product with the precomputed ``forms.quad`` for the whole pool,
      and S_c is inverted in closed form (d <= 3).
    * otherwise (direct): ``M_c = M_rest + X_c^T X_c`` is formed from its p(p+1)/2 entries and inverted by
      the adjugate formula for p <= 3 (a few vector operations for the whole pool), beyond by Cholesky on
      M_c scaled to a unit diagonal (:func:`_scaled_inverse_traces`, vectorised over the pool the same way).
      Since ``lambda_min / lambda_max >= 1 / (||M_c^-1||_F trace M_c)``, candidates where that bound is at
      most ``DIRECT_MIN_RATIO`` (near singular, where round-off would matter) are rescored by the general
      path (:func:`stiffcal.model.criteria.loss_from_info`, an eigen-decomposition), so singular plans get +inf
      by the same rule as everywhere else and the others are accurate to about 1e-9.
    """
    M_rest = np.asarray(M_rest, float)
    if M_rest.ndim == 2:
        return exchange_scores(forms, M_rest[None], Xt)[0]
    p = M_rest.shape[-1]
    w = np.linalg.eigvalsh(M_rest)
    out = np.empty((len(M_rest), len(forms.info)))
    woodbury = p > 3 and forms.quad is not None
    if woodbury:
        fast = w[:, 0] > WOODBURY_MIN_RATIO * w[:, -1]
    else:
        # lambda_min(M_c) >= lambda_min(M_rest), lambda_max(M_c) <= trace(M_rest) + max trace(P_c): where that ratio
        # clears DIRECT_MIN_RATIO, no candidate is near singular and the adjugate formula serves the whole pool
        fast = (w[:, 0] > DIRECT_MIN_RATIO * (w.sum(axis=1) + forms.max_trace)) & (p <= 3)
    G = vech(Xt.T @ Xt)
    # one M_rest at a time: the pool's temporaries stay in cache (a batch's would not)
    for i in range(len(M_rest)):
        if not fast[i]:
            out[i] = _direct_scores(forms, M_rest[i], Xt)
        elif woodbury:
            out[i] = _woodbury_scores(forms, M_rest[i], Xt)
        else:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                out[i] = _inverse_traces(vech(M_rest[i])[:, None] + forms.vech, G, p, norm=False)[0]
    return out


def _woodbury_scores(forms: PoolForms, M_rest: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """The Woodbury path of :func:`exchange_scores` for one M_rest (p, p) -> (K,), in the pool's scaled
    parameters (``forms.unit``). The score is a difference, ``trace(W R)`` less the candidate's gain, and R is
    large along a direction the other poses barely hold: against exact rational arithmetic its error stayed below
    eps kappa^2 trace(W R), kappa the condition of the (scaled) M_rest (40 information matrices of a Jaco2's pool,
    kappa 16 .. 1e4, and the one where it reached 1e-3 trace(W R) at kappa 7e7 unscaled: a score of -22.5 for a true
    1.63, which the exchange took). A candidate whose score is below :data:`WOODBURY_CANCELLATION` kappa^2
    trace(W R) (more than about 1e-9 of it possibly lost) is rescored by the direct path; every candidate where
    that bound reaches trace(W R)."""
    Ms, Xs = M_rest * np.outer(forms.unit, forms.unit), Xt * forms.unit
    ev = np.linalg.eigvalsh(Ms)
    bound = WOODBURY_CANCELLATION * (ev[-1] / ev[0]) ** 2 if ev[0] > 0 else np.inf
    if not bound < 1.0:
        return _direct_scores(forms, M_rest, Xt)
    R = np.linalg.inv(Ms)
    W = Xs.T @ Xs
    RWR = R @ W @ R
    d = forms.d
    SG = (np.stack([vech(R), vech(RWR)]) @ forms.quad).reshape(2, d * (d + 1) // 2, -1)
    total = float(np.trace(W @ R))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = total - _inverse_traces(SG[0] + vech(np.eye(d))[:, None], SG[1], d, norm=False)[0]
    lost = ~(out >= bound * total)  # NaN too
    if lost.any():
        out[lost] = _direct_scores(PoolForms(forms.info[lost], forms.vech[:, lost], None, d, forms.max_trace),
                                   M_rest, Xt)
    return out


def _direct_scores(forms: PoolForms, M_rest: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """The direct path of :func:`exchange_scores` for one M_rest (p, p) that may leave candidates near
    singular: each candidate checked, those near singular by the general path. Returns (K,)."""
    p = M_rest.shape[-1]
    Mc = vech(M_rest)[:, None] + forms.vech  # (p(p+1)/2, K)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        val, ok = _inverse_traces_checked(Mc, vech(Xt.T @ Xt), p) if p <= 3 else _scaled_inverse_traces(Mc, Xt, p)
    if not ok.all():
        val = np.array(val, float)
        val[~ok] = _general_scores(M_rest[None] + forms.info[~ok], Xt)
    return val


def _inverse_traces_checked(Mc: np.ndarray, G: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """``(trace(M_c^-1 G), ok)`` for candidates' information matrices M_c (upper triangles, component first), ok
    where ``1 / (||M_c^-1||_F trace M_c)`` (a lower bound on the eigenvalue ratio) clears DIRECT_MIN_RATIO."""
    val, inv_norm = _inverse_traces(Mc, G, p)
    r, c = np.triu_indices(p)
    return val, np.isfinite(val) & (1.0 / (inv_norm * Mc[r == c].sum(axis=0)) > DIRECT_MIN_RATIO)


#: the eigenvalue-ratio bound above which a candidate is certainly not singular by the zero-eigenvalue rule of
#: :func:`stiffcal.model.stiffness.spectral` (ratio <= n eps), with a margin of 1e4 for the round-off of that rule
SINGULAR_MARGIN = 1e4 * np.finfo(float).eps


def _scaled_inverse_traces(Mc: np.ndarray, Xt: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """``(trace(X_t M_c^-1 X_t^T), ok)`` for candidates' information matrices M_c (p > 3; upper triangles,
    component first), each scaled to a unit diagonal first (Jacobi scaling, ``M_c = D^1/2 S D^1/2``) and S
    factored by Cholesky (:func:`_inverse_cholesky_factor`, ``S^-1 = L^-T L^-1``): the value is
    ``||L^-1 D^-1/2 X_t^T||_F^2``, and its accuracy follows the condition of S (van der Sluis; Higham, Accuracy and
    Stability of Numerical Algorithms, 2nd ed., secs. 7.3 and 10.1), not the scale of the compliances' units (a
    wrist joint's information 1e-8 of the base's), so only candidates near singular in fact go the general path.
    ok: the pivots are positive, and the eigenvalue-ratio bounds ``1 / (||L^-1||_F^2 p)`` of S and ``1 /
    (||L^-1 D^-1/2||_F^2 trace M_c)`` of M_c (``||A^-1||_2 <= ||L^-1||_F^2``) clear DIRECT_MIN_RATIO and
    :data:`SINGULAR_MARGIN` (the zero-eigenvalue rule is on M_c itself). Every step on (K,) vectors, one entry
    at a time (no (p, p, K) temporaries)."""
    r, c = np.triu_indices(p)
    diag = Mc[r == c]  # (p, K)
    good = np.all(diag > 0.0, axis=0)
    scale = 1.0 / np.sqrt(np.where(good, diag, 1.0))
    Li, regular = _inverse_cholesky_factor(Mc * (scale[r] * scale[c]), p)
    val, norm_s, norm = (np.zeros(Mc.shape[1]) for _ in range(3))
    xs = [Xt[:, j][:, None] * scale[j] for j in range(p)]  # columns of X_t D^-1/2, (d_t, K) each
    for i in range(p):
        y = Li[i][i] * xs[i]
        norm_s += Li[i][i] ** 2
        norm += (Li[i][i] * scale[i]) ** 2
        for j in range(i):
            y += Li[i][j] * xs[j]
            norm_s += Li[i][j] ** 2
            norm += (Li[i][j] * scale[j]) ** 2
        val += np.einsum("tk,tk->k", y, y)
    ratio_s = 1.0 / (norm_s * p)
    ratio = 1.0 / (norm * diag.sum(axis=0))
    return val, good & regular & np.isfinite(val) & (ratio_s > DIRECT_MIN_RATIO) & (ratio > SINGULAR_MARGIN)


def _inverse_cholesky_factor(S: np.ndarray, p: int) -> tuple[list, np.ndarray]:
    """The inverse L^-1 of the Cholesky factor of a batch of symmetric positive definite p x p matrices, ``S =
    L L^T`` (Golub and Van Loan, Matrix Computations, 4th ed., alg. 4.2.1), vectorised over the batch: S
    (p(p+1)/2, K) upper triangles component first (:func:`stiffcal.planning.certificate.vech` order) -> ``Li`` with
    ``Li[i][j]`` (K,) the entry (i, j <= i) of L^-1, and ok (K,): every pivot positive (else that candidate's
    entries are meaningless). A few hundred operations on (K,) vectors instead of K LAPACK calls."""
    at = {ij: k for k, ij in enumerate(zip(*np.triu_indices(p)))}
    L = [[None] * p for _ in range(p)]
    ok = np.ones(S.shape[1], bool)
    for j in range(p):
        d = S[at[j, j]].copy()
        for k in range(j):
            d -= L[j][k] ** 2
        ok &= d > 0.0
        L[j][j] = np.sqrt(np.where(d > 0.0, d, 1.0))
        for i in range(j + 1, p):
            v = S[at[j, i]].copy()
            for k in range(j):
                v -= L[i][k] * L[j][k]
            L[i][j] = v / L[j][j]
    Li = [[None] * p for _ in range(p)]
    for i in range(p):
        Li[i][i] = 1.0 / L[i][i]
        for j in range(i):
            v = L[i][j] * Li[j][j]
            for k in range(j + 1, i):
                v += L[i][k] * Li[k][j]
            Li[i][j] = -v * Li[i][i]
    return Li, ok


def _symmetric_det(S: np.ndarray, dim: int) -> np.ndarray:
    """Determinants of a batch of symmetric dim x dim matrices given by their upper triangles, component
    first (dim(dim+1)/2, K) as :func:`_inverse_traces` takes them: closed forms for dim <= 3, LU beyond."""
    if dim == 1:
        return S[0]
    if dim == 2:
        return S[0] * S[2] - S[1] * S[1]
    if dim == 3:
        a, b, c, d, e, f = S[:6]
        return a * (d * f - e * e) + b * (c * e - b * f) + c * (b * e - c * d)
    return np.linalg.det(_full_symmetric(S, dim))


#: criteria whose exchange step has a closed form other than the L-optimal ones': D (the determinant lemma)
#: and T (a sum of traces)
CLOSED_FORM = tuple(k for k, c in criteria.CRITERIA.items() if c.exchange == "closed")  # registered as such


def closed_form_scores(key: str, forms: PoolForms, M_rest: np.ndarray) -> np.ndarray:
    """The loss (:func:`stiffcal.model.criteria.loss_from_info`, minus the value of these 'max' criteria) of every
    candidate c of a pool with the other poses' information M_rest (p, p): for ``key`` 'd',
    ``-det(M_rest + X_c^T X_c)``, for 't' ``-trace(M_rest) - trace(X_c^T X_c)``. Returns (K,).

    D: where M_rest is well conditioned and p > 3, the determinant lemma ``det(M_rest + X_c^T X_c) =
    det(M_rest) det(I + X_c M_rest^-1 X_c^T)`` (Harville, Matrix Algebra From a Statistician's Perspective,
    thm. 18.1.1), the d x d matrices ``I + X_c R X_c^T`` linear in R = M_rest^-1 and so one product with the
    pool's ``forms.quad``, their determinants in closed form (d <= 3); otherwise (a singular M_rest, as
    for any plan of fewer poses than it takes to identify the compliances) each ``M_rest + X_c^T X_c`` from
    its upper triangle by the closed form (p <= 3) or LU. Either way no eigen-decomposition per candidate."""
    p = M_rest.shape[-1]
    if key == "t":
        r, c = np.triu_indices(p)
        return -(np.trace(M_rest) + forms.vech[r == c].sum(axis=0))
    w = np.linalg.eigvalsh(M_rest)
    if p > 3 and forms.quad is not None and w[0] > WOODBURY_MIN_RATIO * w[-1]:
        d = forms.d
        Ms = M_rest * np.outer(forms.unit, forms.unit)  # the pool's scaled parameters (PoolForms.quad)
        S = (vech(np.linalg.inv(Ms)) @ forms.quad).reshape(d * (d + 1) // 2, -1) + vech(np.eye(d))[:, None]
        return -np.prod(w) * _symmetric_det(S, d)
    return -_symmetric_det(vech(M_rest)[:, None] + forms.vech, p)


@dataclass
class ExchangeResult:
    """Result of :func:`fedorov_exchange`: indices (m,) of the chosen pool points (sorted; repeats allowed);
    value: ``trace(X_t M^-1 X_t^T)`` of the plan (O_t / sigma^2, eq. 16), +inf if no start identified every
    parameter; starts: number of starting plans exchanged."""

    indices: np.ndarray
    value: float
    starts: int


def exchange_loop(score, best, slot_P, slot_idx, pool_P, max_passes: int, slot_X=None, pool_X=None) -> np.ndarray:
    """Fedorov's exchange of S plans in lockstep: the project's one exchange engine (of :func:`exchange_plans`,
    :func:`fedorov_exchange` and the discrimination planner's :func:`stiffcal.measured.discrimination.exchange`,
    which plugs in its own scorer). slot_P (S, m, p, p), slot_X (S, m, d, p) or None and slot_idx (S, m) (pool
    index, or -1 for a starting pose outside the pool) describe the plans and are updated in place; best (S,)
    are their losses. Each plan visits its slots in turn (at most ``max_passes`` passes) until m visits in
    a row change nothing; at a visit to slot j, ``score(plans, slots, M_rest)`` gives, for each plan due a
    scoring (one row each; M_rest (S', p, p) the information of its other poses), the loss with slot j
    replaced by every candidate; the plans share each step's bookkeeping (M_rest and the best candidates in
    vectorised form, not a Python step per plan and slot). The best candidate (the first of those within a
    relative 1e-12 of it, so that exact ties such as symmetric copies do not hang on round-off) is taken
    when it lowers the loss by a relative 1e-12. Returns the losses (S,).

    A slot holding the same pool point as one visited since the plan's last change has the same other poses'
    information, hence the same scores and no improvement: it is not rescored (so a plan of m poses at k
    distinct points costs k scorings a pass once it has converged)."""
    S, m = slot_idx.shape
    best = np.array(best, float)
    t, unchanged, checked = np.zeros(S, int), np.zeros(S, int), [set() for _ in range(S)]
    end = max_passes * m
    due = list(range(S))
    while due:
        now = []
        for s in due:
            while t[s] < end and unchanged[s] < m and slot_idx[s, t[s] % m] in checked[s]:
                unchanged[s] += 1
                t[s] += 1
            if t[s] < end and unchanged[s] < m:
                now.append(s)
        if not now:
            break
        js = t[now] % m
        keep = np.arange(m) != js[:, None]  # the other slots (a zero term leaves a sum unchanged)
        M_rest = np.einsum("sm,smij->sij", keep.astype(float), slot_P[now])
        vals = score(np.array(now), js, M_rest)
        low = np.min(vals, axis=1, keepdims=True)  # ties (symmetric copies: the same information) go to the first
        cs = np.argmax(vals <= low + 1e-12 * np.abs(low), axis=1)
        for v, c, s, j in zip(vals[np.arange(len(now)), cs], cs, now, js):
            if v < best[s] * (1 - 1e-12) - 1e-300:
                best[s] = v
                slot_P[s, j], slot_idx[s, j] = pool_P[c], c
                if slot_X is not None:
                    slot_X[s, j] = pool_X[c]
                unchanged[s], checked[s] = 1, {c}
            else:
                unchanged[s] += 1
                if slot_idx[s, j] >= 0:
                    checked[s].add(int(slot_idx[s, j]))
            t[s] += 1
        due = now
    return best


#: the ridge (relative to the candidates' mean information per parameter) on nuisance parameters
#: (:func:`nuisance_ridge`): O_t then differs from its limit by about this fraction
NUISANCE_RIDGE = 1e-9


def nuisance_ridge(info: np.ndarray, nuisance: np.ndarray) -> np.ndarray:
    """(p, p): a diagonal ridge on the ``nuisance`` parameters (p,) bool, those the test point's deflection does not
    depend on (their column of X_t zero) and nothing else determines (a backlash of a joint the test load does not
    turn): the exchange's prior. O_t = tr(X_t M^-1 X_t^T) is then finite whether or not a plan determines them,
    the limit as the ridge r -> 0 being the inverse of the Schur complement M_aa - M_an M_nn^+ M_na on the other
    parameters (Pukelsheim, *Optimal Design of Experiments*, 1993, sec. 3.10: the information matrix of a parameter
    subsystem), which a small r gives to a relative r while keeping every plan's M invertible for the exchange.
    info (K, p, p): the candidates' information matrices (the ridge's scale)."""
    mean = float(np.trace(info.mean(axis=0))) / max(info.shape[-1], 1)
    return np.diag(np.where(nuisance, NUISANCE_RIDGE * max(mean, 1e-300), 0.0))


@single_threaded
def fedorov_exchange(pool: np.ndarray, Xt: np.ndarray, m: int, *, information: bool = False,
                     starts: list | tuple = (), n_starts: int = 16, greedy: bool = False, seed: int = 0,
                     max_passes: int = 30, prior: np.ndarray | None = None) -> ExchangeResult:
    """The best plan of m points from a finite pool for the L-optimality criterion O_t of ANY linear model
    ``y = X beta + e`` (Fedorov's exchange, Fedorov 1972, ch. 3; scores by :func:`exchange_scores`).

    pool: (K, d, p) regressors X_c of the candidate points or, with ``information=True``, (K, p, p)
    information matrices ``X_c^T X_c``; Xt: (d_t, p) regressor at the test point (O_t / sigma^2 =
    ``trace(X_t M^-1 X_t^T)``, ``M = sum X_i^T X_i``); m: number of points (a point may repeat); starts:
    starting plans, each (m,) pool indices; n_starts: random starting plans drawn with ``seed``; greedy: also
    start from the sequential (greedy) construction on a ridge-regularised information matrix (1e-9 of the
    pool's mean trace). Each start is exchanged until no single replacement improves it; the best result is
    returned (the first on ties). Deterministic for a seed. Raises ValueError without any start.
    prior: (p, p) the information already collected (a previous round's, in the units of ``X_c^T X_c``), added
    to every plan's: ``M = prior + sum X_i^T X_i`` (sequential design, Fedorov 1972, sec. 4.2); None: none.
    """
    pool = np.asarray(pool, float)
    Xt = np.atleast_2d(np.asarray(Xt, float))
    forms = pool_forms(info=pool) if information else pool_forms(X=pool)
    K, p = len(forms.info), forms.info.shape[-1]
    rng = np.random.default_rng(seed)
    inits = [np.asarray(s, int) for s in starts]
    inits += [rng.choice(K, m, replace=K < m) for _ in range(n_starts)]
    M0 = np.zeros((p, p)) if prior is None else np.asarray(prior, float)
    if greedy:
        base, chosen = M0 + 1e-9 * np.trace(forms.info.mean(axis=0)) * np.eye(p), []
        for _ in range(m):
            c = int(np.argmin(exchange_scores(forms, base, Xt)))
            chosen.append(c)
            base = base + forms.info[c]
        inits.append(np.array(chosen))
    if not inits:
        raise ValueError("fedorov_exchange needs at least one start (starts, n_starts or greedy)")
    idx = np.array(inits, int)
    slot_P = forms.info[idx]
    vals = exchange_loop(lambda _, __, M_rest: exchange_scores(forms, M_rest + M0, Xt),
                          _general_scores(slot_P.sum(axis=1) + M0, Xt), slot_P, idx, forms.info, max_passes)
    best = int(np.argmin(vals))  # the first on ties
    return ExchangeResult(np.sort(idx[best]), float(vals[best]), len(inits))


#: criteria whose exchange step is scored by :func:`exchange_scores` (L-optimality: W = A_t^T A_t or I)
L_OPTIMAL = tuple(k for k, c in criteria.CRITERIA.items() if c.exchange == "linear")  # registered as such


def exchange_plans(problem: Problem, plans: np.ndarray, pool: np.ndarray, pool_A: np.ndarray, max_passes: int = 30,
                   forms: PoolForms | None = None, scores=None) -> tuple[np.ndarray, np.ndarray]:
    """Fedorov exchange of S plans of m poses (S, m, n) [rad] over a pool (N, n) with rows pool_A (N, d, p),
    in lockstep (:func:`exchange_loop`; each plan exactly as alone).

    O_t and A-optimality are scored by :func:`exchange_scores` (``scores``: another function of its
    single-M_rest signature, e.g. :func:`stiffcal.testing.reference.general_exchange_scores` in the tests; forms: the
    pool's :func:`pool_forms`, computed here when not given); D and T by :func:`closed_form_scores`; other
    criteria from the eigen-decomposition of the information matrices ``M_rest + A_c^T A_c`` of every
    candidate, and G-optimality, which needs the rows themselves, stacks them.
    Returns the improved plans (S, m, n) and their losses (S,).
    """
    plans = np.asarray(plans, float)
    S, m = plans.shape[:2]
    d, p = pool_A.shape[-2:]
    key = problem.criterion
    A = _plan_A(problem, plans)  # (S, m, d, p)
    slot_P = pose_information(A)
    idx = np.full((S, m), -1)
    if key in L_OPTIMAL + CLOSED_FORM:
        forms = forms or pool_forms(pool_A)
        pool_P = forms.info
    if key in L_OPTIMAL:
        Xt, s2 = (problem.At, problem.sigma**2) if key == "ot" else (np.eye(p), 1.0)

        def score(_, __, M_rest):
            if scores is None:
                return s2 * exchange_scores(forms, M_rest, Xt)
            return s2 * np.stack([scores(forms, M, Xt) for M in M_rest])
    elif key in CLOSED_FORM:
        def score(_, __, M_rest):
            return np.stack([closed_form_scores(key, forms, M) for M in M_rest])
    else:
        pool_P = pose_information(pool_A)

        def score(ss, js, M_rest):
            out = []
            for s, j, M in zip(ss, js, M_rest):
                rows = None
                if key == "g":
                    others = np.delete(A[s], j, axis=0)
                    rows = np.concatenate([np.broadcast_to(others.reshape(1, -1, p), (len(pool), (m - 1) * d, p)),
                                           pool_A], axis=1)
                out.append(criteria.loss_from_info(key, M[None] + pool_P, m, problem.At, problem.sigma, rows))
            return np.stack(out)

    start = [criteria.loss(key, a.reshape(m * d, p), m, problem.At, problem.sigma) for a in A]
    best = exchange_loop(score, start, slot_P, idx, pool_P, max_passes, A, pool_A)
    return np.where((idx >= 0)[..., None], pool[np.maximum(idx, 0)], plans), best


def exchange(problem: Problem, plan: np.ndarray, pool: np.ndarray, pool_A: np.ndarray, max_passes: int = 30,
             forms: PoolForms | None = None, scores=None):
    """Fedorov exchange of one m-pose plan (m, n) [rad] (:func:`exchange_plans`). Returns the improved plan
    and its loss."""
    plans, best = exchange_plans(problem, plan[None], pool, pool_A, max_passes, forms, scores)
    return plans[0], float(best[0])


def l_criterion_gradient(problem: Problem, plan: np.ndarray, free: np.ndarray | None = None,
                         h: float = 1e-5, At: np.ndarray | None = None):
    """The loss of an L-optimality criterion (O_t, eq. 16, or A) of plan (m, n) [rad] and its gradient with
    respect to the free joint angles (m, n_free) [per rad]; for plans (S, m, n) the losses (S,) and
    gradients (S, m, n_free), all from one evaluation of the rows.

    With the plan's information ``M = sum_i A_i^T A_i`` and ``loss = s^2 trace(W M^-1)`` (O_t: W = A_t^T A_t,
    s = sigma; A: W = I, s = 1), ``d loss / d q_ij = -2 s^2 sum((A_i B) * dA_i/dq_ij)`` with
    ``B = M^-1 W M^-1`` (Magnus & Neudecker, Matrix Differential Calculus, ch. 8), so one evaluation of the
    observation rows at the m poses and at each pose with one joint moved by +-h (a central difference of
    the rows, error about h^2) gives the whole gradient, whatever m; M^-1 comes from the eigen-decomposition
    that gives the loss. The loss is :func:`plan_loss`'s (+inf for a singular plan, with a zero gradient).
    At: the test pose's rows ``problem.At``, when the caller has them (a polish computes them once)."""
    plan = np.asarray(plan, float)
    if plan.ndim == 2:
        loss, g = l_criterion_gradient(problem, plan[None], free, h, At)
        return float(loss[0]), g[0]
    S, m, n = plan.shape
    js = np.flatnonzero(np.ones(n, bool) if free is None else free)
    f = len(js)
    E = np.zeros((f, 1, n))
    E[np.arange(f), 0, js] = h
    R = problem.rows(np.concatenate([plan[:, None], plan[:, None] + E, plan[:, None] - E], axis=1))  # (S, 1+2f, m, d, p)
    A = R[:, 0]
    p = A.shape[-1]
    if problem.criterion == "ot":
        At = problem.At if At is None else At
        W, s2 = At.T @ At, problem.sigma**2
    else:
        At, W, s2 = None, np.eye(p), 1.0
    stacked = A.reshape(S, -1, p)
    M = np.einsum("...ri,...rj->...ij", stacked, stacked)  # as criteria.loss forms it: the same loss
    spec = spectral(M)
    w, V, null = spec
    loss = np.nan_to_num(criteria.from_info(problem.criterion, M, m, At, problem.sigma, stacked, spec), nan=np.inf)
    bad = null.any(axis=-1) | ~np.isfinite(loss)
    loss = np.where(bad, np.inf, loss)
    dA = (R[:, 1:1 + f] - R[:, 1 + f:]) / (2 * h)
    Minv = (V / np.where(bad[:, None], 1.0, w)[:, None, :]) @ np.swapaxes(V, -1, -2)
    AB = A @ (Minv @ W @ Minv)[:, None]
    g = -2.0 * s2 * np.einsum("sfmdp,smdp->smf", dA, AB)
    return loss, np.where(bad[:, None, None], 0.0, g)


def lbfgsb_lockstep(fun_grad, Z0: np.ndarray, bounds: np.ndarray, maxiter: int, ftol: float, gtol: float,
                    maxcor: int = 10, maxls: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """L-BFGS-B (Byrd, Lu, Nocedal & Zhu 1995; scipy's implementation and its ``minimize`` defaults) from
    every start Z0 (S, k) at once: each start runs its own L-BFGS-B, and the points they ask for are
    evaluated together, ``fun_grad(starts (S',), Z (S', k)) -> (f (S',), g (S', k))`` (which starts ask,
    and where), so that a batched objective costs
    one call per step for all starts. bounds: (k, 2), +-inf where a variable is free. Each start follows
    exactly the iterates ``scipy.optimize.minimize(method="L-BFGS-B")`` would give it with the same values
    (scipy's reverse-communication routine ``setulb``; without it, those ``minimize`` calls one by one).
    Returns (Z (S, k), f (S,)): each start's final iterate (scipy's ``x``: after a failed line search, the
    iterate before it) and the last value evaluated (scipy's ``fun``)."""
    Z0 = np.array(Z0, float)
    S, k = Z0.shape
    lo, hi = np.asarray(bounds, float).T
    Z0 = np.clip(Z0, lo, hi)
    try:
        from scipy.optimize import _lbfgsb
        setulb = _lbfgsb.setulb
    except (ImportError, AttributeError):  # pragma: no cover - another scipy: the same runs one by one
        out = [minimize(lambda z, i=i: tuple(np.asarray(a)[0] for a in fun_grad(np.array([i]), z[None])), z,
                        jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi)),
                        options=dict(maxiter=maxiter, ftol=ftol, gtol=gtol, maxcor=maxcor, maxls=maxls))
               for i, z in enumerate(Z0)]
        return np.array([r.x for r in out]), np.array([r.fun for r in out])
    nbd = (np.isfinite(lo) & ~np.isfinite(hi)) * 1 + (np.isfinite(lo) & np.isfinite(hi)) * 2 \
        + (~np.isfinite(lo) & np.isfinite(hi)) * 3
    nbd = nbd.astype(np.int32)
    low, up = np.where(np.isfinite(lo), lo, 0.0), np.where(np.isfinite(hi), hi, 0.0)
    factr = ftol / np.finfo(float).eps
    st = [dict(x=z.copy(), f=0.0, g=np.zeros(k), wa=np.zeros(2 * maxcor * k + 5 * k + 11 * maxcor**2 + 8 * maxcor),
               iwa=np.zeros(3 * k, np.int32), task=np.zeros(2, np.int32), ln_task=np.zeros(2, np.int32),
               lsave=np.zeros(4, np.int32), isave=np.zeros(44, np.int32), dsave=np.zeros(29), nit=0) for z in Z0]
    last_f = np.full(S, np.inf)
    alive = list(range(S))
    while alive:
        ask = []
        for i in alive:
            s = st[i]
            while True:
                setulb(maxcor, s["x"], low, up, nbd, s["f"], s["g"], factr, gtol, s["wa"], s["iwa"], s["task"],
                       s["lsave"], s["isave"], s["dsave"], maxls, s["ln_task"])
                if s["task"][0] == 3:  # wants the value and gradient at x
                    ask.append(i)
                    break
                if s["task"][0] != 1:  # converged or stopped
                    break
                s["nit"] += 1  # a new iterate
                if s["nit"] >= maxiter:
                    s["task"][:] = (5, 504)
        if not ask:
            break
        Z = np.array([st[i]["x"] for i in ask])
        F, G = fun_grad(np.array(ask), Z)
        for i, z, fv, gv in zip(ask, Z, F, G):
            st[i]["f"], st[i]["g"] = float(fv), np.array(gv, float)
            last_f[i] = float(fv)
        alive = ask
    return np.array([s["x"] for s in st]), last_f


#: step of the central differences in the polish of criteria other than O_t and A [rad]: truncation ~ h^2,
#: round-off ~ 1e-16 / h
POLISH_STEP_RAD = 1e-6
#: the early stop of the first polish of every exchanged plan, and how many of them are polished to the end
ROUGH_POLISH = dict(maxiter=300, ftol=1e-12, gtol=1e-8)
FULL_POLISH = dict(maxiter=2000, ftol=1e-15, gtol=1e-10)
N_FINISH = 4
#: in a cell, the polish sees a pose the cell does not allow at this many times its start's loss (the line search
#: then backtracks to a feasible step: infeasible steps are rejected, never taken)
INFEASIBLE_FACTOR = 1e3
#: the polish in a cell (both passes): a plan pressed against the boundary of the feasible set crawls along it
#: in steps that each gain less than 1e-10 of its loss, for thousands of steps; they stop (UR10, M = 2..8: O_t
#: within 1e-6 of the full run's, at a tenth of its CPU)
CELL_POLISH = dict(maxiter=150, ftol=1e-10, gtol=1e-10)


def _outside_cell_refused(problem: Problem, q: np.ndarray, val: np.ndarray) -> np.ndarray:
    """Relative losses val (S,) of plans q (S, m, n) [rad] with a plan the cell does not allow put far above the
    start (:data:`INFEASIBLE_FACTOR`), so the line search backtracks (a finite value: the routine needs one)."""
    if problem.robot.cell is None:
        return val
    return np.where(~problem.feasible(q).all(axis=-1), np.maximum(val, 1.0) * INFEASIBLE_FACTOR, val)


def _polish_options(problem: Problem, rough: bool) -> dict:
    """The L-BFGS-B options of a polish: :data:`CELL_POLISH` in a cell, else the rough or the full stop."""
    return CELL_POLISH if problem.robot.cell is not None else ROUGH_POLISH if rough else FULL_POLISH


def _polish_bounds(problem: Problem, free: np.ndarray, m: int) -> np.ndarray:
    """L-BFGS-B bounds (m n_free, 2) [rad] of the free joints of m poses: +-inf for full-turn joints."""
    lims = problem.robot.joint_limits_rad[free]
    full = np.array([_is_full_turn(lo, hi) for lo, hi in lims], bool)
    return np.tile(np.where(full[:, None], [-np.inf, np.inf], lims), (m, 1))


def polish_plans(problem: Problem, plans: np.ndarray, free: np.ndarray | None = None,
                 rough: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """L-BFGS-B on the free joint angles of every pose of plans (S, m, n) [rad], all at once. Returns
    (plans (S, m, n), losses (S,)), each never worse than its start.

    O_t and A use their gradient (:func:`l_criterion_gradient`: one batched evaluation of the rows per step
    for all plans, whatever m; the L-BFGS-B runs in lockstep, :func:`lbfgsb_lockstep`); the other criteria
    central differences of the 2 m n + 1 plans in one batch, one plan at a time. The loss is taken relative
    to the start's, so that the tolerances do not depend on the unit of sigma (O_t ~ sigma^2).
    rough: stop early (:data:`ROUGH_POLISH`), to rank plans before the full polish of the best."""
    plans = np.array(plans, float)
    S, m, n = plans.shape
    free = np.ones(n, bool) if free is None else np.asarray(free, bool)
    if problem.criterion not in L_OPTIMAL:
        out = [polish(problem, q, free, rough) for q in plans]
        return np.array([q for q, _ in out]), np.array([v for _, v in out])
    f0 = np.asarray(plan_loss(problem, plans), float)
    go = np.flatnonzero(np.isfinite(f0) & (f0 > 0))
    if not go.size:
        return plans, f0
    At = problem.At

    def full(rows, Z):
        q = plans[rows].copy()
        q[:, :, free] = Z.reshape(len(rows), m, -1)
        return q

    def fun_grad(starts, Z):
        rows = go[starts]
        q = full(rows, Z)
        val, g = l_criterion_gradient(problem, q, free, At=At)
        val, g = val / f0[rows], g.reshape(len(rows), -1) / f0[rows, None]
        return _outside_cell_refused(problem, q, val), g

    opts = _polish_options(problem, rough)
    Z0 = plans[go][:, :, free].reshape(len(go), -1)
    Z, _ = lbfgsb_lockstep(fun_grad, Z0, _polish_bounds(problem, free, m), **opts)
    out, losses = plans.copy(), f0.copy()
    cand = full(go, Z)
    vals = np.asarray(plan_loss(problem, cand), float)
    ok = np.isfinite(vals) & (vals <= f0[go])
    out[go[ok]], losses[go[ok]] = cand[ok], vals[ok]
    return out, losses


def polish(problem: Problem, plan: np.ndarray, free: np.ndarray | None = None, rough: bool = False):
    """L-BFGS-B on the free joint angles of every pose of plan (m, n) [rad] (:func:`polish_plans`; the
    criteria other than O_t and A by central differences of the 2 m n + 1 plans in one batch). Returns
    (plan, loss)."""
    m, n = plan.shape
    free = np.ones(n, bool) if free is None else np.asarray(free, bool)
    if problem.criterion in L_OPTIMAL:
        out, loss = polish_plans(problem, plan[None], free, rough)
        return out[0], float(loss[0])

    def full(z):
        q = plan.copy()
        q[:, free] = z.reshape(m, free.sum())
        return q

    def f(z):
        return float(plan_loss(problem, full(z)))

    z0 = plan[:, free].ravel()
    f0 = f(z0)
    if not np.isfinite(f0) or f0 == 0:
        return plan, f0
    scale = abs(f0)  # a 'max' criterion's loss is minus its value (negative): relative to its size all the same
    steps = POLISH_STEP_RAD * np.vstack([np.eye(z0.size), -np.eye(z0.size)])

    def differences(z):
        """The loss relative to the start's (so that gtol does not depend on the unit of sigma; O_t ~
        sigma^2) and its central-difference gradient, all 2 m n + 1 plans evaluated in one batch."""
        zs = np.vstack([z, z + steps])
        q = np.broadcast_to(plan, (len(zs), m, n)).copy()
        q[:, :, free] = zs.reshape(len(zs), m, -1)
        v = _outside_cell_refused(problem, q, plan_loss(problem, q) / scale)
        k = z.size
        up, down = v[1:k + 1], v[k + 1:]
        with np.errstate(invalid="ignore"):  # a step onto a singular plan (loss inf): one-sided differences
            g = np.where(np.isfinite(up) & np.isfinite(down), (up - down) / (2 * POLISH_STEP_RAD),
                         np.where(np.isfinite(up), (up - v[0]) / POLISH_STEP_RAD,
                                  np.where(np.isfinite(down), (v[0] - down) / POLISH_STEP_RAD, 0.0)))
        return float(v[0]), np.nan_to_num(g, nan=0.0, posinf=0.0, neginf=0.0)

    bounds = [(None if np.isinf(lo) else lo, None if np.isinf(hi) else hi) for lo, hi in _polish_bounds(problem, free, m)]
    res = minimize(differences, z0, jac=True, method="L-BFGS-B", bounds=bounds, options=_polish_options(problem, rough))
    loss = f(res.x)
    feasible = problem.robot.cell is None or problem.feasible(full(res.x)).all()
    if np.isfinite(loss) and loss <= f0 and feasible:
        return full(res.x), loss
    return plan, f0


def _in_pool(plan: np.ndarray, pool: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether every pose of plan (m, n) [rad] is one of the pool's (N, n) (to ``tol`` on every joint)."""
    return all(np.any(np.all(np.abs(angle_diff(pool, q)) <= tol, axis=1)) for q in plan)


def _compact(pool_A: np.ndarray) -> tuple:
    """The arguments of :func:`pool_forms` for a pool's rows (N, r, p): the rows themselves, or, when there are
    more rows than parameters (every pose measured under several loads), their information matrices (factored
    on their rank inside :func:`pool_forms`), which carry the same information in fewer rows."""
    r, p = pool_A.shape[-2:]
    return (pool_A,) if r <= max(p, 3) else (None, pose_information(pool_A))


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
    live = w > 0  # a support point of zero weight (round-off of the weights' solver) never gets a pose
    safe = np.where(live, w, 1.0)
    while counts.sum() < m:
        counts[np.argmin(np.where(live, counts / safe, np.inf))] += 1
    while counts.sum() > m:
        j = np.argmax(np.where((counts > 0) & live, (counts - 1) / safe, -np.inf))
        counts[j] -= 1
    return np.repeat(design.support_deg, counts, axis=0)


def information_classes(problem: Problem, design: ApproximateDesign, tol: float = 2e-2) -> ApproximateDesign:
    """The approximate design with its support points merged by their information: points whose per-pose
    information matrices agree to ``tol`` (relative to the largest) are one class, with the summed weight,
    represented by its heaviest member. Returns an :class:`ApproximateDesign` (support (k', n) [deg]).

    The design's Fisher information, and so O_t, is a function of the class weights alone; the way the
    iterations split a class's weight among near-copies of a pose, or among symmetric copies with equal
    information (a mirror through the plane of the force), follows round-off. Rounding the classes gives
    starts that do not (Pukelsheim, *Optimal Design of Experiments*, 1993, sec. 12.5: rounding acts on the
    design measure, which copies with equal information share).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    P = vech(pose_information(_plan_A(problem, np.radians(design.support_deg))))
    P = P / max(float(np.linalg.norm(P, axis=1).max()), 1e-300)
    pairs = cKDTree(P).query_pairs(tol, output_type="ndarray").reshape(-1, 2)
    k = len(P)
    n_cls, label = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k)),
                                        directed=False)
    weights = np.bincount(label, design.weights, n_cls)
    heaviest = [int(np.flatnonzero(label == c)[np.argmax(design.weights[label == c])]) for c in range(n_cls)]
    return replace(design, support_deg=design.support_deg[heaviest], weights=weights)


def apportion(design: ApproximateDesign, m: int) -> np.ndarray:
    """Largest-remainder (Hamilton) rounding of an approximate design to m poses [deg]: floor(m w_i) copies
    of each support point, and one more for the largest remainders m w_i - floor(m w_i)."""
    x = m * np.asarray(design.weights, float)
    counts = np.floor(x).astype(int)
    counts[np.argsort(-(x - counts), kind="stable")[:m - int(counts.sum())]] += 1
    return np.repeat(design.support_deg, counts, axis=0)


def design_starts(problem: Problem, design: ApproximateDesign, m: int) -> list[np.ndarray]:
    """Starting plans of m poses [deg] from an approximate design: its efficient rounding
    (:func:`round_design`) and the largest-remainder rounding of its information classes
    (:func:`information_classes`, :func:`apportion`), which does not depend on how round-off split the
    weights; the exchange keeps the better of the two (a URDF and the DH table of the same arm then reach
    plans of the same O_t)."""
    return [round_design(design, m), apportion(information_classes(problem, design), m)]


@single_threaded
def _given_starts(problem: Problem, starts, pool: np.ndarray) -> list[np.ndarray]:
    """The given starting plans [deg] as (m, n) [rad], those the cell or the candidate file does not allow left
    out; ValueError for a plan of the wrong shape."""
    m = problem.m
    inits = [np.radians(np.atleast_2d(s)) for s in (starts or [])]
    for i, init in enumerate(inits):
        if init.shape != (m, problem.robot.n_joints):
            raise ValueError(f"starting plan {i} has shape {init.shape}, expected ({m}, {problem.robot.n_joints})")
    if problem.robot.cell is not None:  # a start with a pose the cell does not allow is no start
        inits = [q for q in inits if problem.feasible(q).all()]
    if not problem.continuous:  # a candidate file: plans of its poses only
        inits = [q for q in inits if _in_pool(q, pool)]
    return inits


def _reported(problem: Problem, results: list, canonical: bool) -> tuple[np.ndarray, float, int]:
    """(the best plan [deg] as reported, its loss, how many distinct plans reach it) of the polished plans
    ``results`` [(loss, plan [rad])]: the representative symmetric copy (``canonical``) or the poses in
    order, its repeated poses merged where that is no worse."""
    vals = np.array([r[0] for r in results])
    best_val, best_plan = results[int(np.argmin(vals))]
    symmetries = information_symmetries(problem) if canonical else None

    def canon_of(plan):
        if canonical:
            return canonical_plan(problem, np.degrees(plan), symmetries)
        q = into_limits(problem.robot, np.degrees(plan))
        return q[np.lexsort(q.T[::-1])]

    canon = canon_of(best_plan)
    merged = merge_repeats(canon)
    merged_val = float(plan_loss(problem, np.radians(merged)))
    if merged_val <= best_val * (1 + 1e-10):
        canon, best_val = merged, merged_val
    near = [canon_of(p) for v, p in results if v <= best_val * (1 + 1e-9) + 1e-300]
    return canon, best_val, len({tuple(np.round(c, 3).ravel()) for c in near})


def optimise_plan(problem: Problem, pool: np.ndarray | None = None, free: np.ndarray | None = None,
                  starts: list[np.ndarray] | None = None, n_starts: int = 16, seed: int = 0,
                  pool_step_deg: float | None = None, canonical: bool = True, n_polish: int | None = None,
                  scores=None) -> PlanResult:
    """Globally optimise the m-pose plan of ``problem`` (module docstring).

    pool: candidate poses (N, n) [rad] (default: :func:`candidate_pool`); free: which joints the continuous
    polish may move (default all; plans (ii)-(iii) fix some); starts: extra starting plans [deg];
    canonical: report each pose as its representative symmetric copy (False keeps the poses as found,
    e.g. when some joints are held fixed, which the symmetric copies would change); n_polish: how many
    of the best exchanged plans are polished in the continuum (default all: the pool's ranking of the
    exchanged plans does not predict the polished ones well, and follows round-off); scores: the candidate scoring of the exchange
    step for O_t and A (default :func:`exchange_scores`; see :func:`exchange`).
    """
    m = problem.m
    rng = np.random.default_rng(seed)
    canonical = canonical and problem.continuous  # a candidate file's poses are reported as they are
    if pool is None:
        pool = candidate_pool(problem.robot, pool_step_deg or default_pool_step(problem.robot.n_joints), problem)
    elif problem.robot.cell is not None:  # a pool given (the workflow's pool.npy): only the poses the cell allows
        pool = pool[problem.feasible(pool)]
    pool_A = _plan_A(problem, pool)
    inits = _given_starts(problem, starts, pool)
    inits += [pool[rng.choice(len(pool), m, replace=len(pool) < m)] for _ in range(n_starts)]
    forms = pool_forms(*_compact(pool_A)) if problem.criterion in L_OPTIMAL + CLOSED_FORM else None
    plans, losses = exchange_plans(problem, np.stack(inits), pool, pool_A, forms=forms, scores=scores)
    order = np.argsort(losses, kind="stable")[:n_polish or len(plans)]
    keys = [q[np.lexsort(q.T[::-1])].tobytes() for q in plans]  # the same plan from several starts: polished once
    order = [i for i in order if keys.index(keys[i]) == i]
    if problem.continuous:
        rough, rough_vals = polish_plans(problem, plans[order], free, rough=True)
        finish = np.argsort(rough_vals, kind="stable")[:N_FINISH]
        done, done_vals = polish_plans(problem, rough[finish], free)
    else:
        done, done_vals = plans[order], losses[order]
    canon, best_val, distinct = _reported(problem, list(zip(done_vals, done)), canonical)
    return PlanResult(canon, float(best_val), len(inits), distinct)


def best_plan(problem: Problem, design: ApproximateDesign, seed: int = 0, pool: np.ndarray | None = None) -> PlanResult:
    """The plan of ``problem.m`` poses that ``stiffcal design``, :func:`stiffcal.design` and the workflow's design
    studies report, from one function so that they give one answer for one input: for m = 1 the exhaustive
    single-pose search (:func:`stiffcal.planning.problem.optimal_single_pose`), else :func:`optimise_plan` started from
    the roundings of the approximate design (:func:`design_starts`) and 16 seeded random plans
    (:data:`CELL_STARTS` in a cell): the best of all starts, polished. pool: the candidate poses (N, n) [rad]
    (default the one :func:`optimise_plan` builds; the workflow passes the same, saved by its design job)."""
    from .problem import optimal_single_pose

    if problem.m == 1:
        res = optimal_single_pose(problem)
        return PlanResult(res.pose_deg[None, :], res.loss, 1, notes=list(res.notes))
    n_starts = CELL_STARTS if problem.robot.cell is not None else 16
    return optimise_plan(problem, pool=pool, starts=design_starts(problem, design, problem.m), seed=seed,
                         n_starts=n_starts)


#: random starts of a plan in a cell: its boundary makes more local optima (UR10, M = 4: with 16 starts O_t moved
#: by 2.9 % over seeds 0..4, with 64 by 0.07 %, and the best of them is the 64-start plan; benchmarks/bench_workcell.py)
CELL_STARTS = 64
