"""Joint ranges as data sheets give them (issue 15, item 5): ranges that pass +-180 deg without a full turn
(ABB IRB 140 axis 3: -230 to +50) and ranges wider than a turn (axis 6: +-400). Every pose that a command, a
table or the report prints lies within the joint limits as the robot file writes them (no wrapping
tolerance), for every robot file in the repository and for random limits that pass +-180."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

import stiffcal
from stiffcal.planning.problem import into_limits
from stiffcal.errors import InputError
from stiffcal.model.robot import load_robot, planar_robot

ROOT = Path(__file__).resolve().parents[1]
#: every robot file of the repository, with a test pose inside its own limits and a force
ROBOT_FILES = sorted([*ROOT.glob("config/robots/*.yaml"), *ROOT.glob("tests/data/*.yaml"),
                      *ROOT.glob("tests/data/discrepancy/*.robot.yaml")])


def _inside(poses_deg, limits_deg) -> bool:
    """Every angle within [lower, upper] as written (1e-9 deg for the degree conversions), no angle wrapped."""
    q = np.asarray(poses_deg, float).reshape(-1, len(limits_deg))
    lo, hi = np.asarray(limits_deg, float).T
    return bool(np.all((q >= lo - 1e-9) & (q <= hi + 1e-9)))


def _printed_poses(res) -> list:
    """Every pose the design's JSON prints."""
    d = res.to_dict()
    return [d["poses_deg"], d["optimal_set_deg"], d["approximate_design"]["support_deg"]]


def _random_limits(rng, n: int) -> np.ndarray:
    """Per joint a range that contains +180 or -180 inside it (not as an end), 40 to 500 deg wide."""
    out = []
    for _ in range(n):
        width = rng.uniform(40.0, 500.0)
        lo = rng.choice([-180.0, 180.0]) - rng.uniform(5.0, width - 5.0)
        out.append([round(lo, 1), round(lo + width, 1)])
    return np.array(out)


def test_into_limits_moves_angles_by_whole_turns_into_any_range(rng):
    """Random angles and random ranges (passing +-180, wider than a turn, wholly beyond 180): the result is the
    same angle modulo 360 and lies within the range whenever some whole-turn copy does; otherwise it is the copy
    nearest to the range."""
    for _ in range(200):
        n = 4
        lim = _random_limits(rng, n) if rng.random() < 0.7 else np.sort(rng.uniform(-720, 720, (n, 2)), axis=1)
        robot = planar_robot(np.ones(n), joint_limits_deg=lim)
        q = rng.uniform(-1000, 1000, (50, n))
        out = into_limits(robot, q)
        np.testing.assert_allclose(np.cos(np.radians(out - q)), 1.0, atol=1e-9)
        copies = q[..., None] + 360.0 * np.arange(-5, 6)
        lo, hi = lim[:, 0, None], lim[:, 1, None]
        reachable = np.any((copies >= lo) & (copies <= hi), axis=-1)
        inside = (out >= lim[:, 0]) & (out <= lim[:, 1])
        assert np.all(inside == reachable)
        gap = np.maximum(lim[:, 0] - copies.transpose(2, 0, 1), copies.transpose(2, 0, 1) - lim[:, 1]).min(axis=0)
        np.testing.assert_allclose(np.maximum(lim[:, 0] - out, out - lim[:, 1]).clip(0), gap.clip(0), atol=1e-9)


def test_the_issues_cases_print_within_their_limits(tmp_path):
    """A 2-link arm with q2 in [190, 260] (the issue's minimal case: every pose printed with q2 in [-170, -100]
    before) through the API, and an M-pose plan of the IRB 140 with its data-sheet ranges (q3 = 130 printed for
    a range of -230 to 50 before; a plan of 6 poses from a small quasi-random pool, to keep the test fast)."""
    (tmp_path / "arm.yaml").write_text("name: arm\nkind: planar\nlinks_m: [0.6, 0.4]\n"
                                       "joint_limits_deg: [[-180, 180], [190, 260]]\n")
    arm = load_robot(tmp_path / "arm.yaml")
    for m in (1, 3):
        res = stiffcal.design(arm, [60, 200], [0, -1], experiments=m, progress=False)
        for poses in _printed_poses(res):
            assert _inside(poses, [[-180, 180], [190, 260]]), poses
    assert np.all(res.poses_deg[:, 1] >= 190)
    irb = load_robot(ROOT / "tests/data/abb_irb140.yaml")
    plan = _small_plan(irb, [0, 20, -20, 0, 45, 0], [100, 0, -100], 6)
    assert _inside(plan, np.degrees(irb.joint_limits_rad)), plan


def _small_plan(robot, test_deg, force, m: int) -> np.ndarray:
    """The O_t-optimal m-pose plan [deg] as stiffcal prints it, from a pool of 1024 quasi-random poses within
    the limits and 3 random starts (the printing path of every plan: :func:`stiffcal.planning.plans.canonical_plan`)."""
    from stiffcal.planning.problem import Problem, sample_joint_space
    from stiffcal.planning.plans import optimise_plan

    prob = Problem(robot, np.asarray(force, float), "ot", m, np.radians(test_deg))
    return optimise_plan(prob, pool=sample_joint_space(robot, 10), n_starts=3, n_polish=2).poses_deg


def _case(path: Path, rng):
    """(robot with random limits that pass +-180 on every joint, those limits [deg], a test pose within them
    [deg], a force [N]) for a robot file."""
    robot = load_robot(path)
    lim = _random_limits(rng, robot.n_joints)
    test = rng.uniform(lim[:, 0], lim[:, 1])
    force = [0.0, -1.0] if robot.task_dim == 2 else [100.0, -50.0, -100.0]
    return replace(robot, joint_limits_rad=np.radians(lim), has_joint_limits=True), lim, test, force


@pytest.mark.parametrize("path", ROBOT_FILES, ids=lambda p: p.name)
def test_no_printed_pose_outside_random_limits_that_pass_180(path):
    """Every robot file of the repository, with random limits that pass +-180 on every joint (one seeded draw
    per file; redrawn while the force cannot identify every compliance over the limited joint space). Arms of 2
    joints: everything ``stiffcal design`` prints (plans of one and three poses, the optimal set, the
    approximate design). Arms of 3 or more joints: the plan of the fewest poses that identify every compliance
    from a small pool (:func:`_small_plan`), and for 3 joints the approximate design on coarse grids."""
    from stiffcal.planning.certificate import approximate_design
    from stiffcal.planning.problem import Problem

    rng = np.random.default_rng(sum(map(ord, path.name)))
    for _ in range(10):
        robot, lim, test, force = _case(path, rng)
        try:
            if robot.n_joints == 2:
                printed = [p for m in (1, 3) for p in _printed_poses(
                    stiffcal.design(robot, test, force, experiments=m, progress=False))]
            else:
                printed = [_small_plan(robot, test, force, max(robot.min_poses, 2))]
                if robot.n_joints == 3:
                    design = approximate_design(Problem(robot, np.asarray(force), "ot", 1, np.radians(test)),
                                                pool_step_deg=12.0, search_step_deg=10.0)
                    printed.append(design.support_deg)
        except InputError as err:  # a force that never loads some joint within these limits: draw again
            assert "cannot be identified" in str(err) or "infinite at every pose" in str(err), str(err)
            continue
        for poses in printed:
            assert _inside(poses, lim), (path.name, lim.tolist(), poses)
        return
    pytest.fail(f"no identifiable case in 10 draws for {path.name}")


def test_tables_and_plans_of_a_planar_arm_print_within_limits(rng):
    """The paper's tables (2, 4-5, the approximate design, the best plans) of a 2-link arm with random limits
    that pass +-180: every pose, every optimal set and the support within the limits as written."""
    from stiffcal.planning.certificate import approximate_design
    from stiffcal.planning.study import Study
    from stiffcal.paper.tables import best_plan_row, design_table, parse_plan, plans_table, table2

    for _ in range(5):
        lim = _random_limits(rng, 2)
        robot = planar_robot([0.6, 0.4], joint_limits_deg=lim)
        study = Study("s", robot, np.radians(rng.uniform(lim[:, 0], lim[:, 1])), np.array([0.0, -1.0]), 1.0,
                      ("ot", "d"), 2.0, 2.0)
        try:
            t2 = table2(study)
        except InputError:
            continue
        for _, r in t2.iterrows():
            assert _inside(r[["q1_deg", "q2_deg"]].to_numpy(float), lim)
            if r["optimal_set_deg"]:
                assert _inside(parse_plan(r["optimal_set_deg"]), lim)
        design = approximate_design(study.problem("ot"), pool_step_deg=4.0)
        assert _inside(design_table(design, robot)[["q1_deg", "q2_deg"]].to_numpy(float), lim)
        for plan in plans_table(study, 2, 0, design).poses_deg:
            assert _inside(parse_plan(plan), lim), (lim, plan)
        row = best_plan_row(study, 3, 0, design)
        assert row["within_limits"] and _inside(parse_plan(row["poses_deg"]), lim)
        return
    pytest.fail("no identifiable case in 5 draws")


def test_limits_up_to_720_deg_are_read_and_beyond_refused(tmp_path):
    (tmp_path / "r.yaml").write_text("name: x\nkind: planar\nlinks_m: [1, 1]\njoint_limits_deg: [[-400, 400], "
                                     "[-720, 10]]\n")
    np.testing.assert_allclose(np.degrees(load_robot(tmp_path / "r.yaml").joint_limits_rad), [[-400, 400], [-720, 10]])
    (tmp_path / "r.yaml").write_text("name: x\nkind: planar\nlinks_m: [1, 1]\njoint_limits_deg: [[-800, 0], "
                                     "[-180, 180]]\n")
    with pytest.raises(InputError) as err:
        load_robot(tmp_path / "r.yaml")
    assert "field 'joint_limits_deg[0][0]'" in str(err.value)


def test_every_repository_robot_file_is_listed():
    names = {p.name for p in ROBOT_FILES}
    assert {"paper_2r.yaml", "kuka_kr210_r2700.yaml", "kuka_kr210_r2700_urdf.yaml", "abb_irb140.yaml"} <= names
    assert all(yaml.safe_load(p.read_text())["kind"] in ("planar", "spatial", "urdf") for p in ROBOT_FILES)
