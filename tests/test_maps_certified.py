"""Maps (issue 16 item 4): every cell of the default 1-degree maps certified, including the cells next to
straight and folded arms and to the force through a joint, where double and long double do not resolve the
roots and the exact method (integer coefficients, FLINT root isolation, strong-convexity bound) certifies
them; those very cells against an independent brute force (dense grid, local polish, 128-bit value)."""

import numpy as np
import pytest

from stiffcal.planning import _map_solver as solver
from stiffcal.planning import maps
from stiffcal.testing.reference import brute_force_cell_hp, ot_ball

PHI = -90.0
DEFAULT_RATIOS = (0.2, 0.5, 0.4 / 0.6, 0.9)   # the studies of Figures 7-10


@pytest.fixture(scope="module")
def default_maps():
    return {b: maps.solve_map(b, PHI, 1.0) for b in DEFAULT_RATIOS}


def _normalised_ld(b, qt):
    """The cells' normalised S (N, 3) and factor R (N, 2, 2) in long double, as solve_cells forms them."""
    A = maps.test_observation(b, PHI, qt, np.longdouble)
    S = np.stack([np.sum(A[:, :, 0] ** 2, 1), np.sum(A[:, :, 0] * A[:, :, 1], 1), np.sum(A[:, :, 1] ** 2, 1)], -1)
    tr = S[:, 0] + S[:, 2]
    return S / tr[:, None], A / np.sqrt(tr)[:, None, None]


def _near_joint1_curve(rng, b, n, spread):
    """Test poses within `spread` deg of the curve where the force (phi = -90) passes through joint 1:
    cos q1* + b cos(q1* + q2*) = 0."""
    u = rng.uniform(-min(1.0, b), min(1.0, b), n)                  # cos q1* = u, cos(q1* + q2*) = -u / b
    q1 = np.arccos(u) * rng.choice([-1, 1], n)
    psi = np.arccos(-u / b) * rng.choice([-1, 1], n)
    qt = np.degrees(np.stack([q1, psi - q1], -1)) + rng.uniform(-spread, spread, (n, 2))
    return (qt + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("b", DEFAULT_RATIOS)
def test_every_cell_of_the_default_maps_is_certified(b, default_maps):
    """No cell of the 1-degree maps is left uncertified (all 129,600, the singular neighbourhoods included)."""
    counts = np.bincount(default_maps[b].status.ravel(), minlength=len(maps.STATUS))
    assert counts[maps.UNCERTIFIED] == 0, {maps.STATUS[k]: int(c) for k, c in enumerate(counts) if c}


def test_exactly_certified_cells_against_a_high_precision_brute_force(default_maps):
    """The cells that only the exact method certifies (next to a folded or straight arm and the force through
    joint 1): their O_t is within 1e-9 of an independent brute force (1-degree grid over the whole joint space,
    Nelder-Mead in long double, the value in 128-bit ball arithmetic), the reported pose attains it, and the
    certificate's lower bound is never above the brute force's attained value."""
    F = maps.force_vector(PHI)
    checked = 0
    for b, mp in default_maps.items():
        hard = np.argwhere(mp.status == maps.ARBITRARY)
        if not len(hard):
            continue
        # one cell per distinct value (a symmetry class), spread over the list
        _, first = np.unique(np.round(mp.O_t[hard[:, 0], hard[:, 1]], 12), return_index=True)
        picks = hard[np.sort(first)][:: max(1, len(first) // 3)][:3]
        qt = np.stack([mp.axis[picks[:, 0]], mp.axis[picks[:, 1]]], -1)
        S, R = _normalised_ld(b, qt)
        cert = solver.certify_exact(S, R, b)
        assert cert.certified.all()
        tr = maps.test_information(b, PHI, qt)[:, [0, 2]].sum(1)
        for k, (i, j) in enumerate(picks):
            ot, pose = mp.O_t[i, j], np.array([mp.q1_opt_deg[i, j], mp.q2_opt_deg[i, j]])
            ref = brute_force_cell_hp(b, F, qt[k])
            assert ot <= ref * (1 + 1e-9), (b, qt[k], ot, ref)
            assert float(ot_ball(b, F, qt[k], pose).mid()) == pytest.approx(ot, rel=1e-12)
            assert cert.lower[k] * tr[k] <= ref * (1 + 1e-15), (b, qt[k], cert.lower[k] * tr[k], ref)
            checked += 1
    assert checked >= 6


def test_exact_method_agrees_with_the_floating_point_one(rng):
    """On cells the floating-point method certifies (generic ones and ones next to the force through joint 1
    and to straight or folded arms), the exact method certifies the same optimum (1e-12) and its lower bound
    lies below it."""
    for b in (0.5, 0.9, 1.5):
        qt = np.vstack([rng.uniform(-180, 180, (12, 2)), _near_joint1_curve(rng, b, 12, 3.0),
                        np.column_stack([rng.uniform(-180, 180, 12), rng.choice([-3.0, 2.0, 178.0, -177.0], 12)])])
        sol = maps.solve_cells(b, PHI, qt)
        keep = np.isin(sol.status, [maps.HULL, maps.EXACT, maps.EXTENDED])
        S, R = _normalised_ld(b, qt[keep])
        cert = solver.certify_exact(S, R, b)
        tr = maps.test_information(b, PHI, qt[keep])[:, [0, 2]].sum(1)
        assert cert.certified.all()
        assert np.allclose(cert.value * tr, sol.ot[keep], rtol=1e-12, atol=0)
        assert np.all(cert.lower <= cert.value)


def test_line_minimum_bound_from_strong_convexity(rng):
    """The bound behind the exact certificate: (log O_t)'' >= 1/2 in c at fixed x, so for any c0
    min_c log O_t(x, c) >= log O_t(x, c0) - (d log O_t / dc (x, c0))^2 (finite differences and a fine grid,
    independent of the closed forms)."""
    for b in (0.2, 2 / 3, 1.5):
        rho = rng.uniform(1e-3, 0.5, 40)
        r, a = np.sqrt(0.25 - rho**2), rng.uniform(0, 2 * np.pi, 40)
        S = np.stack([0.5 + r * np.cos(a), r * np.sin(a), 0.5 - r * np.cos(a)], -1)
        x = np.tan(rng.uniform(-1.55, 1.55, 40))
        c = np.linspace(-0.999, 0.999, 20001)
        h = c[1] - c[0]
        L = np.log(maps.ot_xc(S[:, None, :], x[:, None], c[None, :], b))
        assert (L[:, 2:] - 2 * L[:, 1:-1] + L[:, :-2]).min() >= 0.5 * h * h * (1 - 1e-6)
        k = rng.integers(1, len(c) - 1, 40)
        rows = np.arange(40)
        d = (L[rows, k + 1] - L[rows, k - 1]) / (2 * h)
        assert np.all(L[rows, k] - d * d <= L.min(axis=1) + 1e-9)
