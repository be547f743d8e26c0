"""The discrepancy analysis: hide an effect in simulated data (stiffcal.truth, written from the physics and
independent of the analysis) and require the verdict to find it; bad measured data; the CLI."""

import json

import numpy as np
import pytest

from stiffcal import discrepancy as D
from stiffcal import truth as T
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.measurements import Measurements, read_measurements
from stiffcal.robot import planar_robot

SIGMA = 1e-5  # laser-tracker noise [m]
ARMS = {"2-link": [0.6, 0.4], "3-link": [0.5, 0.4, 0.3]}
N_SEEDS = 40


def _truths(n):
    k = np.linspace(1.5e-6, 3e-6, n)  # joint compliances [rad/(N m)]: deflections of tenths of a millimetre
    cp = np.zeros((n, n))
    i, j = (0, 1) if n == 2 else (0, 2)
    cp[i, j] = cp[j, i] = 2e-7
    return k, {"measurement_offset": T.Truth(k, offset=np.array([2e-5, -1.5e-5])),
               "joint_coupling": T.Truth(k, coupling=cp),
               "nonlinear_joint_stiffness": T.Truth(k, tau_max=np.full(n, 700.0)),
               "backlash": T.Truth(k, gap=np.full(n, 5e-5)),
               "link_compliance": T.Truth(k, link_bending=np.full(n, 2e-6)),
               "unexplained": T.Truth(k, drift=np.array([5e-7, 0.0]))}  # tracker drift: not in the catalogue


def _verdict(robot, truth, seed, blunders=None, n_poses=60):
    rng = np.random.default_rng(seed)
    q, f, g = T.random_experiment(robot, rng, n_poses, 3)
    dp = T.simulate(robot, truth, q, f, SIGMA, rng, blunders)
    return D.analyse(robot, Measurements(q, f, dp, g, "simulated"), alpha=0.01)


@pytest.mark.parametrize("arm", ARMS)
@pytest.mark.parametrize("cause", ["measurement_offset", "joint_coupling", "nonlinear_joint_stiffness",
                                   "backlash", "link_compliance", "unexplained"])
def test_hidden_cause_is_found(arm, cause):
    robot = planar_robot(ARMS[arm])
    _, truths = _truths(robot.n_joints)
    named = 0
    for seed in range(N_SEEDS):
        v = _verdict(robot, truths[cause], seed)
        # a cause whose span coincides with, or lies inside, the verdict's is named in indistinguishable_from
        named += v["cause"] == cause or cause in v["indistinguishable_from"]
    assert named >= 0.95 * N_SEEDS, (arm, cause, named)


@pytest.mark.parametrize("cause", ["backlash", "unexplained", "none"])
def test_without_replicates_the_verdict_still_holds(cause):
    """No pure error: sigma from the union model, lack of fit from structure left in the residuals."""
    robot = planar_robot(ARMS["3-link"])
    k, truths = _truths(3)
    truth = truths.get(cause, T.Truth(k))
    named = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        q, f, g = T.random_experiment(robot, rng, 150, 1)
        v = D.analyse(robot, Measurements(q, f, T.simulate(robot, truth, q, f, SIGMA, rng), g, "sim"), 0.01)
        assert v["nominal"]["sigma_source"].startswith("residuals")
        named += v["cause"] == cause
    assert named >= 19, named


def test_link_compliance_and_coupling_are_indistinguishable_for_a_2_link_arm():
    """For a planar arm a bending link acts like a 2 x 2 compliance block on its end joints, so with position
    measurements its span lies inside nominal + joint_coupling; for two links the spans coincide."""
    robot = planar_robot(ARMS["2-link"])
    _, truths = _truths(2)
    v = _verdict(robot, truths["joint_coupling"], 0)
    assert {v["cause"], *v["indistinguishable_from"]} >= {"joint_coupling", "link_compliance"}
    assert any("no choice of poses" in text for text in v["separation"].values())


@pytest.mark.parametrize("arm", ARMS)
def test_clean_data_give_none_within_alpha(arm):
    robot = planar_robot(ARMS[arm])
    k, _ = _truths(robot.n_joints)
    n = 250
    alarms = sum(_verdict(robot, T.Truth(k), 10_000 + s, n_poses=30)["cause"] != "none" for s in range(n))
    assert alarms <= 0.01 * n, alarms


def test_blunders_are_listed_and_do_not_drive_the_verdict():
    robot = planar_robot(ARMS["2-link"])
    _, truths = _truths(2)
    blunders = {5: np.array([1e-3, 0.0]), 77: np.array([0.0, -6e-4])}
    for seed in range(5):
        v = _verdict(robot, truths["backlash"], seed, blunders)
        assert v["outlier_rows"] == [5, 77]
        assert v["cause"] == "backlash"


def test_extended_fit_recovers_the_hidden_parameters():
    robot = planar_robot(ARMS["2-link"])
    k = np.array([1.5e-6, 3e-6])
    v = _verdict(robot, T.Truth(k, offset=np.array([2e-5, -1.5e-5])), 3)
    ext = v["extended"]
    assert ext["cause"] == "measurement_offset"
    assert np.all(np.abs(np.array(ext["parameters"]) - [2e-5, -1.5e-5]) <= np.array(ext["parameters_ci95"]) * 1.5)
    assert np.all(np.abs(np.array(ext["k"]) - k) <= np.array(ext["k_ci95"]) * 1.5)
    assert v["gain"]["lopo_ratio"] > 1


def test_pure_error_is_the_spread_of_replicates():
    y = np.array([[1.0, 2.0], [3.0, 2.0], [5.0, 5.0]])
    ss, df = D.pure_error(y, np.array([0, 0, 1]))
    assert (ss, df) == (2.0 + 0.0, 2)


def test_link_regressors_equal_the_integrated_beam_of_the_truth(rng):
    """The closed-form link columns against the truth simulator's curvature integral."""
    robot = planar_robot([0.7, 0.5, 0.3])
    q = rng.uniform(-np.pi, np.pi, (20, 3))
    f = rng.normal(0, 300, (20, 2))
    c = np.array([1e-6, 2e-6, 3e-6])
    ours = np.einsum("ndp,p->nd", D.cause_columns("link_compliance", robot, q, f), c)
    assert np.allclose(ours, T.link_bending_displacement(robot, q, f, c), rtol=1e-10, atol=1e-18)


# --- bad measured data ----------------------------------------------------------------------------------

GOOD = "pose_id,q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n0,10,20,100,0,1e-4,2e-4\n1,40,70,0,-200,3e-4,-1e-4\n"


@pytest.mark.parametrize("text, message", [
    (GOOD.replace("dx_m", "dx_mm"), "column dx_mm': expected displacements in m"),
    (GOOD.replace("dx_m", "dx"), "column dx': expected displacements in m"),
    (GOOD.replace("q1_deg", "q1_rad"), "column q1_rad': expected joint angles in deg"),
    (GOOD.replace(",dy_m", "").replace(",2e-4", "").replace(",-1e-4", ""), "missing column(s) dy_m"),
    (GOOD.replace("1e-4,2e-4", "1e-4,nan"), "row 2 (data row 0), column dy_m': expected a finite number"),
    (GOOD.replace("3e-4", "inf"), "row 3 (data row 1), column dx_m': expected a finite number"),
    (GOOD.replace("40,70", "forty,70"), "column q1_deg': expected a finite number, got 'forty'"),
    ("q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n", "no measurements"),
    (GOOD.replace("q2_deg,", "q2_deg,q3_deg,").replace("10,20", "10,20,5").replace("40,70", "40,70,5"),
     "expected 2 joint angles"),
])
def test_bad_csv_gets_one_clear_error(tmp_path, paper_robot, text, message):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_measurements(p, paper_robot)
    assert str(err.value).startswith(str(p)) and message in str(err.value)


def test_too_few_equations_and_singular_plans_are_refused(tmp_path):
    robot = planar_robot([0.5, 0.4, 0.3])
    p = tmp_path / "m.csv"
    p.write_text("q1_deg,q2_deg,q3_deg,fx_N,fy_N,dx_m,dy_m\n0,10,20,100,0,1e-4,2e-4\n")
    with pytest.raises(InputError, match="at least 3 equations"):
        D.check_identifiable(robot, read_measurements(p, robot))
    two = planar_robot([0.6, 0.4])
    p.write_text("q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n0,0,100,0,1e-4,2e-4\n0,0,200,0,1e-4,2e-4\n")  # force along the arm
    with pytest.raises(InputError, match="rank 0"):
        D.check_identifiable(two, read_measurements(p, two))


def test_cli_writes_the_verdict_and_nothing_on_bad_data(tmp_path, root, capsys):
    out = tmp_path / "out"
    rc = main(["discrepancy", "--robot", str(root / "config/robots/paper_2r.yaml"), "--data",
               str(root / "data/synthetic_paper_2r.csv"), "--out", str(out), "--test-pose-deg", "60,30",
               "--force-N", "0,-300"])
    assert rc == 0
    v = json.loads((out / "verdict.json").read_text())
    assert v["cause"] == "backlash" and v["outlier_rows"] == [17]
    for key in ("indistinguishable_from", "p_value", "nominal", "extended", "gain"):
        assert key in v
    assert (out / "residuals.png").stat().st_size > 0
    bad = tmp_path / "bad.csv"
    bad.write_text(GOOD.replace("dx_m", "dx_mm"))
    rc = main(["discrepancy", "--robot", str(root / "config/robots/paper_2r.yaml"), "--data", str(bad),
               "--out", str(tmp_path / "none")])
    assert rc == 2 and not (tmp_path / "none").exists()
    assert "dx_mm" in capsys.readouterr().err
