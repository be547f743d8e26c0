"""The elasto-static model: eqs. 2-4, 6, 11, 16, 17 against direct formulas and Monte Carlo."""

import numpy as np
import pytest

from stiffcal.model import criteria
from stiffcal.errors import InputError
from stiffcal.model.robot import planar_robot
from stiffcal.model.stiffness import (covariance, covariance_diagonal, deflection, identify, identify_batch,
                                information_matrix, observation_matrix, pose_information)


def test_observation_matrix_reproduces_eq_2(rng):
    """A k (eqs. 3-4) equals J diag(k) J^T F (eq. 2) computed directly."""
    robot = planar_robot(rng.uniform(0.2, 1, 3))
    q = rng.uniform(-3, 3, (10, 3))
    F = rng.normal(size=2)
    k = rng.uniform(1e-6, 1e-5, 3)
    J = robot.jacobian(q)
    direct = np.stack([Ji @ np.diag(k) @ Ji.T @ F for Ji in J])
    np.testing.assert_allclose(np.einsum("mdn,n->md", observation_matrix(J, F), k), direct, rtol=1e-12)
    np.testing.assert_allclose(deflection(J, k, F), direct, rtol=1e-12)


def test_identify_recovers_compliances_without_noise(rng):
    robot = planar_robot([0.6, 0.4])
    q = rng.uniform(-3, 3, (4, 2))
    k = np.array([2e-6, 5e-6])
    A = observation_matrix(robot.jacobian(q), np.array([0.0, -500.0]))
    dp = np.einsum("mdn,n->md", A, k)
    np.testing.assert_allclose(identify(A, dp), k, rtol=1e-10)


def _mc_plan(robot, q, F, sigma, samples, rng):
    k = np.array([1e-3, 2e-3, 3e-3])[: robot.n_joints]
    A = observation_matrix(robot.jacobian(q), F)
    dp = np.einsum("mdn,n->md", A, k)
    est = identify_batch(A, dp + rng.normal(0, sigma, (samples,) + dp.shape))
    return A, est - k


@pytest.mark.parametrize("m", [1, 3])
def test_eq_11_against_monte_carlo(m, rng):
    """The covariance of least-squares estimates with simulated noise matches sigma^2 M^-1 (eq. 11)."""
    robot = planar_robot([0.6, 0.4])
    q = np.radians([[-27.5, 71.34], [100.0, -40.0], [10.0, 120.0]][:m])
    sigma, samples = 0.01, 40000
    A, dk = _mc_plan(robot, q, np.array([0.0, -1.0]), sigma, samples, rng)
    cov = covariance(information_matrix(A), sigma)
    emp = np.cov(dk.T)
    # standard error of a sample variance ~ var * sqrt(2 / s); allow 5 standard errors
    se = np.sqrt(np.outer(np.diag(cov), np.diag(cov)) + cov**2) / np.sqrt(samples)
    assert np.all(np.abs(emp - cov) < 5 * se)


def test_eq_16_against_empirical_compensation_error(rng):
    """O_t (eq. 16) equals the mean squared error of the compensated deflection at the test pose over
    many simulated calibrations."""
    robot = planar_robot([0.6, 0.4])
    F = np.array([0.0, -1.0])
    q = np.radians([[-27.5, 71.34], [150.0, 30.0]])
    sigma, samples = 0.02, 40000
    A, dk = _mc_plan(robot, q, F, sigma, samples, rng)
    At = observation_matrix(robot.jacobian(np.radians([60.0, 30.0])), F)
    err2 = np.sum((dk @ At.T) ** 2, axis=1)
    ot = float(criteria.o_t(information_matrix(A), At, sigma))
    assert abs(err2.mean() - ot) < 5 * err2.std() / np.sqrt(samples)


@pytest.mark.parametrize("m", [1, 2, 5])
def test_eq_17_measuring_at_the_test_pose(m, rng):
    """All m measurements at a full-rank test pose: O_t = n sigma^2 / m, by formula and by simulation."""
    robot = planar_robot([0.6, 0.4])
    F = np.array([0.3, -1.0])
    qt = np.radians([20.0, 70.0])
    At = observation_matrix(robot.jacobian(qt), F)
    assert np.linalg.matrix_rank(At) == 2
    sigma = 0.5
    M = m * pose_information(At)
    np.testing.assert_allclose(criteria.o_t(M, At, sigma), criteria.o_t_star(2, m, sigma), rtol=1e-10)
    _, dk = _mc_plan(robot, np.repeat(qt[None], m, 0), F, sigma, 40000, rng)
    err2 = np.sum((dk @ At.T) ** 2, axis=1)
    assert abs(err2.mean() - 2 * sigma**2 / m) < 5 * err2.std() / np.sqrt(len(err2))


def test_singular_plans_give_inf_never_nan(paper_robot):
    """T-optimal pose (arm stretched): nothing identifiable -> inf, inf (paper's Table 2 T row).
    Test pose (link 2 parallel to F): k2 unidentifiable -> inf, k1 finite = 1 / |a_1|^2."""
    F = np.array([0.0, -1.0])
    A0 = observation_matrix(paper_robot.jacobian(np.zeros(2)), F)
    cd0 = covariance_diagonal(pose_information(A0))
    assert np.all(np.isinf(cd0)) and not np.any(np.isnan(cd0))
    At = observation_matrix(paper_robot.jacobian(np.radians([60.0, 30.0])), F)
    cd = covariance_diagonal(pose_information(At))
    assert np.isinf(cd[1])
    np.testing.assert_allclose(cd[0], 1.0 / np.sum(At[:, 0] ** 2), rtol=1e-12)
    for key in ("a", "mdc", "g", "ot"):
        assert criteria.loss(key, A0, 1, At) == np.inf


def test_singular_plan_is_refused_by_identification(paper_robot):
    A = observation_matrix(paper_robot.jacobian(np.zeros((1, 2))), np.array([0.0, -1.0]))
    with pytest.raises(InputError, match="singular plan"):
        identify(A, np.zeros((1, 2)))
    with pytest.raises(InputError, match="singular"):
        covariance(information_matrix(A))


def test_o_t_and_chi_do_not_change_when_all_links_scale(rng):
    """O_t and chi depend on the link ratio only (the paper's maps use b = l2/l1 alone)."""
    links = np.array([0.6, 0.4])
    F = np.array([0.0, -1.0])
    q = rng.uniform(-3, 3, (3, 2))
    qt = np.radians([60.0, 30.0])
    vals = []
    for s in (1.0, 2.5, 0.1):
        r = planar_robot(links * s)
        M = information_matrix(observation_matrix(r.jacobian(q), F))
        vals.append(float(criteria.o_t(M, observation_matrix(r.jacobian(qt), F), 1.0)))
    np.testing.assert_allclose(vals, vals[0], rtol=1e-10)
