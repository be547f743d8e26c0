"""Global single-pose optimisation: against a closed form, an independent brute force, shifted grids,
joint limits, and a 3-link arm."""

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from stiffcal.planning.problem import Problem, optimal_single_pose, representative, wrap_deg
from stiffcal.errors import InputError
from stiffcal.model.robot import planar_robot

F = np.array([0.0, -1.0])
QT = np.radians([60.0, 30.0])


def brute_force(key, links, q_grid_deg, force=F, test_pose=QT):
    """Criterion over a list of single poses, written independently of stiffcal (numpy only)."""
    q = np.radians(q_grid_deg)
    c = np.cumsum(q, axis=-1)
    L = np.asarray(links)
    J = np.stack([-np.flip(np.cumsum(np.flip(L * np.sin(c), -1), -1), -1),
                  np.flip(np.cumsum(np.flip(L * np.cos(c), -1), -1), -1)], axis=-2)
    A = J * np.einsum("...dj,d->...j", J, force)[..., None, :]
    M = np.swapaxes(A, -1, -2) @ A
    with np.errstate(all="ignore"):
        s = np.linalg.svd(A, compute_uv=False)
        ok = (s[..., -1] > 1e-7 * s[..., 0]) & (s.shape[-1] == M.shape[-1])
        Minv = np.linalg.inv(np.where(ok[..., None, None], M, np.eye(M.shape[-1])))
    if key == "ot":
        ct = np.cumsum(test_pose)
        Jt = np.stack([-np.flip(np.cumsum(np.flip(L * np.sin(ct))))[None],
                       np.flip(np.cumsum(np.flip(L * np.cos(ct))))[None]])[:, 0, :]
        At = Jt * (Jt.T @ force)[None, :]
        v = np.einsum("ij,...jk,lk->...il", At, Minv, At).trace(axis1=-2, axis2=-1)
        return np.where(ok, v, np.inf)
    if key == "a":
        return np.where(ok, np.trace(Minv, axis1=-2, axis2=-1), np.inf)
    if key == "mdc":
        return np.where(ok, np.diagonal(Minv, axis1=-2, axis2=-1).max(-1), np.inf)
    if key == "d":
        return -np.linalg.det(M)
    if key == "o3":
        return -s[..., -1]
    raise KeyError(key)


def grid(step, n=2, lo=-180.0, hi=180.0):
    g = np.arange(lo, hi, step)
    return np.stack(np.meshgrid(*([g] * n), indexing="ij"), -1).reshape(-1, n)



def test_o_t_optimum_equals_the_closed_form(paper_robot):
    """For the paper's test pose the second column of A_t vanishes, so O_t = |a_t1|^2 / Schur(M), and the
    Schur complement is x^2 l1^2 sin^2 q2: the optimum puts the end effector on the x axis with q2
    maximising (l1^2 + l2^2 + 2 l1 l2 cos q2) sin^2 q2."""
    l1, l2 = 0.6, 0.4
    q2 = minimize_scalar(lambda q: -(l1**2 + l2**2 + 2 * l1 * l2 * np.cos(q)) * np.sin(q) ** 2,
                         bounds=(0.5, 2.5), method="bounded", options={"xatol": 1e-13}).x
    q1 = brentq(lambda a: l1 * np.sin(a) + l2 * np.sin(a + q2), -1.5, 0.0, xtol=1e-15)
    res = optimal_single_pose(Problem(paper_robot, F, "ot", 1, QT))
    np.testing.assert_allclose(res.pose_deg, np.degrees([q1, q2]), atol=1e-5)
    assert len(res.optimal_set_deg) == 4


@pytest.mark.parametrize("key", ["ot", "a", "d", "mdc", "o3"])
def test_optimiser_is_no_worse_than_independent_brute_force(key, paper_robot):
    """Over a 0.5-degree grid of the whole joint space (independent criterion code), no pose beats
    the optimiser's, and the grid's best pose lies next to one of the optimiser's optimal poses."""
    res = optimal_single_pose(Problem(paper_robot, F, key, 1, QT))
    g = grid(0.5)
    bf = brute_force(key, [0.6, 0.4], g)
    best = bf[np.isfinite(bf)].min()
    assert res.loss <= best + 1e-12 * abs(best)
    gap = np.abs(wrap_deg(res.optimal_set_deg - g[np.argmin(bf)])).max(axis=1)
    assert gap.min() < 1.0
    bf_opt = brute_force(key, [0.6, 0.4], res.pose_deg[None])[0]
    np.testing.assert_allclose(bf_opt, res.loss, rtol=1e-9)


@pytest.mark.parametrize("key", ["ot", "d", "mdc"])
def test_result_does_not_depend_on_the_grid(key, rng):
    """Different grid steps (hence different starting points for the polish) give the same optimum."""
    robot = planar_robot([0.7, 0.3])
    force = np.array([0.6, -0.8])
    res = [optimal_single_pose(Problem(robot, force, key, 1, np.radians([20.0, 100.0])), step_deg=s)
           for s in (1.0, 1.7, 3.1)]
    for r in res[1:]:
        assert r.loss == pytest.approx(res[0].loss, rel=1e-9)
        np.testing.assert_allclose(r.pose_deg, res[0].pose_deg, atol=1e-3)


def test_joint_limits_are_respected_and_optimal_within_them():
    limits = [[-45.0, 45.0], [10.0, 90.0]]
    robot = planar_robot([0.6, 0.4], joint_limits_deg=limits)
    res = optimal_single_pose(Problem(robot, F, "ot", 1, QT))
    assert limits[0][0] <= res.pose_deg[0] <= limits[0][1]
    assert limits[1][0] <= res.pose_deg[1] <= limits[1][1]
    g1, g2 = np.meshgrid(np.linspace(-45, 45, 721), np.linspace(10, 90, 641), indexing="ij")
    bf = brute_force("ot", [0.6, 0.4], np.stack([g1.ravel(), g2.ravel()], -1))
    assert res.loss <= bf.min() * (1 + 1e-12)


def test_three_link_arm_against_random_search(rng):
    """D-optimality (no inverse needed) for a 3-link arm: no random pose beats the optimiser."""
    links = [0.5, 0.35, 0.15]
    res = optimal_single_pose(Problem(planar_robot(links), F, "d", 1, None), step_deg=6.0)
    bf = brute_force("d", links, rng.uniform(-180, 180, (200_000, 3)))
    assert res.loss <= bf.min()


def test_one_pose_cannot_identify_three_compliances():
    """Two equations per pose, three compliances: every single-pose plan is singular; clear error."""
    robot = planar_robot([0.5, 0.35, 0.15])
    with pytest.raises(InputError, match="2 equations .* 3 compliances"):
        optimal_single_pose(Problem(robot, F, "ot", 1, np.radians([30.0, 40.0, -20.0])), step_deg=10.0)


def test_representative_rule():
    poses = np.array([[83.34, -98.79], [-83.34, 98.79], [-96.66, -98.79], [96.66, 98.79]])
    np.testing.assert_array_equal(representative(poses), [-83.34, 98.79])
    # accidental tie (O2): two classes with positive elbow and q1 in (-90, 90]: the larger q1
    np.testing.assert_array_equal(representative(np.array([[9.53, 131.81], [86.85, 131.81]])), [86.85, 131.81])
    np.testing.assert_array_equal(representative(np.array([[-180.0, 0.0], [0.0, 0.0]])), [0.0, 0.0])


def test_wrap_deg():
    np.testing.assert_allclose(wrap_deg([180.0, -180.0, 190.0, 540.0, -0.5]), [-180, -180, -170, -180, -0.5])
