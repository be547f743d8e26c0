"""Maps over test poses (Figures 6-10): exactness against an independent brute force, the reduction and
its polynomials, the symmetries and tiles, the paper's cell, and bad map configs."""

import numpy as np
import pytest
from scipy.optimize import minimize

from stiffcal import maps
from stiffcal.criteria import o_t
from stiffcal.errors import InputError
from stiffcal.reference import brute_force_cell, ot_plain
from stiffcal.robot import planar_robot
from stiffcal.stiffness import observation_matrix

PHI = -90.0


def _S(robot, qt_deg, force):
    At = observation_matrix(robot.jacobian(np.radians(qt_deg)), force)
    return At, At.T @ At


def _cells(rng, n):
    """Random test poses, half of them near the singular ones (q2* ~ 0 or 180, q1* + q2* ~ +-90)."""
    generic = rng.integers(-180, 180, (n, 2)).astype(float)
    straight = np.column_stack([rng.integers(-180, 180, n), rng.integers(-12, 13, n) + 180 * rng.integers(0, 2, n)])
    q1 = rng.integers(-180, 180, n)
    diagonal = np.column_stack([q1, maps._wrap(90 - q1 + rng.integers(-3, 4, n))])
    return np.vstack([generic, straight, diagonal]).astype(float)


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
    """O_t(x, c) of the module docstring against eq. 16 evaluated by the library at the same poses."""
    for b in (0.2, 2 / 3, 0.9, 1.5):
        robot = planar_robot([1.0, b])
        F = maps.force_vector(PHI)
        qt = rng.uniform(-180, 180, (20, 2))
        q = rng.uniform(-180, 180, (20, 2))
        S = maps.test_information(b, PHI, qt)
        tau = np.einsum("ndi,d->ni", robot.jacobian(np.radians(q)), F)
        ours = maps.ot_xc(S, tau[:, 0] / tau[:, 1], np.cos(np.radians(q[:, 1])), b)
        A = observation_matrix(robot.jacobian(np.radians(q)), F)
        At = observation_matrix(robot.jacobian(np.radians(qt)), F)
        ref = np.array([o_t(A[i].T @ A[i], At[i]) for i in range(20)])
        assert np.allclose(ours, ref, rtol=1e-9)


def test_every_local_minimum_is_a_root_of_the_derived_polynomial(rng):
    """Independent local minima (Nelder-Mead in joint space) have x = tau1/tau2 at a root of q12 or q4."""
    b = 0.5
    robot = planar_robot([1.0, b])
    F = maps.force_vector(PHI)
    for qt in rng.uniform(-180, 180, (4, 2)):
        _, S = _S(robot, qt, F)
        s = np.array([[S[0, 0], S[0, 1], S[1, 1]]]) / np.trace(S)
        polys = [maps._monomials(s, k) @ C.T for k, C in (maps._coefficient_matrix(t, b) for t in (maps.Q12, maps.Q4))]
        for start in rng.uniform(-180, 180, (6, 2)):
            r = minimize(lambda q: ot_plain(robot, q, S, F)[0], start, method="Nelder-Mead",
                         options=dict(xatol=1e-11, fatol=1e-16, maxiter=6000))
            tau = robot.jacobian(np.radians(r.x)).T @ F
            x = tau[0] / tau[1]
            residual = min(abs(np.polynomial.polynomial.polyval(x, p[0])) /
                           np.polynomial.polynomial.polyval(abs(x), np.abs(p[0])) for p in polys)
            assert residual < 1e-6, (qt, r.x, residual)


@pytest.mark.parametrize("b", [0.2, 2 / 3, 0.9])
def test_cells_are_the_global_optimum_of_a_brute_force(b, rng):
    qt = _cells(rng, 6)
    sol = maps.solve_cells(b, PHI, qt)
    robot = planar_robot([1.0, b])
    F = maps.force_vector(PHI)
    for k, cell in enumerate(qt):
        ref = brute_force_cell(b, F, cell)
        # never worse than the brute force, and the brute force never better by more than its round-off
        assert sol.ot[k] <= ref * (1 + 1e-6), (cell, sol.ot[k], ref)
        assert sol.ot[k] >= ref * (1 - 1e-6), (cell, sol.ot[k], ref)
        if sol.source[k] != 1:  # an attained, regular plan: the library agrees at the reported pose
            _, S = _S(robot, cell, F)
            assert ot_plain(robot, sol.pose_deg[k], S, F)[0] == pytest.approx(sol.ot[k], rel=1e-9)


def test_paper_test_pose_cell_reproduces_table3(paper_study):
    """The map cell at the paper's test pose is Table 3's O_t row (0.3869, chi 5.1694) and Table 2's pose."""
    df = maps.map_frame(0.4 / 0.6, PHI, np.array([[60.0, 30.0]]))
    assert f"{df.O_t[0]:.4f}" == "0.3869"
    assert f"{df.chi[0]:.4f}" == "5.1694"
    assert (f"{df.q1_opt_deg[0]:.2f}", f"{df.q2_opt_deg[0]:.2f}") == ("-27.50", "71.34")


def test_test_poses_along_the_force_line_have_infinite_chi():
    qt = np.array([[90.0, 0.0], [-90.0, 0.0], [90.0, 180.0], [-90.0, -180.0]])
    df = maps.map_frame(0.5, PHI, qt)
    assert np.all(df.O_t == 0) and np.all(np.isinf(df.chi))
    assert df[["q1_opt_deg", "q2_opt_deg"]].isna().all().all()


def test_symmetry_classes_share_their_information_matrix():
    grid, reps, inverse = maps.symmetry_classes(5.0, PHI)
    assert len(reps) < 0.26 * len(grid)
    for b in (0.3, 0.9):
        S_cells = maps.test_information(b, PHI, grid)
        S_reps = maps.test_information(b, PHI, reps)[inverse]
        assert np.allclose(S_cells, S_reps, rtol=1e-9, atol=1e-12)


def test_tiles_cover_the_map_once_and_equal_the_direct_map():
    b, step = 0.5, 10.0
    n = maps.n_tiles(step, PHI, 90)
    assert n > 1
    tiles = [maps.map_tile(b, PHI, step, 90, k) for k in range(n)]
    merged = maps.merge_tiles(tiles, step)
    direct = maps.map_frame(b, PHI, maps.test_pose_grid(step))
    assert list(merged.columns) == maps.MAP_COLUMNS
    assert np.allclose(merged.O_t, direct.O_t, rtol=1e-9)
    with pytest.raises(ValueError, match="cells"):
        maps.merge_tiles(tiles[1:], step)


def test_chi_mean_depends_on_the_grid_but_median_does_not():
    stats = {s: maps.chi_statistics(maps.map_frame(2 / 3, PHI, maps.test_pose_grid(s))) for s in (10.0, 5.0, 2.0)}
    means = [stats[s]["mean"] for s in (10.0, 5.0, 2.0)]
    assert means[0] < means[1] < means[2]  # the continuum mean diverges (chi ~ 1/r^2 near A_t = 0)
    medians = [stats[s]["median"] for s in (10.0, 5.0, 2.0)]
    assert max(medians) / min(medians) < 1.01
    assert stats[2.0]["min"] >= 1 - 1e-9  # the test pose itself gives chi = 1 where A_t is regular


def test_bad_map_config_names_the_field(paper_config):
    cfg = dict(paper_config)
    cfg["maps"] = {**paper_config["maps"], "step_deg": 7.0}
    with pytest.raises(InputError, match=r"maps.step_deg.*divides 180"):
        maps.map_studies(cfg, maps.Path(__file__).parents[1], "config.yaml")
    cfg["maps"] = {**paper_config["maps"], "studies": [{"name": "a", "link_ratio": 0.5, "figure": 7},
                                                        {"name": "a", "link_ratio": 0.2, "figure": 8}]}
    with pytest.raises(InputError, match=r"maps.studies\[1\].name"):
        maps.map_studies(cfg, ".", "config.yaml")
