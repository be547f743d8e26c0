"""Numerics behind :mod:`stiffcal.planning.maps` (private): the reduced single-pose objective, its exact stationary
points by real-root isolation, and the table of the normalised test information S that prunes them.

The argument is in the docstring of :mod:`stiffcal.planning.maps`; this module holds the machinery. Units: l1 = 1,
l2 = b, |F| = 1, tr S = 1 (O_t is linear in S and scales with l^4 |F|^2, so a cell's value is tr S times
the value computed here). Measurement poses are (theta, gamma) with x = tan(theta) = tau1 / tau2 and
gamma = q2 in (0, pi), c = cos(gamma), s = sin(gamma).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ._map_polynomials import Q4, Q12

#: relative rounding bound of polynomial coefficients computed from S, in units of the working precision
#: (about 25 times the worst case of the 35-term sums, so that a sign is called certain only when it is)
COEFF_ULPS = 90
#: the theta strips: K strips of equal width over (-pi/2, pi/2), theta = 0 (x = 0) an edge
N_STRIPS = 32
#: isolation stops below this theta width (the interval is then evaluated at its ends and middle)
MIN_WIDTH = 1e-11
#: an interval where a coefficient's sign stays uncertain is evaluated once narrower than this
AMB_WIDTH = 1e-7
#: a cell with more uncertain intervals than this at once is left to the fallback
MAX_AMBIGUOUS = 24

STRIP_EDGES = np.linspace(-np.pi / 2, np.pi / 2, N_STRIPS + 1)


def _eps(a) -> float:
    """Unit roundoff of the array's precision (double, or long double for the hard cells)."""
    return float(np.finfo(np.asarray(a).dtype).eps)


@lru_cache(maxsize=4)
def _edges(dtype) -> np.ndarray:
    return STRIP_EDGES.astype(dtype)


# --- the reduced objective --------------------------------------------------------------------------

def factor(S: np.ndarray) -> np.ndarray:
    """A factor R (N, 2, 2) with R^T R = S for S (N, 3) = (s11, s12, s22) positive semidefinite (upper
    triangular, by Cholesky; used for table nodes, whose S is exact)."""
    r11 = np.sqrt(np.maximum(S[:, 0], 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        r12 = np.where(r11 > 0, S[:, 1] / r11, 0.0)
    r22 = np.sqrt(np.maximum(S[:, 2] - r12 * r12, 0.0))
    R = np.zeros((len(S), 2, 2), S.dtype)
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 1] = r11, r12, r22
    return R


def objective(R: np.ndarray, b: float, x, c, s):
    """O_t / sigma^2 (l1 = 1, |F| = 1) of the measurement pose (x, c, s) for S = R^T R; R (..., 2, 2)
    broadcasts against x, c, s.

    Written without cancellation near singular poses: Q1 = |R v|^2 + s22 s^2 x^2 with v = (b, -(b + c) x),
    Q2 = (b (x - 1) - c)^2 + s^2, O_t = Q1 Q2 / (b^4 x^2 s^4)."""
    r00, r01, r10, r11 = R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1]
    bx = (b + c) * x
    v1 = r00 * b - r01 * bx
    v2 = r10 * b - r11 * bx
    s2 = s * s
    q1 = v1 * v1 + v2 * v2 + (r01 * r01 + r11 * r11) * s2 * x * x
    d = b * (x - 1.0) - c
    q2 = d * d + s2
    with np.errstate(divide="ignore", invalid="ignore"):
        return q1 * q2 / (b**4 * x * x * s2 * s2)


def _line_parts(r00, r01, r10, r11, b, x, c, s):
    """Q1, dQ1/dc, Q2, dQ2/dc at (x, c, s) from the entries of the factor R of S (accurate next to
    rank-one S)."""
    bx = (b + c) * x
    w1, w2 = r00 * b - r01 * bx, r10 * b - r11 * bx
    s22 = r01 * r01 + r11 * r11
    q1 = w1 * w1 + w2 * w2 + s22 * s * s * x * x
    q1c = -2 * x * (w1 * r01 + w2 * r11) - 2 * s22 * c * x * x
    d = b * (x - 1.0) - c
    return q1, q1c, d * d + s * s, -2 * b * (x - 1.0)


def c_star(S, R, b, x, c0=None, iters: int = 80):
    """The unique minimiser over c in (-1, 1) of O_t at fixed x, as (c, s, value); R (N, 2, 2), x (N,),
    c0 an optional start (N,) (NaN: none). S is not used (kept for a uniform signature).

    For fixed x, O_t = Q1 Q2 / (b^4 x^2 (1 - c^2)^2) with Q1, Q2 linear in c and nonnegative on [-1, 1];
    (log O_t)'' = 4 (1 + c^2)/(1 - c^2)^2 - (Q1_c/Q1)^2 - (Q2_c/Q2)^2 > 0 there (each ratio is at most
    1/(1 - |c|) because Q(+-1) >= 0), so d log O_t / dc increases from -inf to +inf: one root. Found by
    Newton steps in gamma safeguarded by bisection; gamma keeps s accurate near c = +-1."""
    n = len(x)
    eps = _eps(x)
    lo, hi = np.zeros(n, x.dtype), np.full(n, np.pi, x.dtype)
    g = np.full(n, np.pi / 2, x.dtype)
    if c0 is not None:
        g = np.where(np.abs(c0) < 1, np.arccos(np.clip(np.nan_to_num(c0), -1, 1)), g)
    act = np.arange(n)
    ga, xa, la, ha = g, x, lo, hi
    ra = [R[:, i, j] for i in (0, 1) for j in (0, 1)]
    for _ in range(iters):
        c, s = np.cos(ga), np.sin(ga)
        q1, q1c, q2, q2c = _line_parts(*ra, b, xa, c, s)
        with np.errstate(divide="ignore", invalid="ignore"):
            a1, a2 = q1c / q1, q2c / q2
            d = a1 + a2 + 4 * c / (s * s)                 # d log O_t / dc, increasing in c
            dd = -a1 * a1 - a2 * a2 + 4 * (1 + c * c) / (s * s) ** 2
            step = d / (dd * s)                           # Newton in gamma (dc/dgamma = -s)
        # d > 0: the root has a smaller c, i.e. a larger gamma (c = cos(gamma))
        la = np.where(d > 0, ga, la)
        ha = np.where(d > 0, ha, ga)
        done = (np.abs(step) <= 4 * eps * ga) | (ha - la <= 4 * eps * ha) | (d == 0)
        new = ga + step
        bad = ~np.isfinite(new) | (new <= la) | (new >= ha)
        ga = np.where(done, ga, np.where(bad, 0.5 * (la + ha), new))
        if done.all():
            g[act] = ga
            break
        if done.mean() > 0.25:                            # drop the converged ones now and then
            g[act[done]] = ga[done]
            keep = ~done
            act, ga, xa, la, ha = act[keep], ga[keep], xa[keep], la[keep], ha[keep]
            ra = [r[keep] for r in ra]
    else:
        g[act] = ga
    c, s = np.cos(g), np.sin(g)
    return c, s, objective(R, b, x, c, s)


def e1_roots(S, b, x):
    """Roots c in (-1, 1) of E1(x, c) = x dP/dx - 2 P (P = Q1 Q2), a quadratic in c: every stationary
    point (x, c) has its c among them. S (N, 3), x (N, K) -> (N, K, 2), NaN where no root."""
    s11, s12, s22 = (S[:, i, None] for i in range(3))
    a1 = s11 * b * b - 2 * s12 * b * b * x + s22 * (1 + b * b) * x * x
    da1 = -2 * s12 * b * b + 2 * s22 * (1 + b * b) * x
    b1 = -2 * s12 * b * x + 2 * s22 * b * x * x
    db1 = -2 * s12 * b + 4 * s22 * b * x
    a2 = b * b * (x - 1) ** 2 + 1
    da2 = 2 * b * b * (x - 1)
    b2 = -2 * b * (x - 1)
    db2 = -2 * b
    p = [a1 * a2, a1 * b2 + b1 * a2, b1 * b2]
    dp = [da1 * a2 + a1 * da2, da1 * b2 + a1 * db2 + db1 * a2 + b1 * da2, db1 * b2 + b1 * db2]
    e0, e1, e2 = (x * d - 2 * v for d, v in zip(dp, p))
    with np.errstate(all="ignore"):
        disc = np.sqrt(e1 * e1 - 4 * e2 * e0)
        q = -0.5 * (e1 + np.copysign(disc, e1))
        small = np.abs(e2) <= 1e-14 * (np.abs(e0) + np.abs(e1))
        r1 = np.where(small, -e0 / e1, q / e2)
        r2 = np.where(small, np.nan, e0 / q)
    roots = np.stack([r1, r2], axis=-1)
    return np.where(np.abs(roots) < 1, roots, np.nan)


def candidate_values(S, R, b, x):
    """(c, value) (N, K, 2) of the points (x, c) with c a root of E1(x, .) in (-1, 1); +inf elsewhere."""
    c = e1_roots(S, b, x)
    s = np.sqrt((1 - c) * (1 + c))
    with np.errstate(all="ignore"):
        v = objective(R[:, None, None], b, x[:, :, None], c, s)
    return c, np.where(np.isfinite(v) & (v >= 0), v, np.inf)


def _parts(R, b, x, c, s):
    """Q1, Q2 and their derivatives in x and c at (x, c, s), from the factor R of S (accurate next to
    rank-one S): Q1 = |w|^2 + s22 s^2 x^2 with w = R (b, -(b + c) x)."""
    r0, r1 = R[..., :, 0], R[..., :, 1]
    w = r0 * b - r1 * ((b + c) * x)[..., None]
    wx = -r1 * (b + c)[..., None] if np.ndim(c) else -r1 * (b + c)
    wc = -r1 * x[..., None]
    s22 = np.sum(r1 * r1, axis=-1)
    dot = lambda a, bb: np.sum(a * bb, axis=-1)  # noqa: E731
    q1 = dot(w, w) + s22 * s * s * x * x
    q1x = 2 * dot(w, wx) + 2 * s22 * s * s * x
    q1c = 2 * dot(w, wc) - 2 * s22 * c * x * x
    q1xx = 2 * dot(wx, wx) + 2 * s22 * s * s
    q1xc = 2 * (dot(wc, wx) - dot(w, r1)) - 4 * s22 * c * x
    d = b * (x - 1.0) - c
    return q1, q1x, q1c, q1xx, q1xc, d * d + s * s, 2 * b * d, -2 * b * (x - 1.0)


def newton(S, R, b, theta, gamma, iters: int = 12):
    """Damped Newton steps on log O_t in (theta, gamma) with the analytic gradient and Hessian (a gradient
    step where the Hessian is not positive definite), vectorised; never worse than the start. Returns
    (theta, gamma, value)."""
    def value(t, g):
        with np.errstate(all="ignore"):
            v = objective(R, b, np.tan(t), np.cos(g), np.sin(g))
        inside = (np.abs(t) < np.pi / 2) & (t != 0) & (g > 0) & (g < np.pi)
        return np.where(inside & np.isfinite(v) & (v >= 0), v, np.inf)

    f0 = value(theta, gamma)
    for _ in range(iters):
        x, c, s = np.tan(theta), np.cos(gamma), np.sin(gamma)
        with np.errstate(all="ignore"):
            q1, q1x, q1c, q1xx, q1xc, q2, q2x, q2c = _parts(R, b, x, c, s)
            lx = q1x / q1 + q2x / q2 - 2 / x
            lc = q1c / q1 + q2c / q2 + 4 * c / (s * s)
            lxx = q1xx / q1 - (q1x / q1) ** 2 + 2 * b * b / q2 - (q2x / q2) ** 2 + 2 / (x * x)
            lxc = q1xc / q1 - q1x * q1c / q1**2 - 2 * b / q2 - q2x * q2c / q2**2
            lcc = -(q1c / q1) ** 2 - (q2c / q2) ** 2 + 4 * (1 + c * c) / (s * s) ** 2
            xt, xtt = 1 + x * x, 2 * x * (1 + x * x)
            g1, g2 = lx * xt, -lc * s
            h11 = lxx * xt * xt + lx * xtt
            h12 = -lxc * xt * s
            h22 = lcc * s * s - lc * c
            det = h11 * h22 - h12 * h12
            pd = (h11 > 0) & (det > 0)
            d1 = np.where(pd, -(h22 * g1 - h12 * g2) / det, -g1)
            d2 = np.where(pd, -(h11 * g2 - h12 * g1) / det, -g2)
        d1, d2 = np.nan_to_num(d1), np.nan_to_num(d2)
        big = np.maximum(np.abs(d1), np.abs(d2))
        scale = np.minimum(1.0, 0.2 / np.maximum(big, 1e-300))
        d1, d2 = d1 * scale, d2 * scale
        improved = np.zeros(theta.shape, bool)
        for frac in (1.0, 0.5, 0.25, 0.125, 1 / 32):
            t_new, g_new = theta + frac * d1, gamma + frac * d2
            v = value(t_new, g_new)
            take = (v < f0) & ~improved
            theta, gamma = np.where(take, t_new, theta), np.where(take, g_new, gamma)
            f0 = np.where(take, v, f0)
            improved |= take
        if not improved.any():
            break
    return theta, gamma, f0


# --- the derived polynomials and real-root isolation ------------------------------------------------

def _coefficient_matrix(table: dict, b):
    keys = sorted({m for row in table.values() for m in row})
    C = np.zeros((len(table), len(keys)), np.asarray(b).dtype)
    for k, row in table.items():
        for m, coeffs in row.items():
            C[k, keys.index(m)] = np.polynomial.polynomial.polyval(b, coeffs)
    return np.array(keys), C


def _strip_transform(ta: float, tb: float, n: int) -> np.ndarray:
    """T (n+1, n+1): the coefficients (in tau) of r(tau) = sum_k q_k X^k Y^(n-k) with (X, Y) =
    (1 - tau) (sin ta, cos ta) + tau (sin tb, cos tb) are T @ q. The roots tau in (0, 1) of r are the roots
    x = X / Y of q with theta in (ta, tb) (the direction (X, Y) turns monotonically from ta to tb)."""
    P = np.polynomial.polynomial
    X = [np.sin(ta), np.sin(tb) - np.sin(ta)]
    Y = [np.cos(ta), np.cos(tb) - np.cos(ta)]
    T = np.zeros((n + 1, n + 1), np.asarray(ta).dtype)
    for k in range(n + 1):
        col = P.polymul(P.polypow(X, k), P.polypow(Y, n - k))
        T[: len(col), k] = col
    return T


@dataclass(frozen=True)
class Polynomials:
    """q12 and q4 for link ratio b: monomial exponents and coefficient matrices C (coefficients =
    C @ monomials of S), and per theta strip the transforms T (:func:`_strip_transform`) with |T|."""

    b: float
    keys: tuple
    C: tuple
    T: tuple
    Tabs: tuple

    def coefficients(self, S: np.ndarray):
        """[(q, e)] for q12 and q4: coefficients (N, n+1), lowest power first, and rounding bounds."""
        out = []
        for k, C in zip(self.keys, self.C):
            m = np.prod(S[:, None, :] ** k[None, :, :], axis=-1)
            out.append((m @ C.T, COEFF_ULPS * _eps(S) * (np.abs(m) @ np.abs(C).T)))
        return out


@lru_cache(maxsize=16)
def polynomials(b: float, dtype=np.float64) -> Polynomials:
    """:class:`Polynomials` for link ratio b in precision dtype (float64, or longdouble for hard cells)."""
    keys, Cs, Ts, Ta = [], [], [], []
    edges = _edges(dtype)
    for table in (Q12, Q4):
        k, C = _coefficient_matrix(table, dtype(b))
        n = C.shape[0] - 1
        T = np.stack([_strip_transform(edges[i], edges[i + 1], n) for i in range(N_STRIPS)])
        keys.append(k)
        Cs.append(C)
        Ts.append(T)
        Ta.append(np.abs(T))
    return Polynomials(float(b), tuple(keys), tuple(Cs), tuple(Ts), tuple(Ta))


def _variations(r: np.ndarray, er: np.ndarray) -> np.ndarray:
    """Sign variations of the columns of r (n+1, P) (Descartes' rule); -1 where a coefficient's sign is
    uncertain (|r| <= er)."""
    amb = np.abs(r) <= er
    sgn = np.where(amb, 0.0, np.sign(r))
    V = np.zeros(r.shape[1], int)
    last = np.zeros(r.shape[1])
    for row in sgn:
        V += (row * last) < 0
        last = np.where(row != 0, row, last)
    return np.where(amb.any(axis=0), -1, V)


def _taylor_shift(r: np.ndarray) -> np.ndarray:
    """Coefficients of r(u + 1) for r (n+1, P), coefficient-major, lowest power first (in place)."""
    n = r.shape[0] - 1
    for i in range(n):
        for j in range(n - 1, i - 1, -1):
            r[j] += r[j + 1]
    return r


def _theta(strip, tau):
    """theta of the chord parameter tau in [0, 1] of a strip."""
    e = _edges(tau.dtype)
    ta, tb = e[strip], e[strip + 1]
    return np.arctan2(np.sin(ta) + tau * (np.sin(tb) - np.sin(ta)), np.cos(ta) + tau * (np.cos(tb) - np.cos(ta)))


def _shift_with_bounds(r, er, eps):
    """r(u + 1) and a rounding bound, for r, er (n+1, P): shift(er) + (n + 1) eps shift(|r|), computed as
    one shift (the shift is linear with nonnegative weights)."""
    P = r.shape[1]
    n = r.shape[0] - 1
    z = _taylor_shift(np.concatenate([r, er + (n + 1) * eps * np.abs(r)], axis=1))
    return z[:, :P], z[:, P:]


def isolate(r, er, cell, strip):
    """Isolate the roots in (0, 1) of the strip polynomials r (P, n+1) (rounding bounds er) by Descartes'
    rule of signs with bisection (the Collins-Akritas algorithm), vectorised over the pairs.

    Returns (cell, lo, hi, kind) of theta intervals: kind 1 holds exactly one simple root, kind 2 is an
    interval that may hold roots but is narrower than MIN_WIDTH (AMB_WIDTH where a coefficient's sign is
    uncertain): evaluated at its ends and middle; kind 3 marks a cell whose coefficient signs stay
    uncertain on more than MAX_AMBIGUOUS intervals at once: left to the fallback. Intervals without a
    sign variation hold no root and are dropped."""
    n = r.shape[1] - 1
    eps = _eps(r)
    r, er = np.ascontiguousarray(r.T), np.ascontiguousarray(er.T)     # coefficient-major (n+1, P)
    lo_t = np.zeros(r.shape[1], r.dtype)
    w_t = np.ones(r.shape[1], r.dtype)
    ncell = int(cell.max()) + 1 if len(cell) else 0
    out = []
    halves = (2.0 ** -np.arange(n + 1))[:, None]
    strip_width = np.diff(STRIP_EDGES)
    while r.shape[1]:
        # Descartes' bound on (0, 1): the variations of (1 + u)^n r(1 / (1 + u))
        V = _variations(*_shift_with_bounds(r[::-1], er[::-1], eps))
        pending = (V >= 2) | (V < 0)
        count = np.bincount(cell[V < 0], minlength=ncell)
        kind = np.where(V == 1, 1, 0)
        # the chord parameter is within 0.2 % of uniform in theta on a strip of pi/32
        width = 1.01 * w_t * strip_width[strip]
        kind = np.where(pending & ((width <= MIN_WIDTH) | ((V < 0) & (width <= AMB_WIDTH))), 2, kind)
        kind = np.where(pending & (count[cell] > MAX_AMBIGUOUS), 3, kind)
        keep = kind > 0
        if keep.any():
            out.append((cell[keep], _theta(strip[keep], lo_t[keep]), _theta(strip[keep], lo_t[keep] + w_t[keep]),
                        kind[keep]))
        split = pending & (kind == 0)
        if not split.any():
            break
        # left half: r(u / 2); right half: r((1 + u) / 2) = left(u + 1)
        left = r[:, split] * halves
        left_e = er[:, split] * halves + eps * np.abs(left)
        right, right_e = _shift_with_bounds(left.copy(), left_e.copy(), eps)
        r = np.concatenate([left, right], axis=1)
        er = np.concatenate([left_e, right_e], axis=1)
        scale = np.maximum(np.abs(r).max(axis=0), 1e-300)
        r, er = r / scale, er / scale
        cell = np.concatenate([cell[split], cell[split]])
        strip = np.concatenate([strip[split], strip[split]])
        w = 0.5 * w_t[split]
        lo_t = np.concatenate([lo_t[split], lo_t[split] + w])
        w_t = np.concatenate([w, w])
    if not out:
        return np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0, int)
    return tuple(np.concatenate(z) for z in zip(*out))


def _poly_theta(q, th):
    """A positive multiple of q(tan th) and its derivative in th, stable for |th| <= pi/2 (Horner in tan
    for |th| <= pi/4, in cot beyond; the degrees are even). q (P, n+1), th (P,)."""
    n = q.shape[1] - 1
    small = np.abs(th) <= np.pi / 4
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(small, np.tan(th), 1.0 / np.tan(th))
    v = np.zeros(len(th), th.dtype)
    d = np.zeros(len(th), th.dtype)
    order = range(n, -1, -1)
    # small: sum q_k t^k; large: sum q_k t^(n-k) (t = cot)
    for k in order:
        coef = np.where(small, q[:, k], q[:, n - k])
        d = d * t + v
        v = v * t + coef
    dth = np.where(small, 1 + t * t, -(1 + t * t))
    return v, d * dth


def refine(q, lo, hi, iters: int = 80, tol: float = 1e-11):
    """The single root in (lo, hi) of q(tan th) (a sign change), to tol in theta (a stationary value is
    then exact to second order), by Newton steps safeguarded by bisection; returns theta."""
    flo, _ = _poly_theta(q, lo)
    fhi, _ = _poly_theta(q, hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        th = (lo * fhi - hi * flo) / (fhi - flo)            # a secant step to start
    th = np.where(np.isfinite(th) & (th > lo) & (th < hi), th, 0.5 * (lo + hi))
    act = np.arange(len(lo))
    for _ in range(iters):
        if not len(act):
            break
        a_q, a_lo, a_hi, a_th, a_flo = q[act], lo[act], hi[act], th[act], flo[act]
        f, df = _poly_theta(a_q, a_th)
        same = np.sign(f) == np.sign(a_flo)
        a_lo = np.where(same, a_th, a_lo)
        a_hi = np.where(same, a_hi, a_th)
        a_flo = np.where(same, f, a_flo)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = -f / df
        new = a_th + step
        bad = ~np.isfinite(new) | (new <= a_lo) | (new >= a_hi)
        done = (f == 0) | ((np.abs(step) <= tol) & ~bad) | (a_hi - a_lo <= tol)
        new = np.where(f == 0, a_th, np.where(bad, 0.5 * (a_lo + a_hi), new))
        lo[act], hi[act], th[act], flo[act] = a_lo, a_hi, new, a_flo
        act = act[~done]
    return th


# --- exact minima over strips -------------------------------------------------------------------------

def strip_polynomials(poly: Polynomials, coeffs, cell, strip):
    """Strip polynomials of q12 and q4 for the pairs (cell, strip): [(r, er)] with r (P, n+1) in the
    chord parameter of the strip, and rounding bounds (|T| e + 4 n eps |T| |q|)."""
    out = []
    order = np.argsort(strip, kind="stable")
    bounds = np.searchsorted(strip[order], np.arange(N_STRIPS + 1))
    for (q, e), T, Ta in zip(coeffs, poly.T, poly.Tabs):
        n = q.shape[1] - 1
        r = np.empty((len(cell), n + 1), q.dtype)
        er = np.empty_like(r)
        for k in range(N_STRIPS):
            idx = order[bounds[k]:bounds[k + 1]]
            if len(idx):
                qk, ek = q[cell[idx]], e[cell[idx]]
                r[idx] = qk @ T[k].T
                er[idx] = (ek + 4 * n * _eps(q) * np.abs(qk)) @ Ta[k].T
        out.append((r, er))
    return out


@dataclass(frozen=True)
class StripCandidates:
    """Candidate points of pairs (cell, strip): every stationary point of O_t there is among them."""
    cell: np.ndarray
    strip: np.ndarray
    x: np.ndarray
    c: np.ndarray
    value: np.ndarray
    capped: np.ndarray  # bool: the point samples an unresolved interval (polish it)
    failed: np.ndarray  # (N,) bool: cells whose isolation did not resolve (fallback)


def stationary_candidates(S, R, b, cell, strip, n_cells, all_lines: bool = False) -> StripCandidates:
    """All stationary points of O_t with theta in the given strips of the given cells, as candidate
    points (x, c, value), by isolating the real roots of q12 and q4 there (module docstring of maps).
    all_lines: every candidate's value is its exact line minimum (the table's strip minima need that);
    otherwise only those that can compete for the cell's optimum."""
    poly = polynomials(b, S.dtype.type)
    coeffs = poly.coefficients(S)
    xs, cs, ss, caps = [], [], [], []
    failed = np.zeros(n_cells, bool)
    for (r, er), (q, _) in zip(strip_polynomials(poly, coeffs, cell, strip), coeffs):
        c_, lo, hi, kind = isolate(r, er, cell, strip)
        failed[c_[kind == 3]] = True
        one = kind == 1
        th = refine(q[c_[one]], lo[one], hi[one])
        cap = kind == 2
        thc = np.concatenate([lo[cap], 0.5 * (lo[cap] + hi[cap]), hi[cap]])
        xs.append(np.concatenate([np.tan(th), np.tan(thc)]))
        cs.append(np.concatenate([c_[one], np.tile(c_[cap], 3)]))
        ss.append(np.concatenate([_strip_of(th), _strip_of(thc)]))
        caps.append(np.concatenate([np.zeros(len(th), bool), np.ones(len(thc), bool)]))
    x = np.concatenate(xs)
    cell_of = np.concatenate(cs)
    capped = np.concatenate(caps)
    # the line minimum at each root (its unique c-stationary point), for the roots whose value at E1's
    # root c is within 1e-4 of the cell's best (E1's c loses digits next to rank-one S; the value at a
    # stationary point only to second order, far below 1e-4), E1's value elsewhere
    c0, v0 = candidate_values(S[cell_of], R[cell_of], b, x[:, None])
    k0 = np.argmin(v0[:, 0, :], axis=1)
    rows = np.arange(len(x))
    c, v = c0[rows, 0, k0], v0[rows, 0, k0]
    best = np.full(n_cells, np.inf, v.dtype)
    np.minimum.at(best, cell_of, v)
    k = np.nonzero((v <= best[cell_of] * (1 + 1e-4)) | capped | all_lines)[0]
    c2, _, v2 = c_star(S[cell_of[k]], R[cell_of[k]], b, x[k], c[k])
    c[k], v[k] = np.where(v2 <= v[k], c2, c[k]), np.minimum(v[k], v2)
    v = np.where(np.isfinite(v) & (v >= 0), v, np.inf)
    return StripCandidates(cell_of, np.concatenate(ss), x, c, v, capped, failed)


def _strip_of(theta):
    return np.clip(np.searchsorted(_edges(theta.dtype), theta, side="right") - 1, 0, N_STRIPS - 1)


def special_candidates(S, R, b, search):
    """Line minima at x = (b + 1)/b and (b - 1)/b, whose stationary points the resultant's linear factors
    hide (they are not roots of q12 q4), for the cells whose strip holding that x is searched (search
    (N, N_STRIPS) bool): (x, c, value) (N, K) each, value inf where not searched."""
    xs = np.array([(b + 1) / b, (b - 1) / b])
    xs = xs[np.abs(xs) > 1e-12]
    n = len(S)
    x = np.tile(xs, n).astype(S.dtype)
    rep = np.repeat(np.arange(n), len(xs))
    k = np.nonzero(search[rep, _strip_of(np.arctan(x))])[0]
    c = np.full(len(x), np.nan, S.dtype)
    v = np.full(len(x), np.inf, S.dtype)
    if len(k):
        c[k], _, v[k] = c_star(S[rep[k]], R[rep[k]], b, x[k])
    return x.reshape(n, -1), c.reshape(n, -1), v.reshape(n, -1)


# --- the table over normalised S and the pruning hull bound --------------------------------------------

#: relative slack on the strip minima of the table (covers their rounding)
TABLE_SLACK = 1e-12


def disc_point(S: np.ndarray) -> np.ndarray:
    """(u, v) = ((s11 - s22)/2, s12) of normalised S (tr S = 1): S = I/2 + [[u, v], [v, -u]], the disc
    u^2 + v^2 <= 1/4 (its boundary is the rank-one S)."""
    return np.stack([(S[:, 0] - S[:, 2]) / 2, S[:, 1]], axis=-1)


def special_angles(b: float) -> np.ndarray:
    """Disc angles of the rank-one S that test poses approach: e1 e1^T (force through joint 2), e2 e2^T
    (through joint 1) and w w^T with w = ((1 +- b)^2, b^2) (the test arm straight or folded)."""
    w = np.array([[1.0, 0.0], [0.0, 1.0], [(1 + b) ** 2, b * b], [(1 - b) ** 2, b * b]])
    return 2 * np.arctan2(w[:, 1], w[:, 0])


#: rings of the table next to the rank-one boundary (rho = sqrt(det S) of normalised S) and beyond
OUTER_RHOS = (0.0006, 0.0012, 0.0025, 0.005, 0.01, 0.019)
INNER_RHOS = tuple(np.concatenate([np.geomspace(0.03, 0.09, 4), np.linspace(0.13, 0.46, 8)]))


def table_nodes(b: float, cells: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """Nodes (N, 3) of the table: normalised S on rings of constant rho = sqrt(det S) (rho = 1/2 is
    S = I/2), 48 angles each away from the rank-one boundary (rho = 0). The rings next to it (OUTER_RHOS)
    need finer angles to enclose cells there (a chord of angle d cuts rho up to r d / 2 off the disc):
    ring j gets the spacing 1.2 rho_(j+1) / r, at the angles where cells (normalised S (M, 3)) with rho
    below 1.5 rho_(j+1) lie, or, without cells, near the four rank-one S that test poses approach
    (:func:`special_angles`). Any node set gives valid bounds; the nodes only decide how many cells the
    triangles enclose. Returns the nodes and the rings as (radius r = sqrt(1/4 - rho^2), angles) from the
    centre out, the nodes listed ring by ring."""
    rings = [(0.0, np.zeros(1))]
    for i, rho in enumerate(INNER_RHOS):
        a = np.linspace(0, 2 * np.pi, 48, endpoint=False) + (np.pi / 48) * (i % 2)
        rings.append((np.sqrt(0.25 - rho * rho), a))
    if cells is not None and len(cells):
        uv = disc_point(cells)
        c_rho = np.sqrt(np.maximum(cells[:, 0] * cells[:, 2] - cells[:, 1] ** 2, 0.0))
        c_alpha = np.arctan2(uv[:, 1], uv[:, 0]) % (2 * np.pi)
    nxt = OUTER_RHOS[1:] + (INNER_RHOS[0],)
    for rho, rho_next in zip(OUTER_RHOS, nxt):
        r = np.sqrt(0.25 - rho * rho)
        n = int(np.ceil(2 * np.pi * r / (1.2 * rho_next)))
        grid = 2 * np.pi * np.arange(n) / n
        if cells is not None and len(cells):
            near = c_rho < 1.5 * rho_next
            used = np.zeros(n, bool)
            k = np.round(c_alpha[near] * n / (2 * np.pi)).astype(int) % n
            for shift in (-2, -1, 0, 1, 2):
                used[(k + shift) % n] = True
        else:
            d = np.abs(np.angle(np.exp(1j * (grid[:, None] - special_angles(b)[None, :]))))
            used = d.min(axis=1) < 0.25
        if used.any():
            rings.append((r, grid[used]))
    uv = np.concatenate([r * np.stack([np.cos(a), np.sin(a)], axis=-1) for r, a in rings])
    return np.stack([0.5 + uv[:, 0], uv[:, 1], 0.5 - uv[:, 0]], axis=-1), rings


class RingMesh:
    """Triangles over the table's rings: a point between rings j and j + 1 lies in one of the triangles of
    the quadrilateral formed by the nodes bracketing its angle on both rings (or, between a chord and its
    arc, in the next quadrilateral out). Any triangle containing a point gives a valid hull bound."""

    def __init__(self, rings, keep: np.ndarray):
        self.radius, self.angles, self.index = [], [], []
        start = 0
        for r, a in rings:
            idx = np.arange(start, start + len(a))
            start += len(a)
            ok = keep[idx]
            if ok.any():
                order = np.argsort(a[ok])
                self.radius.append(r)
                self.angles.append(a[ok][order])
                self.index.append(idx[ok][order])
        by_radius = np.argsort(self.radius, kind="stable")
        self.radius = np.array(self.radius)[by_radius]
        self.angles = [self.angles[i] for i in by_radius]
        self.index = [self.index[i] for i in by_radius]
        remap = np.cumsum(keep) - 1                       # node index among the kept nodes
        self.index = [remap[i] for i in self.index]
        uv = np.concatenate([r * np.stack([np.cos(a), np.sin(a)], -1) for r, a in rings])
        self.uv = uv[keep]                                # the kept nodes, in node order

    def _bracket(self, j, alpha):
        """The two nodes of ring j (an array per point) around angle alpha (cyclic)."""
        out_lo = np.zeros(len(j), int)
        out_hi = np.zeros(len(j), int)
        for ring in np.unique(j):
            m = j == ring
            a, idx = self.angles[ring], self.index[ring]
            k = np.searchsorted(a, alpha[m], side="right")
            out_lo[m] = idx[(k - 1) % len(a)]
            out_hi[m] = idx[k % len(a)]
        return out_lo, out_hi

    def locate(self, uv: np.ndarray):
        """(corners (N, 3), barycentric weights (N, 3), found (N,)) for points uv (N, 2)."""
        n = len(uv)
        r = np.hypot(uv[:, 0], uv[:, 1])
        alpha = np.arctan2(uv[:, 1], uv[:, 0]) % (2 * np.pi)
        j0 = np.clip(np.searchsorted(self.radius, r, side="right") - 1, 0, len(self.radius) - 2)
        corners = np.zeros((n, 3), int)
        lam = np.zeros((n, 3))
        found = np.zeros(n, bool)
        for dj in (0, 1, -1):
            j = np.clip(j0 + dj, 0, len(self.radius) - 2)
            todo = np.nonzero(~found)[0]
            if not len(todo):
                break
            a, b = self._bracket(j[todo], alpha[todo])
            c, d = self._bracket(j[todo] + 1, alpha[todo])
            for tri in ((a, b, c), (b, c, d), (a, b, d), (a, c, d)):
                t = np.stack(tri, axis=1)
                P = self.uv[t]                                # (m, 3, 2)
                M = np.stack([P[:, 0] - P[:, 2], P[:, 1] - P[:, 2]], axis=-1)
                det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
                rhs = uv[todo] - P[:, 2]
                with np.errstate(divide="ignore", invalid="ignore"):
                    l1 = (rhs[:, 0] * M[:, 1, 1] - rhs[:, 1] * M[:, 0, 1]) / det
                    l2 = (M[:, 0, 0] * rhs[:, 1] - M[:, 1, 0] * rhs[:, 0]) / det
                    l3 = 1 - l1 - l2
                ok = (np.abs(det) > 1e-300) & (l1 >= -1e-12) & (l2 >= -1e-12) & (l3 >= -1e-12) & ~found[todo]
                hit = todo[ok]
                corners[hit] = t[ok]
                lam[hit] = np.stack([l1, l2, l3], axis=-1)[ok].clip(0, 1)
                found[hit] = True
        return corners, lam, found


@dataclass(frozen=True)
class MapTable:
    """For link ratio b: nodes S (N, 3), their Delaunay triangulation in the (u, v) disc, the optimum of
    each half theta > 0 and theta < 0 (x, c, s) (N, 2), and the exact minimum of O_t over every theta
    strip (N, N_STRIPS), lowered by TABLE_SLACK."""
    b: float
    S: np.ndarray
    mesh: RingMesh
    x: np.ndarray
    c: np.ndarray
    s: np.ndarray
    strip_min: np.ndarray


def _node_minima(S: np.ndarray, b: float):
    """Exact strip minima (N, N_STRIPS), per-half optima x, c (N, 2) and a failure flag (N,) of nodes."""
    R = factor(S)
    n = len(S)
    K = N_STRIPS
    cell = np.repeat(np.arange(n), K)
    strip = np.tile(np.arange(K), n)
    cand = stationary_candidates(S, R, b, cell, strip, n, all_lines=True)
    m = np.full((n, K), np.inf)
    np.minimum.at(m, (cand.cell, cand.strip), cand.value.astype(float))
    # line minima on the interior edges (theta = 0 and +-pi/2 are singular: O_t = inf there)
    edges = np.arange(1, K)
    edges = edges[np.abs(STRIP_EDGES[edges]) > 1e-12]
    xe = np.tile(np.tan(_edges(S.dtype.type)[edges]), n)
    Se, Re = np.repeat(S, len(edges), 0), np.repeat(R, len(edges), 0)
    c0, v0 = candidate_values(Se, Re, b, xe[:, None])     # E1's roots start the line searches
    _, _, ve = c_star(Se, Re, b, xe, c0[np.arange(len(xe)), 0, np.argmin(v0[:, 0, :], axis=1)])
    ve = ve.astype(float).reshape(n, len(edges))
    m[:, edges - 1] = np.minimum(m[:, edges - 1], ve)
    m[:, edges] = np.minimum(m[:, edges], ve)
    x = np.full((n, 2), np.nan)
    c = np.full((n, 2), np.nan)
    for h, pos in enumerate((True, False)):
        v = np.where((cand.x > 0) == pos, cand.value, np.inf)
        order = np.lexsort((v, cand.cell))
        first = order[np.minimum(np.searchsorted(cand.cell[order], np.arange(n)), len(order) - 1)]
        ok = np.isfinite(v[first]) & (cand.cell[first] == np.arange(n))
        x[ok, h], c[ok, h] = cand.x[first[ok]], cand.c[first[ok]]
    bad = cand.failed | ~np.all(np.isfinite(m), axis=1) | ~np.all(np.isfinite(x), axis=1)
    return m, x, c, bad


def build_table(b: float, cells: np.ndarray | None = None) -> MapTable:
    """The table of :class:`MapTable` for the normalised S of the cells it will serve (:func:`table_nodes`),
    every entry by the exact method (isolated stationary points of each strip and the unique line minima
    on the strip edges), in long double for nodes next to the rank-one boundary where double precision
    does not resolve the roots; nodes that still fail are left out."""
    S, rings = table_nodes(b, cells)
    m, x, c, bad = _node_minima(S, b)
    if bad.any():
        m2, x2, c2, bad2 = _node_minima(S[bad].astype(np.longdouble), b)
        m[bad], x[bad], c[bad] = m2, x2, c2
        bad[bad] = bad2
    good = ~bad
    S, x, c, m = S[good], x[good], c[good], m[good]
    return MapTable(b, S, RingMesh(rings, good), x, c, np.sqrt((1 - c) * (1 + c)), m * (1 - TABLE_SLACK))


@dataclass(frozen=True)
class Solution:
    """Per cell (normalised S): O_t / sigma^2 / tr S, the optimal (x, c, s), and the certificate: 1 = the
    table's hull bound pruned all but a few strips and the exact method resolved those, 2 = the exact
    method on every strip (S outside the table), 0 = not certified (isolation unresolved: fallback)."""
    value: np.ndarray
    x: np.ndarray
    c: np.ndarray
    s: np.ndarray
    certificate: np.ndarray
    strips: np.ndarray  # strips searched per cell


def solve(S: np.ndarray, R: np.ndarray, b: float, tab: MapTable | None = None) -> Solution:
    """The global minimum of O_t over single measurement poses for normalised S (N, 3) = R^T R (module
    docstring of :mod:`stiffcal.planning.maps`). With a table, the lookup bounds the optimum from above and the
    hull bound prunes strips; without one (tab None), every strip is searched."""
    n = len(S)
    rows = np.arange(n)
    if tab is not None:
        # the lookup: the optima of the table's corners, evaluated for this S, bound the optimum above
        corners, lam, inside = tab.mesh.locate(disc_point(S.astype(float)))
        cx, cc, cs = (a[corners].reshape(n, 6) for a in (tab.x, tab.c, tab.s))
        uvals = objective(R[:, None], b, cx, cc, cs)
        uvals = np.where(np.isfinite(uvals), uvals, np.inf)
        k = np.argmin(uvals, axis=1)
        u = uvals[rows, k]
        # the hull bound: O_t restricted to a strip is a minimum of functions linear in S, hence concave
        # in S, so it is at least the barycentric combination of the corners' exact strip minima
        lower = np.einsum("nc,nck->nk", lam, tab.strip_min[corners])
        search = ~inside[:, None] | (lower <= u[:, None] * (1 + 1e-13))
        ux, uc = cx[rows, k], cc[rows, k]
    else:
        inside = np.zeros(n, bool)
        search = np.ones((n, N_STRIPS), bool)
        u, ux, uc = np.full(n, np.inf), np.full(n, np.nan), np.full(n, np.nan)
    cell, strip = np.nonzero(search)
    cand = stationary_candidates(S, R, b, cell, strip, n)
    sx, sc, sv = special_candidates(S, R, b, search)
    # the smallest candidate of each cell (the lookup's own point included)
    allv = np.concatenate([cand.value, sv.ravel(), u])
    allx = np.concatenate([cand.x, sx.ravel(), ux])
    allc = np.concatenate([cand.c, sc.ravel(), uc])
    soft = np.concatenate([cand.capped, np.ones(sv.size, bool), np.ones(n, bool)])
    allcell = np.concatenate([cand.cell, np.repeat(rows, sx.shape[1]), rows])
    order = np.lexsort((allv, allcell))
    first = order[np.searchsorted(allcell[order], rows)]
    x, c, v = allx[first], allc[first], allv[first]
    s = np.sqrt((1 - c) * (1 + c))
    # a winner that samples an unresolved interval or a hidden line, that lies next to a singular pose
    # (where cos loses precision), or of a cell whose isolation failed, is polished: Newton steps in
    # (theta, gamma), kept if better
    near = np.nonzero(soft[first] | (s < 0.2) | cand.failed)[0]
    if len(near):
        t1, g1, v1 = newton(S[near], R[near], b, np.arctan(x[near]), np.arctan2(s[near], c[near]), iters=100)
        better = v1 < v[near]
        x[near] = np.where(better, np.tan(t1), x[near])
        c[near] = np.where(better, np.cos(g1), c[near])
        s[near] = np.where(better, np.sin(g1), s[near])
        v[near] = np.where(better, v1, v[near])
    cert = np.where(cand.failed, 0, np.where(inside, 1, 2))
    return Solution(v, x, c, s, cert, search.sum(axis=1))


# --- exact arithmetic for the cells that floating point does not resolve -------------------------------

#: bits of the ball arithmetic of :func:`certify_exact` (python-flint's arb): the roots' enclosures are
#: that accurate, and the bounds are evaluated at that precision
EXACT_PREC = 128


def _fraction(v) -> tuple[int, int]:
    """A double or long double as the exact fraction (numerator, denominator) it stores."""
    n, d = v.as_integer_ratio()
    return int(n), int(d)


def integer_coefficients(table: dict, S: list, b: tuple) -> list[int]:
    """Integer coefficients (lowest power of x first) of a positive multiple of q12 or q4 (``table``: Q12 or
    Q4, whose x^k coefficients are integer polynomials in b per monomial of S, all monomials of one degree)
    for S and b given exactly as fractions: S [(num, den)] * 3 = (s11, s12, s22), b (num, den)."""
    den = math.lcm(*(d for _, d in S))
    n = [num * (den // d) for num, d in S]
    deg_b = max(len(v) for row in table.values() for v in row.values()) - 1
    bp = [b[0] ** j * b[1] ** (deg_b - j) for j in range(deg_b + 1)]
    return [sum(sum(w * bp[j] for j, w in enumerate(cb)) * n[0] ** m[0] * n[1] ** m[1] * n[2] ** m[2]
                for m, cb in table[k].items()) for k in range(len(table))]


def _real_roots(coeffs: list[int]):
    """Enclosures (arb balls) of the nonzero real roots of the integer polynomial, None if it is zero:
    FLINT's certified complex root isolation returns the real roots with an exactly zero imaginary part."""
    import flint

    k = next((i for i, v in enumerate(coeffs) if v != 0), None)
    if k is None:
        return None
    return [z.real for z, _ in flint.fmpz_poly(coeffs[k:]).complex_roots() if z.imag.is_zero()]


def _ball_log_ot(S, b, x, c):
    """log O_t and its c-derivative at (x, c) in ball arithmetic (module docstring of :mod:`stiffcal.planning.maps`):
    O_t = Q1 Q2 / (b^4 x^2 (1 - c^2)^2), d log O_t / dc = Q1_c / Q1 + Q2_c / Q2 + 4 c / (1 - c^2)."""
    s11, s12, s22 = S
    q1 = s11 * b * b - 2 * s12 * b * (b + c) * x + s22 * (1 + b * b + 2 * b * c) * x * x
    q2 = b * b * (x - 1) ** 2 + 1 - 2 * b * c * (x - 1)
    w = 1 - c * c
    log_o = (q1 * q2 / (b ** 4 * x * x * w * w)).log()
    return log_o, 2 * b * x * (s22 * x - s12) / q1 - 2 * b * (x - 1) / q2 + 4 * c / w


@dataclass(frozen=True)
class ExactCertificate:
    """Per cell: the optimum's value (O_t / sigma^2 / tr S at the reported pose), a rigorous lower bound on
    the global minimum, the pose (x, c, s) (doubles) and whether value <= lower (1 + tol)."""
    value: np.ndarray
    lower: np.ndarray
    x: np.ndarray
    c: np.ndarray
    s: np.ndarray
    certified: np.ndarray


def _ball_lower_bounds(Sb: list, B, cell: np.ndarray, balls: list, c: np.ndarray, valid: np.ndarray) -> list:
    """Per cell the smallest lower bound (an arb's lower end) of log O_t over the balls of its candidate x:
    log O_t(x, c0) - (d log O_t / dc (x, c0))^2 in ball arithmetic (:func:`certify_exact`); a cell whose line
    minimiser or bound is not finite is marked invalid in ``valid`` (in place)."""
    import flint

    low_ball = [None] * len(Sb)
    for i, (k, X) in enumerate(zip(cell, balls)):
        if not np.isfinite(c[i]):
            valid[k] = False
            continue
        c0 = flint.arb(flint.fmpq(*_fraction(c[i])))
        log_o, d = _ball_log_ot(Sb[k], B, X, c0)
        lb = log_o - d * d
        if not lb.is_finite():
            valid[k] = False
            continue
        lb = lb.lower()
        if low_ball[k] is None or lb < low_ball[k]:
            low_ball[k] = lb
    return low_ball


def _best_points(Sb: list, B, x: np.ndarray, c: np.ndarray, v: np.ndarray, cell: np.ndarray, valid: np.ndarray,
                 low_ball: list, tol: float):
    """(value, lower, x, c, s, certified), each (N,), of :class:`ExactCertificate`: the best point of each valid
    cell, rounded to doubles, its value bounded above in ball arithmetic and certified against the cell's lower
    bound within ``tol``."""
    import flint

    n = len(Sb)
    order = np.lexsort((v, cell))
    first = order[np.minimum(np.searchsorted(cell[order], np.arange(n)), max(len(order) - 1, 0))] \
        if len(cell) else np.zeros(n, int)
    out_x, out_c = np.full(n, np.nan), np.full(n, np.nan)
    out_s, value, lower = np.full(n, np.nan), np.full(n, np.inf), np.full(n, np.inf)
    certified = np.zeros(n, bool)
    for k in np.nonzero(valid)[0]:
        i = first[k]
        xf, cf = float(x[i]), float(c[i])
        sf = float(np.sqrt((1 - c[i]) * (1 + c[i])))
        log_u, _ = _ball_log_ot(Sb[k], B, flint.arb(xf), flint.arb(cf))
        out_x[k], out_c[k], out_s[k] = xf, cf, sf
        value[k] = float(log_u.exp().mid())
        lower[k] = float(low_ball[k].exp().lower())
        certified[k] = bool(log_u.upper() - low_ball[k] < math.log1p(tol))
    return value, lower, out_x, out_c, out_s, certified


def certify_exact(S: np.ndarray, R: np.ndarray, b: float, tol: float = 1e-9) -> ExactCertificate:
    """The global minimum of O_t over single measurement poses for normalised S (N, 3) = R^T R (double or
    long double), by exact arithmetic (the argument is in the module docstring of :mod:`stiffcal.planning.maps`,
    item 3): S and b are the fractions their floating-point values store; q12 and q4 get exact integer
    coefficients and FLINT isolates their real roots in balls of EXACT_PREC bits; at each root, and at
    x = (b +- 1)/b, the line minimiser c0 (long double) gives the point and, since log O_t is
    1/2-strongly convex in c, the bound min_c log O_t(x, c) >= log O_t(x, c0) - (d log O_t / dc (x, c0))^2,
    evaluated in ball arithmetic over the root's whole ball. A cell is certified when the value at its
    reported pose is within tol (relative) of the smallest bound. Slow (about 1 ms a cell): for the few
    cells the floating-point isolation leaves unresolved."""
    import flint

    n = len(S)
    bf = _fraction(float(b))
    xs, cell, balls = [], [], []
    valid = np.zeros(n, bool)
    fr = [[_fraction(v) for v in row] for row in S]
    old = flint.ctx.prec
    flint.ctx.prec = EXACT_PREC
    try:
        B = flint.arb(flint.fmpq(*bf))
        special = [X for X in ((B + 1) / B, (B - 1) / B) if not X.is_zero()]     # x = 0 is no pose (b = 1)
        for k in range(n):
            s11, s12, s22 = (flint.fmpq(*f) for f in fr[k])
            det = s11 * s22 - s12 * s12
            roots = [_real_roots(integer_coefficients(t, fr[k], bf)) for t in (Q12, Q4)]
            # the minimum is attained at a stationary point only for S positive definite (O_t -> inf at
            # every edge); q12 or q4 vanishing identically would make every x a candidate
            if det <= 0 or roots[0] is None or roots[1] is None:
                continue
            valid[k] = True
            for X in roots[0] + roots[1] + special:
                balls.append(X)
                xs.append(float(X.mid()))
                cell.append(k)
        cell = np.array(cell, int)
        x = np.array(xs, S.dtype)
        c, _, v = c_star(S[cell], R[cell], b, x)
        v = np.where(np.isfinite(v) & (v >= 0), v, np.inf)
        Sb = [[flint.arb(flint.fmpq(*f)) for f in row] for row in fr]
        low_ball = _ball_lower_bounds(Sb, B, cell, balls, c, valid)
        value, lower, out_x, out_c, out_s, certified = _best_points(Sb, B, x, c, v, cell, valid, low_ball, tol)
    finally:
        flint.ctx.prec = old
    return ExactCertificate(value, lower, out_x, out_c, out_s, certified)
