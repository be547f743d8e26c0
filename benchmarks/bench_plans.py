"""Benchmark: M-pose plans with their certificate, against a naive baseline in the same run.

Targets (issue 3): the paper's arm, M = 3 with the certificate, in at most 2 s on one core; a 3-link
planar arm, M = 10 with the certificate, in at most 30 s. The baseline is a naive multi-start local
search (random plans, L-BFGS-B on all M n angles, no exchange, no bound) given the same wall time
budget as ours; it is reported as a time ratio and by how far its best O_t is above ours.

Run: .venv/bin/python benchmarks/bench_plans.py   (single-threaded BLAS is forced below)
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import time  # noqa: E402

import numpy as np  # noqa: E402

from stiffcal.certificate import approximate_design  # noqa: E402
from stiffcal.design import Problem  # noqa: E402
from stiffcal.plans import optimise_plan, polish, round_design  # noqa: E402
from stiffcal.robot import planar_robot  # noqa: E402


def ours(problem):
    t0 = time.perf_counter()
    design = approximate_design(Problem(problem.robot, problem.force, "ot", 1, problem.test_pose))
    plan = optimise_plan(problem, starts=[round_design(design, problem.m)])
    return time.perf_counter() - t0, plan.loss, design.lower_bound(problem.m)


def naive(problem, budget_s, seed=0):
    """Random starts + local polish until the budget is spent; returns (time, best O_t, starts)."""
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    best, starts = np.inf, 0
    while time.perf_counter() - t0 < budget_s:
        q0 = rng.uniform(-np.pi, np.pi, (problem.m, problem.robot.n_joints))
        _, val = polish(problem, q0)
        best, starts = min(best, val), starts + 1
    return time.perf_counter() - t0, best, starts


CASES = [
    ("paper 2R arm, M = 3", planar_robot([0.6, 0.4]), [60.0, 30.0], 3, 2.0),
    ("3-link planar arm, M = 10", planar_robot([0.5, 0.35, 0.15]), [30.0, 40.0, -20.0], 10, 30.0),
]

if __name__ == "__main__":
    print(f"{'case':28s} {'ours [s]':>9s} {'target':>7s} {'O_t':>12s} {'bound':>12s} {'gap':>8s} "
          f"{'naive O_t (same time)':>22s} {'naive excess':>13s}")
    for name, robot, qt, m, target in CASES:
        prob = Problem(robot, np.array([0.0, -1.0]), "ot", m, np.radians(qt))
        t, ot, lb = ours(prob)
        tn, otn, starts = naive(prob, t)
        print(f"{name:28s} {t:9.2f} {target:7.1f} {ot:12.6g} {lb:12.6g} {ot / lb - 1:8.2%} "
              f"{otn:22.6g} {otn / ot - 1:13.2%}   ({starts} naive starts; time ratio naive/ours "
              f"{tn / t:.2f})")
        print(f"{'':28s} -> {'meets' if t <= target else 'MISSES'} the {target:.0f} s target")
