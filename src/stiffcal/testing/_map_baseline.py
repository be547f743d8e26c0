"""Baseline for ``benchmarks/bench_maps.py`` and the tests: the map solver and its workflow hand-over as
they were at commit 8afcc70 (before issue 16), verbatim below this docstring except for this paragraph, one
helper now shared with the new solver
(``e1_roots``), and the config, statistics and progress functions, which the new module kept.

Every cell is solved by the exact method alone (companion-matrix roots of q12 and q4, closed forms, a hull
sample, finite-difference Newton polish); every tile recomputes the symmetry classes of the whole grid;
tiles are handed over as CSV. :mod:`stiffcal.planning.maps` replaced it; it is kept only so that today's figures can
be printed beside the baseline's in the same run. The original module docstring follows.

Maps over test poses (Figures 6-10): for every test pose of a planar 2R arm, the globally optimal single
measurement pose for O_t (eq. 16, m = 1) and the accuracy gain chi (eq. 27).

Reduction
---------
O_t and chi do not change when every link length, or the force, is scaled (A_t and A both scale by
l^2 |F|), so a map depends only on b = l2 / l1 and the force direction phi; we work with l1 = 1, l2 = b,
|F| = 1. For one measurement pose q, with S = A_t^T A_t (2 x 2),

    O_t = sigma^2 tr(M(q)^-1 S)                                                       (eq. 16, m = 1)

is linear in S: the map value at a test pose is h(S) = min_q <M(q)^-1, S>, the lower support function of
one point set {M(q)^-1} that every cell shares. With A = J diag(tau) (tau = J^T F, the joint torques),
M = diag(tau) J^T J diag(tau) depends on q only through c = cos q2 and x = tau1 / tau2 (rotating the arm
turns the force relative to it, and mirroring about the force line leaves M unchanged), and

    O_t / sigma^2 = Q1(x, c) Q2(x, c) / (b^4 x^2 (1 - c^2)^2),
    Q1 = s11 b^2 - 2 s12 b (b + c) x + s22 (1 + b^2 + 2 b c) x^2,
    Q2 = b^2 (x - 1)^2 + 1 - 2 b c (x - 1).

Every (x, c) in R x (-1, 1) is reached by four measurement poses (two with the force reversed, and
their mirror images); we report the one with q2 in [0, 180] and q1 in (-90, 90] (the rule of Table 2).

Why every cell is the global optimum (the guarantee)
-----------------------------------------------------
The boundary of the (x, c) domain (x = 0, x = +-inf, c = +-1) is exactly where M is singular, and there
O_t -> inf whenever S is positive definite. So the global minimum is an interior stationary point: a
common root of E1 = x dP/dx - 2P and E2 = (1 - c^2) dP/dc + 4cP, P = Q1 Q2. Their resultant in c is, up
to constants, x (bx - b - 1)(bx - b + 1) q4(x) q12(x) (derived symbolically by
``tools/derive_map_polynomials.py``; the linear factors are the singular poses). So the x of every
stationary point is a real root of q12 or q4, and its c is a root in (-1, 1) of the quadratic E1(x, .).
We compute all of these roots (companion-matrix eigenvalues, every root's real part kept as a candidate)
and take the smallest O_t over the finitely many candidates: no starting point, no grid, nothing to get
stuck in. In exact arithmetic the candidate set contains the global minimiser.

In floating point, two things are added. (1) When S is nearly rank-deficient, roots come in tight
clusters and are computed to only ~1e-6, which can cost 1e-5 in O_t (a narrow valley) and can even rank
two nearly equal minima in the wrong order; so the ``N_POLISH`` best candidates are polished by damped
Newton steps in joint coordinates, where those valleys are well scaled, and the smallest value wins.
(2) When S is singular (A_t of rank < 2: the test arm straight or folded, or the force through joint 2)
the polynomials can vanish identically and the infimum can lie on the boundary; those cases are solved in
closed form (:func:`_closed_form_candidates`). As a safety net every cell also gets the best point of a
shared sample of the point set (its convex-hull vertices: a linear function is minimised over a point set
at a hull vertex), polished where it beats the algebraic candidates. The tests compare random cells,
half of them next to the singular test poses, with an independent brute force for three link ratios
(agreement to 1e-6, usually 1e-10), and ``benchmarks/bench_maps.py`` prints the worst excess. Where
A_t = 0 (the arm stretched or folded along the force line) every plan gives O_t = 0: chi is infinite and
the pose undefined (NaN).

Symmetry. Cells (q1*, q2*), (q1* + 180, q2*) and their mirror images about the force line
(2 phi - q1*, -q2*) have the same S, so a map solves one cell per class (about a quarter of the grid)
and writes it for every member; tiles of classes are the workflow's jobs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial import ConvexHull

from ..planning._map_polynomials import Q4, Q12
from ..planning._map_solver import e1_roots
from ..model.criteria import chi as chi_of
from ..model.robot import planar_jacobian
from ..model.stiffness import observation_matrix

#: columns of results/maps/<study>/map.csv
MAP_COLUMNS = ["link_ratio", "force_deg", "q1t_deg", "q2t_deg", "q1_opt_deg", "q2_opt_deg", "O_t", "chi"]
#: |A_t|^2 below this (l1 = 1, |F| = 1) counts as A_t = 0
ZERO_TEST = 1e-20
#: how many of the best algebraic candidates of a cell are polished (:func:`polish`)
N_POLISH = 3
#: Moebius shift x = (z + T) / (1 - T z) that keeps the polynomials' leading coefficients away from 0
_T = np.tan(0.3)


def force_vector(force_deg: float) -> np.ndarray:
    """Unit force (2,) at angle phi [deg] from the x axis."""
    phi = np.radians(force_deg)
    return np.array([np.cos(phi), np.sin(phi)])


def test_information(b: float, force_deg: float, qt_deg: np.ndarray) -> np.ndarray:
    """S = A_t^T A_t for test poses qt_deg (N, 2) [deg] of the arm (1, b) under a unit force: (N, 3) as
    (s11, s12, s22) [m^4 N^2 / rad^2 with l1 = 1]."""
    J = planar_jacobian(np.array([1.0, b]), np.radians(np.atleast_2d(qt_deg)))
    A = observation_matrix(J, force_vector(force_deg))
    S = np.einsum("...di,...dj->...ij", A, A)
    return np.stack([S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]], axis=-1)


def ot_xc(S: np.ndarray, x: np.ndarray, c: np.ndarray, b: float) -> np.ndarray:
    """O_t / sigma^2 of a single measurement pose given by (x, c) (module docstring), broadcast over
    S (..., 3) and x, c (...); x = tau1 / tau2 must be nonzero."""
    s11, s12, s22 = (S[..., i] for i in range(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        w = 1.0 / x
        u = s11 * b * b * w * w - 2 * s12 * b * (b + c) * w + s22 * (1 + b * b + 2 * b * c)  # Q1 / x^2
        q2 = b * b * (x - 1) ** 2 + 1 - 2 * b * c * (x - 1)
    s2 = 1 - c * c
    with np.errstate(divide="ignore", invalid="ignore"):
        # a singular plan (straight arm, or a torque ratio of 0 or inf) is +inf; its limits are handled
        # by _closed_form_candidates, not by evaluating 0 / 0 in round-off
        return np.where((s2 > 1e-8) & (np.abs(w) < 1e12) & np.isfinite(x), u * q2 / (b**4 * s2**2), np.inf)


# --- stationary points -------------------------------------------------------------------------------

def _monomials(S: np.ndarray, keys) -> np.ndarray:
    """(N, K) values of the S monomials s11^i s12^j s22^l for keys (i, j, l)."""
    e = np.array(keys)
    return np.prod(S[:, None, :] ** e[None, :, :], axis=-1)


def _coefficient_matrix(table: dict, b: float):
    """(keys, C): C (degree + 1, K) with coefficient k of the x-polynomial = C[k] @ monomials."""
    keys = sorted({m for row in table.values() for m in row})
    C = np.zeros((len(table), len(keys)))
    for k, row in table.items():
        for m, coeffs in row.items():
            C[k, keys.index(m)] = np.polynomial.polynomial.polyval(b, coeffs)
    return keys, C


def _moebius_matrix(degree: int) -> np.ndarray:
    """T (d+1, d+1) with p~ = T @ p: coefficients (lowest first) of (1 - T z)^d p((z + T)/(1 - T z))."""
    P = np.polynomial.polynomial
    out = np.zeros((degree + 1, degree + 1))
    for k in range(degree + 1):
        term = P.polymul(P.polypow([_T, 1.0], k), P.polypow([1.0, -_T], degree - k))
        out[: len(term), k] = term
    return out


def polynomial_roots(coeffs: np.ndarray) -> np.ndarray:
    """Candidate real roots x of polynomials with coefficients (N, d+1) (lowest power first) -> (N, d).

    Every root's real part is returned: a real root computed as a complex pair (two nearly equal roots
    split by round-off) is kept, and a spurious candidate only costs one evaluation of O_t. The roots are
    found in z, x = (z + T)/(1 - T z), so a vanishing leading coefficient (a root at infinity) does no
    harm; companion-matrix eigenvalues, batched. NaN for a polynomial that vanishes identically.
    """
    n, d1 = coeffs.shape
    d = d1 - 1
    zc = coeffs @ _moebius_matrix(d).T
    scale = np.abs(zc).max(axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    zc = zc / scale
    lead = zc[:, -1]
    ok = np.abs(lead) > 1e-13
    comp = np.zeros((n, d, d))
    comp[:, 1:, :-1] = np.eye(d - 1)
    comp[ok, :, -1] = -zc[ok, :-1] / lead[ok, None]
    z = np.full((n, d), np.nan)
    z[ok] = np.linalg.eigvals(comp[ok]).real
    with np.errstate(divide="ignore"):
        return (z + _T) / (1 - _T * z)


def _c_roots_e1(S: np.ndarray, x: np.ndarray, b: float) -> np.ndarray:
    """Roots c of the quadratic E1(x, c) = x dP/dx - 2P for S (N, 3), x (N, K) -> (N, K, 2), NaN outside
    (-1, 1) or complex (the same function now serves the new solver)."""
    return e1_roots(S, b, x)


def _closed_form_candidates(S: np.ndarray, tr: np.ndarray, b: float, force_deg: float, qt_deg: np.ndarray):
    """Candidates (x, c, value / tr) (N, 2) for the singular test poses (module docstring); S (N, 3) is
    A_t^T A_t divided by its trace tr (N,).

    1. A_t with a zero second column (tau2* = 0, S = diag(s11, 0)): O_t = s11 Q2 / (b^2 x^2 (1-c^2)^2),
       minimised in w = 1/x in closed form (w* = b (b + c) / (1 + b^2 + 2bc)) and then in c
       (3b c^2 + (1 + b^2) c - b = 0). The candidate is evaluated with the cell's own S, so it is always
       a feasible plan.
    2. A straight or folded test arm (cos q2* = +-1): S = t^2 w w^T with w = ((1 + b c*)^2, b^2) and
       t = the force component across the arm. Only the measurement arm in the same shape (c = c*)
       sees the direction w; its limit O_t = t^2 / t_m^2 is smallest with the force across the arm
       (t_m = 1): O_t = t^2. The plan is singular (it cannot identify k1 and k2 separately) but identifies
       exactly the combination that the test pose needs.
    """
    n = len(S)
    c1 = (-(1 + b * b) + np.sqrt((1 + b * b) ** 2 + 12 * b * b)) / (6 * b)
    x1 = (1 + b * b + 2 * b * c1) / (b * (b + c1))
    val1 = ot_xc(S, np.full(n, x1), np.full(n, c1), b)
    ct = np.cos(np.radians(qt_deg[:, 1]))
    straight = np.abs(np.abs(ct) - 1) < 1e-12
    across = np.sin(np.radians(force_deg - qt_deg[:, 0]))  # force component across a straight arm
    val2 = np.where(straight, across**2 / tr.clip(1e-300), np.inf)
    xs = np.stack([np.full(n, x1), np.where(ct > 0, (1 + b) / b, (b - 1) / b)], axis=1)
    cs = np.stack([np.full(n, c1), np.sign(ct)], axis=1)
    return xs, cs, np.stack([val1, val2], axis=1)


@dataclass(frozen=True)
class PointSet:
    """A shared sample of {M(q)^-1}: (x, c) of the hull vertices and p (V, 3) with O_t = p . S."""
    x: np.ndarray
    c: np.ndarray
    p: np.ndarray


def point_set(b: float, n_theta: int = 180, n_c: int = 120) -> PointSet:
    """The sampled point set (theta = atan x and q2 on open grids that avoid x = 0), reduced to the points
    that can be a minimiser for some S >= 0 with tr S = 1 (those whose M^-1 has its smallest eigenvalue
    below the largest eigenvalue of some other point's M^-1) and then to its convex-hull vertices."""
    th = np.linspace(-np.pi / 2, np.pi / 2, n_theta + 2)[1:-1]
    cc = np.cos(np.linspace(0, np.pi, n_c + 2)[1:-1])
    T, C = np.meshgrid(th, cc, indexing="ij")
    x, c = np.tan(T).ravel(), C.ravel()
    p = np.stack([ot_xc(np.eye(3)[i], x, c, b) for i in range(3)], axis=-1)
    keep = np.all(np.isfinite(p), axis=1)
    x, c, p = x[keep], c[keep], p[keep]
    # O_t = tr(W S) with W = [[p0, p1 / 2], [p1 / 2, p2]] = M^-1 (scaled): lambda_min(W) <= O_t <= lambda_max(W)
    mid, rad = (p[:, 0] + p[:, 2]) / 2, np.hypot((p[:, 0] - p[:, 2]) / 2, p[:, 1] / 2)
    useful = mid - rad <= np.min(mid + rad)
    x, c, p = x[useful], c[useful], p[useful]
    v = np.unique(ConvexHull(p).vertices)
    return PointSet(x[v], c[v], p[v])


def _sample_candidates(S: np.ndarray, ps: PointSet, chunk: int = 4096):
    """Best sampled point per cell: (x, c, value) (N,)."""
    idx = np.empty(len(S), int)
    for i in range(0, len(S), chunk):
        idx[i:i + chunk] = np.argmin(S[i:i + chunk] @ ps.p.T, axis=1)
    return ps.x[idx], ps.c[idx], np.einsum("nk,nk->n", S, ps.p[idx])


# --- local polish of ill-conditioned cells -------------------------------------------------------------

def _xc_from_pose(psi: np.ndarray, q2: np.ndarray, b: float):
    """(x, c) of the measurement pose with elbow q2 [rad] and the force at psi [rad] in the arm frame."""
    s2, c2 = np.sin(q2), np.cos(q2)
    f1, f2 = np.cos(psi), np.sin(psi)
    tau1 = -b * s2 * f1 + (1 + b * c2) * f2
    tau2 = -b * s2 * f1 + b * c2 * f2
    with np.errstate(divide="ignore", invalid="ignore"):
        return tau1 / tau2, c2


def _pose_from_xc_rad(x: np.ndarray, c: np.ndarray, b: float):
    """Inverse of :func:`_xc_from_pose`: (psi, q2) [rad] with q2 in [0, pi]. In the arm frame (q1 = 0)
    J1 = (-b s2, 1 + b c), J2 = (-b s2, b c), and tau1 = x tau2 iff the force is normal to J1 - x J2,
    written with (cos t, sin t) ~ (1, x) so that x = inf is handled."""
    q2 = np.arccos(np.clip(c, -1, 1))
    t = np.arctan(x)
    d1 = -b * np.sin(q2) * (np.cos(t) - np.sin(t))
    d2 = (1 + b * c) * np.cos(t) - b * c * np.sin(t)
    return np.arctan2(d1, -d2), q2


def polish(S: np.ndarray, x: np.ndarray, c: np.ndarray, b: float, iters: int = 8, h: float = 1e-6):
    """Damped Newton steps (central differences) on O_t over the measurement pose (psi, q2), from (x, c),
    for cells S (N, 3). Returns (x, c, value), never worse than the start.

    Used where the algebraic candidates are ill-conditioned: test poses close to a singular A_t put the
    optimum in a narrow valley near the straight arm, where a root error of 1e-6 in x costs 1e-4 in O_t.
    In joint coordinates that valley is well scaled.
    """
    def f(p, q):
        xx, cc = _xc_from_pose(p, q, b)
        with np.errstate(all="ignore"):
            v = ot_xc(S, xx, cc, b)
        return np.where(np.isfinite(v) & (v >= 0), v, np.inf)

    p, q = _pose_from_xc_rad(x, c, b)
    f0 = f(p, q)
    with np.errstate(all="ignore"):
        p, q, f0 = _newton(f, p, q, f0, iters, h)
    xx, cc = _xc_from_pose(p, q, b)
    return xx, cc, f0


def _newton(f, p, q, f0, iters: int, h: float):
    """Damped Newton on f(p, q) (vectorised over cells) with a central-difference gradient and Hessian;
    a gradient step where the Hessian is not positive definite; backtracking keeps only improvements."""
    for _ in range(iters):
        fpp, fmm = f(p + h, q), f(p - h, q)
        fqq, fqm = f(p, q + h), f(p, q - h)
        fa, fb, fc, fd = f(p + h, q + h), f(p + h, q - h), f(p - h, q + h), f(p - h, q - h)
        g = np.stack([(fpp - fmm) / (2 * h), (fqq - fqm) / (2 * h)], axis=-1)
        H11 = (fpp - 2 * f0 + fmm) / h**2
        H22 = (fqq - 2 * f0 + fqm) / h**2
        H12 = (fa - fb - fc + fd) / (4 * h * h)
        det = H11 * H22 - H12**2
        newton = (H11 > 0) & (det > 0) & np.all(np.isfinite(g), axis=-1)
        step = np.where(newton[:, None],
                        -np.stack([H22 * g[:, 0] - H12 * g[:, 1], H11 * g[:, 1] - H12 * g[:, 0]], -1) / det[:, None],
                        -1e-3 * g / np.maximum(np.abs(g).max(axis=-1, keepdims=True), 1e-300))
        step = np.nan_to_num(step)
        norm = np.abs(step).max(axis=-1, keepdims=True)
        step = step * np.minimum(1.0, 0.1 / np.maximum(norm, 1e-300))
        improved = np.zeros(len(p), bool)
        for frac in (1.0, 0.5, 0.25, 0.0625):
            cand = f(p + frac * step[:, 0], q + frac * step[:, 1])
            take = (cand < f0) & ~improved
            p = np.where(take, p + frac * step[:, 0], p)
            q = np.where(take, q + frac * step[:, 1], q)
            f0 = np.where(take, cand, f0)
            improved |= take
        if not improved.any():
            break
    return p, q, f0


# --- from (x, c) back to joint angles ----------------------------------------------------------------

def pose_from_xc(x: np.ndarray, c: np.ndarray, b: float, force_deg: float) -> np.ndarray:
    """Measurement pose (N, 2) [deg] with torque ratio x and cos q2 = c: q2 in [0, 180], q1 in (-90, 90]
    (the other copy with the same information is q1 + 180). A straight or folded arm (|c| = 1, the
    limit plans of :func:`_closed_form_candidates`) gets the force across it."""
    psi, q2 = _pose_from_xc_rad(x, c, b)
    q1 = np.where(np.abs(c) >= 1, force_deg + 90.0, force_deg - np.degrees(psi))
    q1 = (q1 + 90.0) % 180.0 - 90.0
    q1 = np.where(q1 == -90.0, 90.0, q1)
    return np.stack([q1 + 0.0, np.degrees(q2) + 0.0], axis=-1)


# --- the map -----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CellSolution:
    """Per cell: O_t / sigma^2, the optimal measurement pose [deg], and which candidate won."""
    ot: np.ndarray
    pose_deg: np.ndarray
    source: np.ndarray  # 0 algebraic, 1 closed form, 2 hull sample, 3 polished, -1 A_t = 0


def solve_cells(b: float, force_deg: float, qt_deg: np.ndarray, ps: PointSet | None = None) -> CellSolution:
    """The exact map for test poses qt_deg (N, 2) [deg] (module docstring)."""
    qt_deg = np.atleast_2d(np.asarray(qt_deg, float))
    S = test_information(b, force_deg, qt_deg)
    n = len(S)
    tr = S[:, 0] + S[:, 2]
    S_unit = S / np.maximum(tr, 1e-300)[:, None]  # O_t is linear in S: solve for tr S = 1
    xs = []
    for table in (Q12, Q4):
        keys, C = _coefficient_matrix(table, b)
        xs.append(polynomial_roots(_monomials(S_unit, keys) @ C.T))
    x = np.concatenate(xs, axis=1)
    x = np.where(np.abs(x) > 1e-12, x, np.nan)
    c = _c_roots_e1(S_unit, x, b)
    X = np.repeat(x[:, :, None], 2, axis=2).reshape(n, -1)
    Cc = c.reshape(n, -1)
    with np.errstate(all="ignore"):
        vals = ot_xc(S_unit[:, None, :], X, Cc, b)
    vals = np.where(np.isfinite(vals) & (vals >= 0), vals, np.inf)
    cx, cc, cv = _closed_form_candidates(S_unit, tr, b, force_deg, qt_deg)
    ps = ps or point_set(b)
    sx, sc, sv = _sample_candidates(S_unit, ps)
    allx = np.concatenate([X, cx, sx[:, None]], axis=1)
    allc = np.concatenate([Cc, cc, sc[:, None]], axis=1)
    allv = np.concatenate([vals, cv, sv[:, None]], axis=1)
    # Newton polish of the N_POLISH best algebraic candidates (round-off in the roots of a nearly
    # rank-deficient S costs up to 1e-5 in O_t, enough to rank two minima of nearly equal value in the
    # wrong order) and, where the sample came out ahead, of the best sampled point
    k_alg = X.shape[1]
    rows = np.arange(n)
    top = np.argpartition(allv[:, :k_alg], N_POLISH - 1, axis=1)[:, :N_POLISH]
    top = np.take_along_axis(top, np.argsort(np.take_along_axis(allv, top, 1), axis=1, kind="stable"), 1)
    behind = sv < allv[rows, top[:, 0]]
    extra = [polish(S_unit, allx[rows, ia], allc[rows, ia], b) for ia in top.T]
    if behind.any():
        px, pc, pv = polish(S_unit[behind], sx[behind], sc[behind], b)
        ex = [np.zeros(n), np.zeros(n), np.full(n, np.inf)]
        for e, v in zip(ex, (px, pc, pv)):
            e[behind] = v
        extra.append(tuple(ex))
    for px, pc, pv in extra:
        allx = np.concatenate([allx, px[:, None]], axis=1)
        allc = np.concatenate([allc, pc[:, None]], axis=1)
        allv = np.concatenate([allv, pv[:, None]], axis=1)
    # among (near-)ties prefer the algebraic candidates, then the closed forms: an attained, regular plan
    best = np.argmax(allv <= allv.min(axis=1, keepdims=True) * (1 + 1e-10), axis=1)
    n_cf = cx.shape[1]
    source = np.where(best < k_alg, 0, np.where(best < k_alg + n_cf, 1, np.where(best == k_alg + n_cf, 2, 3)))
    ot = allv[rows, best] * tr
    pose = pose_from_xc(allx[rows, best], allc[rows, best], b, force_deg)
    zero = tr <= ZERO_TEST
    ot = np.where(zero, 0.0, ot)
    pose[zero] = np.nan
    source = np.where(zero, -1, source)
    return CellSolution(ot, pose, source)


def test_pose_grid(step_deg: float) -> np.ndarray:
    """The grid of test poses (N, 2) [deg]: q1*, q2* over [-180, 180) with step step_deg, q1* slowest."""
    g = np.arange(-180.0, 180.0 - 1e-9, step_deg)
    Q1, Q2 = np.meshgrid(g, g, indexing="ij")
    return np.stack([Q1.ravel(), Q2.ravel()], axis=-1)


def _wrap(q):
    return (np.asarray(q) + 180.0) % 360.0 - 180.0


def canonical_test_poses(qt_deg: np.ndarray, force_deg: float) -> np.ndarray:
    """The representative (N, 2) [deg] of each test pose's symmetry class: the lexicographically smallest
    of (q1, q2), (q1 + 180, q2) (the force reversed relative to the arm) and their mirror images about
    the force line (2 phi - q1, -q2). All four have the same S = A_t^T A_t, hence the same map cell."""
    q1, q2 = qt_deg[:, 0], qt_deg[:, 1]
    m1 = 2 * force_deg - q1
    orbit = np.stack([np.stack([q1, q2], -1), np.stack([q1 + 180, q2], -1),
                      np.stack([m1, -q2], -1), np.stack([m1 + 180, -q2], -1)])
    orbit = np.round(_wrap(orbit), 9) + 0.0
    orbit[orbit == 180.0] = -180.0
    order = np.lexsort((orbit[..., 1], orbit[..., 0]), axis=0)[0]
    return orbit[order, np.arange(len(qt_deg))]


def map_frame(b: float, force_deg: float, qt_deg: np.ndarray, sigma: float = 1.0, progress=None,
              chunk: int = 16384) -> pd.DataFrame:
    """The map over test poses qt_deg (N, 2) [deg] as a table with :data:`MAP_COLUMNS`.

    chi = O_t* / O_t with O_t* = n sigma^2 / m = 2 sigma^2 (eqs. 17, 27), as in the paper's Table 3;
    inf where A_t = 0. progress(done, total) is called after every chunk of cells.
    """
    ps = point_set(b)
    parts = []
    for i in range(0, len(qt_deg), chunk):
        parts.append(solve_cells(b, force_deg, qt_deg[i:i + chunk], ps))
        if progress:
            progress(min(i + chunk, len(qt_deg)), len(qt_deg))
    ot = np.concatenate([p.ot for p in parts]) * sigma**2
    pose = np.concatenate([p.pose_deg for p in parts])
    with np.errstate(divide="ignore"):
        chi = np.where(ot > 0, chi_of(ot, 2, 1, sigma), np.inf)
    return pd.DataFrame({"link_ratio": b, "force_deg": float(force_deg), "q1t_deg": qt_deg[:, 0],
                         "q2t_deg": qt_deg[:, 1], "q1_opt_deg": pose[:, 0], "q2_opt_deg": pose[:, 1],
                         "O_t": ot, "chi": chi})


def symmetry_classes(step_deg: float, force_deg: float):
    """(grid (N, 2), reps (U, 2), inverse (N,)): the test-pose grid, its class representatives (sorted)
    and the class of every cell; U is about N / 4."""
    grid = test_pose_grid(step_deg)
    canon = canonical_test_poses(grid, force_deg)
    key = np.round((canon + 180.0) * 1e6).astype(np.int64)
    _, first, inverse = np.unique(key[:, 0] * (1 << 31) + key[:, 1], return_index=True, return_inverse=True)
    return grid, canon[first], inverse.ravel()


def n_tiles(step_deg: float, force_deg: float, tile_cells: int) -> int:
    """Jobs per map: tiles of at most tile_cells symmetry classes."""
    return int(np.ceil(len(symmetry_classes(step_deg, force_deg)[1]) / tile_cells))


def map_tile(b: float, force_deg: float, step_deg: float, tile_cells: int, tile: int, sigma: float = 1.0,
             progress=None) -> pd.DataFrame:
    """Tile ``tile`` of the step_deg map: classes tile * tile_cells ... (tile + 1) * tile_cells - 1 (in
    the order of :func:`symmetry_classes`), each solved once and written for every member cell."""
    grid, reps, inverse = symmetry_classes(step_deg, force_deg)
    lo, hi = tile * tile_cells, min((tile + 1) * tile_cells, len(reps))
    if not 0 <= lo < hi:
        raise ValueError(f"tile {tile} is out of range: the map has {n_tiles(step_deg, force_deg, tile_cells)}")
    solved = map_frame(b, force_deg, reps[lo:hi], sigma, progress)
    mine = (inverse >= lo) & (inverse < hi)
    out = solved.iloc[inverse[mine] - lo].reset_index(drop=True)
    out["q1t_deg"], out["q2t_deg"] = grid[mine, 0], grid[mine, 1]
    return out


def merge_tiles(frames: list[pd.DataFrame], step_deg: float) -> pd.DataFrame:
    """The whole map from its tiles, sorted by (q1*, q2*); raises ValueError when cells are missing or
    repeated."""
    df = pd.concat(frames, ignore_index=True).sort_values(["q1t_deg", "q2t_deg"], kind="stable")
    expected = len(test_pose_grid(step_deg))
    if len(df) != expected or df.duplicated(["q1t_deg", "q2t_deg"]).any():
        raise ValueError(f"the map tiles hold {len(df)} cells ({df.duplicated(['q1t_deg', 'q2t_deg']).sum()} "
                         f"repeated); the {step_deg} deg grid has {expected}")
    return df.reset_index(drop=True)[MAP_COLUMNS]
