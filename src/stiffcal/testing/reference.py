"""Slow, independent reference solvers for checking fast ones (tests and ``benchmarks/``).

They use only eq. 16 evaluated by plain linear algebra on the robot's Jacobian, none of the reductions of
:mod:`stiffcal.planning.maps`, so agreement between the two is evidence, not a tautology.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ..model.robot import planar_robot
from ..model.stiffness import observation_matrix


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


def general_exchange_scores(forms, M_rest: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """The slow reference for :func:`stiffcal.planning.plans.exchange_scores`: ``trace(X_t (M_rest + P_c)^-1 X_t^T)``
    for every candidate c of a pool (forms: :func:`stiffcal.planning.plans.pool_forms`, whose ``info`` holds P_c),
    by the general inverse of every candidate's information matrix (its eigen-decomposition, +inf where
    singular: :func:`stiffcal.model.criteria.loss_from_info`), with no closed form and no Woodbury identity."""
    from ..model.criteria import loss_from_info

    return loss_from_info("ot", M_rest[None] + forms.info, 1, Xt, 1.0)


def reference_exchange(pool_info: np.ndarray, Xt: np.ndarray, start, max_passes: int = 30):
    """Fedorov's exchange written plainly, for checking :func:`stiffcal.planning.plans.fedorov_exchange`: from the
    plan ``start`` (m pool indices), each pose in turn is replaced by the pool point that minimises
    ``trace(X_t M^-1 X_t^T)`` (``np.linalg.inv`` of every candidate plan's information matrix, +inf when
    its condition number exceeds 1e12), when that lowers it by a relative 1e-12; passes repeat until none
    does. pool_info: (K, p, p); Xt: (d_t, p). Returns (indices (m,) sorted, value)."""
    idx = [int(i) for i in start]

    def value(M):
        if np.linalg.cond(M) > 1e12:
            return np.inf
        return float(np.trace(Xt @ np.linalg.inv(M) @ Xt.T))

    best = value(sum(pool_info[i] for i in idx))
    for _ in range(max_passes):
        changed = False
        for j in range(len(idx)):
            rest = sum(pool_info[i] for k, i in enumerate(idx) if k != j)
            vals = [value(rest + P) for P in pool_info]
            c = int(np.argmin(vals))
            if vals[c] < best * (1 - 1e-12):
                idx[j], best, changed = c, vals[c], True
        if not changed:
            break
    return np.sort(idx), best


class _Reference:
    """The pieces of :func:`certified_bound_reference`: random poses within the limits, information matrices,
    Phi, and the joint polish of poses and weights by L-BFGS-B."""

    def __init__(self, problem, rng: np.random.Generator, polish_iters: int):
        robot = problem.robot
        self.robot, self.F, self.At = robot, problem.force, problem.At
        self.W = self.At.T @ self.At
        self.n = robot.n_joints
        self.rng, self.polish_iters = rng, polish_iters
        lo, hi = robot.joint_limits_rad.T
        self.lo, self.hi = np.where(hi - lo >= 2 * np.pi, -np.pi, lo), np.where(hi - lo >= 2 * np.pi, np.pi, hi)
        self.free = robot.joint_limits_rad[:, 1] - robot.joint_limits_rad[:, 0] >= 2 * np.pi - 1e-12

    def A_of(self, q):
        return observation_matrix(self.robot.model_jacobian(q), self.F)

    def faces(self, q):
        """Half of the poses with each limited joint at a limit with probability 1/3 (maxima lie there)."""
        u = self.rng.uniform(size=q.shape)
        free, lo, hi = self.free, self.lo, self.hi
        moved = np.where(~free & (u < 1 / 6), lo, np.where(~free & (u > 5 / 6), hi, q))
        return np.where(np.arange(len(q))[:, None] % 2 == 1, moved, q)

    def info(self, q):
        A = self.A_of(q)
        return np.einsum("...di,...dj->...ij", A, A)

    def phi_fun(self, C):
        return lambda q: np.sum((self.A_of(q) @ C) ** 2, axis=(-2, -1))

    def grad_fd(self, fun, X, h=1e-6):
        n = self.n
        steps = h * np.eye(n)
        return (fun((X[:, None, :] + steps).reshape(-1, n)) - fun((X[:, None, :] - steps).reshape(-1, n))
                ).reshape(len(X), n) / (2 * h)

    def Phi_of(self, X, w):
        return float(np.trace(self.W @ np.linalg.inv(np.einsum("k,kij->ij", w, self.info(X)))))

    def polish(self, X, w):
        """Poses and weights (softmax) polished together by L-BFGS-B on Phi, with its gradient
        ``-w_i grad phi(x_i)``, ``-phi_i``."""
        from scipy.optimize import minimize as _minimize

        k, n, W, At = len(w), self.n, self.W, self.At

        def fg(z):
            Xz, logit = z[:k * n].reshape(k, n), z[k * n:]
            wz = np.exp(logit - logit.max())
            wz /= wz.sum()
            M = np.einsum("k,kij->ij", wz, self.info(Xz))
            try:
                Minv = np.linalg.inv(M)
            except np.linalg.LinAlgError:
                return 1e300, np.zeros_like(z)
            val = float(np.trace(W @ Minv))
            if not (np.isfinite(val) and val > 0):
                return 1e300, np.zeros_like(z)
            C = Minv @ At.T
            fun = self.phi_fun(C)
            phis = fun(Xz)
            gx = -wz[:, None] * self.grad_fd(fun, Xz)
            gw = -phis
            return val, np.concatenate([gx.ravel(), wz * (gw - wz @ gw)])

        free, lo, hi = self.free, self.lo, self.hi
        bounds = [(None, None) if free[j % n] else (lo[j % n], hi[j % n]) for j in range(k * n)] + [(-40, 40)] * k
        z0 = np.concatenate([X.ravel(), np.log(np.maximum(w, 1e-16))])
        res = _minimize(fg, z0, jac=True, method="L-BFGS-B", bounds=bounds,
                        options=dict(maxiter=self.polish_iters, ftol=1e-13, gtol=1e-10))
        Xz, logit = res.x[:k * n].reshape(k, n), res.x[k * n:]
        wz = np.exp(logit - logit.max())
        return Xz, wz / wz.sum()


def certified_bound_reference(problem, pool_size: int = 1500, searches: int = 60_000, polish_top: int = 12,
                              rounds: int = 6, iters: int = 2000, polish_iters: int = 300, seed: int = 0):
    """An independent, slower certified lower bound on Phi* = min over designs of trace(W M(xi)^-1), for
    checking :func:`stiffcal.planning.certificate.approximate_design` (tests). Shares no algorithm with it:

    1. a pool of ``pool_size`` uniformly random poses within the limits (half of them with each limited
       joint moved to a limit with probability 1/3); weights by ``iters`` iterations of
       the multiplicative algorithm (Silvey, Titterington & Torsney 1978);
    2. the support (weights >= 1e-4) is polished jointly, poses and weights (softmax), by L-BFGS-B on Phi
       with its gradient ``-w_i grad phi(x_i)``, ``-phi_i``;
    3. ``rounds`` times: the maximum of phi(x, xi) over the joint space, by ``searches`` random poses drawn
       as in step 1 and L-BFGS-B from the ``polish_top`` best, joins the support with weight 0.1 (vertex direction) and
       step 2 repeats;
    4. the bound ``Phi(xi)^2 / max_x phi(x, xi)`` with a fresh maximisation (general equivalence theorem).

    Returns (Phi(xi), max_x phi(x, xi), bound).
    """
    ref = _Reference(problem, np.random.default_rng(seed), polish_iters)
    rng, n = ref.rng, ref.n
    W = ref.W

    def max_phi(X, w):
        return max_phi_reference(problem, X, w, searches, polish_top, rng)

    pool = ref.faces(rng.uniform(ref.lo, ref.hi, (pool_size, n)))
    P = ref.info(pool).reshape(pool_size, -1)
    w = np.full(pool_size, 1.0 / pool_size)
    for _ in range(iters):
        Minv = np.linalg.inv((w @ P).reshape(problem.robot.n_params, -1))
        phis = P @ (Minv @ W @ Minv).ravel()
        w = w * phis / np.trace(W @ Minv)
        w /= w.sum()
    keep = w >= 1e-4 * w.max()
    X, w = ref.polish(pool[keep], w[keep] / w[keep].sum())
    for _ in range(rounds):
        _, x = max_phi(X, w)
        X, w = ref.polish(np.vstack([X, x]), np.append(0.9 * w, 0.1))
    Phi = ref.Phi_of(X, w)
    top, _ = max_phi(X, w)
    top = max(top, Phi)
    return Phi, top, Phi**2 / top


def max_phi_reference(problem, X: np.ndarray, w: np.ndarray, searches: int = 400_000, polish_top: int = 100,
                      rng=1):
    """An independent global maximisation of ``phi(x, xi) = ||A(x) M(xi)^-1 A_t^T||_F^2`` for the design with
    support X (k, n) [rad] and weights w (k,): ``searches`` uniformly random poses within the limits (half of
    them with each limited joint moved to a limit with probability 1/3), then L-BFGS-B (central-difference
    gradient) from the ``polish_top`` best and from the support. rng: a seed or a numpy Generator.
    Returns (max phi, its pose (n,) [rad])."""
    from scipy.optimize import minimize as _minimize

    robot, F, At = problem.robot, problem.force, problem.At
    n = robot.n_joints
    rng = np.random.default_rng(rng)
    free = robot.joint_limits_rad[:, 1] - robot.joint_limits_rad[:, 0] >= 2 * np.pi - 1e-12
    lo, hi = robot.joint_limits_rad.T
    lo, hi = np.where(free, -np.pi, lo), np.where(free, np.pi, hi)

    def A_of(q):
        return observation_matrix(robot.model_jacobian(q), F)

    M = np.einsum("k,kdi,kdj->ij", w, A_of(X), A_of(X))
    C = np.linalg.inv(M) @ At.T

    def fun(q):
        return np.sum((A_of(q) @ C) ** 2, axis=(-2, -1))

    best_q, best_v = [], []
    for start in range(0, searches, 50_000):
        q = rng.uniform(lo, hi, (min(50_000, searches - start), n))
        u = rng.uniform(size=q.shape)
        moved = np.where(~free & (u < 1 / 6), lo, np.where(~free & (u > 5 / 6), hi, q))
        q = np.where(np.arange(len(q))[:, None] % 2 == 1, moved, q)
        v = fun(q)
        top = np.argsort(-v)[:polish_top]
        best_q.append(q[top])
        best_v.append(v[top])
    q, v = np.vstack(best_q), np.concatenate(best_v)
    starts = np.vstack([q[np.argsort(-v)[:polish_top]], X])
    bounds = [(None, None) if free[j] else (lo[j], hi[j]) for j in range(n)]
    steps = 1e-6 * np.eye(n)

    def negative(x):
        g = (fun(x + steps) - fun(x - steps)) / 2e-6
        return -float(fun(x[None])[0]), -g

    out = [(float(fun(starts[:1])[0]), starts[0])]
    for x0 in starts:
        res = _minimize(negative, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                        options=dict(maxiter=500, gtol=1e-12, ftol=1e-15))
        out.append((-float(res.fun), res.x))
    return max(out, key=lambda t: t[0])


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
    det A = 0. Independent of the reduction of :mod:`stiffcal.planning.maps`."""
    At, _ = _observation_ld(b, force, qt_deg)
    A, det = _observation_ld(b, force, q_deg)
    adj = np.empty_like(A)
    adj[:, 0, 0], adj[:, 1, 1], adj[:, 0, 1], adj[:, 1, 0] = A[:, 1, 1], A[:, 0, 0], -A[:, 0, 1], -A[:, 1, 0]
    G = np.einsum("ij,njk->nik", At[0], adj)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.einsum("nij,nij->n", G, G) / (det * det)
    return np.where(det != 0, out, np.inf)


def _brute_force_ld(b: float, force: np.ndarray, qt_deg, step_deg: float, polish: int):
    """(min O_t / sigma^2, argmin pose [deg]) of :func:`brute_force_cell_ld`."""
    g = np.arange(-180.0, 180.0, step_deg) + step_deg / 3   # off the singular lines q2 = 0, 180
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    vals = ot_long_double(b, force, qt_deg, Q).astype(float)
    k = int(np.argmin(vals))
    best, pose = float(vals[k]), Q[k]
    for i in np.argsort(vals)[:polish]:
        with np.errstate(invalid="ignore", over="ignore"):
            r = minimize(lambda q: float(ot_long_double(b, force, qt_deg, q)[0]), Q[i], method="Nelder-Mead",
                         options=dict(xatol=1e-11, fatol=1e-17, maxiter=20000, maxfev=40000))
        if r.fun < best:
            best, pose = float(r.fun), r.x
    return best, pose


def brute_force_cell_ld(b: float, force: np.ndarray, qt_deg, step_deg: float = 2.0, polish: int = 6) -> float:
    """min O_t / sigma^2 over one measurement pose: every pose of a step_deg grid over the whole joint space,
    then Nelder-Mead from the ``polish`` best grid poses, all evaluated by :func:`ot_long_double`."""
    return _brute_force_ld(b, force, qt_deg, step_deg, polish)[0]


def ot_ball(b: float, force: np.ndarray, qt_deg, q_deg, prec: int = 128):
    """O_t / sigma^2 = ||A_t A^-1||_F^2 (eq. 16, one measurement pose q_deg (2,) [deg], test pose qt_deg (2,);
    l1 = 1, unit force) in ball arithmetic of prec bits (python-flint's arb), from the angles as the
    doubles they are: an enclosure of the exact value (an arb ball). Plain 2 x 2 algebra on J diag(J^T F)."""
    import flint

    old = flint.ctx.prec
    flint.ctx.prec = prec
    try:
        pi = flint.arb.pi()
        B = flint.arb(float(b))
        F = [flint.arb(float(v)) for v in force]

        def observation(q):
            q1, q2 = (flint.arb(float(v)) * pi / 180 for v in q)
            J = [[-(q1.sin() + B * (q1 + q2).sin()), -B * (q1 + q2).sin()],
                 [q1.cos() + B * (q1 + q2).cos(), B * (q1 + q2).cos()]]
            tau = [J[0][j] * F[0] + J[1][j] * F[1] for j in range(2)]
            return [[J[i][j] * tau[j] for j in range(2)] for i in range(2)]

        At, A = observation(qt_deg), observation(q_deg)
        det = A[0][0] * A[1][1] - A[0][1] * A[1][0]
        inv = [[A[1][1] / det, -A[0][1] / det], [-A[1][0] / det, A[0][0] / det]]
        G = [[At[i][0] * inv[0][j] + At[i][1] * inv[1][j] for j in range(2)] for i in range(2)]
        return sum(G[i][j] * G[i][j] for i in range(2) for j in range(2))
    finally:
        flint.ctx.prec = old


def brute_force_cell_hp(b: float, force: np.ndarray, qt_deg, step_deg: float = 1.0, polish: int = 8) -> float:
    """min O_t / sigma^2 over one measurement pose, for cells where precision matters: a dense step_deg grid
    over the whole joint space and Nelder-Mead from the ``polish`` best grid poses in long double
    (:func:`brute_force_cell_ld`), then the best pose's value in 128-bit ball arithmetic (:func:`ot_ball`;
    its upper end, so the result is an attained value: never below the true minimum)."""
    _, pose = _brute_force_ld(b, force, qt_deg, step_deg, polish)
    return float(ot_ball(b, force, qt_deg, pose).upper())


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
            num = S[0, 0] * t[:, 2] - 2 * S[0, 1] * t[:, 1] + S[1, 1] * t[:, 0]
            v = np.where(det > 1e-12 * t[:, 0] * t[:, 2], num / det,
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
