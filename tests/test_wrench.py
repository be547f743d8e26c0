"""Loads as wrenches, orientation and several targets per pose (issue 15, items 2-3): the observation matrix
of eqs. 2-4 on the 6-D geometric Jacobian against finite differences of the kinematics, O_t (eq. 16) with the
weighting of eqs. 10-11 against a Monte Carlo simulation of the calibration, the design criteria through the
API and the command line, and the config and robot-file checks."""

import json

import numpy as np
import pytest

import stiffcal
from stiffcal.cli import main
from stiffcal.planning.problem import Problem, plan_observations
from stiffcal.errors import InputError
from stiffcal.model.observation import Sensing, observation_rows, sensed_params
from stiffcal.model.robot import load_robot, spatial_robot, with_targets
from stiffcal.model.stiffness import identify_batch, observation_matrix
from stiffcal.planning.study import study_from_entry
from stiffcal.paper.tables import plan_summary

PAPER = "config/robots/paper_2r.yaml"
KUKA = "config/robots/kuka_kr210_r2700.yaml"


def _rotvec(R):
    return 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)


def _finite_difference_rows(robot, q, wrench, targets, orientation, h=1e-6):
    """The observation matrix from the kinematics alone: the 6-D Jacobian of the tool point and of each target
    by central differences of tool_frame, the torques tau = J_W^T W, and column j the change of the measured
    quantities per unit rotation of joint j times tau_j."""
    n = robot.n_joints
    planar = robot.kind == "planar"

    def quantities(qq):
        R, p = robot.tool_frame(qq)
        pts = [p + R @ robot.target_point(t) for t in ("tool", *targets)]
        return pts, R

    cols_load, cols_obs = [], []
    for j in range(n):
        (pp, Rp), (pm, Rm) = quantities(q + h * np.eye(n)[j]), quantities(q - h * np.eye(n)[j])
        dpts = [(a - b) / (2 * h) for a, b in zip(pp, pm)]
        rot = _rotvec(Rp @ Rm.T) / (2 * h)
        load6 = np.r_[dpts[0], rot]
        cols_load.append(load6[[0, 1, 5]] if planar else load6)
        obs = [d[:2] if planar else d for d in dpts[1:]]
        if orientation:
            obs.append(rot[2:] if planar else rot)
        cols_obs.append(np.concatenate(obs))
    J_load, J_obs = np.array(cols_load).T, np.array(cols_obs).T
    tau = J_load.T @ wrench
    return J_obs * tau


@pytest.mark.parametrize("name, wrench, extra", [
    (PAPER, [30.0, -200.0, 15.0], {"B": [-0.1, 0.05]}),
    (KUKA, [500.0, -300.0, -800.0, 40.0, -25.0, 60.0], {"A": [0.1, 0.05, 0.2], "B": [-0.05, 0.12, 0.25]}),
])
def test_observation_rows_with_a_wrench_targets_and_orientation_equal_finite_differences(name, wrench, extra, root,
                                                                                          rng):
    robot = with_targets(load_robot(root / name), extra, "test")
    targets = ("tool", *extra)
    sensing = Sensing(targets, True, 1.0, 1.0)
    for q in rng.uniform(-2.5, 2.5, (4, robot.n_joints)):
        ours = observation_rows(robot, q, np.array(wrench), sensing)
        ref = _finite_difference_rows(robot, q, np.array(wrench), targets, True)
        np.testing.assert_allclose(ours, ref, atol=1e-7 * np.abs(ref).max())


def test_a_force_and_the_tool_point_give_eq_4_exactly(root, rng):
    """The paper's problem is unchanged: the general rows with a zero moment equal eq. 4."""
    robot = load_robot(root / PAPER)
    q = rng.uniform(-3, 3, (50, 2))
    F = np.array([0.0, -1.0])
    np.testing.assert_allclose(observation_rows(robot, q, np.r_[F, 0.0], Sensing()),
                               observation_matrix(robot.jacobian(q), F), rtol=0, atol=1e-15)
    prob = Problem(robot, F, "ot", 1, np.radians([60, 30]), moment=np.zeros(1), sensing=Sensing())
    assert prob.is_default and np.array_equal(prob.rows(q), observation_matrix(robot.jacobian(q), F))


def test_o_t_with_orientation_targets_and_a_length_scale_is_the_monte_carlo_mean_error(root):
    """Eq. 16 with the weighting of eqs. 10-11: calibrations simulated with position noise sigma_m and rotation
    noise sigma_rad, identified by weighted least squares; the mean of |dp_B|^2 + L^2 |dr|^2 at the test pose
    equals O_t, and measuring at the test pose itself gives O_t* (eq. 17)."""
    robot = with_targets(load_robot(root / PAPER), {"B": [-0.1, 0.05]}, "test")
    sm, sr, L = 2e-5, 5e-5, 0.3
    prob = Problem(robot, np.array([40.0, -300.0]), "ot", 3, np.radians([60.0, 30.0]), sigma=sm,
                   moment=np.array([20.0]), sensing=Sensing(("tool", "B"), True, sm, sr), test_target="B",
                   length_m=L)
    plan = np.radians([[10.0, 80.0], [-70.0, 120.0], [150.0, -45.0]])
    A = prob.rows(plan)  # (3, 5, 2): rows of tool and B positions, then the rotation times sm / sr
    assert A.shape == (3, 5, 2)
    ot = float(plan_summary_study(robot, prob, plan))
    rng = np.random.default_rng(7)
    s = 40000
    noise = rng.normal(size=(s, 3, 5)) * np.array([sm] * 4 + [sr])  # the data: rotations in rad
    Aw = A.copy()
    yw = noise * np.array([1.0] * 4 + [sm / sr])  # weighted as the rows are
    dk = identify_batch(Aw, yw)  # the error of the identified compliances (truth 0)
    J_t = prob.At  # rows of B's position and L times the rotation
    err = dk @ J_t.T
    mc = np.mean(np.sum(err**2, axis=1))
    se = np.std(np.sum(err**2, axis=1)) / np.sqrt(s)
    assert abs(mc - ot) < 4 * se
    # A_t: B's position and L times the rotation, from the finite-difference rows at the test pose
    ref = _finite_difference_rows(robot, prob.test_pose, prob.test_load, ("B",), True)
    np.testing.assert_allclose(J_t, ref * np.array([[1.0], [1.0], [L]]), atol=1e-7 * np.abs(ref).max())
    # O_t* (eq. 17): every measurement at the test pose
    at_test = np.repeat(prob.test_pose[None], 3, axis=0)
    assert plan_summary_study(robot, prob, at_test) == pytest.approx(prob.ot_star(3), rel=1e-9)


def plan_summary_study(robot, prob, plan):
    from stiffcal.planning.study import Study

    st = Study("t", robot, prob.test_pose, prob.force, prob.sigma, ("ot",), 1.0, 1.0, prob.moment, prob.sensing,
               prob.test_target, prob.length_m)
    return plan_summary(st, np.degrees(plan))["O_t"]


def test_the_length_scale_is_the_rms_over_a_sphere(rng):
    """Module docstring of stiffcal.model.observation: L^2 |w|^2 is the mean of |w x r|^2 over points r at distance
    L sqrt(3/2) in every direction."""
    w, L = rng.normal(size=3), 0.4
    r = rng.normal(size=(400000, 3))
    r *= L * np.sqrt(1.5) / np.linalg.norm(r, axis=1, keepdims=True)
    assert np.mean(np.sum(np.cross(w, r) ** 2, axis=1)) == pytest.approx(L**2 * w @ w, rel=5e-3)


def test_orientation_identifies_a_joint_whose_axis_passes_through_the_measured_point():
    """A tool point on the axis of joint 6 never moves with it: positions cannot identify k6; the orientation
    (or a target off the axis) can."""
    rows = [[0.35, -90, 0.675, 0], [1.15, 0, 0, 0], [0.041, -90, 0, -90], [0, 90, 1.0, 0], [0, -90, 0, 0],
            [0, 0, 0.24, 0]]
    robot = spatial_robot(rows, (0.0, 0.0, 0.1), joint_limits_deg=[[-180, 180]] * 6)
    assert robot.inert_joints == (5,)
    assert list(sensed_params(robot, Sensing())) == [0, 1, 2, 3, 4]
    assert list(sensed_params(robot, Sensing(orientation=True, sigma_rad=1e-5))) == list(range(6))
    plan = np.radians(np.random.default_rng(1).uniform(-150, 150, (4, 6)))
    F, M = np.array([300.0, -200.0, -500.0]), np.array([30.0, 20.0, -40.0])
    qt = np.radians([20, -60, 110, 30, 45, -20])
    pos = Problem(robot, F, "ot", 4, qt, sigma=1e-5, moment=M)
    rot = Problem(robot, F, "ot", 4, qt, sigma=1e-5, moment=M, sensing=Sensing(orientation=True, sigma_rad=2e-5))
    assert pos.n_params == 5 and rot.n_params == 6
    M_rot = np.einsum("mri,mrj->ij", rot.rows(plan), rot.rows(plan))
    assert np.linalg.matrix_rank(M_rot) == 6


def test_design_with_a_wrench_reports_the_o_t_of_its_poses(root):
    """With a moment the half-turn and mirror copies of a pose no longer carry the same information: the plan
    is reported as found, and its O_t recomputed from the reported poses (finite-difference rows) is the
    reported O_t; the certified bound lies below it."""
    robot = load_robot(root / PAPER)
    res = stiffcal.design(robot, [60, 30], wrench=[0.0, -1.0, 0.3], experiments=2)
    rows = np.array([_finite_difference_rows(robot, np.radians(q), np.array([0.0, -1.0, 0.3]), ("tool",), False)
                     for q in res.poses_deg])
    At = _finite_difference_rows(robot, np.radians([60, 30]), np.array([0.0, -1.0, 0.3]), ("tool",), False)
    M = np.einsum("mri,mrj->ij", rows, rows)
    assert res.O_t == pytest.approx(np.trace(At @ np.linalg.solve(M, At.T)), rel=1e-6)
    assert res.lower_bound <= res.O_t * (1 + 1e-9)
    assert res.moment_Nm.tolist() == [0.3]
    prob = Problem(robot, np.array([0.0, -1.0]), "ot", 1, np.radians([60, 30]), moment=np.array([0.3]))
    assert not prob.symmetric
    grid = np.radians(np.stack(np.meshgrid(np.arange(-180, 180, 2.0), np.arange(-180, 180, 2.0)), -1).reshape(-1, 2))
    from stiffcal.model import criteria

    brute = criteria.loss("ot", plan_observations(prob, grid[:, None, :]), 1, prob.At).min()
    single = stiffcal.design(robot, [60, 30], wrench=[0.0, -1.0, 0.3])
    assert single.O_t <= brute * (1 + 1e-9)


def test_cli_design_takes_a_wrench_targets_and_orientation(root, tmp_path, capsys):
    robot = tmp_path / "r.yaml"
    robot.write_text((root / PAPER).read_text() + "targets: {B: [-0.1, 0.05]}\n")
    argv = ["design", "--robot", str(robot), "--test-pose-deg", "60,30", "--wrench", "0,-1,0.2", "--targets",
            "tool,B", "--orientation", "--sigma-rad", "0.5", "--test-target", "B", "--orientation-length-m", "0.2",
            "--quiet"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["targets"] == ["tool", "B"] and out["orientation"] and out["test_target"] == "B"
    assert out["force_N"] == [0.0, -1.0] and out["moment_Nm"] == [0.2]
    st = study_from_entry({"name": "x", "robot": str(robot), "test_pose_deg": [60, 30], "force_N": [0, -1],
                           "moment_Nm": [0.2], "targets": ["tool", "B"], "orientation": True, "sigma_rad": 0.5,
                           "test_target": "B", "orientation_length_m": 0.2})
    assert out["O_t"] == pytest.approx(float(plan_summary(st, np.array(out["poses_deg"]))["O_t"]), rel=1e-9)
    for bad, message in [(["--force-N", "0,-1"], "'--wrench': expected the force or the wrench, not both"),
                         (["--wrench", "0,-1"], "'--wrench': expected 3 wrench components (fx, fy, mz)"),
                         (["--targets", "tool,C"], "'--targets': expected a target of robot"),
                         (["--sigma-rad", "0"], "'--sigma-rad'")]:
        args = list(argv)
        if bad[0] in args:
            args[args.index(bad[0]) + 1] = bad[1]
        else:
            args += bad
        assert main(args) == 2
        assert message in capsys.readouterr().err


@pytest.mark.parametrize("entry, field, message", [
    ({"moment_Nm": [1.0, 2.0]}, "study.moment_Nm", "expected 1 moment component for a planar robot"),
    ({"targets": ["C"]}, "study.targets", "expected a target of robot"),
    ({"orientation": True}, "study.sigma_rad", "expected the orientation noise sigma_rad > 0"),
    ({"test_target": "C"}, "study.test_target", "expected a target of robot"),
    ({"force_N": [0, 0], "moment_Nm": [0]}, "study.force_N", "expected a nonzero force or moment"),
    ({"test_pose_deg": [0, 0], "force_N": [1, 0]}, "study.force_N", "produces no joint torque"),
    ({"test_pose_deg": [0, 0], "force_N": [-3, 0], "moment_Nm": [0]}, "study.force_N", "produces no joint torque"),
])
def test_study_entries_with_bad_loads_or_measurements_are_refused(entry, field, message, root):
    base = {"name": "x", "robot": PAPER, "test_pose_deg": [60, 30], "force_N": [0, -1]}
    with pytest.raises(InputError) as err:
        study_from_entry({**base, **entry}, root, "config.yaml")
    assert err.value.field == field and message in str(err.value)


def test_robot_file_targets_are_checked(tmp_path, root):
    text = (root / PAPER).read_text()
    for extra, message in [("targets: {A: [0.1, 0.0, 0.2]}\n", "expected 2 coordinates"),
                           ("targets: {tool: [0.1, 0.0]}\n", "the name 'tool' is the tool point's")]:
        p = tmp_path / "r.yaml"
        p.write_text(text + extra)
        with pytest.raises(InputError, match=message):
            load_robot(p)
    p.write_text(text + "targets: {A: [0.1, 0.02], B: [-0.2, 0.0]}\n")
    robot = load_robot(p)
    assert robot.target_names == ("tool", "A", "B")
    np.testing.assert_array_equal(robot.target_point("A"), [0.1, 0.02, 0.0])


UPRIGHT_3R = """name: upright-3r
kind: spatial
dh_convention: standard
dh:
  - {a_m: 0.0, alpha_deg: 90, d_m: 0.4}
  - {a_m: 0.5, alpha_deg: 0, d_m: 0.0, offset_deg: 90}
  - {a_m: 0.4, alpha_deg: 0, d_m: 0.0}
"""


@pytest.mark.parametrize("robot,pose,load", [
    (PAPER, "0,0", ["--force-N", "1,0"]),                    # a force along the straight arm
    (PAPER, "90,0", ["--force-N", "0,-2"]),
    (PAPER, "0,0", ["--wrench", "1,0,0"]),
    ("upright", "0,0,0", ["--force-N", "0,0,-100"]),        # a spatial arm pointing up, a vertical force
    ("upright", "40,0,0", ["--wrench", "0,0,-100,0,0,0"]),
])
@pytest.mark.parametrize("experiments", ["1", "3"])
def test_a_load_without_torque_at_the_test_pose_is_refused(robot, pose, load, experiments, tmp_path, capsys, root):
    """tau = J^T F = 0 at the test pose: nothing deflects there and O_t is 0 for every plan; one message naming the
    option, exit 2 (it was a singular-matrix crash), and the API and a config study refuse it the same way."""
    if robot == "upright":
        robot = tmp_path / "upright.yaml"
        robot.write_text(UPRIGHT_3R)
    else:
        robot = root / robot
    code = main(["design", "--robot", str(robot), "--test-pose-deg", pose, *load, "--experiments", experiments,
                 "--quiet"])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert out.err.startswith(f"stiffcal design: error: field '{load[0]}': expected a load that bends the arm")
    assert "O_t is 0 for every plan" in out.err and len(out.err.splitlines()) == 1
    key = "force_N" if load[0] == "--force-N" else "wrench"
    with pytest.raises(InputError, match="produces no joint torque") as err:
        stiffcal.design(robot, [float(a) for a in pose.split(",")], **{key: [float(v) for v in load[1].split(",")]},
                        experiments=int(experiments))
    assert err.value.field == key


def test_a_force_along_the_straight_arm_with_a_moment_has_a_certified_answer(root):
    """The force along the straight test arm plus a moment bends it (tau = (mz, mz)): a well-posed problem whose
    information matrices are singular in places (it was a singular-matrix crash in the approximate design). The
    single optimal pose is compared with a brute force over a 0.5-degree grid of O_t (eq. 16) written here from
    the 2R kinematics, and lies above the certified bound."""
    l1, l2, (fx, fy, mz) = 0.6, 0.4, (1.0, 0.0, 0.1)

    def rows(q1, q2):  # (..., 2, 2): column j = d(tool)/d(theta_j) * tau_j, tau = J_W^T W
        s1, c1, s12, c12 = np.sin(q1), np.cos(q1), np.sin(q1 + q2), np.cos(q1 + q2)
        J = np.stack([np.stack([-l1 * s1 - l2 * s12, -l2 * s12], -1), np.stack([l1 * c1 + l2 * c12, l2 * c12], -1)],
                     -2)
        tau = np.einsum("...ij,...i->...j", J, np.broadcast_to([fx, fy], J.shape[:-1])) + mz
        return J * tau[..., None, :]

    At = rows(0.0, 0.0)
    g = np.radians(np.arange(-180, 180, 0.5))
    A = rows(*np.meshgrid(g, g, indexing="ij"))
    M = np.einsum("...ki,...kj->...ij", A, A)
    det = np.linalg.det(M)
    ok = np.abs(det) > 1e-12
    Minv = np.linalg.inv(np.where(ok[..., None, None], M, np.eye(2)))
    ot = np.where(ok, np.einsum("ij,...jk,ik->...", At, Minv, At), np.inf)
    brute = float(ot.min())
    res = stiffcal.design(root / PAPER, [0, 0], wrench=[fx, fy, mz])
    assert res.O_t <= brute * (1 + 1e-9)
    assert brute <= res.O_t * (1 + 1e-3)
    assert res.lower_bound <= res.O_t * (1 + 1e-9) and res.approximate_design["converged"]
    A1 = rows(*np.radians(res.poses_deg[0]))
    assert res.O_t == pytest.approx(float(np.trace(At @ np.linalg.inv(A1.T @ A1) @ At.T)), rel=1e-9)


def test_a_joint_the_force_never_turns_is_left_out_whatever_is_measured():
    """UR10 (tool point on wrist 3's axis) with the orientation or a second target measured: a force at the
    tool point has no torque about wrist 3 at any pose (checked on random poses from the robot's Jacobian), so
    its compliance cannot be identified and is left out with a note (cov_diag "inf"), instead of every pose
    being singular; with a moment (a wrench) it is identified."""
    from pathlib import Path

    import stiffcal

    root = Path(__file__).resolve().parents[1]
    robot = stiffcal.load_robot(root / "tests/data/lab/ur10.yaml")
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (200, 6))
    force = np.array([30.0, 20.0, -100.0])
    assert np.abs(np.einsum("kdn,d->kn", robot.jacobian(q), force)[:, 5]).max() < 1e-9  # tau_6 = J_6^T F = 0
    kw = dict(test_pose_deg=[20, -100, 90, -80, -90, 0], sigma=1e-5, experiments=2, progress=False)
    for sensing in (dict(orientation=True, sigma_rad=2e-5), dict(targets=["tool", "A"])):
        res = stiffcal.design(robot, force_N=force, **sensing, **kw)
        assert np.isinf(res.cov_diag[5]) and np.all(np.isfinite(res.cov_diag[:5]))
        assert any("wrist_3_joint" in n and "moment" in n for n in res.notes)
        assert res.lower_bound <= res.O_t < np.inf
    res = stiffcal.design(robot, wrench=[30, 20, -100, 0, 5, 2], orientation=True, sigma_rad=2e-5, **kw)
    assert np.all(np.isfinite(res.cov_diag)) and not any("wrist_3_joint" in n and "left out" in n for n in res.notes)
