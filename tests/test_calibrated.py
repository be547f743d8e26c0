"""The calibrated model in use (stiffcal.calibrated): the exported file reloads to the verdict's numbers, its
predictions equal the simulator's deflection (stiffcal.truth, written apart from the regressors) for every
catalogue extension, with wrenches, targets and rotations and the arm's own weight, and a finite difference of the
kinematics; compensation with the true model leaves nothing, with a calibrated one an error whose distribution
over seeds is the one its covariance predicts."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from stiffcal import calibrated as C
from stiffcal import discrepancy as D
from stiffcal import rates as R
from stiffcal import truth as T
from stiffcal.measurements import read_measurements
from stiffcal.robot import load_robot

ROOT = Path(__file__).resolve().parents[1]
ARMS = R.robots(ROOT)


def _calibration(robot, causes, theta, cov=None) -> C.Calibration:
    """A calibration of every joint with the extension ``causes`` and parameters ``theta`` (catalogue order)."""
    names = tuple(robot.joint_columns("k")) + tuple(
        name for c in causes for name in D.parameter_names(c, robot, D.Observed()))
    p = len(theta)
    return C.Calibration(tuple(causes), tuple(range(robot.n_joints)), names, np.asarray(theta, float),
                         np.zeros((p, p)) if cov is None else cov, (True,) * p, robot.task_dim, 1e-5)


def _poses(robot, rng, count):
    n = robot.n_joints
    limits = robot.joint_limits_rad
    lo, hi = limits.T if limits is not None else (np.full(n, -np.pi), np.full(n, np.pi))
    return rng.uniform(np.maximum(lo, -2.5), np.minimum(hi, 2.5), (count, n))


def _truths(robot, rng):
    """{cause: (Truth with that effect, the calibration's parameters of the same physics)}. The backlash's tanh
    is saturated (tau_gap = 1e-6 N m: a sign at every torque here) and the softening joint's tau_max is 100 times
    the largest torque, so the cubic term g = k / (2 tau_max^2) of its Taylor series leaves a relative remainder
    below 1e-4 (3/4 (tau/tau_max)^2)."""
    n, k = robot.n_joints, R.compliances(robot)
    iu = np.triu_indices(n, 1)
    pair = rng.uniform(0.1, 0.3, len(iu[0])) * k.mean()
    coupling = np.zeros((n, n))
    coupling[iu] = pair
    bending = rng.uniform(1e-7, 3e-7, robot.n_segments)
    gap = rng.uniform(2e-5, 5e-5, n)
    return {"nominal": (T.Truth(k), k),
            "joint_coupling": (T.Truth(k, coupling=coupling + coupling.T), np.r_[k, pair]),
            "link_compliance": (T.Truth(k, link_bending=bending), np.r_[k, bending]),
            "backlash": (T.Truth(k, gap=gap, tau_gap=1e-6), np.r_[k, gap / 2]),
            "nonlinear_joint_stiffness": (None, None)}


@pytest.mark.parametrize("arm", list(ARMS))
@pytest.mark.parametrize("cause", D.CAUSES[:-1] + ("nominal",))
def test_predictions_equal_the_simulators_deflection(arm, cause):
    """Every catalogue extension of the robot (the measuring system's offset is not the robot's), on the 2- and
    3-link arms and the 6-axis arm whose own weight preloads its joints: the prediction with the simulator's
    parameters equals the simulator's deflection (the loaded state less the unloaded one) to round-off."""
    robot = ARMS[arm]
    rng = np.random.default_rng(7)
    q = _poses(robot, rng, 25)
    force = rng.normal(0.0, 300.0, (25, robot.task_dim))
    truths = _truths(robot, rng)
    if cause == "nonlinear_joint_stiffness":
        k = R.compliances(robot)
        tau = T.joint_torques(robot, q, force) + T.self_weight_torques(robot, q)
        tau_max = np.full(robot.n_joints, 100.0 * np.abs(tau).max())
        truth, theta = T.Truth(k, tau_max=tau_max), np.r_[k, k / (2.0 * tau_max**2)]
    else:
        truth, theta = truths[cause]
    causes = [] if cause == "nominal" else [cause]
    pred = C.predict(replace(robot, calibration=_calibration(robot, causes, theta)), q, force)
    true = T.deflection(robot, truth, q, force)
    linear = T.deflection(robot, T.Truth(R.compliances(robot)), q, force)
    effect = np.abs(true - linear).max()
    assert cause == "nominal" or effect > 1e-8 * np.abs(true).max()  # the extension shows
    tol = 1e-3 * effect if cause == "nonlinear_joint_stiffness" else 1e-12 * np.abs(true).max()
    assert np.abs(pred.displacement - true).max() <= tol
    assert np.all(pred.sd == 0.0)  # no covariance given, none predicted


@pytest.mark.parametrize("arm", list(ARMS))
def test_predictions_with_wrenches_targets_and_rotations(arm):
    """Link bending, coupling and backlash together, under wrenches (a force and a moment), at the tracker's
    targets and with the tool's rotation: the simulator's deflection to round-off."""
    robot = ARMS[arm]
    rng = np.random.default_rng(3)
    n, d = robot.n_joints, robot.task_dim
    dm = 1 if d == 2 else 3
    q = _poses(robot, rng, 25)
    force, moment = rng.normal(0.0, 300.0, (25, d)), rng.normal(0.0, 50.0, (25, dm))
    target = rng.integers(0, len(robot.target_names), 25)
    t = _truths(robot, rng)
    k = R.compliances(robot)
    truth = T.Truth(k, coupling=t["joint_coupling"][0].coupling, link_bending=t["link_compliance"][0].link_bending,
                    gap=t["backlash"][0].gap, tau_gap=1e-6)
    causes = ["link_compliance", "joint_coupling", "backlash"]
    theta = np.r_[k, t["link_compliance"][1][n:], t["joint_coupling"][1][n:], t["backlash"][1][n:]]
    pred = C.predict(replace(robot, calibration=_calibration(robot, causes, theta)), q, np.hstack([force, moment]),
                     target, orientation=True)
    true = T.deflection(robot, truth, q, force, moment, target, robot.target_names, orientation=True)
    got = np.hstack([pred.displacement, pred.rotation])
    assert np.abs(got - true).max() <= 1e-12 * np.abs(true).max()
    assert set(pred.targets) <= set(robot.target_names)


def test_joint_deflection_against_a_finite_difference_of_the_kinematics():
    """The joint causes' prediction is the tool's motion J dq: a central difference of the forward kinematics
    along the simulator's joint deflection, fk(q + h dq) - fk(q - h dq) / 2h, agrees to O(h^2)."""
    robot = ARMS["6-axis"]
    rng = np.random.default_rng(5)
    q = _poses(robot, rng, 20)
    force = rng.normal(0.0, 300.0, (20, 3))
    truth, theta = _truths(robot, rng)["backlash"]
    tau = T.joint_torques(robot, q, force)
    dq = T.loaded_deflections(truth, tau, T.self_weight_torques(robot, q), q)
    h = 1e-2
    fd = (np.asarray(robot.fk(q + h * dq)) - np.asarray(robot.fk(q - h * dq))) / (2 * h)
    pred = C.predict(replace(robot, calibration=_calibration(robot, ["backlash"], theta)), q, force)
    assert np.abs(pred.displacement - fd).max() <= 1e-6 * np.abs(fd).max()


# --- the calibrated file ---------------------------------------------------------------------------------------

def _lab_data(tmp_path, robot, truth, seed=0, n_configs=12, protocol="hanging x3, reference per visit, 2 passes",
              name="log.csv"):
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, R.PROTOCOLS[protocol], rng, n_configs)
    dp = T.measure(robot, truth, log, rng)
    path = tmp_path / name
    path.write_text(T.lab_csv(robot, log, dp), encoding="utf-8")
    return path


def test_exported_model_reloads_to_the_verdicts_estimates(tmp_path):
    """stiffcal discrepancy writes calibrated.yaml: read back by load_robot, its compliances and the extension's
    parameters are the verdict's to round-off, the data's SHA-256 is the file's, and the analysis of new data
    takes it as its robot."""
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    k = R.compliances(robot)
    data = _lab_data(tmp_path, robot, T.Truth(k, gap=np.full(2, 2e-4), tau_gap=1e-3))
    out = tmp_path / "out"
    v = D.run(robot, str(data), str(out), 0.01)
    assert v["cause"] == "backlash" and v["calibrated_model"] == "calibrated.yaml"
    cal_robot = load_robot(out / "calibrated.yaml")
    cal = cal_robot.calibration
    ext = v["extended"]
    assert cal.causes == ("backlash",)
    expect = np.r_[ext["k"], ext["parameters"]]
    np.testing.assert_allclose(cal.theta, expect, rtol=1e-12, atol=0)
    np.testing.assert_allclose(cal_robot.compliances, ext["k"], rtol=1e-12, atol=0)
    half = stats.t.isf(0.025, v["nominal"]["sigma_df"]) * np.sqrt(np.diag(cal.cov))  # the verdict's intervals
    np.testing.assert_allclose(half, np.r_[ext["k_ci95"], ext["parameters_ci95"]], rtol=1e-6)
    assert cal.source["data_sha256"] == C.sha256(data) and cal.source["verdict_cause"] == "backlash"
    assert json.loads((out / "verdict.json").read_text())["calibrated_model"] == "calibrated.yaml"
    again = D.run(cal_robot, str(_lab_data(tmp_path, robot, T.Truth(k), seed=1, name="next.csv")),
                  str(tmp_path / "next"), 0.01)
    assert again["cause"] in D.CAUSES + ("none", "unexplained")


def test_urdf_arm_keeps_its_urdf(tmp_path):
    """A URDF robot's calibrated file refers to the same URDF (from its own folder) and reloads to the same
    kinematics, with the identified compliances."""
    robot = load_robot(ROOT / "config/robots/kuka_kr210_r2700_urdf.yaml")
    k = R.compliances(robot) * 1.1
    out = tmp_path / "deep" / "folder"
    out.mkdir(parents=True)
    C.write_calibrated(robot, _calibration(robot, [], k, np.diag(k * 0.01) ** 2), out)
    doc = (out / "calibrated.yaml").read_text()
    assert "kind: urdf" in doc
    back = load_robot(out / "calibrated.yaml")
    q = _poses(robot, np.random.default_rng(0), 5)
    np.testing.assert_allclose(back.fk(q), robot.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.compliances, k, rtol=1e-15)


# --- compensation ----------------------------------------------------------------------------------------------

def test_compensation_with_the_true_model_leaves_nothing():
    """With the simulator's own model (coupling and backlash on the weighted 6-axis arm), the compensated joint
    angles put the deflected tool on the nominal point: what is left is the iteration's tolerance, against
    deflections of a millimetre; the first-order step leaves more."""
    robot = ARMS["6-axis"]
    rng = np.random.default_rng(11)
    t = _truths(robot, rng)
    k, n = R.compliances(robot), robot.n_joints
    truth = T.Truth(k, coupling=t["joint_coupling"][0].coupling, gap=t["backlash"][0].gap, tau_gap=1e-6)
    theta = np.r_[k, t["joint_coupling"][1][n:], t["backlash"][1][n:]]
    model = replace(robot, calibration=_calibration(robot, ["joint_coupling", "backlash"], theta))
    q = _poses(robot, rng, 30)
    force = rng.normal(0.0, 800.0, (30, 3))
    comp = C.compensate(model, q, force)
    reached = np.asarray(robot.fk(comp.q_corrected)) + T.deflection(robot, truth, comp.q_corrected, force)
    left = np.linalg.norm(reached - comp.target_m, axis=1)
    before = np.linalg.norm(T.deflection(robot, truth, q, force), axis=1)
    assert comp.converged.all() and before.min() > 1e-5
    assert left.max() <= 1e-9 and np.all(comp.first_order_residual_m >= comp.residual_m)
    assert comp.first_order_residual_m.max() > 1e3 * left.max()


def test_compensation_error_has_the_predicted_distribution_over_seeds(tmp_path):
    """Backlash found from a lab's log (hanging masses, a reference reading per visit, two passes) on 40 seeds;
    each calibrated model compensates a path of 30 random poses and loads. The tool's error left (the simulator's
    arm at the compensated angles) falls within its 95 % ellipsoid (the prediction's covariance) at a rate
    consistent with 95 % (one-sided binomial test on one pose per seed, the seeds independent), within the
    bounding sphere band95_m at >= 95 % of all poses, and its Mahalanobis distance is chi2(d) distributed
    (Kolmogorov-Smirnov, two-sided: a covariance too large fails as one too small does)."""
    robot = ARMS["2-link"]
    k, d = R.compliances(robot), robot.task_dim
    truth = T.Truth(k, gap=np.full(2, 2e-4), tau_gap=1e-3)
    first, inside_band, causes = [], [], []
    for seed in range(40):
        path = _lab_data(tmp_path, robot, truth, seed=seed)
        pre = D.prepare(robot, read_measurements(path, robot), 0.01)
        v = D.verdict_of(robot, pre, 0.01, gain=False)
        causes.append(v["cause"])
        model = replace(robot, calibration=C.from_analysis(robot, pre, v, path))
        rng = np.random.default_rng(1000 + seed)
        q, force = _poses(robot, rng, 30), rng.normal(0.0, 300.0, (30, d))
        comp = C.compensate(model, q, force)
        err = np.asarray(robot.fk(comp.q_corrected)) + T.deflection(robot, truth, comp.q_corrected, force) - \
            comp.target_m
        cov = C.predict(model, comp.q_corrected, force).cov
        m2 = np.einsum("nr,nrs,ns->n", err, np.linalg.inv(cov), err)
        first.append(m2[0])
        inside_band.append(np.linalg.norm(err, axis=1) <= comp.band95_m)
    assert causes.count("backlash") >= 38  # the extension the calibration applies
    first = np.array(first)
    covered = int((first <= stats.chi2.ppf(0.95, d)).sum())
    assert stats.binomtest(covered, len(first), 0.95, alternative="less").pvalue > 0.01
    assert stats.kstest(first, stats.chi2(d).cdf).pvalue > 0.001
    assert np.mean(inside_band) >= 0.95
