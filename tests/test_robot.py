"""Robot files (validation with clear messages) and kinematics (Jacobian against finite differences)."""

import numpy as np
import pytest

from stiffcal.errors import InputError
from stiffcal.model.robot import cross_columns, load_robot, planar_fk, planar_jacobian, planar_robot


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_jacobian_matches_central_finite_differences(n, rng):
    links = rng.uniform(0.1, 1.0, n)
    q = rng.uniform(-np.pi, np.pi, (20, n))
    J = planar_jacobian(links, q)
    h = 1e-6
    fd = np.stack([(planar_fk(links, q + h * np.eye(n)[j]) - planar_fk(links, q - h * np.eye(n)[j])) / (2 * h)
                   for j in range(n)], axis=-1)
    assert J.shape == (20, 2, n)
    np.testing.assert_allclose(J, fd, atol=1e-8)


def test_cross_columns_is_numpys_cross_bit_for_bit(rng):
    # the DH Jacobian's columns: the same numbers and memory layout as np.cross (results stay byte-identical)
    u, v = rng.normal(size=(7, 6, 3)), rng.normal(size=(1, 6, 3))
    ref = np.swapaxes(np.cross(u, v), -1, -2)
    got = cross_columns(u, v)
    assert got.shape == ref.shape == (7, 3, 6) and got.strides == ref.strides
    assert np.array_equal(got, ref)


def test_forward_kinematics_is_eq_18(paper_robot):
    q1, q2 = np.radians([60.0, 30.0])
    x = 0.6 * np.cos(q1) + 0.4 * np.cos(q1 + q2)
    y = 0.6 * np.sin(q1) + 0.4 * np.sin(q1 + q2)
    np.testing.assert_allclose(paper_robot.fk(np.array([q1, q2])), [x, y], rtol=1e-14)


def test_jacobian_batches_over_any_leading_shape(paper_robot, rng):
    q = rng.uniform(-3, 3, (4, 5, 2))
    J = paper_robot.jacobian(q)
    assert J.shape == (4, 5, 2, 2)
    np.testing.assert_allclose(J[2, 3], paper_robot.jacobian(q[2, 3]))


def test_paper_robot_file(paper_robot):
    assert paper_robot.n_joints == 2
    np.testing.assert_array_equal(paper_robot.links_m, [0.6, 0.4])
    assert not paper_robot.has_joint_limits


_TWO_DH = ("name: x\nkind: spatial\ndh_convention: standard\n"
           "dh: [{a_m: 0.5, alpha_deg: 90, d_m: 0.3}, {a_m: 0.4, alpha_deg: 0, d_m: 0}]\n")
BAD_FILES = {
    "missing_links": ("name: x\nkind: planar\n", "links_m"),
    "negative_link": ("name: x\nkind: planar\nlinks_m: [0.6, -0.4]\n", "links_m[1]"),
    "zero_link": ("name: x\nkind: planar\nlinks_m: [0.0]\n", "links_m[0]"),
    "unknown_kind": ("name: x\nkind: delta\nlinks_m: [0.6, 0.4]\n", "kind"),
    "non_numeric": ("name: x\nkind: planar\nlinks_m: [0.6, abc]\n", "links_m[1]"),
    "limits_count": ("name: x\nkind: planar\nlinks_m: [0.6, 0.4]\njoint_limits_deg: [[-90, 90]]\n",
                     "joint_limits_deg"),
    "limits_order": ("name: x\nkind: planar\nlinks_m: [0.6, 0.4]\njoint_limits_deg: [[-90, 90], [10, -10]]\n",
                     "joint_limits_deg[1]"),
    "typo_field": ("name: x\nkind: planar\nlinks_m: [0.6]\nlink_m: [1]\n", "<top level>"),
    # a fresh user's tool point and a target in millimetres (a 104 m tool on a 0.95 m arm was planned in silence)
    "tool_in_mm": (f"{_TWO_DH}tool_m: [100, 30, 0]\n", "tool_m"),
    "target_in_mm": (f"{_TWO_DH}tool_m: [0.1, 0, 0]\ntargets:\n  A: [30, 0, 50]\n", "targets.A"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_robot_file_names_file_and_field(case, tmp_path):
    text, field = BAD_FILES[case]
    path = tmp_path / f"{case}.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        load_robot(path)
    msg = str(err.value)
    assert str(path) in msg and f"'{field}'" in msg, msg
    assert "\n" not in msg


def test_yaml_syntax_error_and_missing_file(tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("name: x\nlinks_m: [0.6, 0.4\n")
    with pytest.raises(InputError, match=r"broken.yaml: not valid YAML at line"):
        load_robot(bad)
    with pytest.raises(InputError, match="cannot read file"):
        load_robot(tmp_path / "absent.yaml")


def test_joint_limits_are_read_in_radians(tmp_path):
    path = tmp_path / "lim.yaml"
    path.write_text("name: x\nkind: planar\nlinks_m: [0.6, 0.4]\njoint_limits_deg: [[-90, 90], [0, 150]]\n")
    r = load_robot(path)
    assert r.has_joint_limits
    np.testing.assert_allclose(np.degrees(r.joint_limits_rad), [[-90, 90], [0, 150]])


def test_in_memory_robot_matches_file(paper_robot):
    r = planar_robot([0.6, 0.4])
    q = np.radians([[10.0, 20.0], [-70.0, 130.0]])
    np.testing.assert_array_equal(r.jacobian(q), paper_robot.jacobian(q))


def _rotation_vector(R):
    """Small-angle rotation vector of a rotation matrix close to I: the axial vector of (R - R^T) / 2."""
    return 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)


def _example_of(kind: str, root):
    """A robot file of ``kind`` among the shipped ones (config/robots/): every registered kind must have one."""
    import yaml

    for path in sorted((root / "config/robots").glob("*.yaml")):
        doc = yaml.safe_load(path.read_text())
        if isinstance(doc, dict) and doc.get("kind") == kind:
            return load_robot(path)
    raise AssertionError(f"no robot file of kind {kind!r} in config/robots: add an example (docs/extending.md)")


def test_the_schema_and_the_field_checks_are_the_kinds_registry(root):
    """The robot schema's kind enum, its per-kind requirements and its fields are the registry's
    (stiffcal.model.robot.ROBOT_KINDS): a new kind cannot be half-registered."""
    import yaml

    from stiffcal.model.robot import FIELD_KINDS, ROBOT_KINDS

    schema = yaml.safe_load((root / "src/stiffcal/schemas/robot.schema.yaml").read_text())
    assert schema["properties"]["kind"]["enum"] == list(ROBOT_KINDS)
    assert sorted(c["if"]["properties"]["kind"]["const"] for c in schema["allOf"]) == sorted(ROBOT_KINDS)
    assert set(FIELD_KINDS) <= set(schema["properties"])
    for kind in ROBOT_KINDS.values():
        assert kind.task_dim in (2, 3)
        required = next(c["then"]["required"] for c in schema["allOf"] if c["if"]["properties"]["kind"]["const"]
                        == kind.name)
        assert set(required) <= set(kind.fields), (kind.name, required)


@pytest.mark.parametrize("kind", list(__import__("stiffcal.model.robot", fromlist=["x"]).ROBOT_KINDS))
def test_every_kind_s_kinematics_agree_with_each_other(kind, root, rng):
    """Conformance of a registered kind: fk's dimension is task_dim, the Jacobian is fk's finite difference, the
    drawn arm starts at the base and ends at the measured point with n_segments segments, the reach bounds the
    measured point, and link frame j turns with joints 1..j only."""
    robot = _example_of(kind, root)
    n, d = robot.n_joints, robot.task_dim
    q = rng.uniform(*robot.joint_limits_rad.T, (5, n))
    x = robot.fk(q)
    assert x.shape == (5, d)
    h = 1e-6
    fd = np.stack([(robot.fk(q + h * np.eye(n)[j]) - robot.fk(q - h * np.eye(n)[j])) / (2 * h) for j in range(n)], -1)
    np.testing.assert_allclose(robot.jacobian(q), fd, atol=1e-7 * max(robot.reach_m, 1.0))
    pts = robot.link_points(q)
    assert pts.shape == (5, robot.n_segments + 1, d)
    np.testing.assert_allclose(pts[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(pts[:, -1], x, atol=1e-12)
    assert np.all(np.linalg.norm(x, axis=-1) <= robot.reach_m * (1 + 1e-12))
    R, o = robot.link_frames(q)
    assert R.shape == (5, n, 3, 3) and o.shape == (5, n, 3)
    for j in range(n):
        R2, o2 = robot.link_frames(q + 0.3 * np.eye(n)[j])
        np.testing.assert_allclose(R2[:, :j], R[:, :j], atol=1e-12)  # frames before j stay
        np.testing.assert_allclose(o2[:, :j], o[:, :j], atol=1e-12)
        assert np.abs(R2[:, j] - R[:, j]).max() > 1e-3  # frame j turns with joint j


@pytest.mark.parametrize("kind", list(__import__("stiffcal.model.robot", fromlist=["x"]).ROBOT_KINDS))
def test_joint_frames_and_tool_frame_give_the_6d_jacobian_of_any_tip_point(kind, root, rng):
    """The interface every robot kind provides: the linear rows axes x (p + R t - origins) and the angular rows
    axes are the derivatives of the point's position and of the tip frame's orientation (finite differences of
    tool_frame alone), for the tool point and for another point of the tip frame."""
    robot = _example_of(kind, root)
    n = robot.n_joints
    q = rng.uniform(-np.pi, np.pi, (6, n))
    origins, axes = robot.joint_frames(q)
    R, p = robot.tool_frame(q)
    assert origins.shape == axes.shape == (6, n, 3) and R.shape == (6, 3, 3) and p.shape == (6, 3)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=-1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    h = 1e-6
    for t in (np.zeros(3) if robot.tool_m is None else robot.tool_m, np.array([0.07, -0.11, 0.05])):
        lin = np.cross(axes, (p + R @ t)[:, None, :] - origins)  # (6, n, 3)
        for j in range(n):
            Rp, pp = robot.tool_frame(q + h * np.eye(n)[j])
            Rm, pm = robot.tool_frame(q - h * np.eye(n)[j])
            np.testing.assert_allclose(lin[:, j], ((pp + Rp @ t) - (pm + Rm @ t)) / (2 * h), atol=1e-8)
            np.testing.assert_allclose(axes[:, j], _rotation_vector(Rp @ np.swapaxes(Rm, -1, -2)) / (2 * h), atol=1e-8)
    tool = np.zeros(3) if robot.tool_m is None else robot.tool_m
    np.testing.assert_allclose((p + R @ tool)[:, :robot.task_dim], robot.fk(q), atol=1e-14)


def test_angles_at_a_limit_are_printed_within_it(rng):
    """A fresh user's strict check found poses at the Panda's 2.8973 rad limit printed as 166.003062 deg, 2.9e-10
    rad past it (rounding outward); round_within rounds a value past a limit to the limit rounded inward, and
    leaves every other value as np.round gives it (checked against np.round on random angles within the limits)."""
    from stiffcal.model.robot import round_within

    lim = np.degrees([[-2.8973, 2.8973], [-1.7628, 1.7628]])
    at = np.array([[lim[0, 1], lim[1, 0]]])
    out = round_within(at, lim)
    assert np.all(np.radians(out) <= np.radians(lim[:, 1])) and np.all(np.radians(out) >= np.radians(lim[:, 0]))
    assert np.all(np.abs(out - at) <= 1e-6)
    inner = rng.uniform(lim[:, 0] + 1e-3, lim[:, 1] - 1e-3, (1000, 2))
    np.testing.assert_array_equal(round_within(inner, lim), np.round(inner, 6) + 0.0)
    np.testing.assert_array_equal(round_within(inner, None, 3), np.round(inner, 3) + 0.0)
