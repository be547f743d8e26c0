"""The cell a robot stands in (stiffcal.model.workcell, issue 24): every pose of every plan feasible, checked by code
that is not the code under test.

* Real arms nobody here wrote (UR10, Panda, Kinova Jaco2 of example-robot-data, pinned in requirements-test.lock):
  every pose of the plans of ``stiffcal design``, of a design study (the workflow's functions) and of
  ``discriminate`` is checked pose by pose against the URDF's own collision meshes with Pinocchio and coal
  directly (the pairs of adjacent links and the SRDF's disabled pairs left out, as the issue's user checked them),
  and the height of every joint above the mounting plane from Pinocchio's frames.
* Planar and DH arms (capsules): every pose against a dense sampling of the links written here.
* The geometry (segment distances, distances to boxes and cylinders) against coal and brute force.
* Measurement loads apart from the test wrench: O_t scales with their size as the model says, the hanging-mass
  experiment on a UR10 is planned (joint 1 left out with a note), its cable free by an independent check.
* One answer per input: API, CLI and workflow give identical plans under 1 and 2 BLAS threads (subprocesses).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import stiffcal
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.model.robot import load_robot

sys.path.insert(0, str(Path(__file__).resolve().parent))
import real_arms  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config/robots/paper_2r.yaml"
needs_arms = pytest.mark.skipif(real_arms.robots_dir() is None, reason="example-robot-data is not installed")


# --- an independent check of URDF poses: Pinocchio and coal on the URDF's meshes -----------------------------

class MeshCheck:
    """The URDF's collision meshes, every pair but adjacent links (a joint and its parent) and the SRDF's
    disabled pairs; poses of the chain's joints mapped to Pinocchio's configuration here (continuous joints as
    cos, sin; every other joint neutral)."""

    def __init__(self, name):
        import pinocchio as pin

        urdf, srdf, base, *_ = real_arms.ARMS[name]
        root = real_arms.robots_dir()
        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(root / urdf))
        self.geom = pin.buildGeomFromUrdf(self.model, str(root / urdf), pin.GeometryType.COLLISION,
                                          package_dirs=[str(root.parent.parent)])
        self.geom.addAllCollisionPairs()
        if srdf:
            pin.removeCollisionPairs(self.model, self.geom, str(root / srdf))
        keep = []
        for cp in self.geom.collisionPairs:
            ja = self.geom.geometryObjects[cp.first].parentJoint
            jb = self.geom.geometryObjects[cp.second].parentJoint
            if ja != jb and self.model.parents[ja] != jb and self.model.parents[jb] != ja:
                keep.append(cp)
        self.geom.removeAllCollisionPairs()
        for cp in keep:
            self.geom.addCollisionPair(cp)
        self.data, self.gdata = self.model.createData(), pin.GeometryData(self.geom)
        self.base = self.model.getFrameId(base)

    def configuration(self, names, q):
        x = self.pin.neutral(self.model)
        for name, a in zip(names, q):
            j = self.model.getJointId(name)
            i = self.model.idx_qs[j]
            if self.model.nqs[j] == 2:
                x[i], x[i + 1] = np.cos(a), np.sin(a)
            else:
                x[i] = a
        return x

    def collides(self, names, q) -> bool:
        return bool(self.pin.computeCollisions(self.model, self.data, self.geom, self.gdata,
                                               self.configuration(names, q), False))

    def lowest_joint(self, names, q) -> float:
        """The smallest height [m] of a joint above the base frame's xy plane (the mounting plane)."""
        self.pin.framesForwardKinematics(self.model, self.data, self.configuration(names, q))
        base = self.data.oMf[self.base]
        return min(float((base.inverse() * self.data.oMi[j]).translation[2]) for j in range(1, self.model.njoints))

    def bad(self, names, poses_deg) -> tuple[int, int]:
        """(poses in collision, poses with a joint below the plane) of poses (k, n) [deg]."""
        q = np.radians(np.atleast_2d(poses_deg))
        return (sum(self.collides(names, x) for x in q), sum(self.lowest_joint(names, x) < -1e-9 for x in q))


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    if real_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    d = tmp_path_factory.mktemp("arms")
    return {name: real_arms.write_robot_file(name, d) for name in real_arms.ARMS}


@needs_arms
def test_the_independent_check_sees_the_issue_s_infeasible_plans(arms):
    """The check has teeth: without a cell, the plans of the real arms put poses under the floor or into the
    arm itself, as the issue's user found (UR10: 29 of 35 poses below the plane)."""
    name = "ur10"
    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    robot = load_robot(arms[name])
    from dataclasses import replace

    free = replace(robot, cell=None)
    res = stiffcal.design(free, qt, force, experiments=5, sigma=1e-5)
    collisions, below = MeshCheck(name).bad(robot.joint_names, res.poses_deg)
    assert collisions + below > 0


@needs_arms
@pytest.mark.parametrize("name", ["ur10", "panda", "jaco2"])
def test_every_design_pose_of_a_real_arm_is_feasible_by_an_independent_check(arms, name):
    """stiffcal design in the cell (the floor as the mounting plane, self-collision from the URDF's meshes and the
    SRDF): no pose in collision or below the plane by Pinocchio + coal on the meshes; the reported clearance of
    each pose is coal's own smallest distance; the certificate holds (continuum bound <= O_t) and says which
    set it bounds."""
    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    robot = load_robot(arms[name])
    res = stiffcal.design(robot, qt, force, experiments=4, sigma=1e-5)
    check = MeshCheck(name)
    assert check.bad(robot.joint_names, res.poses_deg) == (0, 0)
    assert res.O_t >= res.lower_bound and res.O_t >= res.feasible_lower_bound * (1 - 1e-9)
    assert "every plan within the joint limits" in res.lower_bound_over
    assert "feasible" in res.feasible_lower_bound_over and res.approximate_design["region"] == "feasible candidates"
    assert np.all(res.clearance_m >= -1e-9) and len(res.closest) == 4
    support = np.radians(res.approximate_design["support_deg"])
    assert sum(check.collides(robot.joint_names, x) for x in support) == 0


@needs_arms
def test_a_design_study_of_a_real_arm_through_the_workflow_functions(arms, tmp_path):
    """The workflow's jobs (stiffcal.workflow.pipeline: the design job, one job for every M, the summary): every pose of
    every plan feasible by the independent check, plans.csv with each pose's clearance, the certificate with both
    regions, the figure drawn."""
    import pandas as pd

    from stiffcal.workflow import pipeline

    name = "jaco2"
    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    p = {"name": name, "test_pose_deg": qt, "force_N": force, "sigma_m": 1e-5}
    f = {k: str(tmp_path / k) for k in ("design.json", "support.csv", "cert.csv", "pool.npy", "best.csv", "vm.csv",
                                         "plans.csv", "plan.png", "vm.png")}
    pipeline.approximate_design(p, str(arms[name]), f["design.json"], f["support.csv"], f["cert.csv"], None, name,
                                f["pool.npy"])
    pipeline.study_plans(p, str(arms[name]), [2, 5], 0, f["design.json"], f["pool.npy"], f["best.csv"])
    pipeline.study_summary({**p, "draw_m": 5}, str(arms[name]), f["best.csv"], f["vm.csv"], f["plans.csv"],
                           f["plan.png"], f["vm.png"])
    cert = pd.read_csv(f["cert.csv"])
    assert list(cert.region) == ["joint space", "feasible candidates"]
    plans = pd.read_csv(f["plans.csv"])
    robot = load_robot(arms[name])
    cols = robot.joint_columns("q", "_deg")
    check = MeshCheck(name)
    assert check.bad(robot.joint_names, plans[cols].to_numpy(float)) == (0, 0)
    assert "clearance_m" in plans.columns and (plans.clearance_m > -1e-9).all()
    best = pd.read_csv(f["best.csv"])
    assert best.feasible.all() and (best.O_t >= best.lower_bound).all()
    assert (best.O_t >= best.feasible_lower_bound * (1 - 1e-9)).all()


@needs_arms
def test_the_hanging_mass_experiment_on_a_ur10_is_planned_with_its_cable_free(arms):
    """The standard hanging-mass experiment (--loads hanging, the test pose under a hanging mass too): joint 1,
    which hanging masses never turn, is left out with a note instead of refused; every pose feasible by the
    independent check, and the cable from the tool point down to the floor misses every mesh but the one it hangs
    from (coal on the meshes); the sizes of the loads set O_t as the model says (O_t ~ 1 / |F|^2)."""
    import coal

    name = "ur10"
    robot = load_robot(arms[name])
    qt = real_arms.ARMS[name][5]
    res = stiffcal.design(robot, qt, [0, 0, -98.1], loads="hanging:49.05,98.1,147.15", experiments=4, sigma=1e-5)
    assert res.cov_diag[0] == "inf" or np.isinf(res.cov_diag[0])
    assert any("shoulder_pan_joint is never turned by the measurement loads" in n for n in res.notes)
    check = MeshCheck(name)
    assert check.bad(robot.joint_names, res.poses_deg) == (0, 0)
    tip_joint = check.model.frames[check.model.getFrameId("tool0")].parentJoint
    for q in np.radians(res.poses_deg):
        x = check.configuration(robot.joint_names, q)
        check.pin.updateGeometryPlacements(check.model, check.data, check.geom, check.gdata, x)
        check.pin.framesForwardKinematics(check.model, check.data, x)
        top = check.data.oMf[check.model.getFrameId("tool0")].act(np.array(real_arms.ARMS[name][4]))
        assert top[2] > 0
        cable = coal.Capsule(1e-6, float(top[2]))
        where = coal.Transform3s(np.eye(3), top - [0, 0, top[2] / 2])
        for i, g in enumerate(check.geom.geometryObjects):
            if g.parentJoint == tip_joint:
                continue
            M = check.gdata.oMg[i]
            hit = coal.collide(g.geometry, coal.Transform3s(M.rotation, M.translation), cable, where,
                               coal.CollisionRequest(), coal.CollisionResult())
            assert not hit, (g.name, np.degrees(q))
    from stiffcal.planning.study import Study
    from stiffcal.model.observation import measurement_loads
    from stiffcal.paper.tables import plan_summary

    # the same plan under loads twice as heavy: O_t a quarter (the measurement rows scale with |F|)
    st = Study("x", robot, np.radians(qt), np.array([0, 0, -98.1]), 1e-5, ("ot",), 1, 1, None, None, "tool", 0.0,
               measurement_loads(robot, "hanging:98.1,196.2,294.3"))
    assert float(plan_summary(st, res.poses_deg)["O_t"]) == pytest.approx(res.O_t / 4, rel=1e-9)


# --- planar and DH arms: capsules against a dense sampling of the links written here --------------------------

def _points_along(robot, q_deg, per_link=400):
    """(links, per_link, 3) points along every segment of the drawn arm (as_xyz of link_points), sampled here."""
    from stiffcal.model.robot import as_xyz

    P = as_xyz(robot.link_points(np.radians(q_deg)))
    t = np.linspace(0, 1, per_link)[:, None]
    return np.array([P[k] + t * (P[k + 1] - P[k]) for k in range(len(P) - 1)])


PLANAR_CELL = """name: paper-2r-cell
kind: planar
links_m: [0.6, 0.4]
joint_limits_deg: [[-180, 180], [-150, 150]]
cell:
  floor_m: -0.1
  clearance_m: 0.02
  link_radius_m: 0.04
  boxes:
    - {name: fixture, center_m: [0.45, 0.25], size_m: [0.3, 0.2]}
"""


def _planar_violations(pts, r=0.04, clearance=0.02, floor=-0.1):
    """Dense-sample check of a planar pose in PLANAR_CELL: the height of every sampled point of links 2.. (and
    the far end of link 1) above the floor, and the distance of every sampled point to the fixture rectangle
    (x 0.3..0.6, y 0.15..0.35), each at least r + clearance (less the sampling's resolution); and links 1 and 2
    apart (no self-collision pair is not adjacent for two links)."""
    tol = 1e-3
    above = np.concatenate([pts[1:].reshape(-1, 3), pts[0, -1:]])  # the link from the base stands on the floor
    low = above[:, 1].min() - floor - r
    every = pts.reshape(-1, 3)
    dx = np.maximum(np.maximum(0.3 - every[:, 0], every[:, 0] - 0.6), 0)
    dy = np.maximum(np.maximum(0.15 - every[:, 1], every[:, 1] - 0.35), 0)
    inside = (dx == 0) & (dy == 0)
    box = -np.inf if inside.any() else np.hypot(dx, dy).min() - r
    return low < clearance - tol, box < clearance - tol


@pytest.mark.parametrize("criterion, m", [("ot", 1), ("ot", 2), ("ot", 3), ("a", 3), ("g", 1)])
def test_planar_plans_keep_off_the_floor_and_the_fixture(tmp_path, criterion, m):
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL)
    robot = load_robot(path)
    res = stiffcal.design(path, [60, 30], [0, -1], experiments=m, criterion=criterion)
    for pose in res.poses_deg:
        assert _planar_violations(_points_along(robot, pose)) == (False, False), pose
    for pose in res.approximate_design["support_deg"]:
        assert _planar_violations(_points_along(robot, pose)) == (False, False), pose


def test_the_cell_costs_o_t_and_the_certificate_holds_against_a_brute_force(tmp_path):
    """A floor that cuts into the optimum: the O_t-optimal plan of 2 poses in the cell against every pair of a
    2-degree grid of the poses the dense-sample check (written here) allows: the plan is no worse than the
    best pair of that grid (it polishes in the continuum), the continuum bound is below every pair, and the plan
    costs O_t against the unconstrained optimum."""
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL.replace("floor_m: -0.1", "floor_m: -0.03"))
    robot = load_robot(path)
    res = stiffcal.design(path, [60, 30], [0, -1], experiments=2)
    free = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2)
    assert res.O_t > free.O_t * 1.001  # the cell excludes the unconstrained optimum
    g = np.arange(-180.0, 180.0, 2.0)
    Q = np.stack(np.meshgrid(g, np.arange(-150.0, 150.1, 2.0), indexing="ij"), -1).reshape(-1, 2)
    ok = np.array([_planar_violations(_points_along(robot, q, 60), clearance=0.02 + 4e-3, floor=-0.03) ==
                   (False, False) for q in Q])
    Q = Q[ok]
    from stiffcal.planning.study import Study
    from stiffcal.model.stiffness import pose_information

    st = Study("x", load_robot(PAPER), np.radians([60, 30]), np.array([0.0, -1.0]), 1.0, ("ot",), 1, 1)
    prob = st.problem("ot", 2)
    P = pose_information(prob.rows(np.radians(Q)))
    W = prob.At.T @ prob.At
    a, b, c = P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]
    best = np.inf
    for k in range(len(Q)):  # every pair (k, l >= k): the 2 x 2 information matrix inverted by hand
        A, B, C = a[k] + a[k:], b[k] + b[k:], c[k] + c[k:]
        det = A * C - B * B
        ok = det > 1e-12 * np.abs(det).max()
        best = min(best, float(((W[0, 0] * C - 2 * W[0, 1] * B + W[1, 1] * A)[ok] / det[ok]).min()))
    assert res.O_t <= best * (1 + 1e-6)
    assert res.lower_bound <= best and res.lower_bound <= res.O_t


def test_a_dh_arm_in_a_cell_with_capsules(root):
    """The KUKA KR 210 DH file with capsules, the floor and a column: the plan's poses against a dense sampling of
    the links written here (every sampled point above the floor by the radius, outside the column)."""
    body = (root / "config/robots/kuka_kr210_r2700.yaml").read_text()
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "kuka.yaml"
        path.write_text(body + "\ncell:\n  floor_m: 0.0\n  clearance_m: 0.05\n  link_radius_m: 0.12\n  cylinders:\n"
                        "    - {name: column, center_m: [-0.9, 0.0, 1.0], radius_m: 0.25, length_m: 2.0}\n")
        robot = load_robot(path)
        res = stiffcal.design(path, [20, -60, 110, 30, 45, -20], [500, -300, -800], experiments=3, sigma=1e-5)
    for pose in res.poses_deg:
        pts = _points_along(robot, pose, 200)
        above = pts[1:].reshape(-1, 3)  # the link from the base is the mount
        assert above[:, 2].min() - 0.12 >= 0.05 - 2e-3
        v = pts.reshape(-1, 3) - [-0.9, 0.0, 1.0]
        dr, dz = np.hypot(v[:, 0], v[:, 1]) - 0.25, np.abs(v[:, 2]) - 1.0  # the column's signed distance, here
        sdf = np.hypot(np.maximum(dr, 0), np.maximum(dz, 0)) + np.minimum(np.maximum(dr, dz), 0)
        assert sdf.min() - 0.12 >= 0.05 - 2e-3, pose


# --- the geometry against coal and brute force ----------------------------------------------------------------

def test_segment_distances_against_a_brute_force(rng):
    from stiffcal.model.workcell import segment_distance

    a, b, c, d = (rng.normal(size=(300, 3)) for _ in range(4))
    b[:20] = a[:20]  # degenerate segments (points)
    d[10:30] = c[10:30]
    got = segment_distance(a, b, c, d)
    t = np.linspace(0, 1, 801)[:, None]
    for k in range(0, 300, 7):
        p, r = a[k] + t * (b[k] - a[k]), c[k] + t * (d[k] - c[k])
        brute = np.min(np.linalg.norm(p[:, None] - r[None], axis=-1))
        assert got[k] <= brute + 1e-12 and brute - got[k] <= 2e-3 * (1 + np.linalg.norm(b[k] - a[k]))


def test_distances_to_boxes_and_cylinders_against_coal(rng):
    """Obstacle.segment_sdf against coal's distance of a thin capsule to the same box or cylinder (outside), and
    against a dense sampling of the segment (inside)."""
    import coal

    from stiffcal.model.workcell import Obstacle, rpy_matrix

    R = rpy_matrix([0.3, -0.5, 1.1])
    box = Obstacle("b", "box", center=np.array([0.2, -0.1, 0.4]), rotation=R, half=np.array([0.3, 0.2, 0.1]))
    axis = np.array([0.2, 0.3, 0.93])
    axis /= np.linalg.norm(axis)
    cyl = Obstacle("c", "cylinder", center=np.array([-0.3, 0.2, 0.1]), axis=axis, radius=0.15, half_length=0.4)
    from stiffcal.model.workcell import _rotation_to

    shapes = {"b": (coal.Box(0.6, 0.4, 0.2), coal.Transform3s(R, box.center)),
              "c": (coal.Cylinder(0.15, 0.8), coal.Transform3s(_rotation_to(np.array([0.0, 0, 1]), axis), cyl.center))}
    a, b = rng.uniform(-1, 1, (200, 3)), rng.uniform(-1, 1, (200, 3))
    for o in (box, cyl):
        got = o.segment_sdf(a, b)
        t = np.linspace(0, 1, 2001)[:, None, None]
        sampled = o.sdf(a[None] + t * (b - a)[None]).min(axis=0)
        assert np.all(got <= sampled + 1e-12) and np.all(sampled - got <= 1e-3)
        shape, M = shapes[o.name]
        for k in np.flatnonzero(got > 1e-3)[:40]:
            L = float(np.linalg.norm(b[k] - a[k]))
            cap = coal.Capsule(1e-9, L)
            P = coal.Transform3s(_rotation_to(np.array([0.0, 0, 1]), (b[k] - a[k]) / L), (a[k] + b[k]) / 2)
            res, req = coal.DistanceResult(), coal.DistanceRequest()
            req.gjk_tolerance = 1e-12
            coal.distance(shape, M, cap, P, req, res)
            assert res.min_distance == pytest.approx(got[k], abs=1e-8)


# --- candidates, loads, bad input -------------------------------------------------------------------------------

def test_candidate_poses_from_a_csv_are_filtered_and_the_bound_is_exact_over_them(tmp_path, rng):
    """A FIGAROH-style candidate file: the plan uses only its feasible poses, and the bound (exact over the
    candidates) is below every plan of them (every pair of a brute force), with the plan the best pair."""
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL)
    robot = load_robot(path)
    Q = np.round(rng.uniform([-180, -150], [180, 150], (40, 2)), 2)
    csv = tmp_path / "candidates.csv"
    csv.write_text("id,q1_deg,q2_deg\n" + "\n".join(f"{i},{a},{b}" for i, (a, b) in enumerate(Q)) + "\n")
    res = stiffcal.design(path, [60, 30], [0, -1], experiments=2, candidates=csv)
    ok = np.array([_planar_violations(_points_along(robot, q)) == (False, False) for q in Q])
    feasible = {tuple(q) for q in Q[ok]}
    assert {tuple(np.round(p, 2)) for p in res.poses_deg} <= feasible and "candidate poses" in res.lower_bound_over
    from stiffcal.planning.study import Study
    from stiffcal.paper.tables import plan_summary

    st = Study("x", robot, np.radians([60, 30]), np.array([0.0, -1.0]), 1.0, ("ot",), 1, 1)
    F = Q[ok]
    pairs = np.array([[F[i], F[j]] for i in range(len(F)) for j in range(i, len(F))])
    ot = plan_summary(st, pairs)["O_t"]
    assert res.lower_bound <= ot.min() * (1 + 1e-9) and res.O_t == pytest.approx(ot.min(), rel=1e-9)
    # the same candidates in radians under the joint names (ROS joint states)
    rad = tmp_path / "rad.csv"
    rad.write_text("1,2\n" + "\n".join(f"{float(np.radians(a))!r},{float(np.radians(b))!r}" for a, b in Q) + "\n")
    assert np.allclose(stiffcal.design(path, [60, 30], [0, -1], experiments=2, candidates=rad).poses_deg,
                       res.poses_deg)


def test_candidates_that_cannot_identify_the_model_are_named_not_the_load(tmp_path, root):
    """A fresh user's one-pose candidate file: the error blamed the load ('use a load with another direction') and
    named only the robot file. A planar 3R has three compliances and one pose gives two rows: the message names the
    candidate file and asks for more poses; over the whole joint space the same load identifies them."""
    robot = root / "tests/data/newuser/planar_3r.yaml"
    csv = tmp_path / "one.csv"
    csv.write_text("q1_deg,q2_deg,q3_deg\n10,40,-30\n")
    with pytest.raises(InputError, match=r"at the 1 pose\(s\) of the candidate file.*2 equation\(s\) for 3 "
                                         r"compliances: too few poses; give the candidate file more"):
        stiffcal.design(robot, [0, 60, -30], [0, -100], experiments=3, candidates=csv)
    assert np.isfinite(stiffcal.design(robot, [0, 60, -30], [0, -100], experiments=3).O_t)


def test_the_config_check_refuses_a_study_whose_candidates_are_too_few(tmp_path, root):
    """The same one-pose file as a design study's ``candidates``: the config check let it pass (the docs say it
    refuses plans that cannot identify every compliance), and the study's design job failed after the dry run. It is
    refused before any job, naming the study's field; two poses (4 equations for 3 compliances) pass."""
    from stiffcal.planning.study import design_studies

    one = tmp_path / "one.csv"
    one.write_text("q1_deg,q2_deg,q3_deg\n10,40,-30\n")
    two = tmp_path / "two.csv"
    two.write_text("q1_deg,q2_deg,q3_deg\n10,40,-30\n-50,80,20\n")
    entry = {"name": "r3", "robot": str(root / "tests/data/newuser/planar_3r.yaml"), "test_pose_deg": [0, 60, -30],
             "force_N": [0, -100], "sigma_m": 1e-5, "m_values": [3]}
    with pytest.raises(InputError, match=r"studies\[0\]\.candidates.*1 give 2 equations for 3 compliances"):
        design_studies({"studies": [{**entry, "candidates": str(one)}]}, root, "config.yaml")
    assert "r3" in design_studies({"studies": [{**entry, "candidates": str(two)}]}, root, "config.yaml")


def test_loads_apart_from_the_test_wrench(root):
    """--loads: every pose measured under every load, the force the test pose's alone: O_t scales as |F_t|^2 /
    |F_meas|^2 for the same plan, pushes in a few directions, a loading bar and explicit wrenches are read."""
    base = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=3, loads="directions:4:80")
    assert base.loads == "directions:4:80" and np.asarray(base.loads_N).shape == (4, 2)
    twice = stiffcal.design(PAPER, [60, 30], [0, -2], experiments=3, loads="directions:4:160")
    assert twice.O_t == pytest.approx(base.O_t, rel=1e-6)  # both sizes doubled: the same O_t
    heavier = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=3, loads="directions:4:160")
    assert heavier.O_t == pytest.approx(base.O_t / 4, rel=1e-6)
    bar = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=3, loads="bar:0.2,0:50,100")
    wrench = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=3, loads="wrenches:0,-50,10;20,-40,-5")
    assert np.isfinite(bar.O_t) and np.isfinite(wrench.O_t) and wrench.loads_N.shape == (2, 3)


@pytest.mark.parametrize("args, field", [
    (["--loads", "data"], "--loads"),
    (["--loads", "hanging:-1"], "--loads"),
    (["--loads", "hanging:10,20;forces:50,0;-50,0"], "--loads"),  # two kinds: one kind per set, say how to mix
    (["--joint-limits-deg", "-180:180"], "--joint-limits-deg"),
    (["--joint-limits-deg", "-180,180,0,1"], "--joint-limits-deg[0]"),
    (["--cell", "CELL:clearance_m: -1\n"], "clearance_m"),
    (["--cell", "CELL:boxes: [{center_m: [0, 0, 0], size_m: [1, 1]}]\n"], "boxes[0].center_m"),
    (["--cell", "CELL:link_radius_m: 0.05\nignore_pairs: [[link1, nope]]\n"], "ignore_pairs[0]"),
    (["--cell", "CELL:srdf: x.srdf\nlink_radius_m: 0.05\n"], "srdf"),
    (["--cell", "CELL:floor_m: 0.0\n"], "link_radius_m"),
    (["--cell", "CELL:floor_m: 5.0\nlink_radius_m: 0.05\n"], "cell"),
    # a fresh user's wall at offset_m: -600 (millimetres meant) was accepted, and so never checked
    (["--cell", "CELL:link_radius_m: 0.05\nboxes: [{center_m: [450, 250], size_m: [300, 200]}]\n"], "boxes[0]"),
    (["--cell", "CELL:link_radius_m: 0.05\nfloor_m: -100\n"], "floor_m"),
    (["--candidates", "CSV:q1_deg\n10\n"], "columns"),
    (["--candidates", "CSV:q1_deg,q2_deg\n10,abc\n"], "row 2, column q2_deg"),
    # a fresh user's Baxter: degrees under the joint names (radians) were told "expected within +-720 deg, got -17.7"
    (["--candidates", "CSV:1,2\n0.5,-17.7\n"], "a column named by the joint is in radians: -17.7 rad is -1014.14 deg"),
    (["--candidates", "CSV:q1_deg,q2_deg\n\n,\n"], "no poses"),
    (["--joint-limits-deg", "-90:90,-90:90", "--candidates", "CSV:q1_deg,q2_deg\n10,20\n10,120\n"],
     "row 3, column q2_deg"),
])
def test_bad_cell_loads_and_candidates_are_one_line_and_exit_2(tmp_path, capsys, args, field):
    args = list(args)
    for i, a in enumerate(args):
        if a.startswith(("CELL:", "CSV:")):
            kind, text = a.split(":", 1)
            f = tmp_path / ("cell.yaml" if kind == "CELL" else "c.csv")
            f.write_text(text)
            args[i] = str(f)
    code = main(["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--experiments",
                 "2", *args])
    err = capsys.readouterr()
    assert code == 2 and err.out == "" and len(err.err.strip().splitlines()) == 1 and field in err.err, err.err
    assert "Traceback" not in err.err


def test_discriminate_plans_under_a_loading_bar_whose_moment_turns_with_the_tool(root, tmp_path, capsys):
    """discriminate --loads bar: (refused before: a plan held each point's load fixed): every point of the plan
    carries the bar's moment at its own pose, for the paper's arm m_z = (R(q1 + q2) r) x F with r = (0.2, 0) m in
    the tip frame (the planar rotation written out here)."""
    code = main(["discriminate", "--robot", str(PAPER), "--data", str(root / "data/synthetic_paper_2r_hanging.csv"),
                 "--experiments", "2", "--loads", "bar:0.2,0:100", "--out", str(tmp_path / "out")])
    capsys.readouterr()
    assert code == 0
    out = json.loads((tmp_path / "out/plan.json").read_text())
    assert out["loads"]["kind"] == "bar" and out["loads"]["bar_end_m"] == [0.2, 0.0, 0.0]
    for pt in out["plan"]["points"]:
        a = np.radians(sum(pt["pose_deg"]))
        r = 0.2 * np.array([np.cos(a), np.sin(a)])
        F = np.asarray(pt["force_N"])
        assert pt["moment_Nm"] == pytest.approx([r[0] * F[1] - r[1] * F[0]], abs=1e-3)


def test_discriminate_and_the_verdict_s_plan_keep_their_poses_in_the_cell(root, tmp_path, capsys, monkeypatch):
    """stiffcal discriminate with a cell (hanging masses: the cable too) and the verdict's O_t-optimal plan of the
    extended model: every point of every plan against the dense-sample check."""
    cell = tmp_path / "cell.yaml"
    cell.write_text("floor_m: -0.1\nclearance_m: 0.02\nlink_radius_m: 0.04\nboxes:\n"
                    "  - {name: fixture, center_m: [0.45, 0.25], size_m: [0.3, 0.2]}\n")
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL)
    robot = load_robot(path)
    data = str(root / "data/synthetic_paper_2r_hanging.csv")
    from stiffcal.measured import discrimination as X
    from stiffcal.api import _placed
    from stiffcal.measured.measurements import read_measurements

    placed = _placed(load_robot(PAPER), cell=str(cell))
    meas = read_measurements(data, placed)
    res = X.discriminate(placed, meas, 6, X.load_set("hanging:100,300,600", 2), test_pose=np.radians([60, 30]),
                         test_force=np.array([0.0, -300.0]), m_curve=[6],
                         effort=X.Effort(pool_step_deg=10.0, search_step_deg=10.0, n_starts=1, rounds=1))
    plan = X.to_json(res, data)
    assert plan["cell"] is not None and plan["plan"] is not None and "clearance_m" in plan["plan"]
    # a pose within 1 mm of contact is named, as the design names it (a fresh user's discriminating plan put two
    # Panda links 0.12 mm apart without a word); here the cell's 20 mm clearance keeps every pose far from it
    assert min(plan["plan"]["clearance_m"]) >= 0.02 and not any("of contact" in n for n in plan["notes"])
    import stiffcal.model.workcell as W

    monkeypatch.setattr(W, "clearance", lambda robot, q: (np.full(len(q), 5e-4), ["link2-link1"] * len(q)))
    near = X.to_json(res, data)
    m = len(near["plan"]["poses_deg"])
    assert any(n.startswith(f"{m} pose(s) of the discriminating plan lie within 1 mm of contact (pose 1: 0.5 mm "
                            "(link2-link1)") for n in near["notes"]), near["notes"]
    monkeypatch.undo()
    poses = [p for k in ("plan", "compound", "ot_plan") if plan[k] for p in plan[k]["poses_deg"]]
    assert poses
    for pose in poses:
        pts = _points_along(robot, pose)
        assert _planar_violations(pts) == (False, False), pose
        tip = pts[-1, -1]
        # the cable straight down from the tool point misses link 1 (the link it hangs from is link 2)
        link1 = pts[0]
        below = link1[link1[:, 1] < tip[1]]
        assert np.all(np.abs(below[:, 0] - tip[0]) > 0.04) or not len(below), pose
    verdict = stiffcal.analyse_measurements(PAPER, data, test_pose_deg=[60, 30], force_N=[0, -300], cell=str(cell))
    gain = verdict["gain"] or {}
    plans = (gain.get("optimal_plan_extended_deg") or []) + (gain.get("nominal_plan_deg") or [])
    assert plans
    for pose in plans:
        assert _planar_violations(_points_along(robot, pose)) == (False, False), pose


# --- one answer per input --------------------------------------------------------------------------------------

_RUN = """
import json, sys
sys.path.insert(0, {tests!r})
import stiffcal, real_arms
name = {name!r}
_, _, _, _, _, qt, F = real_arms.ARMS[name]
r = stiffcal.design({robot!r}, qt, F, experiments=3, sigma=1e-5)
print(json.dumps({{"poses": r.poses_deg.tolist(), "O_t": r.O_t}}))
"""


@needs_arms
def test_api_cli_and_workflow_give_one_plan_under_one_and_two_blas_threads(arms, tmp_path):
    """The issue's case (stiffcal.design(ur10, ..., experiments=3) with BLAS allowed 2 threads, as a notebook
    has it, against 1; the UR10 of example-robot-data without a cell, as the issue ran it): the API under 1 and 2
    threads, the CLI under 2, and the workflow's study job give the same plan, bit for bit."""
    name = "ur10"
    robot = str(real_arms.write_robot_file(name, tmp_path).with_name("free.yaml"))
    text = Path(robot).with_name("ur10.yaml").read_text()
    Path(robot).write_text(text[:text.index("cell:")])
    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    outs = []
    for threads in ("1", "2"):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads}
        code = _RUN.format(tests=str(Path(__file__).parent), name=name, robot=robot)
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        outs.append(json.loads(run.stdout.strip().splitlines()[-1]))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    cli = subprocess.run([str(Path(sys.executable).parent / "stiffcal"), "design", "--robot", robot,
                          "--test-pose-deg", ",".join(map(str, qt)), "--force-N", ",".join(map(str, force)),
                          "--sigma", "1e-5", "--experiments", "3", "--quiet"], env=env, capture_output=True,
                         text=True, check=True)
    cli = json.loads(cli.stdout)
    assert outs[0] == outs[1]
    assert np.array_equal(np.round(outs[0]["poses"], 6), np.array(cli["poses_deg"])) and cli["O_t"] == outs[0]["O_t"]
    import pandas as pd

    from stiffcal.workflow import pipeline

    p = {"name": name, "test_pose_deg": qt, "force_N": force, "sigma_m": 1e-5}
    files = [str(tmp_path / f) for f in ("d.json", "s.csv", "c.csv", "pool.npy", "best.csv")]
    pipeline.approximate_design(p, robot, files[0], files[1], files[2], None, name, files[3])
    pipeline.study_plans(p, robot, [3], 0, files[0], files[3], files[4])
    row = pd.read_csv(files[4]).iloc[0]
    from stiffcal.paper.tables import parse_plan

    assert np.allclose(parse_plan(row.poses_deg), np.array(outs[0]["poses"]), atol=5e-5)  # 4 decimals in the file
    assert row.O_t == pytest.approx(outs[0]["O_t"], rel=1e-9)


def test_a_bad_robot_file_cell_names_the_field(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL.replace("link_radius_m: 0.04", "link_radius_m: [0.04]"))
    with pytest.raises(InputError) as err:
        load_robot(path)
    assert err.value.field == "cell.link_radius_m" and "one per segment" in str(err.value)
    path.write_text(PLANAR_CELL.replace("  clearance_m: 0.02\n", "  clearance_m: 0.02\n  colour: red\n"))
    with pytest.raises(InputError) as err:
        load_robot(path)
    assert err.value.field == "cell" and "colour" in str(err.value)


@needs_arms
def test_the_documented_example_of_a_real_arm_loads_and_leaves_poses(tmp_path):
    """The UR10 example of docs/contracts.md ("The cell"), with the path of example-robot-data filled in: it loads,
    and its cell (floor, table, wall, self-collision) leaves some poses and refuses others."""
    text = (ROOT / "docs/contracts.md").read_text(encoding="utf-8")
    block = text[text.index("Example, a real arm"):]
    block = block[block.index("```yaml") + 7:]
    block = block[:block.index("```")]
    path = tmp_path / "ur10_cell.yaml"
    path.write_text(block.replace("/path/to/example-robot-data/robots", str(real_arms.robots_dir())))
    robot = load_robot(path)
    from stiffcal.planning.problem import sample_joint_space
    from stiffcal.model.workcell import feasible

    ok = feasible(robot, sample_joint_space(robot, 8, seed=4))
    assert 0 < ok.mean() < 1 and {o.name for o in robot.cell.obstacles} == {"floor", "table", "wall"}


def test_a_single_pose_from_a_candidate_file_is_its_best_feasible_pose(tmp_path, rng):
    path = tmp_path / "robot.yaml"
    path.write_text(PLANAR_CELL)
    robot = load_robot(path)
    Q = np.round(rng.uniform([-180, -150], [180, 150], (60, 2)), 2)
    csv = tmp_path / "c.csv"
    csv.write_text("q1_deg,q2_deg\n" + "\n".join(f"{a},{b}" for a, b in Q) + "\n")
    res = stiffcal.design(path, [60, 30], [0, -1], experiments=1, candidates=csv)
    from stiffcal.planning.study import Study
    from stiffcal.paper.tables import plan_summary

    st = Study("x", robot, np.radians([60, 30]), np.array([0.0, -1.0]), 1.0, ("ot",), 1, 1)
    ok = np.array([_planar_violations(_points_along(robot, q)) == (False, False) for q in Q])
    ot = plan_summary(st, Q[ok][:, None, :])["O_t"]
    assert res.O_t == pytest.approx(ot.min(), rel=1e-12) and tuple(np.round(res.poses_deg[0], 2)) in set(map(tuple, Q))


@needs_arms
def test_discriminate_and_the_next_round_on_a_real_arm_keep_their_poses_feasible(arms, tmp_path):
    """A UR10 in its cell (the floor, self-collision from its meshes) measured in a lab (3-D pushes, backlash,
    stiffcal.testing.truth with the URDF's inertias): every pose of discriminate's plans and of the next round planned
    from the calibrated model (stiffcal.measured.calibrated.next_round) passes the independent mesh check."""
    from dataclasses import replace

    from stiffcal.measured import calibrated as C
    from stiffcal.measured import discrepancy as D
    from stiffcal.measured import discrimination as X
    from stiffcal.testing import rates as R
    from stiffcal.testing import truth as T
    from stiffcal.measured.measurements import read_measurements

    robot = load_robot(arms["ur10"])
    rng = np.random.default_rng(0)
    log = T.lab_log(robot, R.PROTOCOLS["3-D pushes x 2, repeated"], rng, 10)
    dp = T.measure(robot, T.Truth(R.compliances(robot), gap=np.full(6, 3e-5), tau_gap=1e-3), log, rng)
    data = tmp_path / "log.csv"
    data.write_text(T.lab_csv(robot, log, dp), encoding="utf-8")
    meas = read_measurements(data, robot)
    _, _, _, _, _, qt, force = real_arms.ARMS["ur10"]
    res = X.discriminate(robot, meas, 4, X.load_set("directions:6:300", 3), test_pose=np.radians(qt),
                         test_force=np.array(force, float), m_curve=[4],
                         effort=X.Effort(pool_step_deg=30.0, search_step_deg=30.0, n_starts=1, rounds=1))
    plan = X.to_json(res, str(data))
    poses = [p for k in ("plan", "compound", "ot_plan") if plan.get(k) for p in plan[k]["poses_deg"]]
    pre = D.prepare(robot, meas)
    v = D.verdict_of(robot, pre, gain=False)
    nr = C.next_round(replace(robot, calibration=C.from_analysis(robot, pre, v, data)), np.radians(qt),
                      np.array(force, float), 4)
    poses += np.degrees(nr.poses).tolist()
    assert len(poses) >= 8 and MeshCheck("ur10").bad(robot.joint_names, poses) == (0, 0)


@needs_arms
def test_a_calibrated_file_keeps_its_urdf_and_srdf_from_another_folder(tmp_path):
    """A Panda robot file naming its URDF and SRDF by relative paths; its calibrated.yaml written two folders
    away refers to the same two files (rewritten from its own folder), and reloads with the same cell."""
    from stiffcal.measured import calibrated as C
    from stiffcal.testing import rates as R

    urdf, srdf, base, tip, tool, _, _ = real_arms.ARMS["panda"]
    root = real_arms.robots_dir()
    here = tmp_path / "robots"
    here.mkdir()
    rel = lambda p: os.path.relpath(root / p, here)  # noqa: E731
    path = here / "panda.yaml"
    path.write_text(f"name: panda\nkind: urdf\nurdf: {rel(urdf)}\nbase_frame: {base}\ntip_frame: {tip}\n"
                    f"tool_m: {tool}\ncell:\n  floor_m: 0.0\n  self_collision: true\n  srdf: {rel(srdf)}\n",
                    encoding="utf-8")
    robot = load_robot(path)
    k = R.compliances(robot)
    cal = C.Calibration((), tuple(range(robot.n_joints)), tuple(robot.joint_columns("k")), k, np.diag(k * 0.01) ** 2,
                        (True,) * robot.n_joints, 3, 1e-5)
    out = tmp_path / "results" / "deep"
    out.mkdir(parents=True)
    C.write_calibrated(robot, cal, out)
    back = load_robot(out / "calibrated.yaml")
    assert back.cell.srdf == robot.cell.srdf and Path(back.cell.srdf).is_file()
    q = np.radians([[10, 20, 0, -120, 0, 140, 45]])
    np.testing.assert_allclose(back.fk(q), robot.fk(q), atol=1e-12)
    from stiffcal.model.workcell import feasible
    poses = np.radians(np.random.default_rng(0).uniform(-150, 150, (50, 7)))
    assert np.array_equal(feasible(back, poses), feasible(robot, poses))


def test_the_cell_s_engine_is_shared_by_equal_geometry_and_rebuilt_for_any_other(tmp_path):
    """The feasibility engine is kept per robot geometry, whatever the kind's own fields: a copy with another name or
    compliances shares it; a robot scaled, with other limits or another tool point gets its own (and answers for
    its own bodies: a pose feasible for the short arm collides for the long one)."""
    from dataclasses import replace

    from stiffcal.model.workcell import engine, feasible

    path = tmp_path / "r.yaml"
    path.write_text(PAPER.read_text() + "cell:\n  floor_m: -0.5\n  link_radius_m: 0.02\n  self_collision: false\n")
    robot = load_robot(path)
    assert engine(replace(robot, name="other", compliances=np.array([1e-6, 2e-6]))) is engine(robot)
    longer = robot.scaled(2.0)
    assert engine(longer) is not engine(robot)
    q = np.radians([[-20.0, 0.0]])  # the tip 0.34 m below the base, 0.68 m once scaled: the floor is at -0.5 m
    assert feasible(robot, q)[0] and not feasible(longer, q)[0]
    assert feasible(robot, q)[0]  # asked again after the long arm's engine was built: still the short arm's answer


def test_the_next_round_plans_in_the_cell_the_data_were_analysed_in(tmp_path):
    """A fresh user's Panda: `discrepancy --cell` wrote a calibrated.yaml without the cell, and `design --prior` with
    a robot file without a cell planned poses through the table. The calibrated file keeps the cell given apart,
    and a next round whose robot file has none plans in the prior's, with a note; every pose passes the
    dense-sample check written here. Limits wider than the robot file's are refused (a plan beyond them cannot
    be run), on the command line and in the API."""
    robot_file = tmp_path / "arm.yaml"
    robot_file.write_text(PLANAR_CELL.split("cell:")[0])
    cell_file = tmp_path / "cell.yaml"
    cell_file.write_text("\n".join(line[2:] for line in PLANAR_CELL.split("cell:\n")[1].splitlines()) + "\n")
    out = tmp_path / "out"
    stiffcal.analyse_measurements(str(robot_file), str(ROOT / "data/synthetic_paper_2r.csv"), cell=str(cell_file),
                                  out=str(out), test_pose_deg=[60, 30], force_N=[0, -300], figures=False)
    import yaml

    doc = yaml.safe_load((out / "calibrated.yaml").read_text())
    assert doc["cell"]["floor_m"] == -0.1 and doc["cell"]["boxes"][0]["name"] == "fixture"
    res = stiffcal.plan_next_round(str(out / "calibrated.yaml"), [60, 30], [0, -300], experiments=3,
                                   robot=str(robot_file))
    assert any("the prior's" in n and "is the next round's" in n for n in res["notes"])
    robot = load_robot(robot_file)
    for pose in res["poses_deg"]:
        assert _planar_violations(_points_along(robot, pose)) == (False, False), pose
    # each pose's clearance, as design's: the smallest distance to the floor or the fixture, sampled here
    assert len(res["clearance_m"]) == len(res["closest"]) == 3
    for pose, clear in zip(res["poses_deg"], res["clearance_m"]):
        pts = _points_along(robot, pose)
        above = np.concatenate([pts[1:].reshape(-1, 3), pts[0, -1:]])
        every = pts.reshape(-1, 3)
        dx = np.maximum(np.maximum(0.3 - every[:, 0], every[:, 0] - 0.6), 0)
        dy = np.maximum(np.maximum(0.15 - every[:, 1], every[:, 1] - 0.35), 0)
        sampled = min(above[:, 1].min() + 0.1, np.hypot(dx, dy).min()) - 0.04
        assert clear == pytest.approx(sampled, abs=2e-3), (pose, clear, sampled)
    with pytest.raises(InputError, match=r"joint_limits_deg\[1\].*within joint 2's robot file's limits \[-150, 150\]"):
        stiffcal.design(robot_file, [60, 30], [0, -1], joint_limits_deg=[[-180, 180], [-170, 170]])


def test_limits_given_apart_are_kept_in_the_calibrated_file_and_bound_the_next_round(tmp_path):
    """Noticed last stop: `discrepancy --joint-limits-deg` analysed the data within narrowed limits but wrote a
    calibrated.yaml without them, and `design --prior` planned the next round over the whole range. The file keeps
    them; a next round whose robot file is wider plans within the prior's (with a note); limits that are the file's
    own are not written (a URDF's continuous joint stays continuous)."""
    import yaml

    robot_file = tmp_path / "arm.yaml"
    robot_file.write_text(PLANAR_CELL.split("cell:")[0])
    narrow = [[-100.0, 100.0], [-120.0, 120.0]]
    out = tmp_path / "out"
    stiffcal.analyse_measurements(str(robot_file), str(ROOT / "data/synthetic_paper_2r.csv"), joint_limits_deg=narrow,
                                  out=str(out), test_pose_deg=[60, 30], force_N=[0, -300], figures=False)
    doc = yaml.safe_load((out / "calibrated.yaml").read_text())
    assert doc["joint_limits_deg"] == narrow
    assert np.allclose(load_robot(out / "calibrated.yaml").limits_deg, narrow, rtol=0, atol=1e-9)
    res = stiffcal.plan_next_round(str(out / "calibrated.yaml"), [60, 30], [0, -300], experiments=3,
                                   robot=str(robot_file))
    assert any("the prior's joint limits narrow" in n and "joints 1, 2" in n for n in res["notes"]), res["notes"]
    q = np.asarray(res["poses_deg"])
    assert np.all(q >= np.array(narrow)[:, 0]) and np.all(q <= np.array(narrow)[:, 1]), q
    own = tmp_path / "own"
    stiffcal.analyse_measurements(str(robot_file), str(ROOT / "data/synthetic_paper_2r.csv"), out=str(own),
                                  test_pose_deg=[60, 30], force_N=[0, -300], figures=False)
    assert yaml.safe_load((own / "calibrated.yaml").read_text()).get("joint_limits_deg") == \
        yaml.safe_load(robot_file.read_text()).get("joint_limits_deg")


@needs_arms
def test_a_tip_link_named_like_its_fixed_joint_is_the_link(tmp_path):
    """A fresh user's Unitree Z1: its URDF names a link and the fixed joint to it alike (``gripperStator``); the
    robot file took it as the tip, and the cell's check then raised pinocchio's 'Several frames match'. The tip is
    the link (the body frame first, as the kinematic chain reads it): the same poses are feasible, and the tool
    point is where it is, as with the parent link link06 and the fixed joint's 0.051 m added to the tool offset."""
    root = real_arms.robots_dir()
    cell = ("cell:\n  floor_m: 0.0\n  clearance_m: 0.01\n  self_collision: true\n"
            f"  srdf: {root}/z1_description/srdf/z1.srdf\n")
    files = []
    for tip, tool in (("gripperStator", 0.10), ("link06", 0.151)):
        path = tmp_path / f"z1_{tip}.yaml"
        path.write_text(f"name: z1\nkind: urdf\nurdf: {root}/z1_description/urdf/z1.urdf\nbase_frame: link00\n"
                        f"tip_frame: {tip}\ntool_m: [{tool}, 0.0, 0.0]\n{cell}", encoding="utf-8")
        files.append(load_robot(path))
    from stiffcal.model.workcell import feasible

    q = np.random.default_rng(3).uniform(files[0].joint_limits_rad[:, 0], files[0].joint_limits_rad[:, 1], (64, 6))
    np.testing.assert_allclose(files[0].fk(q), files[1].fk(q), atol=1e-12)
    ok = feasible(files[0], q)
    assert np.array_equal(ok, feasible(files[1], q)) and 0 < ok.sum() < len(q)


@needs_arms
def test_bodies_that_never_move_relative_to_each_other_are_not_a_pair(tmp_path):
    """A fresh user's Baxter (left arm; example-robot-data's URDF and SRDF): the gripper's two fingers, whose own
    joints are not in the chain, were checked as a pair at a constant 16 mm, and every plan's clearance named them,
    hiding the pair that does limit it. Now no checked self pair is fixed relative to itself: for every pair the
    relative placement of its two bodies, computed here by Pinocchio at random poses, changes; the fingers are none."""
    import pinocchio as pin

    from stiffcal.model.workcell import engine, full_configuration

    root = real_arms.robots_dir()
    path = tmp_path / "baxter.yaml"
    path.write_text(f"name: baxter-left\nkind: urdf\nurdf: {root}/baxter_description/urdf/baxter.urdf\n"
                    "base_frame: base\ntip_frame: left_gripper\ncell:\n  self_collision: true\n"
                    f"  srdf: {root}/baxter_description/srdf/baxter_manipulation.srdf\n", encoding="utf-8")
    robot = load_robot(path)
    eng = engine(robot)
    lo, hi = robot.joint_limits_rad[:, 0], robot.joint_limits_rad[:, 1]
    q = np.random.default_rng(4).uniform(lo, hi, (3, robot.n_joints))
    data, gdata = eng.model.createData(), pin.GeometryData(eng.geom)
    placements = []
    for x in full_configuration(robot, eng.model, q):
        pin.updateGeometryPlacements(eng.model, data, eng.geom, gdata, x)
        placements.append([gdata.oMg[i].copy() for i in range(len(eng.geom.geometryObjects))])
    selfs = [(a, b) for (a, b), lab in zip(eng.pairs, eng.labels) if lab[2] == "self"]
    assert selfs
    for a, b in selfs:
        rel = [(P[a].inverse() * P[b]).homogeneous for P in placements]
        assert max(np.abs(r - rel[0]).max() for r in rel[1:]) > 1e-9, eng.labels[eng.pairs.index((a, b))]
    assert any(lab[0].startswith("l_gripper_") for lab in eng.labels)  # the fingers are checked against the rest
    assert not any(lab[0].startswith("l_gripper_") and lab[1].startswith("l_gripper_") for lab in eng.labels)


@needs_arms
def test_a_foreign_srdf_that_disables_nothing_is_refused_naming_its_field(tmp_path):
    """A fresh user's Z1 given the Kinova's SRDF (robot 'kinova', joints j2s6s200_*, no disabled pair) ran with a
    note only; now an SRDF none of whose links and joints (groups, chains, states: read here with the standard
    library's XML parser) is in the URDF is refused, in a robot file as cell.srdf and in a cell file (--cell) as its
    own field srdf; the Z1's own SRDF, which disables nothing either, is taken."""
    import xml.etree.ElementTree as ET

    from stiffcal.model.workcell import feasible

    root = real_arms.robots_dir()
    kinova, z1 = root / "kinova_description/srdf/kinova.srdf", root / "z1_description/srdf/z1.srdf"
    names = {e.get("name") for e in ET.parse(kinova).getroot().iter("joint")}
    urdf = root / "z1_description/urdf/z1.urdf"
    assert names and not names & {e.get("name") for e in ET.parse(urdf).getroot().iter("joint")}
    head = f"name: z1\nkind: urdf\nurdf: {urdf}\nbase_frame: link00\ntip_frame: link06\n"
    for srdf, refused in ((kinova, True), (z1, False)):
        path = tmp_path / f"z1_{srdf.stem}.yaml"
        path.write_text(head + f"cell:\n  floor_m: 0\n  srdf: {srdf}\n", encoding="utf-8")
        if refused:
            with pytest.raises(InputError, match="names links and joints none of which is in the URDF") as err:
                feasible(load_robot(path), np.zeros((1, 6)))
            assert err.value.field == "cell.srdf"
        else:
            assert feasible(load_robot(path), np.radians([[0.0, 60.0, -60.0, 0.0, 0.0, 0.0]])).shape == (1,)
    (tmp_path / "z1.yaml").write_text(head, encoding="utf-8")
    (tmp_path / "cell.yaml").write_text(f"floor_m: 0\nsrdf: {kinova}\n", encoding="utf-8")
    with pytest.raises(InputError) as err:
        stiffcal.design(tmp_path / "z1.yaml", [0, 60, -60, 0, 0, 0], [0, 0, -20], experiments=2,
                        cell=tmp_path / "cell.yaml", cache_dir=None)
    assert err.value.field == "srdf" and "none of which is in the URDF" in str(err.value)


@needs_arms
def test_a_missing_or_foreign_srdf_is_named(tmp_path, capsys):
    """A fresh user's Baxter (left arm, self-collision): without its SRDF the cell left no pose, and the message asked
    to lower a clearance of 0 and move obstacles there were none of; a Panda's SRDF given for it was taken in
    silence, with the same result. Now a foreign SRDF (no link of it in the URDF) is refused naming cell.srdf, and
    without one the message names the links that collide at most random poses (the forearm's two bodies, which the
    SRDF disables), each at the share of the probe poses Pinocchio and coal find here too."""
    import pinocchio as pin

    from stiffcal.model.workcell import PROBE_LOG2, engine, full_configuration, probe_poses

    root = real_arms.robots_dir()
    base = (f"name: baxter-left\nkind: urdf\nurdf: {root}/baxter_description/urdf/baxter.urdf\nbase_frame: base\n"
            "tip_frame: left_gripper\ncell:\n  self_collision: true\n")
    foreign = tmp_path / "foreign.yaml"
    foreign.write_text(base + f"  srdf: {root}/panda_description/srdf/panda.srdf\n", encoding="utf-8")
    assert main(["design", "--robot", str(foreign), "--test-pose-deg", "10,-30,0,60,0,40,0", "--force-N",
                 "0,0,-20", "--experiments", "8", "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "field 'cell.srdf'" in err and "none of which is in the URDF" in err
    bare = tmp_path / "bare.yaml"
    bare.write_text(base, encoding="utf-8")
    assert main(["design", "--robot", str(bare), "--test-pose-deg", "10,-30,0,60,0,40,0", "--force-N", "0,0,-20",
                 "--experiments", "8", "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "these links collide most often: left_lower_forearm and left_upper_forearm_visual" in err, err
    robot = load_robot(bare)
    eng = engine(robot)
    a, b, share = eng.frequent[0]
    geom = pin.buildGeomFromUrdf(eng.model, str(root / "baxter_description/urdf/baxter.urdf"), pin.COLLISION,
                                 package_dirs=[str(root.parent.parent)])
    ia = [i for i, g in enumerate(geom.geometryObjects) if eng.model.frames[g.parentFrame].name == a]
    ib = [i for i, g in enumerate(geom.geometryObjects) if eng.model.frames[g.parentFrame].name == b]
    geom.removeAllCollisionPairs()
    for i in ia:
        for j in ib:
            geom.addCollisionPair(pin.CollisionPair(i, j))
    data, gdata = eng.model.createData(), pin.GeometryData(geom)
    q = full_configuration(robot, eng.model, probe_poses(robot))
    hits = [pin.computeCollisions(eng.model, data, geom, gdata, x, True) for x in q]
    assert len(q) == 2**PROBE_LOG2 and abs(np.mean(hits) - share) <= 1.0 / len(q)


def test_a_test_pose_whose_cable_meets_the_cell_is_said_so(tmp_path):
    """A fresh user's Z1 on a table: hanging masses could not hang at the test pose (the cable lay on the table), and
    the design's note said 'a body within the clearance'. Here the 2-link arm at (60, -90) deg with a box under its
    tool point: link 2 descends from the elbow (0.30, 0.52) m to the tool point (0.646, 0.32) m, and the cable runs
    straight down through the box (0.10 m square about (0.646, 0.15) m), while both links stay more than their
    radius and clearance away from it (by hand below); the note names the cable. Without the box the note is
    absent (the cable hangs clear of link 2, which rises away from the tool point)."""
    q = np.radians([60.0, -90.0])
    elbow = 0.6 * np.array([np.cos(q[0]), np.sin(q[0])])
    tool = elbow + 0.4 * np.array([np.cos(q.sum()), np.sin(q.sum())])
    assert abs(tool[0] - 0.646) < 1e-3 and tool[1] > 0.2 and tool[1] < elbow[1]  # the cable meets the box only
    t = np.linspace(0, 1, 2001)[:, None]
    pts = np.vstack([t * elbow, elbow + t * (tool - elbow)])
    gap = np.maximum(np.abs(pts - [tool[0], 0.15]) - 0.05, 0.0)
    assert np.linalg.norm(gap, axis=1).min() > 0.04 + 0.02  # the links clear the box by radius and clearance
    cell = ("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: -0.1\n"
            "  clearance_m: 0.02\n  link_radius_m: 0.04\n")
    for box, said in ((f"  boxes:\n    - {{name: stand, center_m: [{tool[0]:.4f}, 0.15], size_m: [0.1, 0.1]}}\n", True),
                      ("", False)):
        path = tmp_path / "r.yaml"
        path.write_text(cell + box, encoding="utf-8")
        res = stiffcal.design(path, [60, -90], [0, -100], experiments=2, loads="hanging:50,100")
        assert any("the cable of the hanging masses meets" in n for n in res.notes) == said, res.notes


@needs_arms
def test_self_collision_without_an_srdf_is_noted(tmp_path):
    """A fresh user's Panda without its SRDF: accepted in silence (the pairs the SRDF disables then checked). The
    cell's notes say the SRDF is missing; with it, no such note; with an SRDF that disables nothing, a note says
    so."""
    from stiffcal.model.workcell import cell_notes

    root = real_arms.robots_dir()
    urdf, srdf, base, tip, tool, _, _ = real_arms.ARMS["panda"]
    for given in (False, True):
        path = tmp_path / f"panda_{given}.yaml"
        path.write_text(f"name: panda\nkind: urdf\nurdf: {root / urdf}\nbase_frame: {base}\ntip_frame: {tip}\n"
                        f"tool_m: {tool}\ncell:\n  floor_m: 0.0\n  self_collision: true\n"
                        + (f"  srdf: {root / srdf}\n" if given else ""), encoding="utf-8")
        missing = any("without an SRDF" in n for n in cell_notes(load_robot(path)))
        assert missing == (not given)
        assert not any("disables no pair" in n for n in cell_notes(load_robot(path)))
    # another's Z1 SRDF (example-robot-data's has no disable_collisions entry) given for the arm: accepted in silence
    # before; now a note says it disables nothing
    empty = tmp_path / "empty.srdf"
    empty.write_text('<?xml version="1.0"?>\n<robot name="panda"></robot>\n', encoding="utf-8")
    path = tmp_path / "panda_empty.yaml"
    path.write_text(f"name: panda\nkind: urdf\nurdf: {root / urdf}\nbase_frame: {base}\ntip_frame: {tip}\n"
                    f"tool_m: {tool}\ncell:\n  floor_m: 0.0\n  self_collision: true\n  srdf: {empty}\n",
                    encoding="utf-8")
    assert any("disables no pair of links" in n for n in cell_notes(load_robot(path)))


def test_the_cable_keeps_its_clearance(tmp_path):
    """A fresh user's UR10: the plan's cable of hanging masses passed 27 um from the wrist's mesh, which the cell
    allowed (the cable is a line that must not touch). cable_clearance_m keeps it off: the 2-link arm at (60, -90)
    deg, whose cable runs straight down from the tool point at x = 0.6464 m (link 2 rising away from it), beside a
    box whose edge is at x = 0.6764 m (3.0 cm away, by hand): free with no clearance and with 2 cm, not with 5 cm;
    the floor it ends on is no obstacle to it."""
    from stiffcal.model.workcell import feasible

    q = np.radians([[60.0, -90.0]])
    tool_x = 0.6 * np.cos(q[0, 0]) + 0.4 * np.cos(q[0].sum())
    assert abs((0.6764 - tool_x) - 0.0300) < 1e-3
    for clearance, free in ((0.0, True), (0.02, True), (0.05, False)):
        path = tmp_path / f"c{clearance}.yaml"
        path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: -0.1\n"
                        f"  link_radius_m: 0.04\n  cable_clearance_m: {clearance}\n  boxes:\n"
                        "    - {name: stand, center_m: [0.7764, 0.15], size_m: [0.2, 0.1]}\n", encoding="utf-8")
        assert feasible(load_robot(path), q, hanging=True)[0] == free, clearance


def test_a_hanging_mass_that_would_rest_on_the_table_is_refused(tmp_path):
    """A fresh user's iiwa on a table (floor_m 0, cable_length_m 0.5): 5 of 8 planned poses had the tool point 0.355 m
    above the table, so the mass on its 0.5 m cable would have rested on the table and loaded nothing; the cable was
    cut at the table. Now the mass must hang clear of every half-space: the 2-link arm's tool point at heights set
    by hand (forward kinematics below), against cable lengths shorter and longer than that height; without
    cable_length_m the cable still runs down to the table, unchecked."""
    from stiffcal.model.workcell import feasible

    q = np.radians([[90.0, -120.0], [45.0, -90.0]])  # link 2 descending to the tool point: the cable clears it
    height = 0.6 * np.sin(q[:, 0]) + 0.4 * np.sin(q.sum(axis=1))  # 0.4000 and 0.1414 m above the base
    assert np.allclose(height, [0.4, 0.1414], atol=1e-4)
    for length, free in (("0.1", [True, True]), ("0.3", [True, False]), ("0.5", [False, False]), (None, [True, True])):
        path = tmp_path / f"c{length}.yaml"
        path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: 0.0\n"
                        "  link_radius_m: 0.02\n" + (f"  cable_length_m: {length}\n" if length else ""),
                        encoding="utf-8")
        assert list(feasible(load_robot(path), q, hanging=True)) == free, length


def test_the_cable_is_checked_against_the_link_it_hangs_from(tmp_path):
    """A fresh user's UR10: a cable from a flange facing sideways or up ran through the flange's own link (22-49 mm
    inside wrist_3_link in 18 of 34 planned poses), which was never checked. The 2-link arm (links 0.6 and 0.4 m,
    radius 0.04 m, a 0.3 m cable): at (0, 90) deg link 2 stands straight up from (0.6, 0) to the tool point
    (0.6, 0.4), and the cable runs down its axis to (0.6, 0.1), 0.1 m clear of link 1 (by hand below): refused; at
    (0, 0) it hangs from the tip of a horizontal link 2: free."""
    from stiffcal.model.workcell import feasible

    q = np.radians([[0.0, 90.0], [0.0, 0.0]])
    bottom = np.array([0.6, 0.4 - 0.3])
    assert np.hypot(*(bottom - [0.6, 0.0])) - 0.04 > 0.05  # the cable's end is clear of link 1 at (0.6, 0)
    path = tmp_path / "r.yaml"
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: -0.5\n"
                    "  link_radius_m: 0.04\n  cable_length_m: 0.3\n", encoding="utf-8")
    assert list(feasible(load_robot(path), q, hanging=True)) == [False, True]
    assert list(feasible(load_robot(path), q)) == [True, True]  # without a cable both poses are free


def _cable_meets(geom, gdata, bodies, top: np.ndarray, length: float) -> bool:
    """Whether a vertical cable (a line) from ``top`` (3,) [m] down ``length`` [m] meets any of the collision
    ``bodies`` (indices into Pinocchio's ``geom``, placed in ``gdata``), by coal on the meshes themselves."""
    import coal

    cable = coal.Capsule(1e-6, length)
    where = coal.Transform3s(np.eye(3), top - [0.0, 0.0, length / 2])
    return any(coal.collide(geom.geometryObjects[i].geometry, coal.Transform3s(gdata.oMg[i].rotation,
                            gdata.oMg[i].translation), cable, where, coal.CollisionRequest(), coal.CollisionResult())
               for i in bodies)


def test_a_ur10_cable_through_its_own_flange_is_refused_as_the_meshes_say(tmp_path):
    """The fresh user's UR10 pose (tool point at tool0's origin, the flange 25 deg above horizontal, 48.5 mm of
    cable inside wrist_3_link by the user's check) against a pose whose flange faces down: stiffcal's check with
    the cable against the link it hangs from agrees with coal on the collision meshes (the cable from 1 mm below
    the tool point)."""
    import pinocchio as pin

    from stiffcal.model.workcell import feasible

    root = real_arms.robots_dir()
    urdf = root / real_arms.ARMS["ur10"][0]
    path = tmp_path / "ur10.yaml"
    path.write_text(f"name: ur10\nkind: urdf\nurdf: {urdf}\nbase_frame: base_link\ntip_frame: tool0\n"
                    "tool_m: [0, 0, 0]\ncell:\n  floor_m: -0.8\n  cable_length_m: 0.45\n", encoding="utf-8")
    robot = load_robot(path)
    q = np.radians([[15.14, -43.34, -116.84, -174.84, -90.00, 143.85], [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]])
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(root.parent.parent)])
    data, gdata = model.createData(), pin.GeometryData(geom)
    wrist = [i for i, g in enumerate(geom.geometryObjects) if g.name.startswith("wrist_3_link")]
    hits = []
    for x in q:
        pin.forwardKinematics(model, data, x)
        pin.updateFramePlacements(model, data)
        pin.updateGeometryPlacements(model, data, geom, gdata)
        top = data.oMf[model.getFrameId("tool0")].translation - [0.0, 0.0, 1e-3]
        hits.append(_cable_meets(geom, gdata, wrist, top, 0.45 - 1e-3))
    assert hits == [True, False]
    assert list(feasible(robot, q, hanging=True)) == [False, True]


@needs_arms
def test_a_cable_that_starts_inside_a_hand_is_said_to_be_unchecked_against_it(tmp_path):
    """A fresh user's Panda with its hand, the tool point at the flange (panda_link8) under hanging masses: the cable
    ran 35-104 mm inside panda_hand at every planned pose (by the user's check), the hand left unchecked because its
    hull held the tool point, and nothing said it. coal on the hand's convex hull: the flange point lies inside it,
    more than 1 mm deep; design's notes now name panda_hand and the hook; with the tool point at a hook 15 mm past the
    fingertips (outside every hull) no such note."""
    import coal
    import pinocchio as pin

    from stiffcal.model.workcell import cell_notes

    root = real_arms.robots_dir()
    urdf = root / real_arms.ARMS["panda"][0]
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(root.parent.parent)])
    data, gdata = model.createData(), pin.GeometryData(geom)
    pin.framesForwardKinematics(model, data, np.zeros(model.nq))
    pin.updateGeometryPlacements(model, data, geom, gdata)
    flange = data.oMf[model.getFrameId("panda_link8")].translation
    hand = [i for i, g in enumerate(geom.geometryObjects) if g.name.startswith("panda_hand")
            and "tcp" not in g.name][0]
    mesh = geom.geometryObjects[hand].geometry
    mesh.buildConvexHull(True, "Qt")
    T = coal.Transform3s(gdata.oMg[hand].rotation, gdata.oMg[hand].translation)
    deep = [coal.distance(mesh.convex, T, coal.Sphere(1e-9), coal.Transform3s(np.eye(3), flange + d),
                          coal.DistanceRequest(), coal.DistanceResult()) < 0 or
            coal.collide(mesh.convex, T, coal.Sphere(1e-9), coal.Transform3s(np.eye(3), flange + d),
                         coal.CollisionRequest(), coal.CollisionResult())
            for d in [np.zeros(3)] + [s * 1e-3 * e for e in np.eye(3) for s in (1, -1)]]
    assert all(deep)
    said = "the hanging masses' cable starts inside the hull of panda_hand"
    for tip, hook, expect in (("panda_link8", 0.0, True), ("panda_hand_tcp", 0.015, False)):
        path = tmp_path / f"{tip}.yaml"
        path.write_text(f"name: panda\nkind: urdf\nurdf: {urdf}\nbase_frame: panda_link0\ntip_frame: {tip}\n"
                        f"tool_m: [0, 0, {hook}]\ncell:\n  floor_m: -1.5\n  cable_length_m: 0.3\n", encoding="utf-8")
        robot = load_robot(path)
        assert any(n.startswith(said) for n in cell_notes(robot, hanging=True)) == expect, tip
        assert not any(n.startswith(said) for n in cell_notes(robot))  # no hanging masses: no cable


@needs_arms
def test_a_cable_from_a_fingertip_is_checked_against_the_fingers(tmp_path):
    """A fresh user's Panda (tool point panda_hand_tcp, on the closed fingertips' faces) under hanging masses: every
    planned pose tilted the gripper 62-87 deg and hung the cable through the fingertips (8.5 mm deep by the user's
    check), because a body whose hull held the tool point was left unchecked, and a point on its face counted as
    held. coal on the collision meshes, from 1 mm below the tool point: the cable meets a finger at that pose and not
    with the hook 15 mm past the fingertips at the ready pose (gripper down); stiffcal agrees, and with no pose left
    its message names the fingers and the hook."""
    import pinocchio as pin

    from stiffcal.model.workcell import feasible

    root = real_arms.robots_dir()
    urdf = root / real_arms.ARMS["panda"][0]
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(root.parent.parent)])
    data, gdata = model.createData(), pin.GeometryData(geom)
    fingers = [i for i, g in enumerate(geom.geometryObjects) if "finger" in g.name]
    poses = np.radians([[7.01, 75.58, 2.97, -26.69, -0.26, 170.0, 63.02], [0.0, -45.0, 0.0, -135.0, 0.0, 90.0, 45.0]])
    hits = []
    for x, hook in zip(poses, (0.0, 0.015)):
        pin.framesForwardKinematics(model, data, np.r_[x, 0.0, 0.0])  # the fingers closed (their neutral)
        pin.updateGeometryPlacements(model, data, geom, gdata)
        tcp = data.oMf[model.getFrameId("panda_hand_tcp")]
        top = tcp.translation + tcp.rotation @ [0.0, 0.0, hook] - [0.0, 0.0, 1e-3]
        hits.append(_cable_meets(geom, gdata, fingers, top, 0.3 - 1e-3))
    assert hits == [True, False]
    ok = []
    for x, hook in zip(poses, (0.0, 0.015)):
        path = tmp_path / f"panda{hook}.yaml"
        path.write_text(f"name: panda\nkind: urdf\nurdf: {urdf}\nbase_frame: panda_link0\ntip_frame: panda_hand_tcp\n"
                        f"tool_m: [0, 0, {hook}]\ncell:\n  floor_m: -1.5\n  cable_length_m: 0.3\n", encoding="utf-8")
        ok.append(bool(feasible(load_robot(path), x[None], hanging=True)[0]))
    assert ok == [False, True]
    with pytest.raises(InputError, match=r"cable runs through the arm \(panda_\w*finger.*a hook past the fingertips"):
        stiffcal.design(tmp_path / "panda0.0.yaml", [0, 30, 0, -120, 0, 150, 45], [0, 0, -29.42], experiments=4,
                        loads="hanging:9.81,19.61", cache_dir=None)
    # discriminate's candidates say the same (a fresh user's IRB 6640 got "no pose ... can be taken" alone)
    from stiffcal.measured import discrimination as X

    robot = load_robot(tmp_path / "panda0.0.yaml")
    with pytest.raises(InputError, match=r"none of the 256 candidate poses .* cable runs through the arm \(panda_"):
        X.make_pool(robot, X.pose_pool(robot, log2_count=8), np.array([[0.0, 0.0, -9.81]]), hanging=True)


@needs_arms
def test_an_obstacle_through_the_fixed_base_is_refused(tmp_path):
    """A fresh user's Panda with a wall at x = -0.08 m: link0's collision mesh reaches x = -0.154 m (its vertices,
    read here), 74 mm into the wall, and the cell was accepted in silence (no joint moves the base, so it was never
    checked). Refused now, naming both and the depth from the mesh; the wall 0.2 m further back (the pose free),
    or the pair ignored, is accepted, and the table top under the base (floor_m 0, the mesh touching it) is no
    overlap."""
    import pinocchio as pin

    root = real_arms.robots_dir()
    urdf = root / real_arms.ARMS["panda"][0]
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(root.parent.parent)])
    link0 = [g.geometry for g in geom.geometryObjects if g.name.startswith("panda_link0")][0]
    reach = min(float(link0.vertices(i)[0]) for i in range(link0.num_vertices))  # the mesh's placement is the origin
    depth_mm = round((-0.08 - reach) * 1e3)
    assert 70 <= depth_mm <= 80
    from stiffcal.model.workcell import feasible

    q = np.radians([[10, 20, 0, -120, 0, 140, 45]])
    ignore = "  ignore_pairs: [[panda_link0, wall]]\n"
    for offset, extra, refused in ((-0.08, "", True), (-0.28, "", False), (-0.08, ignore, False)):
        wall = f"  half_spaces:\n    - {{name: wall, normal: [1, 0, 0], offset_m: {offset}}}\n"
        path = real_arms.write_robot_file("panda", tmp_path, floor_m=0.0, extra=wall + extra)
        if refused:
            with pytest.raises(InputError, match=f"wall cuts {depth_mm} mm into panda_link0"):
                feasible(load_robot(path), q)
        else:  # no refusal (with the pair ignored the wall still meets link1, which turns about the base)
            assert feasible(load_robot(path), q)[0] == (offset == -0.28)


def test_a_cable_longer_than_the_drop_is_named_when_no_pose_is_left(tmp_path):
    """A fresh user's UR10 with a 3 m cable over a floor 0.8 m below the base: refused with a message that never
    said cable_length_m. The 2-link arm (reach 1 m) over a floor 0.5 m below its base with a 2 m cable: no tool
    point is 2 m above the floor, so no pose is left with hanging masses; the message names the cable's length,
    and the same arm plans without hanging masses."""
    path = tmp_path / "r.yaml"
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: -0.5\n"
                    "  link_radius_m: 0.02\n  cable_length_m: 2.0\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"at \d+ the mass or cable meets an obstacle \(cable_length_m 2 m more than "
                                         r"the tool point's height\?\)"):
        stiffcal.design(path, [30, 30], [0, -100], experiments=2, loads="hanging:50,100")
    assert stiffcal.design(path, [30, 30], [0, -100], experiments=2).poses_deg.shape == (2, 2)


def test_a_cell_in_millimetres_is_refused_naming_the_unit(tmp_path):
    """A fresh user's table given in millimetres (800 x 1000 x 750 "m") was accepted and then said to cut 374628 mm
    into the base. The 2-link arm (reach 1 m): a square box of side 80 m (113 m across, its diagonal) is refused
    naming the unit; one of side 14.14 m (20 m across: a hall's floor as a box) is accepted."""
    for size, refused in ((80.0, True), (14.14, False)):
        box = f"{{name: table, center_m: [0.0, {-size / 2 - 0.5}], size_m: [{size}, {size}]}}"
        _refused_or_read(tmp_path, f"  boxes:\n    - {box}\n",
                         r"'table' is 113.1 m across.*\(millimetres given\?\)" if refused else None)


def _refused_or_read(tmp_path, cell: str, refused: str | None) -> None:
    """The 2-link arm (links 0.6 and 0.4 m) with a cell of capsules 0.02 m and the further cell lines ``cell``:
    refused with a message matching ``refused``, or (None) read with its cell."""
    path = tmp_path / "r.yaml"
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  link_radius_m: 0.02\n"
                    + cell, encoding="utf-8")
    if refused:
        with pytest.raises(InputError, match=refused):
            load_robot(path)
    else:
        assert load_robot(path).cell is not None


def test_a_clearance_longer_than_the_arm_is_refused_naming_the_field(tmp_path):
    """A fresh user's clearance_m: 5 (meant as 5 mm) on a Panda planned in silence, every link checked for contact
    only. The 2-link arm (its links 1 m in all): a clearance of 1.5 m from the cell's solids or between the arm's
    bodies is refused naming that field; 0.9 m is accepted (the cable's clearance has the schema's bound of 1 m)."""
    for key in ("clearance_m", "self_clearance_m"):
        for value, refused in ((1.5, True), (0.9, False)):
            expect = rf"cell.{key}.*longer than the arm itself \(1 m, its links without the tool\).*millimetres"
            _refused_or_read(tmp_path, f"  {key}: {value}\n", expect if refused else None)


def test_a_plan_without_a_cell_names_its_poses_below_the_base(root):
    """A fresh user's next round under hanging masses, the robot without a cell, put the tool 13 mm under the plane
    its base stands on, with no word of it. The note names exactly the poses whose tool point lies more than 1 mm
    below that plane, by the tool point's height written out here from the DH chain (independent of the robot's
    own forward kinematics), and gives the deepest."""
    from stiffcal.model.workcell import below_base_note

    robot = load_robot(root / "config/robots/kuka_kr210_r2700.yaml")
    rng = np.random.default_rng(3)
    lo, hi = np.radians(robot.limits_deg).T
    q = lo + (hi - lo) * rng.random((40, robot.n_joints))

    def height(qi):  # standard DH: T = Rz(theta) Tz(d) Tx(a) Rx(alpha), then the tool point in the tip frame
        T = np.eye(4)
        for (a, alpha, d, off), th in zip(robot.dh, qi):
            ct, st, ca, sa = np.cos(th + off), np.sin(th + off), np.cos(alpha), np.sin(alpha)
            T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                              [0, 0, 0, 1]])
        return (T @ np.append(robot.tool_m, 1.0))[2]

    z = np.array([height(qi) for qi in q])
    low = np.flatnonzero(z < -1e-3)
    assert low.size and low.size < len(q)
    note, = below_base_note(robot, q)
    assert note.startswith(f"pose(s) {', '.join(str(i + 1) for i in low)} put the tool point up to "
                           f"{-1e3 * z.min():.3g} mm below")
    assert below_base_note(robot, q[z > 0]) == []


def test_a_length_beyond_the_schema_in_millimetres_names_the_unit(tmp_path):
    """A fresh user's Z1 table of 900 x 1200 x 750 (millimetres) stopped at the schema's 1000 m with 'expected a
    number <= 1000, got 1200', no word of the unit; a non-length field beyond its bound keeps the plain message."""
    path = tmp_path / "r.yaml"
    box = "{name: table, center_m: [0.0, -700.0], size_m: [900, 1200]}"
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  link_radius_m: 0.02\n"
                    f"  boxes:\n    - {box}\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"size_m\[1\]'.*got 1200: size_m is in metres; millimetres given"):
        load_robot(path)
    # another's whole cell in millimetres stopped first at a clearance of 20 against the bound of 10, no word of the
    # unit; a clearance beyond the bound that no unit slip explains keeps the plain message
    for clearance, hinted in ((20, True), (20000, False)):
        path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  link_radius_m: 0.02\n"
                        f"  clearance_m: {clearance}\n", encoding="utf-8")
        with pytest.raises(InputError, match="clearance_m") as err:
            load_robot(path)
        assert ("millimetres given as metres" in str(err.value)) == hinted, str(err.value)
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\n"
                    "joint_limits_deg: [[-180, 180], [-180, 4000]]\n", encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_robot(path)
    assert "millimetres" not in str(err.value)


def test_a_test_pose_inside_an_obstacle_names_the_pair(tmp_path):
    """A fresh user's Panda test pose inside a fixture: the note did not say which body met what. The 2-link arm
    at (0, 0) deg lies along the x axis to x = 1 m; a box of 0.1 m about (0.8, 0) m holds link 2 (its axis
    0.05 m inside the box, by hand): the note names link2 and the box with the depth the cell reports (a pair that
    overlaps, not the closest: a fresh user's Bravo 7 was told of a cylinder pair where two links overlapped)."""
    from stiffcal.model.workcell import clearance

    path = tmp_path / "r.yaml"
    path.write_text("name: r\nkind: planar\nlinks_m: [0.6, 0.4]\ngravity: [0, -1]\ncell:\n  floor_m: -0.5\n"
                    "  link_radius_m: 0.02\n  boxes:\n"
                    "    - {name: fixture, center_m: [0.8, 0.0], size_m: [0.1, 0.1]}\n", encoding="utf-8")
    d, names = clearance(load_robot(path), np.radians([[0.0, 0.0]]))
    assert names[0] == "link2-fixture" and d[0] < -0.05
    res = stiffcal.design(path, [0, 0], [0, -100], experiments=2)
    assert any("the test pose itself cannot be taken" in n and f"link2-fixture ({-d[0] * 1e3:.3g} mm deep)" in n
               for n in res.notes), res.notes


@needs_arms
def test_a_pose_s_clearance_does_not_depend_on_the_poses_before_it(tmp_path):
    """A fresh user's Z1 plan printed 0.015061 and 0.015062 m for one pose measured twice (its CLI), 0.015061 for both
    (the workflow): coal's mesh distance starts where the last query ended. The clearance of each pose, alone, after
    the others or in reverse order: bit for bit the same."""
    from stiffcal.model.workcell import clearance

    root = real_arms.robots_dir()
    path = tmp_path / "z1.yaml"
    path.write_text(f"name: z1\nkind: urdf\nurdf: {root}/z1_description/urdf/z1.urdf\nbase_frame: link00\n"
                    f"tip_frame: gripperStator\ncell:\n  floor_m: -0.5\n  srdf: {root}/z1_description/srdf/z1.srdf\n",
                    encoding="utf-8")
    robot = load_robot(path)
    q = np.radians([[-32.89, 32.63, -58.77, -6.44, 34.98, 12.20], [0.05, 21.94, -61.48, 21.95, -19.89, 1.57],
                    [40.0, 50.0, -100.0, 30.0, 60.0, -20.0]])
    together = clearance(robot, np.vstack([q, q[::-1]]))[0]
    alone = np.array([clearance(robot, x[None])[0][0] for x in q])
    assert np.array_equal(together[:3], alone) and np.array_equal(together[3:], alone[::-1])


def test_a_loading_bar_of_length_0_or_in_millimetres_is_refused(root, tmp_path, capsys):
    """A fresh user's 'bar:400,0,0:196' (a 0.4 m bar in mm) planned 46 kN m moments in silence, and 'bar:0,0,0:..'
    was taken too: both refused, by design and discriminate, naming --loads (the paper's arm of 1 m: a bar over
    10 m is refused, one of 8 m taken)."""
    data = str(root / "data/synthetic_paper_2r_hanging.csv")
    for spec, words in (("bar:400,0:100", "400 m from the tool point, more than 10 times the arm's own length"),
                        ("bar:0,0:100", "a loading bar of length 0")):
        for argv in (["discriminate", "--robot", str(PAPER), "--data", data, "--experiments", "2", "--out",
                      str(tmp_path / "out")],
                     ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-300",
                      "--experiments", "2", "--no-cache"]):
            assert main([*argv, "--loads", spec]) == 2
            err = capsys.readouterr().err
            assert "field '--loads'" in err and words in err, err
    assert not (tmp_path / "out").exists()
    assert main(["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-300", "--experiments",
                 "2", "--no-cache", "--quiet", "--loads", "bar:8,0:100"]) == 0


def test_a_missing_mesh_is_named_without_the_loader_s_source_location(tmp_path):
    """A fresh user's UR5 with a mesh path that does not exist: refused naming the URDF and the mesh, but the
    message began with coal's C++ source location ("From file: /project/src/mesh_loader/assimp.cpp in function:
    ..."), which says nothing to a lab. The URDF of real_arms' UR10 copied with its meshes' package:// paths made
    absolute into a folder that does not exist: the message names the mesh, and not the loader's source."""
    root = real_arms.robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed")
    urdf = (root / real_arms.ARMS["ur10"][0]).read_text(encoding="utf-8")
    (tmp_path / "ur10.urdf").write_text(urdf.replace("package://", f"{tmp_path / 'nowhere'}/"), encoding="utf-8")
    path = real_arms.write_robot_file("ur10", tmp_path)
    text = path.read_text(encoding="utf-8").replace(f"urdf: {root / real_arms.ARMS['ur10'][0]}",
                                                    f"urdf: {tmp_path / 'ur10.urdf'}")
    path.write_text(text, encoding="utf-8")
    from stiffcal.model.workcell import clearance

    expect = r"cannot read the collision geometry of the URDF .*ur10\.urdf: .*nowhere/"
    with pytest.raises(InputError, match=expect) as err:
        clearance(load_robot(path), np.zeros((1, 6)))
    assert "From file" not in str(err.value) and "assimp.cpp" not in str(err.value)
