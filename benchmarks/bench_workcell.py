"""The cell (stiffcal.model.workcell, issue 24) on real arms nobody here wrote: the UR10, Panda and Kinova Jaco2 of the
example-robot-data package (pinned in requirements-test.lock), on the floor with self-collision from their meshes.

Prints, in one run (CPU seconds, one BLAS thread):

1. the feasibility check's speed: stiffcal's engine (one call of Pinocchio's batched collision check, convex hulls
   against half-spaces, joints in numpy) against Pinocchio's per-pose loop on the same meshes (the baseline), per
   pose, on 8192 Sobol poses, and the fraction of the joint-limit box that is feasible;
2. for M = 2..8 (Panda 3..8: 7 joints): the O_t of the plan in the cell beside the unconstrained optimum (the cost
   of feasibility), the bounds, and an independent check of every pose of both plans against the URDF's meshes
   (Pinocchio + coal; adjacent links and the SRDF's pairs left out) and the joints' heights above the floor:
   ``stiffcal design`` (the API) and the workflow's design-study functions (stiffcal.workflow.pipeline), which give the
   same plans;
3. the next experiment (``discriminate``) on simulated hanging-mass data of each arm: every point of its plans
   by the same independent check;
4. how much the seed still moves O_t (seeds 0..S-1), in the cell.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_workcell.py [--seeds 5] [--robots ur10,panda,jaco2]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import real_arms  # noqa: E402
from test_workcell import MeshCheck  # noqa: E402

import stiffcal  # noqa: E402
from stiffcal.workflow import pipeline  # noqa: E402
from stiffcal.model import workcell  # noqa: E402
from stiffcal.planning.problem import sample_joint_space  # noqa: E402
from stiffcal.model.robot import load_robot  # noqa: E402


def cpu():
    return time.process_time()


def speed(name, robot, check):
    q = sample_joint_space(robot, 13, seed=11)
    eng = workcell.engine(robot)
    t = cpu()
    ok = eng._feasible(q, None)
    ours = (cpu() - t) / len(q)
    t = cpu()
    base = [check.collides(robot.joint_names, x) for x in q]
    loop = (cpu() - t) / len(q)
    print(f"  {name}: feasibility {1e6 * ours:.1f} us/pose (Pinocchio per-pose loop on the meshes, self pairs only: "
          f"{1e6 * loop:.1f} us/pose, ratio {loop / ours:.2f}); {100 * ok.mean():.1f} % of the joint-limit box "
          f"feasible ({100 * (1 - np.mean(base)):.1f} % free of self-collision)")


def plans_and_costs(name, path, d, ms, seed=0):
    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    robot = load_robot(path)
    check = MeshCheck(name)
    free_robot = replace(robot, cell=None)
    rows, bad_free, bad_cell, bad_wf, poses = [], [0, 0], [0, 0], [0, 0], 0
    t_cell = t_free = 0.0
    p = {"name": name, "test_pose_deg": qt, "force_N": force, "sigma_m": 1e-5}
    files = {k: str(Path(d) / f"{name}-{k}") for k in ("d.json", "s.csv", "c.csv", "pool.npy", "best.csv")}
    t = cpu()
    pipeline.approximate_design(p, str(path), files["d.json"], files["s.csv"], files["c.csv"], None, name,
                                files["pool.npy"])
    pipeline.study_plans(p, str(path), ms, seed, files["d.json"], files["pool.npy"], files["best.csv"])
    t_wf = cpu() - t
    import pandas as pd

    from stiffcal.paper.tables import parse_plan

    wf = pd.read_csv(files["best.csv"])
    from stiffcal.planning.certificate import approximate_design
    from stiffcal.planning.plans import CELL_STARTS, design_starts, optimise_plan
    from stiffcal.planning.study import Study

    st_free = Study(name, free_robot, np.radians(qt), np.array(force, float), 1e-5, ("ot",), 1.0, 1.0)
    d_free = approximate_design(st_free.problem("ot"))
    for m in ms:
        t = cpu()
        cell = stiffcal.design(robot, qt, force, experiments=m, sigma=1e-5, seed=seed)
        t_cell += cpu() - t
        t = cpu()
        free = stiffcal.design(free_robot, qt, force, experiments=m, sigma=1e-5, seed=seed)
        t_free += cpu() - t
        prob = st_free.problem("ot", m)  # the unconstrained reference with as many starts as the cell's plan
        free_best = min(free.O_t, optimise_plan(prob, starts=design_starts(prob, d_free, m), n_starts=CELL_STARTS,
                                                seed=seed).loss)
        wf_poses = parse_plan(wf[wf.m == m].poses_deg.iloc[0])
        for acc, P in ((bad_cell, cell.poses_deg), (bad_free, free.poses_deg), (bad_wf, wf_poses)):
            c, b = check.bad(robot.joint_names, P)
            acc[0] += c
            acc[1] += b
        poses += m
        same = np.allclose(wf_poses, cell.poses_deg, atol=5e-5)
        rows.append((m, cell.O_t, free_best, cell.lower_bound, cell.feasible_lower_bound, cell.lower_bound_converged,
                     min(cell.clearance_m), same))
    print(f"  {name}: M, O_t in the cell, unconstrained O_t (the better of stiffcal design without the cell and 64 "
          "starts), cost of feasibility, continuum bound, gap, feasible bound, its gap, smallest clearance [mm], "
          "workflow's plan = API's")
    for m, oc, of, lb, fb, conv, cmin, same in rows:
        print(f"    M = {m}: {oc:.4e}  {of:.4e}  {100 * (oc / of - 1):+6.2f} %  {lb:.4e}  {100 * (oc / lb - 1):5.2f} %"
              f"{'' if conv else ' (NOT CONVERGED)'}  {fb:.4e}  {100 * (oc / fb - 1):5.2f} %  {1e3 * cmin:6.1f}  "
              f"{same}")
    print(f"  {name}: {poses} poses; in collision / a joint below the floor, by the independent check: "
          f"design in the cell {bad_cell[0]} / {bad_cell[1]}, the workflow's study in the cell {bad_wf[0]} / "
          f"{bad_wf[1]}, unconstrained (no cell) {bad_free[0]} / {bad_free[1]}")
    print(f"  {name}: CPU {t_cell:.1f} s for the {len(ms)} designs in the cell (API, each with both approximate "
          f"designs) against {t_free:.1f} s without it (ratio {t_cell / t_free:.2f}); the workflow's study "
          f"(one design job, the {len(ms)} plans) {t_wf:.1f} s")
    return robot


def next_experiment(name, robot):
    from stiffcal.measured import discrimination as X
    from stiffcal.testing import rates as R
    from stiffcal.testing import truth as T
    from stiffcal.measured.measurements import Measurements

    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    rng = np.random.default_rng(1)
    pr = T.Protocol("hanging masses, twice", magnitudes_N=(50.0, 150.0), repeats=2)
    log = T.lab_log(robot, pr, rng, 10)
    k = R.compliances(robot)
    unit = R._unit_truth("backlash", robot, k, rng, log)
    truth = R._scaled_truth("backlash", unit, T.Truth(k), robot, log, 2.0 * pr.sigma_m)
    meas = Measurements.from_arrays(log.q, log.force, T.measure(robot, truth, log, rng), config=log.config)
    t = cpu()
    res = X.discriminate(robot, meas, 6, X.load_set("hanging:50,150", 3, gravity=robot.gravity),
                         test_pose=np.radians(qt), test_force=np.array(force, float))
    check = MeshCheck(name)
    counted, bad = 0, [0, 0]
    for s in (res.plan, res.compound, res.ot_plan):
        if s is not None:
            c, b = check.bad(robot.joint_names, s.poses_deg)
            bad[0] += c
            bad[1] += b
            counted += len(s.poses_deg)
    what = ", ".join(k for k, s in (("plan", res.plan), ("compound", res.compound), ("ot_plan", res.ot_plan)) if s)
    print(f"  {name}: discriminate ({what}): {counted} points, in collision {bad[0]}, a joint below the floor "
          f"{bad[1]}; {cpu() - t:.1f} s")


def seed_spread(name, path, ms, seeds):
    """How much the seed of the random starts moves O_t, in the cell (64 starts) and without it (16 starts, the
    issue's UR10 case): the design (the slow part, seed-free) once per M, the plan for every seed."""
    from stiffcal.planning.certificate import approximate_design
    from stiffcal.planning.plans import best_plan
    from stiffcal.planning.study import Study

    _, _, _, _, _, qt, force = real_arms.ARMS[name]
    robot = load_robot(path)
    for label, r in (("in the cell", robot), ("without a cell", replace(robot, cell=None))):
        st = Study(name, r, np.radians(qt), np.array(force, float), 1e-5, ("ot",), 1.0, 1.0)
        design = approximate_design(st.problem("ot"))
        out = []
        for m in ms:
            ot = [best_plan(st.problem("ot", m), design, s).loss for s in range(seeds)]
            out.append(f"M = {m}: {100 * (max(ot) / min(ot) - 1):.3f} %")
        print(f"  {name} {label}: O_t over seeds 0..{seeds - 1} (largest / smallest - 1): " + ", ".join(out))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", default="ur10,panda,jaco2")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--skip", default="", help="parts to skip: speed,plans,discriminate,seeds")
    args = ap.parse_args(argv)
    if real_arms.robots_dir() is None:
        sys.exit("example-robot-data is not installed (pip install -r requirements-test.lock)")
    skip = set(args.skip.split(","))
    with tempfile.TemporaryDirectory() as d:
        for name in args.robots.split(","):
            path = real_arms.write_robot_file(name, Path(d))
            robot = load_robot(path)
            ms = list(range(3 if name == "panda" else 2, 9))
            print(f"{name} ({robot.n_joints} joints), the cell: {robot.cell.describe()}")
            if "speed" not in skip:
                speed(name, robot, MeshCheck(name))
            if "plans" not in skip:
                plans_and_costs(name, path, d, ms)
            if "discriminate" not in skip:
                next_experiment(name, robot)
            if "seeds" not in skip:
                seed_spread(name, path, ms, args.seeds)


if __name__ == "__main__":
    main()
