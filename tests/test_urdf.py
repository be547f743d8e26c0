"""Robot files of kind urdf (src/stiffcal/model/urdf.py): the kinematics against the DH file of the same arm and
against Pinocchio's own forward kinematics and frame Jacobian, the same plans from both files of the KUKA
KR 210 R2700, joint names in tables, JSON and measured data, and every bad URDF robot file refused with one
message naming the file and the field."""

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.measured.measurements import read_measurements
from stiffcal.model.robot import load_robot, planar_robot

KUKA_DH = "config/robots/kuka_kr210_r2700.yaml"
KUKA_URDF = "config/robots/kuka_kr210_r2700_urdf.yaml"
TEST_POSE, FORCE = "20,-60,110,30,45,-20", "500,-300,-800"


@pytest.fixture(scope="module")
def kuka(root):
    return load_robot(root / KUKA_DH), load_robot(root / KUKA_URDF)


def test_kuka_urdf_gives_the_dh_files_kinematics(kuka, rng):
    """The URDF (written from the data sheet's dimensions, not from the DH table) and the DH file give the same
    measured point, Jacobian, drawn arm, joint limits and reach, at random poses over every joint's whole turn."""
    dh, urdf = kuka
    q = rng.uniform(-np.pi, np.pi, (2000, 6))
    np.testing.assert_allclose(urdf.fk(q), dh.fk(q), atol=1e-12)
    np.testing.assert_allclose(urdf.jacobian(q), dh.jacobian(q), atol=1e-12)
    np.testing.assert_allclose(urdf.link_points(q), dh.link_points(q), atol=1e-12)
    np.testing.assert_allclose(np.degrees(urdf.joint_limits_rad), np.degrees(dh.joint_limits_rad), atol=1e-9)
    assert urdf.joint_names == ("a1", "a2", "a3", "a4", "a5", "a6") and urdf.kind == "urdf" and urdf.task_dim == 3
    assert urdf.inert_joints == dh.inert_joints == () and urdf.has_joint_limits
    np.testing.assert_allclose(urdf.compliances, dh.compliances)


@pytest.mark.parametrize("which", [0, 1])
def test_joint_frames_and_tool_frame_give_the_jacobian_of_any_point(kuka, rng, which):
    """J_lin = axes x (p + R t - origins) for a point t in the tip frame equals a central difference of that
    point's position (the interface every kind provides), for the DH and the URDF file."""
    robot = kuka[which]
    t = rng.uniform(-0.3, 0.3, 3)
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    origins, axes = robot.joint_frames(q)
    R, p = robot.tool_frame(q)
    point = p + R @ t
    J = np.swapaxes(np.cross(axes, point[:, None, :] - origins), -1, -2)
    h = 1e-6
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        Rp, pp = robot.tool_frame(q + dq)
        Rm, pm = robot.tool_frame(q - dq)
        np.testing.assert_allclose(J[..., j], ((pp + Rp @ t) - (pm + Rm @ t)) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=-1), 1.0)
    np.testing.assert_allclose(p + R @ robot.tool_m, robot.fk(q), atol=1e-12)


def test_planar_joint_frames_lie_in_the_plane(rng):
    robot = planar_robot([0.6, 0.4, 0.3])
    q = rng.uniform(-np.pi, np.pi, (10, 3))
    origins, axes = robot.joint_frames(q)
    R, p = robot.tool_frame(q)
    assert np.all(origins[..., 2] == 0) and np.all(axes == [0, 0, 1]) and np.all(p[..., 2] == 0)
    J = np.swapaxes(np.cross(axes, p[:, None, :] - origins), -1, -2)
    np.testing.assert_allclose(J[:, :2], robot.jacobian(q), atol=1e-12)
    np.testing.assert_allclose(R[..., :2, 0], np.stack([np.cos(q.sum(1)), np.sin(q.sum(1))], -1), atol=1e-12)


def _rpy(rng):
    return " ".join(f"{v:.6f}" for v in rng.uniform(-np.pi, np.pi, 3))


def _xyz(rng, scale=0.4):
    return " ".join(f"{v:.6f}" for v in rng.uniform(-scale, scale, 3))


def _random_urdf(rng) -> str:
    """A tree: a revolute joint above the base (not in the chain), revolute and continuous joints about random
    axes, a joint held at a fixed angle, fixed joints, and a prismatic branch off the chain."""
    def axis():
        a = rng.normal(size=3)
        return " ".join(f"{v:.6f}" for v in a / np.linalg.norm(a))

    joints = [("rail", "revolute", "world", "base_link"), ("j1", "revolute", "base_link", "l1"),
              ("j2", "continuous", "l1", "l2"), ("j3", "revolute", "l2", "l3"), ("f1", "fixed", "l3", "l3b"),
              ("j4", "revolute", "l3b", "l4"), ("j5", "revolute", "l4", "l5"), ("f2", "fixed", "l5", "tool_link"),
              ("finger", "prismatic", "l2", "finger_link")]
    links = sorted({j[2] for j in joints} | {j[3] for j in joints})
    out = ['<?xml version="1.0"?>', '<robot name="random">'] + [f'  <link name="{name}"/>' for name in links]
    for name, kind, parent, child in joints:
        out.append(f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                   f'<origin xyz="{_xyz(rng)}" rpy="{_rpy(rng)}"/>')
        if kind != "fixed":
            out.append(f'    <axis xyz="{axis()}"/>')
        if kind in ("revolute", "prismatic"):
            out.append('    <limit lower="-2.5" upper="2.9" effort="1" velocity="1"/>')
        out.append("  </joint>")
    return "\n".join(out + ["</robot>", ""])


def test_urdf_chain_matches_pinocchio_pose_by_pose(tmp_path, rng):
    """Our batched chain against Pinocchio's forwardKinematics and frame Jacobian, one pose at a time, on random
    URDFs: the measured point in the base frame and its Jacobian over the moving joints, with a joint above the
    base, a continuous joint about a skew axis, a joint held at a stated angle and a branch off the chain."""
    pin = pytest.importorskip("pinocchio")
    for trial in range(4):
        (tmp_path / "r.urdf").write_text(_random_urdf(rng))
        tool = rng.uniform(-0.2, 0.2, 3)
        (tmp_path / "r.yaml").write_text(textwrap.dedent(f"""\
            name: random
            kind: urdf
            urdf: r.urdf
            base_frame: base_link
            tip_frame: tool_link
            joints: [j1, j2, j4, j5]
            fixed_joints_deg: {{j3: 25}}
            tool_m: {tool.tolist()}
            """))
        robot = load_robot(tmp_path / "r.yaml")
        assert robot.joint_names == ("j1", "j2", "j4", "j5")
        np.testing.assert_allclose(robot.joint_limits_rad, [[-2.5, 2.9], [-np.pi, np.pi], [-2.5, 2.9], [-2.5, 2.9]])
        model = pin.buildModelFromUrdf(str(tmp_path / "r.urdf"))
        base, tip = model.getFrameId("base_link"), model.getFrameId("tool_link")
        at_point = model.frames[tip].placement * pin.SE3(np.eye(3), tool)
        point = model.addFrame(pin.Frame("point", model.frames[tip].parentJoint, tip, at_point, pin.FrameType.OP_FRAME))
        data = model.createData()
        ids = {model.names[j]: j for j in range(1, model.njoints)}
        qs = rng.uniform(-2.5, 2.9, (8, 4))
        ours_p, ours_J = robot.fk(qs), robot.jacobian(qs)
        for q, p_ours, J_ours in zip(qs, ours_p, ours_J):
            full = pin.neutral(model)
            for name, angle in [("rail", rng.uniform(-2, 2)), ("j1", q[0]), ("j2", q[1]), ("j3", np.radians(25)),
                                ("j4", q[2]), ("j5", q[3]), ("finger", rng.uniform(0, 0.1))]:
                i = model.idx_qs[ids[name]]
                if model.nqs[ids[name]] == 2:
                    full[i:i + 2] = np.cos(angle), np.sin(angle)
                else:
                    full[i] = angle
            pin.forwardKinematics(model, data, full)
            pin.updateFramePlacements(model, data)
            oMb = data.oMf[base]
            np.testing.assert_allclose(p_ours, oMb.actInv(data.oMf[point]).translation, atol=1e-12)
            J = pin.computeFrameJacobian(model, data, full, point, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
            cols = [model.idx_vs[ids[name]] for name in ("j1", "j2", "j4", "j5")]
            np.testing.assert_allclose(J_ours, oMb.rotation.T @ J[:, cols], atol=1e-12)


def _design(root, robot, capsys, *extra, experiments="6"):
    assert main(["design", "--robot", str(root / robot), "--test-pose-deg", TEST_POSE, "--force-N", FORCE,
                 "--sigma", "1e-5", "--experiments", experiments, "--quiet", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_kuka_urdf_and_dh_files_give_the_same_plans(root, kuka, capsys):
    """``stiffcal design ... --experiments M`` on the URDF and on the DH file of the KUKA: the same plans (every
    pose to 0.01 deg, as printed: the same copy of the mirror and wrist-flip symmetries), the same O_t (each
    plan evaluated on the other file's robot too, to 1e-9) and the same certified bound (1e-5). The two
    files' Jacobians differ by round-off (1e-16), which the approximate design's support and the exchange
    follow; the rounding of information classes, the converged polish and the symmetry copies remove it."""
    from stiffcal.planning.study import Study
    from stiffcal.paper.tables import plan_summary

    studies = [Study("s", r, np.radians([20, -60, 110, 30, 45, -20]), np.array([500.0, -300, -800]), 1e-5, ("ot",),
                     1.0, 1.0) for r in kuka]
    for m in ("6",):
        a, b = _design(root, KUKA_DH, capsys, experiments=m), _design(root, KUKA_URDF, capsys, experiments=m)
        assert b["joint_names"] == ["a1", "a2", "a3", "a4", "a5", "a6"] and a["joint_names"] == list("123456")
        np.testing.assert_allclose(b["poses_deg"], a["poses_deg"], atol=1e-2)
        for plan in (a["poses_deg"], b["poses_deg"]):
            ot = [float(plan_summary(s, np.array(plan))["O_t"]) for s in studies]
            assert ot[0] == pytest.approx(ot[1], rel=1e-9)
        assert b["O_t"] == pytest.approx(a["O_t"], rel=1e-9)
        assert b["lower_bound"] == pytest.approx(a["lower_bound"], rel=1e-5)
        for r in (a, b):
            assert r["lower_bound"] <= r["O_t"] and r["gap"] < 0.01
            assert not kuka[0].outside_limits(np.radians(r["poses_deg"])).any()


def test_named_joints_name_every_column(tmp_path, capsys):
    """joint_names of a planar file: the tables' columns, the long-form plans and the JSON name the joints;
    without joint_names the columns stay q1_deg ..."""
    from stiffcal.planning.study import Study
    from stiffcal.paper.tables import plans_long, table2

    (tmp_path / "arm.yaml").write_text("name: arm\nkind: planar\nlinks_m: [0.6, 0.4]\njoint_names: [shoulder, elbow]\n")
    robot = load_robot(tmp_path / "arm.yaml")
    study = Study("s", robot, np.radians([60, 30]), np.array([0.0, -1.0]), 1.0, ("ot",), 2.0, 2.0)
    t2 = table2(study)
    assert {"q_shoulder_deg", "q_elbow_deg", "E_dk_shoulder", "E_dk_elbow"} <= set(t2.columns)
    assert list(plans_long({("best", 1): np.array([[1.0, 2.0]])}, robot).columns)[-2:] == ["q_shoulder_deg",
                                                                                           "q_elbow_deg"]
    assert main(["design", "--robot", str(tmp_path / "arm.yaml"), "--test-pose-deg", "60,30", "--force-N", "0,-1",
                 "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["joint_names"] == ["shoulder", "elbow"] and round(out["O_t"], 4) == 0.3869  # Table 3's O_t
    plain = planar_robot([0.6, 0.4])
    assert plain.joint_columns("q", "_deg") == ["q1_deg", "q2_deg"] and plain.joint_names == ("1", "2")


def test_measured_data_accept_joint_names_beside_numbers(root, tmp_path, kuka):
    """A CSV with q_<name>_deg columns reads the same joint angles as the same CSV with q1_deg ...; both forms of
    one joint, an unknown name and a named column in another unit are refused naming the column."""
    src = root / "tests/data/discrepancy/case4_kuka_coupling.a.csv"
    text = src.read_text()
    named = text.replace("q1_deg", "q_a1_deg").replace("q4_deg", "q_a4_deg").replace("q6_deg", "q_a6_deg")
    (tmp_path / "named.csv").write_text(named)
    ref = read_measurements(src, kuka[0])
    got = read_measurements(tmp_path / "named.csv", kuka[1])
    np.testing.assert_array_equal(got.q, ref.q)
    np.testing.assert_array_equal(got.dp, ref.dp)
    assert not any("q_a" in note for note in got.notes)  # every named column is used
    bad = {"q_a1_deg,q1_deg": "joint a1 is given twice", "q_a7_deg": "q_<name>_deg with a name of a1, a2",
           "q_a1_rad": "expected joint angles in deg", "q7_deg": "got a column q7_deg"}
    for header, message in bad.items():
        cols = header.split(",")
        first = text.splitlines()[0].replace("q1_deg", cols[0]) + ("," + cols[1] if len(cols) > 1 else "")
        rows = [r + (",1" if len(cols) > 1 else "") for r in text.splitlines()[1:]]
        (tmp_path / "bad.csv").write_text("\n".join([first] + rows) + "\n")
        with pytest.raises(InputError) as err:
            read_measurements(tmp_path / "bad.csv", kuka[1])
        assert message in str(err.value) and "bad.csv" in str(err.value) and "column" in str(err.value)


def _urdf_file(tmp_path, root, body: str, urdf: str | None = None) -> str:
    (tmp_path / "arm.urdf").write_text(urdf if urdf is not None else (root / "config/robots/kuka_kr210_r2700.urdf")
                                       .read_text())
    path = tmp_path / "robot.yaml"
    path.write_text("name: u\nkind: urdf\nurdf: arm.urdf\n" + body)
    return str(path)


GOOD = "base_frame: base_link\ntip_frame: tool0\ntool_m: [-0.15, 0, 0.3]\n"
PRISMATIC = """<robot name="p"><link name="a"/><link name="b"/><link name="c"/>
<joint name="slide" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
<limit lower="0" upper="1" effort="1" velocity="1"/></joint>
<joint name="turn" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""
MIMIC = PRISMATIC.replace('type="prismatic"', 'type="revolute"').replace(
    '<axis xyz="1 0 0"/>', '<axis xyz="0 0 1"/><mimic joint="turn"/>').replace("<robot", "<robot")


@pytest.mark.parametrize("body, urdf, field, message", [
    ("base_frame: base_link\n", None, "<top level>", "tip_frame"),
    (GOOD.replace("tool0", "tool9"), None, "tip_frame",
     "no link or frame 'tool9'; its links, the closest names first: tool0, base_link"),
    (GOOD.replace("base_link", "link_3").replace("tool0", "link_1"), None, "base_frame", "is not on the path"),
    (GOOD + "joints: [a1, a3, a4, a5, a6]\n", None, "fixed_joints_deg.a2",
     "held at 0 deg (the default), outside its limits [-140, -5]"),
    (GOOD + "joints: [a1, a3, a4, a5, a6]\nfixed_joints_deg: {a2: -200}\n", None, "fixed_joints_deg.a2",
     "held at -200 deg"),
    (GOOD + "joints: [a2, a1, a3, a4, a5, a6]\n", None, "joints", "in their order from base to tip"),
    (GOOD + "joints: [a1, a9]\n", None, "joints[1]", "joint 'a9' is not in the chain"),
    (GOOD + "joints: [a1, a2, a3, a4, a5]\nfixed_joints_deg: {a5: 0}\n", None, "fixed_joints_deg.a5", "moves"),
    # a URDF file may narrow its URDF's limits (issue 24): one pair per moving joint, each within the URDF's
    (GOOD + "joint_limits_deg: [[-1, 1]]\n", None, "joint_limits_deg", "expected 6 [lower, upper] pairs"),
    (GOOD + "joint_limits_deg: [[-200, 1], [-10, -6], [-1, 1], [-1, 1], [-1, 1], [-1, 1]]\n", None,
     "joint_limits_deg[0]", "within joint a1's URDF limits"),
    (GOOD + "compliances_rad_per_Nm: [1.0e-6]\n", None, "compliances_rad_per_Nm", "expected 6 values"),
    (GOOD, "<robot name='x'><link name='a'>", "urdf", "not well-formed XML"),
    (GOOD, "<!DOCTYPE r [<!ENTITY a 'b'>]><robot name='x'/>", "urdf", "entity or DOCTYPE"),
    (GOOD, "<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
           "<child link='b'/><axis xyz='0 0 1'/></joint></robot>", "urdf", "does not specify limits"),
    ("base_frame: a\ntip_frame: c\n", PRISMATIC, "urdf", "'slide' of the chain from 'a' to 'c' is not revolute"),
    ("base_frame: a\ntip_frame: c\n", MIMIC, "urdf", "mimics another joint"),
    ("base_frame: b\ntip_frame: c\n", PRISMATIC.replace('lower="-1" upper="1"', 'lower="-20" upper="1"'),
     "urdf", "expected within +-720 deg"),
])
def test_bad_urdf_robot_files_get_one_clear_error(root, tmp_path, body, urdf, field, message):
    path = _urdf_file(tmp_path, root, body, urdf)
    with pytest.raises(InputError) as err:
        load_robot(path)
    text = str(err.value)
    assert text.startswith(f"{path}: field '{field}'") and message in text and "\n" not in text, text


def test_a_missing_urdf_is_named_and_the_cli_prints_one_line(root, tmp_path, capsys):
    path = _urdf_file(tmp_path, root, GOOD)
    (tmp_path / "arm.urdf").unlink()
    assert main(["design", "--robot", path, "--test-pose-deg", TEST_POSE, "--force-N", FORCE, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "field 'urdf': no such file" in err and "arm.urdf" in err


def test_a_joint_subset_of_the_urdf_is_the_dh_arm_with_that_joint_held(root, tmp_path, kuka, rng):
    """joints: a1..a5 with a6 held at 30 deg gives the DH arm's position and Jacobian columns 1-5 at q6 = 30."""
    path = _urdf_file(tmp_path, root, GOOD + "joints: [a1, a2, a3, a4, a5]\nfixed_joints_deg: {a6: 30}\n")
    sub = load_robot(path)
    q = rng.uniform(-np.pi, np.pi, (50, 5))
    full = np.column_stack([q, np.full(50, np.radians(30))])
    np.testing.assert_allclose(sub.fk(q), kuka[0].fk(full), atol=1e-12)
    np.testing.assert_allclose(sub.jacobian(q), kuka[0].jacobian(full)[..., :5], atol=1e-12)
    assert sub.joint_names == ("a1", "a2", "a3", "a4", "a5")


def test_the_workflow_lists_the_urdf_as_an_input_of_its_robot(root):
    """robot_inputs (the rules' ``urdf`` input): a URDF robot file reads its URDF, other kinds nothing."""
    from stiffcal.model.robot import robot_inputs

    assert robot_inputs(KUKA_URDF) == ["config/robots/kuka_kr210_r2700.urdf"]
    assert robot_inputs(KUKA_DH) == [] and robot_inputs("no/such/robot.yaml") == []
    rules = (root / "workflow/rules/studies.smk").read_text() + (root / "workflow/rules/discrepancy.smk").read_text()
    assert rules.count("urdf=lambda wc: robot_inputs(") == 2  # discrepancy, discriminate
    assert rules.count("urdf=study_files,") == 3  # design, plans, summary (robot_inputs and the cell's files)


def test_a_cell_lists_the_collision_meshes_pinocchio_reads(tmp_path):
    """With a cell, the collision meshes are inputs too (an edited mesh reruns the robot's jobs and goes into the
    archive): the files robot_inputs names are exactly those Pinocchio's geometry model of the URDF reads."""
    import sys

    import pinocchio as pin

    from stiffcal.model.robot import robot_inputs
    from stiffcal.model.workcell import _package_dirs

    sys.path.insert(0, str(Path(__file__).parent))
    import real_arms

    if real_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed (requirements-test.lock pins it)")
    robot_file = real_arms.write_robot_file("panda", tmp_path)
    urdf = str(real_arms.robots_dir() / real_arms.ARMS["panda"][0])
    model = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION, package_dirs=_package_dirs(Path(urdf)))
    read = {str(Path(g.meshPath).resolve()) for g in geom.geometryObjects if Path(g.meshPath).is_file()}  # not "BOX"
    listed = robot_inputs(robot_file)
    assert listed[0] == urdf and listed[-1].endswith("panda.srdf")
    assert set(listed[1:-1]) == read and len(read) >= 5
    without_cell = tmp_path / "plain.yaml"
    without_cell.write_text(robot_file.read_text().split("cell:")[0])
    assert robot_inputs(without_cell) == [urdf]
    # a cell given beside the robot file (a design study's ``cell:`` in the config) reads the same meshes: they are
    # the study's inputs and the archive's files (a fresh user's inline cell listed none)
    assert set(robot_inputs(without_cell, cell=True)[1:]) == read
    from stiffcal.workflow.archive import config_files

    study = {"studies": [{"name": "s", "robot": str(without_cell), "cell": {"floor_m": 0.0}}]}
    assert {str(p) for p in config_files(study)} == {str(without_cell), urdf, *read}
    assert {str(p) for p in config_files({"studies": [{**study["studies"][0], "cell": None}]})} == {str(without_cell),
                                                                                                     urdf}


@pytest.mark.parametrize("arm, flange", [("ur10", "wrist_3_link"), ("panda", "panda_link7"),
                                         ("jaco2", "j2s6s200_link_6")])
def test_load_robot_takes_a_urdf_path_and_guesses_the_base_and_the_flange(tmp_path, arm, flange):
    """load_robot('x.urdf') failed with 'not valid YAML': now the arm from the root link to the end of its longest
    chain of revolute joints (the flange that the tool frames and the gripper's fingers hang from), the same
    kinematics and masses as a robot file naming those frames; the frames can be named instead."""
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    import real_arms

    if real_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed (requirements-test.lock pins it)")
    urdf = real_arms.robots_dir() / real_arms.ARMS[arm][0]
    guessed = load_robot(urdf)
    assert guessed.urdf_info["tip_frame"] == flange
    named = tmp_path / "named.yaml"
    named.write_text(f"name: n\nkind: urdf\nurdf: {urdf}\nbase_frame: {guessed.urdf_info['base_frame']}\n"
                     f"tip_frame: {flange}\n")
    by_file = load_robot(named)
    q = np.random.default_rng(1).uniform(-1, 1, (5, guessed.n_joints))
    np.testing.assert_allclose(guessed.fk(q), by_file.fk(q), atol=1e-12)
    np.testing.assert_allclose(guessed.gravity_torques(q), by_file.gravity_torques(q), atol=1e-9)
    tool = real_arms.ARMS[arm][3]
    assert load_robot(urdf, tip_frame=tool).urdf_info["tip_frame"] == tool


def test_a_urdf_whose_longest_chains_end_apart_asks_for_the_tip(tmp_path):
    """Two branches of three revolute joints from one root (a two-armed robot): no tip is guessed, the message lists
    both ends and names tip_frame; naming one loads that arm; frames given for a robot file are refused."""
    joint = ('<joint name="{n}" type="revolute"><parent link="{a}"/><child link="{b}"/><origin xyz="0.1 0 0.2"/>'
             '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="0" velocity="1"/></joint>')
    links = ["base", "a1", "a2", "a3", "b1", "b2", "b3"]
    chain = [("ja1", "base", "a1"), ("ja2", "a1", "a2"), ("ja3", "a2", "a3"),
             ("jb1", "base", "b1"), ("jb2", "b1", "b2"), ("jb3", "b2", "b3")]
    path = tmp_path / "two_arms.urdf"
    path.write_text('<robot name="two">' + "".join(f'<link name="{x}"/>' for x in links)
                    + "".join(joint.format(n=n, a=a, b=b) for n, a, b in chain) + "</robot>")
    with pytest.raises(InputError, match=r"field 'tip_frame'.*end in .*a3.*b3"):
        load_robot(path)
    assert load_robot(path, tip_frame="b3").joint_names == ("jb1", "jb2", "jb3")
    with pytest.raises(InputError, match="field 'tip_frame'"):
        load_robot(Path(__file__).resolve().parents[1] / "config/robots/paper_2r.yaml", tip_frame="x")


def test_a_continuous_joint_has_no_limits(root):
    """The UR5 of example-robot-data with its shoulder pan (and wrist 3) made continuous: those joints take any
    angle (a test pose of 200 deg is accepted; it was refused as outside [-180, 180]), a revolute joint keeps
    the URDF's limits."""
    import xml.etree.ElementTree as ET

    from stiffcal.api import design
    from stiffcal.planning.study import check_test_inputs

    robot = load_robot(root / "tests/data/urdf/ur5_cont.yaml")
    kinds = {j.get("name"): j.get("type") for j in ET.parse(root / "tests/data/urdf/ur5_cont.urdf").iter("joint")
             if j.get("type")}
    expected = [kinds[name] != "continuous" for name in robot.joint_names]
    assert expected.count(False) >= 1 and robot.limited.tolist() == expected
    q = np.radians([200, -60, 90, -120, -90, 0])
    assert robot.outside_limits(q).tolist() == [False] * 6
    check_test_inputs(robot, np.degrees(q), np.array([0, 0, -50.0]), "test_pose_deg", "force_N")
    lift = robot.joint_names.index("shoulder_lift_joint")
    assert robot.limited[lift] and robot.outside_limits(np.where(np.arange(6) == lift, np.radians(400), q))[lift]
    with pytest.raises(InputError, match="shoulder_lift_joint within the joint limits"):
        design(robot, [0, 400, 90, -120, -90, 0], [0, 0, -50], experiments=2)


def test_an_unknown_tip_frame_lists_every_link_the_closest_first(root, tmp_path):
    """A misspelt tip frame: the message lists every link of the URDF (it cut the list at 12, hiding the one the
    user meant), the closest names first."""
    import re
    import shutil
    import xml.etree.ElementTree as ET

    shutil.copy(root / "tests/data/urdf/franka_panda.urdf", tmp_path / "panda.urdf")
    text = (root / "tests/data/urdf/franka_panda.yaml").read_text().replace("franka_panda.urdf", "panda.urdf")
    (tmp_path / "p.yaml").write_text(text.replace("tip_frame: panda_hand_tcp", "tip_frame: panda_hand_tpc"))
    with pytest.raises(InputError) as err:
        load_robot(tmp_path / "p.yaml")
    assert err.value.field == "tip_frame"
    listed = re.search(r"closest names first: (.*)$", err.value.message).group(1).split(", ")
    links = [link.get("name") for link in ET.parse(tmp_path / "panda.urdf").getroot().iter("link")]
    assert len(links) > 12 and sorted(listed) == sorted(links)
    assert listed[0] == "panda_hand_tcp"
    # a name that begins every link of a numbered chain lists them in the file's order (a fresh user's Z1 'link0'
    # listed link06 .. link00, the one meant last); a name wrong only in case comes first
    for given, first in (("panda_link", "panda_link0"), ("PANDA_LINK3", "panda_link3")):
        (tmp_path / "p.yaml").write_text(text.replace("tip_frame: panda_hand_tcp", f"tip_frame: {given}"))
        with pytest.raises(InputError) as err:
            load_robot(tmp_path / "p.yaml")
        listed = re.search(r"closest names first: (.*)$", err.value.message).group(1).split(", ")
        assert listed[0] == first
        if given == "panda_link":
            numbered = [n for n in links if n.startswith("panda_link")]
            assert listed[:len(numbered)] == numbered


def test_the_report_says_why_a_joint_is_not_identifiable_as_the_design_does(root):
    """A fresh user's Baxter: the report said every unidentifiable joint's axis 'passes through the measured point',
    also for a vertical axis that a vertical force never turns (the design's notes said so rightly). The report's
    design study now carries the design's own notes: here the KUKA under a vertical force, whose joint 1 is never
    turned, and the Panda, whose joint 7's axis passes through the tool point."""
    from stiffcal.report.html import robot_summary
    from stiffcal.planning.study import study_from_entry

    for robot, pose, force, joint, why in (
            ("config/robots/kuka_kr210_r2700.yaml", [20, -60, 110, 30, 45, -20], [0, 0, -1000], "1", "never turned"),
            ("tests/data/urdf/franka_panda.yaml", [0, -30, 0, -120, 0, 90, 45], [20, 0, -30], "panda_joint7",
             "passes through")):
        entry = {"name": "s", "robot": robot, "force_N": force, "sigma_m": 1e-5, "test_pose_deg": pose}
        r = robot_summary(study_from_entry(entry, root))
        assert r["inert"] == [joint] and len(r["inert_notes"]) == 1 and why in r["inert_notes"][0]


def test_the_report_counts_the_identifiable_compliances(root, tmp_path):
    """The Franka Panda with the tool point on joint 7's axis: that compliance cannot be identified, so a single
    pose gives 3 equations for 6 compliances, as the design says (it said 7 in the report)."""
    import re

    import jinja2

    import stiffcal
    from stiffcal.report.html import TEMPLATE_DIR, fmt, robot_summary
    from stiffcal.planning.study import study_from_entry

    entry = {"name": "panda", "robot": "tests/data/urdf/franka_panda.yaml", "force_N": [20, 0, -30], "sigma_m": 1e-5,
             "test_pose_deg": [0, -30, 0, -120, 0, 90, 45]}
    r = robot_summary(study_from_entry(entry, root))
    assert (r["n"], r["n_params"], r["inert"]) == (7, 6, ["panda_joint7"])
    with pytest.raises(InputError, match="1 give 3 equations for 6 compliances"):
        stiffcal.design(root / entry["robot"], entry["test_pose_deg"], entry["force_N"])
    template = (TEMPLATE_DIR / "report.html.j2").read_text()
    sentence = re.search(r"A single pose gives .*?;", template, re.S).group(0)
    env = jinja2.Environment(undefined=jinja2.StrictUndefined)
    env.filters["num"] = fmt
    text = " ".join(env.from_string(sentence).render(r=r).split())
    assert text.startswith("A single pose gives 3 equations for 6 compliances (of the 7 joints, panda_joint7 is "
                           "left out")


def test_the_report_prints_limits_and_poses_within_the_limits(root):
    """A fresh user's Bravo 7: the report printed a limit of 200.5352 deg as "0 to 201" and a plan's pose at 200.54
    (2 decimals, rounded outward). The limits are printed rounded inward to 2 decimals, each within 0.01 deg of the
    robot's, and the study's poses within them."""
    from stiffcal.model.robot import round_within
    from stiffcal.planning.study import study_from_entry
    from stiffcal.report.html import robot_summary

    entry = {"name": "panda", "robot": "tests/data/urdf/franka_panda.yaml", "force_N": [20, 0, -30], "sigma_m": 1e-5,
             "test_pose_deg": [0, -30, 0, -120, 0, 90, 45]}
    study = study_from_entry(entry, root)
    printed = np.array(robot_summary(study)["limits_deg"], float)
    true = study.robot.limits_deg
    assert np.all(printed[:, 0] >= true[:, 0]) and np.all(printed[:, 1] <= true[:, 1])
    assert np.abs(printed - true).max() < 0.01
    from stiffcal.report.html import _limits_text

    assert _limits_text(np.array([[0.0, np.degrees(3.5)], [-200.5352, -0.004]])) == [["0", "200.53"],
                                                                                      ["-200.53", "-0.01"]]
    at_limit = np.where(np.arange(7) == 3, true[:, 0] + 1e-4, 0.0)  # joint 4 just inside its lower limit
    assert round_within(at_limit[None], true, 2)[0, 3] >= true[3, 0]


def test_the_report_names_a_compliance_a_study_plan_leaves_nearly_free(root, tmp_path):
    """A fresh reviewer's Panda study: the plan of M = 3 left joint 5 with an sd 1200 times its nominal compliance,
    `design` said so in its notes, the report's study said nothing (the README promises the note). The study's
    section now carries it for every M whose plan does, from versus_m.csv's E[dk^2] (eq. 11) and the robot file's
    compliances: here the plan of M = 3 names panda_joint5 at sqrt(9.2e-3) / 8e-5 = 1200 times its nominal, and the
    plan of M = 4, every joint determined alike, nothing."""
    from stiffcal.planning.study import study_from_entry
    from stiffcal.report.html import study_context

    entry = {"name": "panda", "robot": "tests/data/urdf/franka_panda.yaml", "force_N": [20, 0, -30], "sigma_m": 1e-5,
             "test_pose_deg": [0, -30, 0, -120, 0, 90, 45]}
    study = study_from_entry(entry, root)
    robot = study.robot
    k = np.asarray(robot.compliances, float)
    sd = np.where(np.arange(7) == 4, 1200.0, 0.1) * k  # M = 3: joint 5 nearly free
    sd[6] = np.inf  # joint 7: its axis through the tool point
    rows = [{"m": 3, **dict(zip(robot.joint_columns("E_dk"), sd**2))},
            {"m": 4, **dict(zip(robot.joint_columns("E_dk"), np.where(np.arange(7) == 6, np.inf, (0.1 * k) ** 2)))}]
    paths = {"studym": tmp_path / "versus_m.csv", "studyplans": tmp_path / "plans.csv",
             "studycert": tmp_path / "certificate.csv", "studyfigplan": tmp_path / "a.png",
             "studyfigm": tmp_path / "b.png"}
    import pandas as pd

    pd.DataFrame(rows).to_csv(paths["studym"], index=False)
    plan = {"plan": "M=3", "m": 3, "pose": 1, **dict(zip(robot.joint_columns("q", "_deg"), [0.0] * 7))}
    pd.DataFrame([plan]).to_csv(paths["studyplans"], index=False)
    pd.DataFrame([{"lower_bound": 1.0}]).to_csv(paths["studycert"], index=False)
    for f in ("studyfigplan", "studyfigm"):
        paths[f].write_bytes(b"")
    notes = study_context(study, entry, paths)["plan_notes"]
    assert len(notes) == 1 and notes[0].startswith("the plan of M = 3: this plan determines the compliance of "
                                                   "joint(s) panda_joint5 (1.2e+03 times its nominal)"), notes


def test_plans_csv_prints_a_pose_at_a_joint_limit_within_it(root):
    """A fresh user's Panda study: plans.csv printed q4 = -176.0012 where the URDF's limit is -176.001176 (rounded
    outward to 1e-4 deg); every printed angle lies within its limit, the nearest 1e-4 deg inside it."""
    from stiffcal.paper.tables import plans_long
    from stiffcal.model.robot import load_robot

    robot = load_robot(root / "tests/data/urdf/franka_panda.yaml")
    lo = robot.limits_deg[:, 0]
    pose = np.where(np.arange(7) == 3, lo, 0.0)  # joint 4 at its lower limit
    df = plans_long({("ot", 1): pose[None]}, robot)
    q = df[[c for c in df.columns if c.endswith("_deg")]].to_numpy()[0]
    assert np.all(q >= lo - 1e-12) and abs(q[3] - lo[3]) < 1e-4, (q[3], lo[3])


def test_a_test_pose_of_the_wrong_length_names_the_guessed_chain():
    """A fresh user gave the Z1's URDF (example-robot-data) directly and six angles: the guessed chain ends at the
    gripper's jaw, seven joints, and the message said only 'expected 7 joint angles'. It now lists the joints, the
    frames and how to end the arm elsewhere; with tip_frame link06 the six angles are taken."""
    from real_arms import robots_dir
    from stiffcal.planning.study import check_test_inputs

    if robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    urdf = robots_dir() / "z1_description/urdf/z1.urdf"
    q, f = [0, 80, -60, -20, 0, 0], np.array([0.0, 0.0, -20.0])
    with pytest.raises(InputError, match=r"7 joints: joint1, .*, jointGripper, from world to gripperMover; a robot "
                                         r"file's tip_frame"):
        check_test_inputs(load_robot(urdf), q, f, "test_pose_deg", "force_N")
    assert check_test_inputs(load_robot(urdf, tip_frame="link06"), q, f, "test_pose_deg", "force_N").size == 6
