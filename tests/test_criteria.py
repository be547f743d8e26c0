"""Table 1 criteria against independent formulas (numpy SVD and inverse), and their singular cases."""

import numpy as np
import pytest

from stiffcal.model import criteria


def _independent(key, A, m, At):
    """Table 1 written directly from its formulas."""
    M = A.T @ A
    s = np.linalg.svd(A, compute_uv=False)  # descending
    Minv = np.linalg.inv(M)
    return {
        "a": np.trace(Minv), "t": np.trace(M), "d": np.linalg.det(M),
        "g": np.max(np.diag(A @ Minv @ A.T)), "mdc": np.max(np.diag(Minv)),
        "o1": np.prod(s) ** (1 / len(s)) / np.sqrt(m), "o2": s[-1] / s[0], "o3": s[-1],
        "o4": s[-1] ** 2 / s[0], "ot": np.trace(At @ Minv @ At.T),
    }[key]


@pytest.mark.parametrize("key", criteria.CRITERIA_KEYS)
@pytest.mark.parametrize("m,n", [(1, 2), (3, 2), (2, 3), (4, 3)])
def test_criteria_match_their_formulas(key, m, n, rng):
    for _ in range(5):
        A = rng.normal(size=(m * 2, n))
        At = rng.normal(size=(2, n))
        got = criteria.evaluate(key, A, m, At)
        np.testing.assert_allclose(got, _independent(key, A, m, At), rtol=1e-9)


def test_criteria_batch_over_plans(rng):
    A = rng.normal(size=(7, 4, 2))
    At = rng.normal(size=(2, 2))
    batched = criteria.evaluate("ot", A, 2, At)
    np.testing.assert_allclose(batched, [criteria.evaluate("ot", a, 2, At) for a in A], rtol=1e-12)


def test_loss_turns_max_criteria_into_minimisation(rng):
    A = rng.normal(size=(2, 2))
    assert criteria.loss("d", A, 1) == pytest.approx(-np.linalg.det(A.T @ A))
    assert criteria.loss("a", A, 1) == pytest.approx(np.trace(np.linalg.inv(A.T @ A)))


def test_singular_plan_is_inf_for_inverse_criteria_and_finite_for_others():
    A = np.array([[1.0, 2.0], [2.0, 4.0]])  # rank 1
    At = np.eye(2)
    for key in ("a", "g", "mdc", "ot"):
        assert criteria.loss(key, A, 1, At) == np.inf
    assert criteria.loss("t", A, 1) == pytest.approx(-25.0)
    assert criteria.loss("d", A, 1) == pytest.approx(0.0, abs=1e-12)
    assert criteria.loss("o3", A, 1) == 0.0


def test_round_off_singularity_is_inf_not_a_huge_number():
    """A matrix singular up to round-off (as at the T-optimal pose) must not give 1e16-sized values."""
    A = np.array([[1.0, 1.0 + 1e-17], [0.4, 0.4]])
    assert criteria.loss("a", A, 1) == np.inf


def test_o_t_star_and_chi():
    assert criteria.o_t_star(2, 1) == 2.0
    assert criteria.o_t_star(6, 3, 0.5) == pytest.approx(0.5)
    assert criteria.chi(0.5, 2, 1) == pytest.approx(4.0)
    assert criteria.chi(np.inf, 2, 1) == 0.0


def test_o_t_star_is_o_t_with_every_measurement_at_the_test_pose_for_a_six_axis_arm():
    """Eq. 17 for an arm with more compliances (6) than measured coordinates (3): measuring m times at the test
    pose identifies only rank(A_t) = 3 combinations, and O_t of that plan (eq. 16 with the pseudo-inverse:
    the error at the test pose is estimable) is 3 sigma^2 / m, not 6 sigma^2 / m; the paper's 2-link arm keeps
    n = 2."""
    from pathlib import Path

    from stiffcal.planning.problem import Problem
    from stiffcal.model.robot import load_robot

    root = Path(__file__).resolve().parents[1]
    kuka = load_robot(root / "config/robots/kuka_kr210_r2700.yaml")
    prob = Problem(kuka, np.array([500.0, -300, -800]), "ot", 2, np.radians([20, -60, 110, 30, 45, -20]), sigma=1e-5)
    At = prob.At
    direct = 1e-10 * np.trace(At @ np.linalg.pinv(2 * At.T @ At) @ At.T)
    assert prob.ot_star(2) == pytest.approx(direct, rel=1e-9) == pytest.approx(3 * 1e-10 / 2)
    arm = load_robot(root / "config/robots/paper_2r.yaml")
    assert Problem(arm, np.array([0.0, 1.0]), "ot", 1, np.radians([60, 20])).ot_star(3) == 2 / 3


def test_o_t_star_counts_a_direction_the_load_barely_moves_in_full():
    """O_t* from the test pose's rows (criteria.o_t_of_rows): with every measurement at the test pose, each
    measured coordinate counts sigma^2 / (m sum s^2) however small its deflection (eq. 17: trace(A_t (A_t^T A_t)^+
    A_t^T) = rank A_t). A coordinate a billion times smaller than the others (a vertical hanging mass seen from
    the side, as on an iiwa) made the information A^T A round it off: O_t* and chi came out inf."""
    rng = np.random.default_rng(4)
    At = rng.normal(size=(3, 5)) * 80.0
    At[1] *= 1e-9  # the load barely moves the tool along y at the test pose
    scales = np.array([0.25, 0.5, 1.0])  # three hanging masses along the test load
    A1 = np.concatenate([s * At for s in scales])
    expected = 3 * 1e-10 / (8 * np.sum(scales**2))
    assert criteria.o_t_of_rows(A1, At, 1e-5) / 8 == pytest.approx(expected, rel=1e-6)
    assert criteria.o_t(8 * A1.T @ A1, At, 1e-5) == np.inf  # what the information alone gives
    other = rng.normal(size=(1, 5))  # a test deflection the measurements cannot give
    assert criteria.o_t_of_rows(A1, np.vstack([At, other]), 1e-5) == np.inf


def test_an_o_t_star_the_loads_cannot_give_is_inf_and_said_so():
    """A fresh user's UR5 pushed along +-x and +-y with a vertical test load: O_t_star and chi came out "inf" with no
    word, and "chi: inf" read as infinitely better. A planar 3R arm pushed along x only: the test pose's rows
    (rank 2 of 3 compliances, by numpy's SVD) do not span the rows of the test load along y, so O_t* is inf and the
    design's note says why; pushed along x and y they do, and there is no note."""
    from stiffcal.api import _ot_star_note
    from stiffcal.model.observation import measurement_loads
    from stiffcal.planning.problem import Problem
    from stiffcal.model.robot import planar_robot

    arm = planar_robot([0.5, 0.4, 0.3])
    qt = np.radians([30.0, 40.0, -50.0])
    for spec, finite in (("forces:100,0;-100,0", False), ("forces:100,0;0,100", True)):
        prob = Problem(arm, np.array([0.0, -100.0]), "ot", 4, qt, loads=measurement_loads(arm, spec))
        A1 = prob.rows(qt).reshape(-1, prob.n_params)
        gained = np.linalg.matrix_rank(np.vstack([A1, prob.At])) > np.linalg.matrix_rank(A1)
        assert gained != finite
        assert np.isfinite(prob.ot_star(4)) == finite
        notes = _ot_star_note(prob, prob.ot_star(4))
        assert (notes == []) == finite
        assert finite or ("O_t_star and chi are inf" in notes[0] and spec in notes[0])


def test_every_list_of_criteria_is_the_registry_s(root):
    """The config schema's enum and default (taken from the registry when the schema is read), the CLI's help and
    the docs' table of criteria name exactly the registered criteria (stiffcal.model.criteria.CRITERIA), and the
    registry's flags are what its formulas say: those that invert the information matrix are +inf on a singular
    plan, the others finite."""
    import re

    from stiffcal.cli import build_parser
    from stiffcal.validation import load_schema

    keys = set(criteria.CRITERIA_KEYS)
    crit = load_schema("config")["properties"]["study"]["properties"]["criteria"]
    assert set(crit["items"]["enum"]) == keys and set(crit["default"]) == keys
    assert crit["default"][:9] == ["t", "a", "d", "g", "mdc", "o1", "o2", "o3", "o4"] and crit["default"][-1] == "ot"
    design = build_parser()._subparsers._group_actions[0].choices["design"]
    (help_text,) = [a.help for a in design._actions if "--criterion" in a.option_strings]
    assert set(help_text.split(" (")[0].split()) == keys
    contracts = (root / "docs/contracts.md").read_text(encoding="utf-8")
    table = contracts.split("<!-- registry:criteria -->", 1)[1].split("<!-- /registry:criteria -->", 1)[0]
    assert re.findall(r"^\| `([a-z0-9]+)` \|", table, flags=re.M) == list(criteria.CRITERIA_KEYS)
    singular = np.array([[1.0, 0.0], [2.0, 0.0]])  # the second compliance unidentified
    At = np.eye(2)
    for key, c in criteria.CRITERIA.items():
        assert np.isinf(criteria.loss(key, singular, 1, At)) == c.needs_inverse, key
