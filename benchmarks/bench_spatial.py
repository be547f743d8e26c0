"""Benchmark: the 6-axis industrial arm of the default config (config/robots/kuka_kr210_r2700.yaml), an
M = 6 plan with its certificate, against a naive baseline in the same run.

Target (issue 6): M = 6 with the certificate in at most 60 s on one core. The baseline is a naive
multi-start local search (random plans within the joint limits, L-BFGS-B on all 36 angles, no exchange,
no bound) given the same wall time as ours; reported as how far its best O_t is above ours.

Run: .venv/bin/python benchmarks/bench_spatial.py   (single-threaded BLAS is forced below)
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from stiffcal.certificate import approximate_design  # noqa: E402
from stiffcal.design import Problem  # noqa: E402
from stiffcal.plans import optimise_plan, polish, round_design  # noqa: E402
from stiffcal.robot import load_robot  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "config/robots/kuka_kr210_r2700.yaml"
TARGET_S = 60.0

if __name__ == "__main__":
    robot = load_robot(ROBOT)
    force, qt, sigma, m = np.array([500.0, -300.0, -800.0]), np.radians([20, -60, 110, 30, 45, -20]), 1e-5, 6
    t0 = time.perf_counter()
    design = approximate_design(Problem(robot, force, "ot", 1, qt, None, sigma))
    t_design = time.perf_counter() - t0
    prob = Problem(robot, force, "ot", m, qt, None, sigma)
    plan = optimise_plan(prob, starts=[round_design(design, m)])
    t = time.perf_counter() - t0
    bound = design.lower_bound(m, sigma)
    rng = np.random.default_rng(0)
    lo, hi = robot.joint_limits_rad.T
    best, starts, tn0 = np.inf, 0, time.perf_counter()
    while time.perf_counter() - tn0 < t:
        best, starts = min(best, polish(prob, rng.uniform(lo, hi, (m, 6)))[1]), starts + 1
    within = np.all((plan.poses_deg >= np.degrees(lo)) & (plan.poses_deg <= np.degrees(hi)))
    print(f"{robot.name}, M = {m}: {t:.1f} s on one core (design + certificate {t_design:.1f} s; "
          f"target {TARGET_S:.0f} s: "
          f"{'meets' if t <= TARGET_S else 'MISSES'})")
    print(f"  O_t = {plan.loss:.6g} m^2 (RMS {1e6 * np.sqrt(plan.loss):.3f} um), certified bound {bound:.6g}, "
          f"gap {plan.loss / bound - 1:.2%}, equivalence gap {design.equivalence_gap:.2e}, within limits: {within}")
    print(f"  naive multi-start, same time: best O_t {best:.6g} ({best / plan.loss - 1:+.1%} vs ours, {starts} starts)")
