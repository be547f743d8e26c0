"""Maps over test poses (Figures 6-10): every cell against an independent long-double brute force (random
cells, half of them next to the singular test poses), the lemmas behind the certificate (log-convexity in c,
the derived polynomials, complete root isolation, the hull bound), the rows where the test arm is straight
or folded, the symmetry classes and tiles, the binary hand-over, the paper's cell, and bad map configs."""

import numpy as np
import pytest
from scipy.optimize import minimize

from stiffcal.planning import _map_solver as solver
from stiffcal.planning import maps
from stiffcal.model.criteria import o_t
from stiffcal.errors import InputError
from stiffcal.testing.reference import brute_force_cell_ld, brute_force_pair, ot_long_double, ot_plain
from stiffcal.model.robot import planar_robot
from stiffcal.model.stiffness import observation_matrix

PHI = -90.0


def _S(robot, qt_deg, force):
    At = observation_matrix(robot.jacobian(np.radians(qt_deg)), force)
    return At, At.T @ At


def _random_S(rng, n, rho_min=0.005):
    """Normalised S (n, 3) spread over the disc (rho = sqrt(det S) uniform in [rho_min, 1/2])."""
    rho = rng.uniform(rho_min, 0.5, n)
    r, a = np.sqrt(0.25 - rho**2), rng.uniform(0, 2 * np.pi, n)
    return np.stack([0.5 + r * np.cos(a), r * np.sin(a), 0.5 - r * np.cos(a)], -1)


def _cells(rng, n):
    """Random test poses: generic ones, ones within 1e-3..3 deg of the straight and folded rows, and ones
    next to the curves where the force passes through joint 2 (q1* + q2* = +-90 for phi = -90)."""
    generic = rng.uniform(-180, 180, (n, 2))
    off = 10 ** rng.uniform(-3, np.log10(3), n) * rng.choice([-1, 1], n)
    straight = np.column_stack([rng.uniform(-180, 180, n), off + 180 * rng.integers(0, 2, n)])
    q1 = rng.uniform(-180, 180, n)
    diagonal = np.column_stack([q1, maps_wrap(90 - q1 + rng.uniform(-2, 2, n))])
    return np.vstack([generic, straight, diagonal])


def maps_wrap(q):
    return (np.asarray(q) + 180.0) % 360.0 - 180.0


def test_ot_and_chi_do_not_change_when_all_links_scale(rng):
    robot = planar_robot([0.6, 0.4])
    force = np.array([0.0, -1.0])
    for _ in range(5):
        qt, q = rng.uniform(-np.pi, np.pi, (2, 2))
        vals = []
        for scale, fscale in ((1.0, 1.0), (3.7, 1.0), (0.05, 250.0)):
            r = robot.scaled(scale)
            At = observation_matrix(r.jacobian(qt), force * fscale)
            A = observation_matrix(r.jacobian(q), force * fscale)
            vals.append(o_t(A.T @ A, At))
        assert np.allclose(vals, vals[0], rtol=1e-12)


def test_reduced_formula_equals_the_library(rng):
    """O_t(x, c) of the module docstring, and the cancellation-free form from the factor of S, against eq. 16
    evaluated by the library at the same poses."""
    for b in (0.2, 2 / 3, 0.9, 1.5):
        robot = planar_robot([1.0, b])
        F = maps.force_vector(PHI)
        qt = rng.uniform(-180, 180, (20, 2))
        q = rng.uniform(-180, 180, (20, 2))
        At = observation_matrix(robot.jacobian(np.radians(qt)), F)
        S = maps.test_information(b, PHI, qt)
        tau = np.einsum("ndi,d->ni", robot.jacobian(np.radians(q)), F)
        x, c, s = tau[:, 0] / tau[:, 1], np.cos(np.radians(q[:, 1])), np.abs(np.sin(np.radians(q[:, 1])))
        A = observation_matrix(robot.jacobian(np.radians(q)), F)
        ref = np.array([o_t(A[i].T @ A[i], At[i]) for i in range(20)])
        assert np.allclose(maps.ot_xc(S, x, c, b), ref, rtol=1e-9)
        assert np.allclose(solver.objective(At, b, x, c, s), ref, rtol=1e-9)
        assert np.allclose(maps.test_observation(b, PHI, qt), At, rtol=1e-12, atol=1e-14)


def test_ot_is_log_convex_in_c_at_fixed_x(rng):
    """The lemma behind the line minima: d^2 log O_t / dc^2 > 0 on (-1, 1) for every S >= 0 and x (finite
    differences on a grid, independent of the closed-form bound)."""
    for b in (0.2, 2 / 3, 1.5):
        S = _random_S(rng, 30, rho_min=0.0)
        x = np.tan(rng.uniform(-1.55, 1.55, 30))
        c = np.linspace(-0.999, 0.999, 4001)
        L = np.log(maps.ot_xc(S[:, None, :], x[:, None], c[None, :], b))
        d2 = L[:, 2:] - 2 * L[:, 1:-1] + L[:, :-2]
        assert d2.min() > 0


def test_every_local_minimum_is_a_root_of_the_derived_polynomial(rng):
    """Independent local minima (Nelder-Mead in joint space) have x = tau1/tau2 at a root of q12 or q4."""
    b = 0.5
    robot = planar_robot([1.0, b])
    F = maps.force_vector(PHI)
    for qt in rng.uniform(-180, 180, (3, 2)):
        _, S = _S(robot, qt, F)
        s = np.array([[S[0, 0], S[0, 1], S[1, 1]]]) / np.trace(S)
        polys = [q[0] for q, _ in solver.polynomials(b).coefficients(s)]
        for start in rng.uniform(-180, 180, (3, 2)):
            r = minimize(lambda q: ot_plain(robot, q, S, F)[0], start, method="Nelder-Mead",
                         options=dict(xatol=1e-11, fatol=1e-16, maxiter=6000))
            tau = robot.jacobian(np.radians(r.x)).T @ F
            x = tau[0] / tau[1]
            P = np.polynomial.polynomial
            residual = min(abs(P.polyval(x, p)) / P.polyval(abs(x), np.abs(p))
                           for p in polys)
            assert residual < 1e-6, (qt, r.x, residual)


def test_root_isolation_finds_every_real_root(rng):
    """Descartes isolation over the 32 strips against the real eigenvalues of the companion matrix
    (numpy.roots), for q12 and q4 at random S."""
    for b in (0.3, 2 / 3, 1.4):
        S = _random_S(rng, 60, rho_min=0.02)
        n = len(S)
        cell, strip = np.repeat(np.arange(n), solver.N_STRIPS), np.tile(np.arange(solver.N_STRIPS), n)
        poly = solver.polynomials(b)
        coeffs = poly.coefficients(S)
        for (r, er), (q, _) in zip(solver.strip_polynomials(poly, coeffs, cell, strip), coeffs):
            c_, lo, hi, kind = solver.isolate(r, er, cell, strip)
            assert set(kind) <= {1}
            th = solver.refine(q[c_], lo, hi)
            for i in range(n):
                ref = np.roots(q[i][::-1])
                ref = np.sort(ref[np.abs(ref.imag) < 1e-9 * np.maximum(1, np.abs(ref))].real)
                assert np.allclose(np.sort(np.tan(th[c_ == i])), ref, rtol=1e-8, atol=1e-10), (b, S[i])


def test_hull_bound_is_below_every_value_of_the_strip(rng):
    """The pruning bound (barycentric combination of the table's exact strip minima) is below O_t at every
    sampled point of the strip, for S anywhere in the table."""
    b = 2 / 3
    S = _random_S(rng, 200, rho_min=0.002)
    tab = solver.build_table(b, S)
    corners, lam, found = tab.mesh.locate(solver.disc_point(S))
    assert found.mean() > 0.99
    S, corners, lam = S[found], corners[found], lam[found]
    assert np.allclose(np.einsum("nc,nck->nk", lam, tab.S[corners]), S, atol=1e-12)   # S is their combination
    bound = np.einsum("nc,nck->nk", lam, tab.strip_min[corners])
    edges = solver.STRIP_EDGES
    for k in range(solver.N_STRIPS):
        th = np.linspace(edges[k], edges[k + 1], 41)[1:-1]
        g = np.linspace(0.002, np.pi - 0.002, 400)
        TH, G = np.meshgrid(th, g, indexing="ij")
        v = maps.ot_xc(S[:, None, None, :], np.tan(TH)[None], np.cos(G)[None], b)
        assert np.all(bound[:, k] <= v.min(axis=(1, 2)) * (1 + 1e-12))


@pytest.mark.parametrize("b", [0.2, 2 / 3, 0.9, 1.5])
def test_cells_are_the_global_optimum_of_a_long_double_brute_force(b, rng):
    """Random cells, two thirds of them next to singular test poses: never above the brute force's optimum by
    more than 1e-9, and the reported pose attains the reported O_t (both in long double)."""
    qt = _cells(rng, 4)
    sol = maps.solve_cells(b, PHI, qt)
    F = maps.force_vector(PHI)
    for k, cell in enumerate(qt):
        ref = brute_force_cell_ld(b, F, cell)
        assert sol.ot[k] <= ref * (1 + 1e-9), (cell, sol.ot[k], ref, sol.status[k])
        if sol.status[k] != maps.NO_OPTIMUM:
            at = float(ot_long_double(b, F, cell, sol.pose_deg[k])[0])
            assert at == pytest.approx(sol.ot[k], rel=1e-10), (cell, sol.status[k])


def test_every_cell_carries_a_certificate():
    """On the paper's arm (2-degree grid) every cell is certified, most by the lookup and the hull bound
    (the 1-degree maps of every study: tests/test_maps_certified.py)."""
    mp = maps.solve_map(2 / 3, PHI, 2.0)
    counts = np.bincount(mp.status.ravel(), minlength=len(maps.STATUS))
    assert counts[maps.UNCERTIFIED] == 0
    assert counts[maps.HULL] > 0.9 * mp.status.size


def test_straight_rows_have_no_optimal_pose_and_t_squared_is_the_infimum(rng):
    """q2* = 0: O_t >= t^2 for every plan (sampled in long double, none below), approached by measuring with
    a nearly straight arm across the force; the cell is marked, O_t holds t^2."""
    b = 2 / 3
    F = maps.force_vector(PHI)
    q1 = rng.uniform(-180, 180, 5)
    q1 = q1[np.abs(np.cos(np.radians(q1))) > 0.1]          # t != 0
    sol = maps.solve_cells(b, PHI, np.column_stack([q1, np.zeros_like(q1)]))
    t2 = np.sin(np.radians(PHI - q1)) ** 2
    assert np.all(sol.status == maps.NO_OPTIMUM) and np.isnan(sol.pose_deg).all()
    assert np.allclose(sol.ot, t2, rtol=1e-14)
    g = np.arange(-179.75, 180, 0.5)
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    for k, q in enumerate(q1):
        vals = ot_long_double(b, F, [q, 0.0], Q).astype(float)
        assert vals.min() >= t2[k] * (1 - 1e-12)
        # the arm straight (q2 = 1e-4 deg) with the force across it: within 1e-6 of t^2
        near = ot_long_double(b, F, [q, 0.0], [[PHI + 90, 1e-4], [PHI - 90, 1e-4]]).astype(float)
        assert near.min() == pytest.approx(t2[k], rel=1e-6)


def test_folded_rows_take_the_regular_optimum_where_one_exists():
    """q2* = +-180: for b < 1 the non-singular pose cos q2 = 1 - 2b with the force perpendicular to link 2
    attains t^2 (checked in long double), the same pose on the whole row (no speckle); for b > 1 none does."""
    F = maps.force_vector(PHI)
    q1 = np.arange(-175.0, 180.0, 10.0)
    for b in (0.2, 0.5, 0.9):
        cells = np.column_stack([np.concatenate([q1, q1]), np.repeat([-180.0, 180.0], len(q1))])
        sol = maps.solve_cells(b, PHI, cells)
        assert np.all(sol.status == maps.CLOSED)
        assert np.ptp(sol.pose_deg, axis=0).max() == 0
        assert np.cos(np.radians(sol.pose_deg[0, 1])) == pytest.approx(1 - 2 * b, abs=1e-12)
        at = ot_long_double(b, F, cells[0], sol.pose_deg[0]).astype(float)
        assert at[0] == pytest.approx(np.sin(np.radians(PHI - cells[0, 0])) ** 2, rel=1e-12)
    sol = maps.solve_cells(1.5, PHI, np.column_stack([q1, np.full_like(q1, 180.0)]))
    assert np.all(sol.status == maps.NO_OPTIMUM)


@pytest.mark.parametrize("b", [0.5, 1.5])
def test_force_through_a_joint_closed_forms_against_the_brute_force(b):
    """tau2* = 0 (force through joint 2) and tau1* = 0 (through joint 1): the closed forms against the
    long-double brute force (for tau1* = 0 and b <= 1 only the infimum, approached by singular poses)."""
    F = maps.force_vector(PHI)
    q1 = np.array([20.0, -50.0, 130.0])
    through2 = np.column_stack([q1, 90.0 - q1])                 # cos(q1 + q2) = 0
    c2 = -np.cos(np.radians(q1)) / b                              # cos(q1 + q2) = -cos(q1) / b
    ok = np.abs(c2) <= 1
    through1 = np.column_stack([q1[ok], np.degrees(np.arccos(c2[ok])) - q1[ok]])
    for cells, kind in ((through2, "2"), (through1, "1")):
        sol = maps.solve_cells(b, PHI, cells)
        for k, cell in enumerate(cells):
            ref = brute_force_cell_ld(b, F, cell)
            assert sol.ot[k] <= ref * (1 + 1e-9)
            assert sol.ot[k] >= ref * (1 - 1e-6)      # the infimum: the brute force gets within 1e-6
            if kind == "1" and b <= 1:
                assert sol.status[k] == maps.NO_OPTIMUM
            else:
                assert sol.status[k] == maps.CLOSED
                assert float(ot_long_double(b, F, cell, sol.pose_deg[k])[0]) == pytest.approx(sol.ot[k], rel=1e-10)


def test_paper_test_pose_cell_reproduces_table3():
    """The map cell at the paper's test pose is Table 3's O_t row (0.3869, chi 5.1694) and Table 2's pose."""
    sol = maps.solve_cells(0.4 / 0.6, PHI, np.array([[60.0, 30.0]]))
    assert f"{sol.ot[0]:.4f}" == "0.3869"
    assert f"{2 / sol.ot[0]:.4f}" == "5.1694"
    assert (f"{sol.pose_deg[0, 0]:.2f}", f"{sol.pose_deg[0, 1]:.2f}") == ("-27.50", "71.34")


def test_test_poses_along_the_force_line_have_infinite_chi():
    qt = np.array([[90.0, 0.0], [-90.0, 0.0], [90.0, 180.0], [-90.0, -180.0]])
    sol = maps.solve_cells(0.5, PHI, qt)
    assert np.all(sol.ot == 0) and np.all(sol.status == maps.AT_ZERO) and np.isnan(sol.pose_deg).all()


@pytest.mark.parametrize("step, phi", [(5.0, -90.0), (4.0, 30.0), (6.0, -87.0)])
def test_symmetry_classes_cover_the_grid_once_and_share_their_information(step, phi):
    grid = maps.test_pose_grid(step)
    h = len(maps.grid_axis(step)) // 2
    reps, cells, cls = maps.class_members(step, phi, 0, h)
    assert np.array_equal(np.sort(cells), np.arange(len(grid)))
    assert len(reps) == maps.class_counts(step, phi).sum()
    if maps._mirror_shift(step, phi) is not None:
        assert len(reps) < 0.26 * len(grid)
    for b in (0.3, 0.9):
        assert np.allclose(maps.test_information(b, phi, grid[cells]), maps.test_information(b, phi, reps)[cls],
                           rtol=1e-9, atol=1e-12)


def test_tiles_cover_the_map_once_and_equal_the_whole_map(tmp_path):
    b, step = 0.5, 10.0
    n = maps.n_tiles(step, PHI, 90)
    assert n > 1
    tiles = [maps.map_tile(b, PHI, step, 90, k) for k in range(n)]
    paths = []
    for k, t in enumerate(tiles):
        paths.append(tmp_path / f"{k}.npz")
        maps.save_arrays(paths[-1], t)
    merged = maps.merge_tiles([maps.load_arrays(p, maps.TILE_ARRAYS) for p in paths], b, PHI, step)
    whole = maps.solve_map(b, PHI, step)
    # batches of another size may round the last bit differently (BLAS blocking)
    assert np.allclose(merged.O_t, whole.O_t, rtol=1e-12)
    assert np.allclose(merged.q2_opt_deg, whole.q2_opt_deg, rtol=0, atol=1e-9, equal_nan=True)
    assert np.array_equal(merged.status, whole.status)
    with pytest.raises(ValueError, match="missing"):
        maps.merge_tiles(tiles[1:], b, PHI, step)


def test_binary_map_round_trip_is_deterministic_and_bad_files_are_named(tmp_path):
    mp = maps.solve_map(0.9, PHI, 12.0)
    a, b_ = tmp_path / "a.npz", tmp_path / "b.npz"
    maps.save_map(a, mp)
    maps.save_map(b_, mp)
    assert a.read_bytes() == b_.read_bytes()
    back = maps.load_map(a)
    assert np.array_equal(back.O_t, mp.O_t) and np.array_equal(back.status, mp.status)
    assert np.array_equal(back.chi, mp.chi) and back.link_ratio == mp.link_ratio
    df = maps.map_frame(back)
    assert list(df.columns) == maps.MAP_COLUMNS and len(df) == 30 * 30
    # map.csv is written without pandas: the bytes pandas writes
    from stiffcal.csvtext import write_numeric_csv
    from stiffcal.paper.tables import FLOAT_FORMAT

    write_numeric_csv(maps.map_columns(back), tmp_path / "map.csv")
    assert (tmp_path / "map.csv").read_text() == df.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="bad.npz"):
        maps.load_map(tmp_path / "bad.npz")
    maps.save_arrays(tmp_path / "partial.npz", {"O_t": mp.O_t})
    with pytest.raises(InputError, match=r"partial.npz.*missing.*chi"):
        maps.load_map(tmp_path / "partial.npz")


def test_subgrid_equals_solving_the_coarse_grid():
    fine = maps.solve_map(0.2, PHI, 5.0)
    coarse = maps.solve_map(0.2, PHI, 15.0)
    sub = fine.subgrid(15.0)
    assert np.allclose(sub.O_t, coarse.O_t, rtol=1e-12)
    with pytest.raises(ValueError, match="subgrid"):
        fine.subgrid(12.0)


def test_chi_mean_depends_on_the_grid_but_median_does_not():
    stats = {s: maps.chi_statistics(maps.solve_map(2 / 3, PHI, s)) for s in (10.0, 5.0, 2.0)}
    means = [stats[s]["mean"] for s in (10.0, 5.0, 2.0)]
    assert means[0] < means[1] < means[2]  # the continuum mean diverges (chi ~ 1/r^2 near A_t = 0)
    medians = [stats[s]["median"] for s in (10.0, 5.0, 2.0)]
    assert max(medians) / min(medians) < 1.01
    assert stats[2.0]["min"] >= 1 - 1e-9  # the test pose itself gives chi = 1 where A_t is regular
    assert stats[2.0]["cells_no_optimum"] == 180 - 2  # the straight row, less the two cells with A_t = 0


def test_bad_map_config_names_the_field(paper_config):
    cfg = dict(paper_config)
    cfg["maps"] = {**paper_config["maps"], "step_deg": 7.0}
    with pytest.raises(InputError, match=r"maps.step_deg.*divides 180"):
        maps.map_studies(cfg, maps.Path(__file__).parents[1], "config.yaml")
    cfg["maps"] = {**paper_config["maps"], "studies": [{"name": "a", "link_ratio": 0.5, "figure": 7},
                                                        {"name": "a", "link_ratio": 0.2, "figure": 8}]}
    with pytest.raises(InputError, match=r"maps.studies\[1\].name"):
        maps.map_studies(cfg, ".", "config.yaml")


def test_best_pair_at_the_paper_test_pose_is_table4_case_iv():
    """The two-pose map's cell at q* = (60, 30) is Table 4's plan (iv): O_t 0.1640 at (0, 29.12) and
    (48.19, 131.81) (the printed (-131.81, 131.81), (180, -29.12) up to symmetric copies)."""
    b = 0.4 / 0.6
    qt = np.array([[60.0, 30.0]])
    single = maps.solve_cells(b, PHI, qt)
    ot, poses = maps.best_pairs(b, PHI, qt, single.pose_deg)
    assert f"{ot[0]:.4f}" == "0.1640"
    got = sorted((round(p[0] % 180, 2) % 180, round(p[1], 2)) for p in poses[0])
    assert got == [(0.0, 29.12), (48.19, 131.81)]


def test_best_pairs_against_a_brute_force_over_all_pairs(rng):
    """Sampled cells: never more than 1e-6 above a brute force over every pair of a 6-degree grid polished by
    Nelder-Mead, and never above the single optimum measured twice (plan (i))."""
    b = 0.4 / 0.6
    F = maps.force_vector(PHI)
    qt = rng.uniform(-180, 180, (5, 2))
    single = maps.solve_cells(b, PHI, qt)
    ot, _ = maps.best_pairs(b, PHI, qt, single.pose_deg)
    assert np.all(ot <= single.ot / 2 * (1 + 1e-12))
    for k, cell in enumerate(qt):
        assert ot[k] <= brute_force_pair(b, F, cell) * (1 + 1e-6), cell


def test_pair_map_covers_the_grid_and_round_trips(tmp_path):
    pm = maps.pair_map(0.5, PHI, 30.0)
    assert pm.O_t2.shape == (12, 12) and np.all(np.isfinite(pm.O_t2))
    assert pm.gain.min() >= -1e-5 and pm.gain.max() > 0.01
    maps.save_pair_map(tmp_path / "p.npz", pm)
    back = maps.load_pair_map(tmp_path / "p.npz")
    assert np.array_equal(back.O_t2, pm.O_t2) and np.array_equal(back.poses_deg, pm.poses_deg)
    assert len(maps.pair_frame(back)) == 144
    from stiffcal.csvtext import numeric_csv
    from stiffcal.paper.tables import FLOAT_FORMAT

    assert numeric_csv(maps.pair_columns(back)) == maps.pair_frame(back).to_csv(
        index=False, float_format=FLOAT_FORMAT, lineterminator="\n")  # pairs.csv, written without pandas


def test_grid_statistics_handed_over_give_the_same_table(tmp_path):
    """map_grid_statistics solves the finer grids of the Figure-7 map once for map_statistics and
    paper_comparison: the table from the saved statistics is the table computed from the map, to the byte."""
    from stiffcal.paper.tables import FLOAT_FORMAT

    st = maps.MapStudy("b", 0.9, 7, 12.0, PHI, 65536)
    other = maps.MapStudy("c", 0.5, 8, 12.0, PHI, 65536)
    mp, mp2 = maps.solve_map(0.9, PHI, 12.0), maps.solve_map(0.5, PHI, 12.0)
    steps = [36.0, 12.0, 9.0]  # a subgrid, the map's own grid and a grid that is solved
    paper = {"mean": 4.0}
    direct = maps.statistics_table({"b": mp, "c": mp2}, [st, other], steps, paper)
    maps.save_grid_statistics(tmp_path / "g.npz", maps.grid_statistics(mp, st, steps))
    handed = maps.statistics_table({"c": mp2}, [st, other], steps, paper,
                                   {"b": maps.load_grid_statistics(tmp_path / "g.npz")})
    assert sorted(direct.grid_deg.unique()) == [9.0, 12.0, 36.0]
    kw = dict(index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    assert handed.to_csv(**kw) == direct.to_csv(**kw)
    with pytest.raises(InputError, match="g2.npz"):
        maps.save_arrays(tmp_path / "g2.npz", {"step_deg": np.array([1.0])})
        maps.load_grid_statistics(tmp_path / "g2.npz")
