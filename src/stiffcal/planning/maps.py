"""Maps over test poses (Figures 6-10): for every test pose of a planar 2R arm, the globally optimal single
measurement pose for O_t (eq. 16, m = 1) and the accuracy gain chi (eq. 27), each cell certified.

Reduction
---------
O_t and chi do not change when every link length, or the force, is scaled (A_t and A both scale by
l^2 |F|), so a map depends only on b = l2 / l1 and the force direction phi; we work with l1 = 1, l2 = b,
|F| = 1. For one measurement pose q, with S = A_t^T A_t (2 x 2),

    O_t = sigma^2 tr(M(q)^-1 S)                                                       (eq. 16, m = 1)

is linear in S, so a cell's optimum is tr(S) times the optimum for S / tr S: a point of a 2-D family (the
disc of normalised S; its boundary holds the rank-one S). With A = J diag(tau) (tau = J^T F), M depends on
q only through c = cos q2 and x = tau1 / tau2 = tan(theta) (rotating the arm turns the force relative to
it; mirroring about the force line leaves M unchanged), and

    O_t / sigma^2 = Q1 Q2 / (b^4 x^2 (1 - c^2)^2),
    Q1 = s11 b^2 - 2 s12 b (b + c) x + s22 (1 + b^2 + 2 b c) x^2,   Q2 = b^2 (x - 1)^2 + 1 - 2 b c (x - 1).

Every (x, c) in R x (-1, 1) is reached by four measurement poses (two with the force reversed, and their
mirror images); we report the one with q2 in [0, 180] and q1 in (-90, 90] (the rule of Table 2). The edges
x = 0, x = +-inf, c = +-1 are the singular poses (M singular); for S positive definite O_t -> inf there.

The candidate, and why each cell is the global optimum (the certificate)
-------------------------------------------------------------------------
1. The exact method. Stationary points solve E1 = x dP/dx - 2P = 0 and E2 = (1 - c^2) dP/dc + 4cP = 0
   (P = Q1 Q2); their resultant in c is -64 b^6 x (bx - b - 1)(bx - b + 1) q4(x) q12(x) (derived
   symbolically, ``tools/derive_map_polynomials.py``). So the x of every stationary point is a real root
   of q12 or q4, or (b +- 1)/b; its c is a root of the quadratic E1(x, .). For fixed x, O_t is strictly
   log-convex in c on (-1, 1) (Q1, Q2 are linear in c and nonnegative at c = +-1, so (log O_t)'' >=
   4(1 + c^2)/(1 - c^2)^2 - 2/(1 - |c|)^2 > 0), hence the minimum over any line x = const is its unique
   c-stationary point. The real roots are isolated exactly, strip by strip of theta (32 strips), by
   Descartes' rule of signs with bisection (Collins-Akritas), with a rounding bound on every coefficient
   so that a sign is only used when it is certain, and refined by safeguarded Newton steps; an interval
   that stays unresolved below 1e-11 rad (1e-7 rad where signs are uncertain) is evaluated at its ends and
   middle, which is exact to second order at a stationary point. The smallest value over all candidates
   of a strip is its minimum (the values at non-stationary candidates are values of O_t, so never below
   it). No starting point, no grid.
2. The lookup and the hull bound. Doing 1 for all 32 strips of every cell is slow; a table over the
   disc of normalised S (about 1,000 nodes on rings, finer where the map's cells approach the rank-one
   boundary; triangles between neighbouring rings) stores, by the exact method, each node's
   optimum in each half theta > 0, theta < 0 and its exact minimum over every strip. For a cell, the
   corners' optima evaluated at its own S give a candidate value u (an achieved O_t, so an upper bound).
   The minimum of O_t over a strip is a minimum of functions linear in S, hence concave in S: at the
   cell it is at least the barycentric combination of the corners' strip minima (the hull bound). Every
   strip whose bound exceeds u is certified empty of better points; the exact method runs on the rest
   (1-2 strips for 98 % of the cells). The optimum is then the smallest candidate, and c is recomputed
   in gamma = q2 next to singular poses (where cos loses precision).
3. Precision. Next to the rank-one boundary (test poses within a few degrees of a straight or folded arm, or
   of the force through joint 1) the polynomials' roots cluster and their coefficients, computed from S,
   lose digits: where the isolation does not resolve in double precision, the cell is solved again in long
   double (80-bit) from its test pose. The few cells that still do not resolve (at 1 degree 0, 12, 16 and
   132 of 129,600 for b = 0.2, 0.5, 0.67, 0.9; about 1 ms a symmetry class) are solved exactly (status
   "exact_arbitrary_precision", :func:`stiffcal.planning._map_solver.certify_exact`): their S (computed in long
   double from the test pose) and b are the fractions they store, so q12 and q4 get exact integer
   coefficients, and FLINT's certified root isolation (python-flint) encloses every real root in a ball of
   128 bits. At each root x, and at x = (b +- 1)/b, the line minimiser c0 (long double) is a candidate,
   and a lower bound follows from strong convexity: at fixed x,
       (log O_t)'' >= 4 (1 + c^2)/(1 - c^2)^2 - 2/(1 - |c|)^2 = 2/(1 + |c|)^2 >= 1/2   (the bound of 1),
   so for any c0,  min_c log O_t(x, c) >= log O_t(x, c0) - (d log O_t / dc (x, c0))^2,  evaluated in
   ball arithmetic over the root's whole ball. Every stationary point has its x among the roots, and for
   det S > 0 (checked exactly) O_t -> inf at every edge, so the smallest bound is below the global minimum;
   the cell is certified when the value at its reported pose (rounded to doubles, bounded above in ball
   arithmetic) is within 1e-9 of it (in practice below 1e-30). A cell the exact method cannot certify
   (none on the default maps at 1 and 0.5 degrees) would be reported "uncertified", with the best of damped
   Newton runs from the table's optima and a grid.
4. Rank-deficient test information (det S = 0 exactly; the status "closed_form" or "no_optimum"):
   - the test arm straight or folded (q2* = 0, +-180): S = t^2 w w^T, w = ((1 + b c*)^2, b^2), t = the
     force component across the arm. For any plan, w^T M^-1 w = min{|y|^2 : A^T y = w} >= 1 because
     tau_j (J_j . y) = w_j with |tau_j| <= |J_j|, |J_1| <= 1 + b and |J_2| = b. So O_t >= t^2 sigma^2,
     approached by measuring with the arm in the same shape and the force across it, which is singular
     (it cannot identify k1 and k2). By the report's rule (a plan that cannot identify every compliance
     counts as infinitely bad) the optimum is the best non-singular pose, which exists only when equality
     holds at one: for a folded test arm with b < 1, at cos q2 = 1 - 2b with the force perpendicular to
     link 2 (x = (1 - b)/b); it is reported. Elsewhere on these rows no non-singular pose attains t^2
     (every one is beaten by one closer to the singular shape): the cell has no optimal pose (NaN, status
     "no_optimum"), O_t holds the infimum t^2 sigma^2 and chi the supremum, and the figures mark it.
   - the force through joint 2 (tau2* = 0, S = s11 e1 e1^T): minimising over 1/x in closed form, then
     over c (3 b c^2 + (1 + b^2) c - b = 0) gives the optimum, non-singular.
   - the force through joint 1 (tau1* = 0, S = s22 e2 e2^T): the optimum over x is at x = 1 + c/b with
     O_t = s22 (1 + b^2 + 2bc)/(b^4 (1 - c^2)), smallest at c = -1/b for b > 1 (non-singular) and at
     c = -b for b <= 1, where x = 0 (tau1 = 0, singular): no optimal pose.
   - A_t = 0 (the arm along the force line, stretched or folded): every plan gives O_t = 0; chi is
     infinite and the pose undefined (status "exact_everywhere").
   The tests compare random cells, half of them next to the singular test poses (down to 1e-3 deg), with
   an independent brute force in long double, and the cells certified by the exact method of 3 with one
   whose best pose is valued in 128-bit ball arithmetic (:mod:`stiffcal.testing.reference`).

Symmetry and jobs
-----------------
Cells (q1*, q2*), (q1* + 180, q2*) and, when the grid maps onto itself under it, their mirror images
about the force line (2 phi - q1*, -q2*) have the same S. Each class is enumerated exactly once, by index
arithmetic on the grid columns (:func:`class_members`), so a map solves about a quarter of its cells and
no job ever looks at the whole grid; tiles (the workflow's jobs) are ranges of columns.

Files (the hand-over between jobs; deterministic bytes, written only when complete)
-----------------------------------------------------------------------------------
``tiles/<k>.npz``: ``cell`` (M,) int32, the flat grid index i * n + j of every cell of the tile, and per
cell ``O_t``, ``q1_opt_deg``, ``q2_opt_deg`` (M,) float64 and ``status`` (M,) int8 (:data:`STATUS`).
``map.npz``: scalars ``link_ratio``, ``force_deg``, ``step_deg``, ``sigma``; axes ``q1t_deg``,
``q2t_deg`` (n,); and (n, n) arrays indexed [i, j] = (q1*, q2*): ``O_t``, ``chi``, ``q1_opt_deg``,
``q2_opt_deg``, ``status``. ``map.csv`` holds the same cells as rows (:data:`MAP_COLUMNS`).
``pairs.npz`` (plans of two poses, :func:`pair_map`): ``link_ratio``, ``force_deg``, ``step_deg``, the axes,
and (n, n) arrays ``O_t1`` (single optimum), ``O_t2`` (best pair), ``gain`` and (n, n, 2, 2) ``poses_deg``.
"""

from __future__ import annotations

import io
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import _map_solver as solver
from ..errors import InputError

#: columns of results/maps/<study>/map.csv
MAP_COLUMNS = ["link_ratio", "force_deg", "q1t_deg", "q2t_deg", "q1_opt_deg", "q2_opt_deg", "O_t", "chi"]
#: status of a cell (map.npz ``status``): how its optimum is known
STATUS = {0: "uncertified", 1: "lookup_hull_exact", 2: "exact", 3: "exact_long_double", 4: "closed_form",
          5: "no_optimum", 6: "exact_everywhere", 7: "exact_arbitrary_precision"}
UNCERTIFIED, HULL, EXACT, EXTENDED, CLOSED, NO_OPTIMUM, AT_ZERO, ARBITRARY = range(8)
#: |A_t|^2 below this (l1 = 1, |F| = 1) counts as A_t = 0
ZERO_TEST = 1e-20
#: a test pose with |sin q2*| or a joint torque below this (relative) is exactly rank-deficient
SINGULAR_TOL = 1e-12


def force_vector(force_deg: float) -> np.ndarray:
    """Unit force (2,) at angle phi [deg] from the x axis."""
    phi = np.radians(force_deg)
    return np.array([np.cos(phi), np.sin(phi)])


def test_observation(b: float, force_deg: float, qt_deg: np.ndarray, dtype=np.float64) -> np.ndarray:
    """A_t = J diag(J^T F) (eq. 4) of test poses qt_deg (N, 2) [deg] for the arm (1, b) under a unit force at
    force_deg, in precision dtype: (N, 2, 2) [m^2 N / rad with l1 = 1]."""
    q = np.radians(np.atleast_2d(np.asarray(qt_deg, dtype)))
    phi = np.radians(dtype(force_deg))
    F = np.array([np.cos(phi), np.sin(phi)])
    c1, s1, c12, s12 = np.cos(q[:, 0]), np.sin(q[:, 0]), np.cos(q.sum(1)), np.sin(q.sum(1))
    J = np.empty((len(q), 2, 2), dtype)
    J[:, 0, 0], J[:, 1, 0] = -(s1 + b * s12), c1 + b * c12
    J[:, 0, 1], J[:, 1, 1] = -b * s12, b * c12
    tau = np.einsum("ndi,d->ni", J, F)
    return J * tau[:, None, :]


def _info(A: np.ndarray) -> np.ndarray:
    return np.stack([np.sum(A[:, :, 0] ** 2, 1), np.sum(A[:, :, 0] * A[:, :, 1], 1), np.sum(A[:, :, 1] ** 2, 1)], -1)


def test_information(b: float, force_deg: float, qt_deg: np.ndarray) -> np.ndarray:
    """S = A_t^T A_t for test poses qt_deg (N, 2) [deg] of the arm (1, b) under a unit force: (N, 3) as
    (s11, s12, s22) [m^4 N^2 / rad^2 with l1 = 1]."""
    return _info(test_observation(b, force_deg, qt_deg))


def ot_xc(S: np.ndarray, x: np.ndarray, c: np.ndarray, b: float) -> np.ndarray:
    """O_t / sigma^2 of a single measurement pose given by (x, c) (module docstring), broadcast over
    S (..., 3) and x, c (...); +inf at singular poses (x = 0, +-inf or |c| = 1)."""
    s11, s12, s22 = (S[..., i] for i in range(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        q1 = s11 * b * b - 2 * s12 * b * (b + c) * x + s22 * (1 + b * b + 2 * b * c) * x * x
        q2 = b * b * (x - 1) ** 2 + 1 - 2 * b * c * (x - 1)
        v = q1 * q2 / (b**4 * x * x * (1 - c * c) ** 2)
    return np.where((np.abs(c) < 1) & (x != 0) & np.isfinite(x), v, np.inf)


def pose_from_xc(x: np.ndarray, c: np.ndarray, s: np.ndarray, b: float, force_deg: float) -> np.ndarray:
    """Measurement pose (N, 2) [deg] with torque ratio x, cos q2 = c, sin q2 = s >= 0: q2 in [0, 180],
    q1 in (-90, 90] (the other copy with the same information is q1 + 180). In the arm frame (q1 = 0)
    J1 = (-b s, 1 + b c), J2 = (-b s, b c), and tau1 = x tau2 iff the force is normal to J1 - x J2."""
    q2 = np.arctan2(s, c)
    t = np.arctan(x)
    d1 = -b * s * (np.cos(t) - np.sin(t))
    d2 = (1 + b * c) * np.cos(t) - b * c * np.sin(t)
    q1 = force_deg - np.degrees(np.arctan2(d1, -d2))
    q1 = (q1 + 90.0) % 180.0 - 90.0
    q1 = np.where(q1 == -90.0, 90.0, q1)
    return np.stack([q1 + 0.0, np.degrees(q2) + 0.0], axis=-1).astype(float)


# --- one map cell --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CellSolution:
    """Per cell: O_t / sigma^2 (l1 = 1, |F| = 1; the infimum where no pose attains it), the optimal
    measurement pose [deg] (NaN where there is none) and the status code (:data:`STATUS`)."""
    ot: np.ndarray
    pose_deg: np.ndarray
    status: np.ndarray


def _rank_deficient(b: float, force_deg: float, qt: np.ndarray, A: np.ndarray):
    """Closed forms for exactly rank-deficient S (module docstring, 4): (mask, O_t, x, c, s, status)."""
    n = len(qt)
    tr = np.einsum("nij,nij->n", A, A)
    q = np.radians(qt)
    F = force_vector(force_deg)
    s2t = np.sin(q[:, 1])
    scale = 1 + b
    row = (np.abs(s2t) <= SINGULAR_TOL) & (tr > ZERO_TEST)
    c12, s12, c1, s1 = np.cos(q.sum(1)), np.sin(q.sum(1)), np.cos(q[:, 0]), np.sin(q[:, 0])
    tau = np.stack([-(s1 + b * s12) * F[0] + (c1 + b * c12) * F[1], -b * s12 * F[0] + b * c12 * F[1]], -1)
    col1 = ~row & (np.abs(tau[:, 0]) <= SINGULAR_TOL * scale) & (tr > ZERO_TEST)
    col2 = ~row & ~col1 & (np.abs(tau[:, 1]) <= SINGULAR_TOL * scale) & (tr > ZERO_TEST)
    ot = np.full(n, np.nan)
    x, c = np.full(n, np.nan), np.full(n, np.nan)
    status = np.zeros(n, np.int8)
    # straight or folded test arm: O_t >= t^2, attained by a regular pose only when folded with b < 1
    t = np.sin(np.radians(force_deg) - q[:, 0])
    folded = np.cos(q[:, 1]) < 0
    ot[row] = t[row] ** 2
    attained = row & folded & (b < 1)
    x[attained], c[attained] = (1 - b) / b, 1 - 2 * b
    status[row] = np.where(attained[row], CLOSED, NO_OPTIMUM)
    # force through joint 2: S = s11 e1 e1^T
    c_1 = (-(1 + b * b) + np.sqrt((1 + b * b) ** 2 + 12 * b * b)) / (6 * b)
    s11 = tr
    ot[col2] = s11[col2] / ((1 - c_1 * c_1) * (1 + b * b + 2 * b * c_1))
    x[col2], c[col2] = (1 + b * b + 2 * b * c_1) / (b * (b + c_1)), c_1
    status[col2] = CLOSED
    # force through joint 1: S = s22 e2 e2^T
    s22 = tr
    if b > 1:
        ot[col1] = s22[col1] / b**2
        x[col1], c[col1] = 1 - 1 / b**2, -1 / b
        status[col1] = CLOSED
    else:
        ot[col1] = s22[col1] / b**4
        status[col1] = NO_OPTIMUM
    mask = row | col1 | col2
    return mask, ot, x, c, np.sqrt((1 - c) * (1 + c)), status


def _fallback(S, R, b, tab):
    """Best of damped Newton runs from the table's optima and a coarse grid (uncertified cells only)."""
    th = np.concatenate([np.linspace(-1.5, -0.05, 8), np.linspace(0.05, 1.5, 8)])
    ga = np.linspace(0.1, np.pi - 0.1, 8)
    T, G = (a.ravel() for a in np.meshgrid(th, ga, indexing="ij"))
    starts_t = np.concatenate([np.arctan(tab.x.ravel()), T]) if tab is not None else T
    starts_g = np.concatenate([np.arctan2(tab.s.ravel(), tab.c.ravel()), G]) if tab is not None else G
    n = len(S)
    vals = solver.objective(R[:, None], b, np.tan(starts_t)[None], np.cos(starts_g)[None], np.sin(starts_g)[None])
    vals = np.where(np.isfinite(vals), vals, np.inf)
    best = np.argsort(vals, axis=1)[:, :6]
    t0, g0 = starts_t[best].ravel(), starts_g[best].ravel()
    rep = np.repeat(np.arange(n), best.shape[1])
    t1, g1, v1 = solver.newton(S[rep], R[rep], b, t0, g0, iters=200)
    v1 = v1.reshape(n, -1)
    k = np.argmin(v1, axis=1)
    t1, g1 = t1.reshape(n, -1)[np.arange(n), k], g1.reshape(n, -1)[np.arange(n), k]
    return v1[np.arange(n), k], np.tan(t1), np.cos(g1), np.sin(g1)


#: below this many cells the table costs more than it saves: every strip is searched instead
TABLE_MIN_CELLS = 2000


def solve_cells(b: float, force_deg: float, qt_deg: np.ndarray, tab=None) -> CellSolution:
    """The certified map for test poses qt_deg (N, 2) [deg] (module docstring); tab: a table for b
    (by default built for these cells when there are at least TABLE_MIN_CELLS)."""
    qt = np.atleast_2d(np.asarray(qt_deg, float))
    A = test_observation(b, force_deg, qt)
    S = _info(A)
    tr = S[:, 0] + S[:, 2]
    zero = tr <= ZERO_TEST
    special, ot, x, c, s, status = _rank_deficient(b, force_deg, qt, A)
    status[zero] = AT_ZERO
    ot[zero] = 0.0
    reg = np.nonzero(~zero & ~special)[0]
    if len(reg):
        Sn, Rn = S[reg] / tr[reg, None], A[reg] / np.sqrt(tr[reg])[:, None, None]
        if tab is None and len(reg) >= TABLE_MIN_CELLS:
            tab = solver.build_table(float(b), Sn)
        sol = solver.solve(Sn, Rn, b, tab)
        v, xx, cc, ss = sol.value, sol.x, sol.c, sol.s
        st = np.where(sol.certificate == 1, HULL, EXACT).astype(np.int8)
        bad = np.nonzero(sol.certificate == 0)[0]
        if len(bad):
            AL = test_observation(b, force_deg, qt[reg[bad]], np.longdouble)
            SL = _info(AL)
            trL = SL[:, 0] + SL[:, 2]
            solL = solver.solve(SL / trL[:, None], AL / np.sqrt(trL)[:, None, None], b, tab)
            v[bad], xx[bad], cc[bad], ss[bad] = (np.asarray(a, float) for a in (solL.value, solL.x, solL.c, solL.s))
            st[bad] = np.where(solL.certificate == 0, UNCERTIFIED, EXTENDED)
            hard = solL.certificate == 0
            left = bad[hard]
            if len(left):
                SLn, RLn = (SL / trL[:, None])[hard], (AL / np.sqrt(trL)[:, None, None])[hard]
                ex = solver.certify_exact(SLn, RLn, b)
                ok = ex.certified
                v[left[ok]], xx[left[ok]], cc[left[ok]], ss[left[ok]] = ex.value[ok], ex.x[ok], ex.c[ok], ex.s[ok]
                st[left[ok]] = ARBITRARY
                left = left[~ok]
            if len(left):
                fv, fx, fc, fs = _fallback(Sn[left], Rn[left], b, tab)
                better = fv < v[left]
                v[left] = np.where(better, fv, v[left])
                xx[left], cc[left], ss[left] = (np.where(better, a, o) for a, o in
                                                ((fx, xx[left]), (fc, cc[left]), (fs, ss[left])))
        ot[reg], x[reg], c[reg], s[reg], status[reg] = v * tr[reg], xx, cc, ss, st
    pose = pose_from_xc(x, c, s, b, force_deg)
    pose[np.isnan(x)] = np.nan
    return CellSolution(ot, pose, status)


# --- the grid and its symmetry classes -----------------------------------------------------------------

def test_pose_grid(step_deg: float) -> np.ndarray:
    """The grid of test poses (N, 2) [deg]: q1*, q2* over [-180, 180) with step step_deg, q1* slowest
    (flat index i * n + j)."""
    g = grid_axis(step_deg)
    Q1, Q2 = np.meshgrid(g, g, indexing="ij")
    return np.stack([Q1.ravel(), Q2.ravel()], axis=-1)


def grid_axis(step_deg: float) -> np.ndarray:
    """The n angles -180, -180 + step, ..., 180 - step [deg]."""
    n = int(round(360.0 / step_deg))
    return -180.0 + step_deg * np.arange(n)


def _mirror_shift(step_deg: float, force_deg: float):
    """m with column i mirrored to (m - i) mod n about the force line, or None when the mirror does not
    map the grid onto itself (2 phi / step not an integer)."""
    k = 2 * force_deg / step_deg
    if abs(k - round(k)) > 1e-9:
        return None
    n = int(round(360.0 / step_deg))
    return int(round((2 * force_deg + 360.0) / step_deg)) % n


def class_counts(step_deg: float, force_deg: float) -> np.ndarray:
    """Number of symmetry classes whose representative lies in each column i0 = 0 .. n/2 - 1 (q1* in
    [-180, 0)): the representative is the class member with the smallest column i0 (q1* + 180 folds
    columns i and i + n/2 together) and, in a column that is its own mirror image, the smaller of j and
    its mirror row."""
    n = int(round(360.0 / step_deg))
    h = n // 2
    i0 = np.arange(h)
    m = _mirror_shift(step_deg, force_deg)
    if m is None:
        return np.full(h, n)
    im = (m - i0) % h
    self_rows = n // 2 + 1 if n % 2 == 0 else (n + 1) // 2
    return np.where(im > i0, n, np.where(im == i0, self_rows, 0))


def class_members(step_deg: float, force_deg: float, i_lo: int, i_hi: int):
    """The symmetry classes represented in columns i_lo .. i_hi - 1 of the half grid: (reps (U, 2) [deg],
    cells (M,) flat indices i * n + j of all member cells, cls (M,) the class of each member)."""
    n = int(round(360.0 / step_deg))
    h = n // 2
    m = _mirror_shift(step_deg, force_deg)
    i0 = np.arange(i_lo, i_hi)
    j = np.arange(n)
    ii, Jr = (a.ravel() for a in np.meshgrid(i0, j, indexing="ij"))
    if m is None:
        keep = np.ones(len(ii), bool)
        im, jm = ii, Jr
    else:
        im, jm = (m - ii) % h, (-Jr) % n
        keep = (im > ii) | ((im == ii) & (Jr <= jm))
    ii, Jr, im, jm = ii[keep], Jr[keep], im[keep], jm[keep]
    U = len(ii)
    members = [ii * n + Jr, (ii + h) * n + Jr]
    if m is not None:
        # mirror images: column (m - i) mod n; with q1 + 180 both of (m - i) and (m - i) + n/2 appear
        mi = (m - ii) % n
        members += [mi * n + jm, ((mi + h) % n) * n + jm]
    cells = np.concatenate(members)
    cls = np.tile(np.arange(U), len(members))
    # a class has fewer than four distinct members when a mirror image coincides with the cell itself
    key = cells.astype(np.int64) * (U + 1) + cls
    _, first = np.unique(key, return_index=True)
    first = np.sort(first)
    axis = grid_axis(step_deg)
    return np.stack([axis[ii], axis[Jr]], -1), cells[first].astype(np.int32), cls[first]


def tile_ranges(step_deg: float, force_deg: float, tile_cells: int) -> list[tuple[int, int]]:
    """Column ranges [i_lo, i_hi) of the tiles: consecutive columns with at most tile_cells classes each
    (at least one column)."""
    counts = class_counts(step_deg, force_deg)
    ranges, lo, acc = [], 0, 0
    for i, k in enumerate(counts):
        if acc and acc + k > tile_cells:
            ranges.append((lo, i))
            lo, acc = i, 0
        acc += k
    ranges.append((lo, len(counts)))
    return ranges


def n_tiles(step_deg: float, force_deg: float, tile_cells: int) -> int:
    """Jobs per map: tiles of at most tile_cells symmetry classes (whole columns)."""
    return len(tile_ranges(step_deg, force_deg, tile_cells))


# --- maps as arrays, tiles, files -----------------------------------------------------------------------

@dataclass(frozen=True)
class MapArrays:
    """A whole map: b, phi [deg], grid step [deg], sigma, and (n, n) arrays indexed [i, j] = (q1*, q2*)
    of O_t [m^2 with l1 = 1, |F| = 1, times sigma^2], chi, the optimal pose [deg] and the status."""
    link_ratio: float
    force_deg: float
    step_deg: float
    sigma: float
    O_t: np.ndarray
    q1_opt_deg: np.ndarray
    q2_opt_deg: np.ndarray
    status: np.ndarray

    @property
    def axis(self) -> np.ndarray:
        return grid_axis(self.step_deg)

    @property
    def chi(self) -> np.ndarray:
        """chi = O_t* / O_t with O_t* = n sigma^2 / m = 2 sigma^2 (eqs. 17, 27, as in Table 3); inf where
        A_t = 0."""
        with np.errstate(divide="ignore"):
            return np.where(self.O_t > 0, 2 * self.sigma**2 / self.O_t, np.inf)

    def subgrid(self, step_deg: float) -> "MapArrays":
        """The map on a coarser grid whose step is a multiple of this one's (same cells, no solving)."""
        k = step_deg / self.step_deg
        if abs(k - round(k)) > 1e-9 or round(k) < 1:
            raise ValueError(f"a {step_deg} deg grid is not a subgrid of the {self.step_deg} deg map")
        k = int(round(k))
        return MapArrays(self.link_ratio, self.force_deg, float(step_deg), self.sigma,
                         *(a[::k, ::k] for a in (self.O_t, self.q1_opt_deg, self.q2_opt_deg, self.status)))


def solve_tile(b: float, force_deg: float, step_deg: float, i_lo: int, i_hi: int, sigma: float = 1.0,
               progress=None, chunk: int = 32768, tab=None) -> dict:
    """The cells of the classes represented in columns [i_lo, i_hi): a dict of the tile file's arrays
    (module docstring): each class solved once, written for every member."""
    reps, cells, cls = class_members(step_deg, force_deg, i_lo, i_hi)
    ot, pose, status = np.empty(len(reps)), np.empty((len(reps), 2)), np.empty(len(reps), np.int8)
    for k in range(0, len(reps), chunk):
        sol = solve_cells(b, force_deg, reps[k:k + chunk], tab)
        ot[k:k + chunk], pose[k:k + chunk], status[k:k + chunk] = sol.ot, sol.pose_deg, sol.status
        if progress:
            progress(min(k + chunk, len(reps)), len(reps))
    return {"cell": cells, "O_t": ot[cls] * sigma**2, "q1_opt_deg": pose[cls, 0], "q2_opt_deg": pose[cls, 1],
            "status": status[cls]}


def map_tile(b: float, force_deg: float, step_deg: float, tile_cells: int, tile: int, sigma: float = 1.0,
             progress=None) -> dict:
    """Tile ``tile`` of the step_deg map (:func:`tile_ranges`), as the arrays of a tile file."""
    ranges = tile_ranges(step_deg, force_deg, tile_cells)
    if not 0 <= tile < len(ranges):
        raise ValueError(f"tile {tile} is out of range: the map has {len(ranges)}")
    return solve_tile(b, force_deg, step_deg, *ranges[tile], sigma, progress)


def merge_tiles(tiles: list[dict], b: float, force_deg: float, step_deg: float, sigma: float = 1.0) -> MapArrays:
    """The whole map from its tiles; ValueError when cells are missing or repeated."""
    n = int(round(360.0 / step_deg))
    cells = np.concatenate([t["cell"] for t in tiles])
    count = np.bincount(cells, minlength=n * n)
    if len(count) != n * n or count.min() != 1 or count.max() != 1:
        raise ValueError(f"the map tiles hold {len(cells)} cells ({int((count > 1).sum())} repeated, "
                         f"{int((count == 0).sum())} missing); the {step_deg} deg grid has {n * n}")
    out = {}
    for k, dtype in (("O_t", float), ("q1_opt_deg", float), ("q2_opt_deg", float), ("status", np.int8)):
        a = np.empty(n * n, dtype)
        a[cells] = np.concatenate([t[k] for t in tiles])
        out[k] = a.reshape(n, n)
    return MapArrays(float(b), float(force_deg), float(step_deg), float(sigma), **out)


def solve_map(b: float, force_deg: float, step_deg: float, sigma: float = 1.0, progress=None) -> MapArrays:
    """A whole map in one call (every class once)."""
    h = int(round(360.0 / step_deg)) // 2
    tile = solve_tile(b, force_deg, step_deg, 0, h, sigma, progress)
    return merge_tiles([tile], b, force_deg, step_deg, sigma)


def save_arrays(path, arrays: dict) -> None:
    """Write arrays as an .npz file with fixed member timestamps (byte-identical reruns), via a temporary
    file renamed on completion (no partial output)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for name in sorted(arrays):
            buf = io.BytesIO()
            a = np.asarray(arrays[name])
            np.lib.format.write_array(buf, a if a.flags.c_contiguous else a.copy(order="C"), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, buf.getvalue(), compresslevel=1)
    tmp.replace(path)


def load_arrays(path, required) -> dict:
    """Read an .npz file written by :func:`save_arrays`; InputError naming the file and the array when it is
    not one or an array is missing."""
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in required if k not in z.files]
            if missing:
                raise InputError(f"expected the arrays {', '.join(required)}; missing {', '.join(missing)}",
                                 source=str(path))
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise InputError(f"expected a map file (.npz, see stiffcal.planning.maps), could not read it: {err}",
                         source=str(path)) from None


TILE_ARRAYS = ("cell", "O_t", "q1_opt_deg", "q2_opt_deg", "status")
MAP_ARRAYS = ("link_ratio", "force_deg", "step_deg", "sigma", "q1t_deg", "q2t_deg", "O_t", "chi",
              "q1_opt_deg", "q2_opt_deg", "status")


def save_map(path, mp: MapArrays) -> None:
    save_arrays(path, {"link_ratio": np.float64(mp.link_ratio), "force_deg": np.float64(mp.force_deg),
                       "step_deg": np.float64(mp.step_deg), "sigma": np.float64(mp.sigma),
                       "q1t_deg": mp.axis, "q2t_deg": mp.axis, "O_t": mp.O_t, "chi": mp.chi,
                       "q1_opt_deg": mp.q1_opt_deg, "q2_opt_deg": mp.q2_opt_deg, "status": mp.status})


def load_map(path) -> MapArrays:
    z = load_arrays(path, MAP_ARRAYS)
    n = len(z["q1t_deg"])
    if any(z[k].shape != (n, n) for k in ("O_t", "q1_opt_deg", "q2_opt_deg", "status")):
        raise InputError(f"expected ({n}, {n}) arrays for the {n} grid angles", source=str(path))
    return MapArrays(float(z["link_ratio"]), float(z["force_deg"]), float(z["step_deg"]), float(z["sigma"]),
                     z["O_t"], z["q1_opt_deg"], z["q2_opt_deg"], z["status"])


def map_columns(mp: MapArrays) -> dict[str, np.ndarray]:
    """The map as columns :data:`MAP_COLUMNS` -> (N,) float64, rows sorted by (q1*, q2*) (map.csv, written
    without pandas: :func:`stiffcal.csvtext.write_numeric_csv`)."""
    Q1, Q2 = np.meshgrid(mp.axis, mp.axis, indexing="ij")
    n = Q1.size
    return {"link_ratio": np.full(n, float(mp.link_ratio)), "force_deg": np.full(n, float(mp.force_deg)),
            "q1t_deg": Q1.ravel(), "q2t_deg": Q2.ravel(), "q1_opt_deg": mp.q1_opt_deg.ravel(),
            "q2_opt_deg": mp.q2_opt_deg.ravel(), "O_t": mp.O_t.ravel(), "chi": mp.chi.ravel()}


def map_frame(mp: MapArrays):
    """The map as a table with :data:`MAP_COLUMNS`, rows sorted by (q1*, q2*) (:func:`map_columns`)."""
    import pandas as pd

    return pd.DataFrame(map_columns(mp))


def log_progress(label: str):
    """A progress callback printing '<label>: done/total cells (rate)' lines."""
    t0 = time.perf_counter()

    def report(done, total):
        dt = time.perf_counter() - t0
        print(f"[stiffcal {time.strftime('%H:%M:%S')}] {label}: {done}/{total} cells "
              f"({done / max(dt, 1e-9):,.0f} cells/s)", flush=True)
    return report


# --- studies and statistics --------------------------------------------------------------------------

MAP_DEFAULTS = {"step_deg": 1.0, "force_deg": -90.0, "tile_cells": 65536, "statistics_steps_deg": [10, 5, 2, 1, 0.5],
                "pairs_step_deg": 6.0}


@dataclass(frozen=True)
class MapStudy:
    """One map of the config's ``maps.studies``: b = l2 / l1, the paper's figure number, grid settings."""

    name: str
    link_ratio: float
    figure: int
    step_deg: float
    force_deg: float
    tile_cells: int

    @property
    def n_tiles(self) -> int:
        return n_tiles(self.step_deg, self.force_deg, self.tile_cells)


def _check_step(step: float, source: str, field: str) -> None:
    k = 180.0 / step
    if abs(k - round(k)) > 1e-9:
        raise InputError(f"expected a step that divides 180 deg (so that the grid maps onto itself under "
                         f"the arm's symmetries), got {step}", source=source, field=field)


def map_studies(config: dict, root=".", source: str = "config") -> list[MapStudy]:
    """The map studies of a validated config (empty without a ``maps`` block); InputError names the field."""
    if not config.get("maps"):
        return []
    m = {**MAP_DEFAULTS, **config["maps"]}
    _check_step(float(m["step_deg"]), source, "maps.step_deg")
    for i, s in enumerate(m["statistics_steps_deg"]):
        _check_step(float(s), source, f"maps.statistics_steps_deg[{i}]")
    _check_step(float(m["pairs_step_deg"]), source, "maps.pairs_step_deg")
    out, names, figures = [], set(), set()
    for i, s in enumerate(m["studies"]):
        field = f"maps.studies[{i}]"
        if s["name"] in names:
            raise InputError(f"expected a unique name, got {s['name']!r} twice", source=source, field=f"{field}.name")
        if s["figure"] in figures:
            raise InputError(f"expected each figure once, got figure {s['figure']} twice", source=source,
                             field=f"{field}.figure")
        names.add(s["name"])
        figures.add(s["figure"])
        if "robot" in s:
            from ..model.robot import load_config_robot

            robot = load_config_robot(root, s["robot"], source, f"{field}.robot")
            if not robot.planar or robot.n_joints != 2:
                raise InputError(f"expected a planar robot with 2 joints for a map, got {robot.kind} with "
                                 f"{robot.n_joints}", source=source, field=f"{field}.robot")
            b = float(robot.links_m[1] / robot.links_m[0])
        else:
            b = float(s["link_ratio"])
        out.append(MapStudy(s["name"], b, int(s["figure"]), float(m["step_deg"]), float(m["force_deg"]),
                            int(m["tile_cells"])))
    return out


def rank_deficient(b: float, force_deg: float, qt_deg: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """(N,) bool: A_t has rank < 2 (det S / tr(S)^2 < rtol): the test arm is straight or folded, or the
    force passes through a joint. Measuring at such a test pose cannot identify both compliances."""
    S = test_information(b, force_deg, qt_deg)
    tr = S[:, 0] + S[:, 2]
    return (S[:, 0] * S[:, 2] - S[:, 1] ** 2) <= rtol * tr * tr


#: Figure 6 shades 1/chi: "white" cells gain at least 10-fold (1/chi <= 0.1), "dark" ones at most 1.25-fold
WHITE_CHI, DARK_CHI = 10.0, 1.25


def chi_statistics(mp: MapArrays) -> dict[str, float]:
    """The statistics that the paper quotes for Figure 6, computed from a map.

    ``mean`` is over every cell with A_t != 0 (chi = 2 sigma^2 / O_t there, eq. 27 with eq. 17, the
    convention of the paper's Table 3; on the straight or folded rows O_t is the infimum, chi its
    supremum); ``mean_regular`` leaves out the rank-deficient test poses, where measuring at the test pose
    is impossible (O_t* is really infinite). Near the test poses with A_t = 0, chi grows like 1 / r^2
    (r the distance in the test-pose plane), so the mean over the continuum is infinite and any grid mean
    grows like log(1 / step): the median and the harmonic mean do not. ``white`` / ``dark`` are the
    fractions of the plane with 1/chi <= 0.1 and 1/chi >= 0.8; ``cells_no_optimum`` counts the cells
    without an optimal pose (module docstring, 4) and ``cells_uncertified`` those without a certificate.
    """
    chi = mp.chi.ravel()
    finite = np.isfinite(chi)
    regular = ~rank_deficient(mp.link_ratio, mp.force_deg, test_pose_grid(mp.step_deg))
    status = mp.status.ravel()
    return {"cells": float(len(chi)), "cells_At_zero": float((~finite).sum()),
            "cells_rank_deficient": float((~regular).sum()),
            "cells_no_optimum": float((status == NO_OPTIMUM).sum()),
            "cells_uncertified": float((status == UNCERTIFIED).sum()),
            "mean": float(chi[finite].mean()), "mean_regular": float(chi[regular].mean()),
            "median": float(np.median(chi[finite])), "harmonic_mean": float(1.0 / np.mean(1.0 / chi)),
            "p99": float(np.percentile(chi[finite], 99)), "max_regular": float(chi[regular].max()),
            "min": float(chi.min()), "white": float(np.mean(chi >= WHITE_CHI)), "dark": float(np.mean(chi <= DARK_CHI))}


def grid_statistics(mp: MapArrays, st: MapStudy, steps_deg) -> dict[float, dict[str, float]]:
    """:func:`chi_statistics` of a map on its own grid and on every grid of ``steps_deg`` [deg] (step ->
    statistics): grids whose step is a multiple of the map's are its subgrids; others are solved
    (:func:`solve_map`)."""
    grids = {st.step_deg: mp}
    for step in map(float, steps_deg):
        if step not in grids:
            try:
                grids[step] = mp.subgrid(step)
            except ValueError:
                grids[step] = solve_map(st.link_ratio, st.force_deg, step, mp.sigma)
    return {step: chi_statistics(g) for step, g in grids.items()}


def save_grid_statistics(path, stats: dict[float, dict[str, float]]) -> None:
    """:func:`grid_statistics` as an .npz file (exact float64: the tables read from it are the same bytes)."""
    steps = list(stats)
    names = list(stats[steps[0]])
    save_arrays(path, {"step_deg": np.array(steps, float), "statistic": np.array(names),
                       "value": np.array([[stats[s][k] for k in names] for s in steps], float)})


def load_grid_statistics(path) -> dict[float, dict[str, float]]:
    z = load_arrays(path, ("step_deg", "statistic", "value"))
    names = [str(k) for k in z["statistic"]]
    if z["value"].shape != (len(z["step_deg"]), len(names)):
        raise InputError("expected one value per grid and statistic", source=str(path))
    return {float(s): dict(zip(names, map(float, row))) for s, row in zip(z["step_deg"], z["value"])}


def statistics_table(maps_by_study: dict[str, MapArrays], studies: list[MapStudy], steps_deg, paper: dict,
                     grid_stats: dict | None = None):
    """Rows (study, link_ratio, grid_deg, statistic, ours, paper): every study's map statistics, and for
    the paper's arm (the study of Figure 7) the mean chi on each grid of steps_deg, beside the paper's
    (:func:`grid_statistics`, or ``grid_stats[study]`` when given: then that study's map is not needed)."""
    import pandas as pd

    rows = []
    for st in studies:
        if st.figure == 7:
            stats = (grid_stats or {}).get(st.name)
            if stats is None:
                stats = grid_statistics(maps_by_study[st.name], st, steps_deg)
        else:
            stats = {st.step_deg: chi_statistics(maps_by_study[st.name])}
        for step in sorted(stats, reverse=True):
            keys = stats[step] if step == st.step_deg else ("mean", "mean_regular", "median", "harmonic_mean")
            for k in keys:
                p = paper.get(k) if st.figure == 7 else None
                rows.append({"study": st.name, "link_ratio": st.link_ratio, "grid_deg": step, "statistic": k,
                             "ours": stats[step][k], "paper": p if p is not None else np.nan})
    return pd.DataFrame(rows)


# --- plans of two poses (case iv of Table 4) over the test poses -----------------------------------------

def pose_pool(step_deg: float) -> np.ndarray:
    """Measurement poses (K, 2) [deg] that hold every information matrix once (q1 in [-90, 90), q2 in
    [0, 180]; the other copies are q1 + 180 and the mirror image), singular ones included: one pose of a
    pair may be singular when the other makes up for it."""
    g1 = np.arange(-90.0, 90.0 - 1e-9, step_deg)
    g2 = np.arange(0.0, 180.0 + 1e-9, step_deg)
    Q1, Q2 = np.meshgrid(g1, g2, indexing="ij")
    return np.stack([Q1.ravel(), Q2.ravel()], axis=-1)


def _pair_ot(S: np.ndarray, M: np.ndarray) -> np.ndarray:
    """tr(S M^-1) for S, M (..., 3) as (11, 12, 22); +inf where M is (numerically) singular."""
    det = M[..., 0] * M[..., 2] - M[..., 1] ** 2
    num = S[..., 0] * M[..., 2] - 2 * S[..., 1] * M[..., 1] + S[..., 2] * M[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = num / det
    return np.where(det > 1e-12 * M[..., 0] * M[..., 2] + 1e-300, v, np.inf)


def _pair_polish(b, force_deg, S, q, iters: int = 20, h: float = 1e-5):
    """Damped Newton steps (central differences) on log O_t of two-pose plans q (N, 4) [rad], vectorised
    over the cells S (N, 3); never worse than the start. Returns (q, value)."""
    def f(qq):
        A = test_observation(b, force_deg, np.degrees(qq.reshape(-1, 2))).reshape(len(qq), 2, 2, 2)
        with np.errstate(all="ignore"):
            v = _pair_ot(S, _info(A[:, 0]) + _info(A[:, 1]))
            return np.where(np.isfinite(v) & (v > 0), np.log(v), np.inf)

    f0 = f(q)
    eye = np.eye(4) * h
    act = np.isfinite(f0)
    for _ in range(iters):
        fp = np.stack([f(q + e) for e in eye], 1)
        fm = np.stack([f(q - e) for e in eye], 1)
        H = np.empty((len(q), 4, 4))
        with np.errstate(all="ignore"):
            g = (fp - fm) / (2 * h)
            for i in range(4):
                H[:, i, i] = (fp[:, i] - 2 * f0 + fm[:, i]) / h**2
                for j in range(i + 1, 4):
                    H[:, i, j] = H[:, j, i] = (f(q + eye[i] + eye[j]) - fp[:, i] - fp[:, j] + f0) / h**2
            w, V = np.linalg.eigh(np.nan_to_num(H))
            step = -np.einsum("nij,nj,nkj,nk->ni", V, 1 / np.maximum(np.abs(w), 1e-3), V, np.nan_to_num(g))
        step *= np.minimum(1.0, 0.1 / np.maximum(np.abs(step).max(axis=1, keepdims=True), 1e-300))
        improved = np.zeros(len(q), bool)
        for frac in (1.0, 0.5, 0.25, 0.0625):
            cand = f(q + frac * step)
            take = (cand < f0 - 1e-15) & ~improved & act
            q = np.where(take[:, None], q + frac * step, q)
            f0 = np.where(take, cand, f0)
            improved |= take
        act = improved
        if not act.any():
            break
    return q, np.exp(f0)


def _partner_values(S: np.ndarray, Ma: np.ndarray, MP: np.ndarray) -> np.ndarray:
    """tr(S (Ma + MP_k)^-1) for cells S, Ma (n, 3) and every pool pose MP (K, 3): (n, K)."""
    m0 = Ma[:, 0, None] + MP[None, :, 0]
    m1 = Ma[:, 1, None] + MP[None, :, 1]
    m2 = Ma[:, 2, None] + MP[None, :, 2]
    det = m0 * m2 - m1 * m1
    num = S[:, 0, None] * m2 - 2 * S[:, 1, None] * m1 + S[:, 2, None] * m0
    with np.errstate(divide="ignore", invalid="ignore"):
        v = num / det
    return np.where(det > 1e-12 * m0 * m2 + 1e-300, v, np.inf)


def _coarse_pairs(S: np.ndarray, MC: np.ndarray, keep: int) -> np.ndarray:
    """The keep best unordered pairs (n, keep, 2) of the coarse pool MC (K, 3) for cells S (n, 3), by
    evaluating every pair."""
    K = len(MC)
    i, j = np.triu_indices(K)
    best_v = np.full((len(S), keep), np.inf)
    best_p = np.zeros((len(S), keep), int)
    for lo in range(0, len(i), 8192):
        sl = slice(lo, lo + 8192)
        v = _partner_values(S, np.zeros_like(S), MC[i[sl]] + MC[j[sl]])
        k = np.argpartition(v, keep - 1, axis=1)[:, :keep]          # this chunk's best, then merged
        allv = np.concatenate([best_v, np.take_along_axis(v, k, 1)], axis=1)
        allp = np.concatenate([best_p, k + lo], axis=1)
        k = np.argsort(allv, axis=1, kind="stable")[:, :keep]
        best_v, best_p = np.take_along_axis(allv, k, 1), np.take_along_axis(allp, k, 1)
    return np.stack([i[best_p], j[best_p]], axis=-1)


def best_pairs(b: float, force_deg: float, qt_deg: np.ndarray, single_deg: np.ndarray, pool_step_deg: float = 3.0,
               coarse_step_deg: float = 12.0, starts: int = 3, chunk: int = 128):
    """The best plan of two measurement poses for test poses qt_deg (N, 2) [deg] (O_t / sigma^2, l1 = 1,
    |F| = 1). Every pair of a coarse pool (:func:`pose_pool`, coarse_step_deg) is evaluated; from the
    ``starts`` best, and from the single optimum single_deg (N, 2) (NaN where there is none) with its best
    partner, each pose is replaced in turn by its best partner on the finer pool until nothing changes,
    and damped Newton steps polish the result in the continuum; the single optimum measured twice (plan
    (i), O_t1 / 2) is the fallback, so the result is never above it. Returns (O_t (N,), poses (N, 2, 2)
    [deg]). A search of a 4-D problem, not a certificate: ``tests/test_maps.py`` and the benchmark check
    sampled cells against a brute force over all pairs."""
    qt = np.atleast_2d(np.asarray(qt_deg, float))
    S = test_information(b, force_deg, qt)
    pool, coarse = pose_pool(pool_step_deg), pose_pool(coarse_step_deg)
    MP = _info(test_observation(b, force_deg, pool))
    MC = _info(test_observation(b, force_deg, coarse))
    # a coarse pose's nearest pose of the fine pool
    near = np.argmin(np.abs(np.angle(np.exp(1j * np.radians(coarse[:, None, :] - pool[None, :, :])))).sum(-1), axis=1)
    out_v = np.full(len(qt), np.inf)
    out_q = np.zeros((len(qt), 4))
    sd_all = np.atleast_2d(np.asarray(single_deg, float))
    for lo in range(0, len(qt), chunk):
        Sc, sd = S[lo:lo + chunk], sd_all[lo:lo + chunk]
        n = len(Sc)
        ok = np.all(np.isfinite(sd), axis=1)
        sd = np.where(ok[:, None], sd, 0.0)
        Ms = _info(test_observation(b, force_deg, sd))
        first = near[_coarse_pairs(Sc, MC, starts)]                       # (n, starts, 2) fine-pool indices
        a_all = np.concatenate([first[:, :, 0].T.ravel(), np.full(n, -1)])
        b_all = np.concatenate([first[:, :, 1].T.ravel(), np.argmin(_partner_values(Sc, Ms, MP), axis=1)])
        rows = np.tile(np.arange(n), starts + 1)
        Sr = Sc[rows]
        Ma = np.where((a_all >= 0)[:, None], MP[a_all], Ms[rows])
        for _ in range(10):                      # exchange on the fine pool (the single optimum stays put)
            b_new = np.argmin(_partner_values(Sr, Ma, MP), axis=1)
            a_new = np.where(a_all >= 0, np.argmin(_partner_values(Sr, MP[b_new], MP), axis=1), -1)
            if np.array_equal(a_new, a_all) and np.array_equal(b_new, b_all):
                break
            a_all, b_all = a_new, b_new
            Ma = np.where((a_all >= 0)[:, None], MP[a_all], Ms[rows])
        qa = np.where((a_all >= 0)[:, None], pool[a_all], sd[rows])
        q, v = _pair_polish(b, force_deg, Sr, np.radians(np.concatenate([qa, pool[b_all]], axis=1)))
        v = np.where((a_all >= 0) | ok[rows], v, np.inf)
        v, q = v.reshape(starts + 1, n), q.reshape(starts + 1, n, 4)
        k = np.argmin(v, axis=0)
        v, q = v[k, np.arange(n)], q[k, np.arange(n)]
        # the single optimum measured twice (plan (i)): a stationary point of the pair problem
        v1 = np.where(ok, _pair_ot(Sc, 2 * Ms), np.inf)
        rep = v1 < v
        out_v[lo:lo + chunk] = np.where(rep, v1, v)
        out_q[lo:lo + chunk] = np.where(rep[:, None], np.radians(np.concatenate([sd, sd], axis=1)), q)
    return out_v, np.degrees(out_q).reshape(-1, 2, 2)


@dataclass(frozen=True)
class PairMap:
    """The best two-pose plan over the test-pose grid (case iv of Table 4): (n, n) arrays indexed
    [q1*, q2*] of O_t of the single optimum (``O_t1``; the infimum where none) and of the best pair
    (``O_t2``), both [l1 = 1, |F| = 1, times sigma^2], and the pair's poses (n, n, 2, 2) [deg]."""
    link_ratio: float
    force_deg: float
    step_deg: float
    O_t1: np.ndarray
    O_t2: np.ndarray
    poses_deg: np.ndarray

    @property
    def axis(self) -> np.ndarray:
        return grid_axis(self.step_deg)

    @property
    def gain(self) -> np.ndarray:
        """How much a designed pair beats the single optimum measured twice (O_t1 / 2, eq. 17): 1 - O_t2 /
        (O_t1 / 2), as a fraction; 0 where A_t = 0."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.O_t1 > 0, 1 - self.O_t2 / (self.O_t1 / 2), 0.0)


def pair_map(b: float, force_deg: float, step_deg: float, pool_step_deg: float = 3.0, progress=None) -> PairMap:
    """:class:`PairMap` for the grid of step_deg (every symmetry class once)."""
    h = int(round(360.0 / step_deg)) // 2
    reps, cells, cls = class_members(step_deg, force_deg, 0, h)
    single = solve_cells(b, force_deg, reps)
    ot2, poses = best_pairs(b, force_deg, reps, single.pose_deg, pool_step_deg)
    zero = single.status == AT_ZERO
    ot2[zero] = 0.0
    if progress:
        progress(len(reps), len(reps))
    n = 2 * h
    O1, O2 = np.empty(n * n), np.empty(n * n)
    P = np.empty((n * n, 2, 2))
    O1[cells], O2[cells], P[cells] = single.ot[cls], ot2[cls], poses[cls]
    return PairMap(float(b), float(force_deg), float(step_deg), O1.reshape(n, n), O2.reshape(n, n),
                   P.reshape(n, n, 2, 2))


PAIR_ARRAYS = ("link_ratio", "force_deg", "step_deg", "q1t_deg", "q2t_deg", "O_t1", "O_t2", "gain", "poses_deg")


def save_pair_map(path, pm: PairMap) -> None:
    save_arrays(path, {"link_ratio": np.float64(pm.link_ratio), "force_deg": np.float64(pm.force_deg),
                       "step_deg": np.float64(pm.step_deg), "q1t_deg": pm.axis, "q2t_deg": pm.axis,
                       "O_t1": pm.O_t1, "O_t2": pm.O_t2, "gain": pm.gain, "poses_deg": pm.poses_deg})


def load_pair_map(path) -> PairMap:
    z = load_arrays(path, PAIR_ARRAYS)
    return PairMap(float(z["link_ratio"]), float(z["force_deg"]), float(z["step_deg"]), z["O_t1"], z["O_t2"],
                   z["poses_deg"])


def pair_columns(pm: PairMap) -> dict[str, np.ndarray]:
    """The pair map as columns -> (N,) float64: test pose, O_t of the single optimum and of the best pair, the
    gain, the poses (pairs.csv, written without pandas)."""
    Q1, Q2 = np.meshgrid(pm.axis, pm.axis, indexing="ij")
    P = pm.poses_deg.reshape(-1, 4)
    n = Q1.size
    return {"link_ratio": np.full(n, float(pm.link_ratio)), "force_deg": np.full(n, float(pm.force_deg)),
            "q1t_deg": Q1.ravel(), "q2t_deg": Q2.ravel(), "O_t_single": pm.O_t1.ravel(), "O_t_pair": pm.O_t2.ravel(),
            "gain": pm.gain.ravel(), "q1a_deg": P[:, 0], "q2a_deg": P[:, 1], "q1b_deg": P[:, 2], "q2b_deg": P[:, 3]}


def pair_frame(pm: PairMap):
    """The pair map as rows (:func:`pair_columns`)."""
    import pandas as pd

    return pd.DataFrame(pair_columns(pm))
