"""Benchmark: the certificate and plans of 6-axis arms, ours against the baseline (stiffcal before issue 16)
in the same run.

Figures (issue 16, items 2-3):
- the M = 6 plan of the default 6-axis study (config/robots/kuka_kr210_r2700.yaml, machining pose, ~1 kN)
  with its certificate (approximate design + plan): CPU seconds (target: at most 3 s), O_t, bound, gap;
- the ABB IRB 140 case (tests/data/irb140_no_limits.yaml; test pose (0, 20, -20, 0, 45, 0) deg, force
  (100, 0, -100) N, M = 6): the equivalence gap and the bound (an independent computation certifies about
  0.1345; the baseline printed 0.0972 with a gap of 0.39-0.92).
The baseline is the code of commit ``bench_plans.BASELINE_COMMIT`` run by the same measuring code in a
subprocess; CPU seconds by ``time.process_time`` with one BLAS thread, printed beside each other as ratios.

With ``--random-arms N`` it also designs for N random 6-axis arms with random joint limits, test poses and
forces (seeds 0..N-1) and checks each certificate against an independent search (500,000 random poses,
half of them on the limits, L-BFGS-B from the best 100: ``stiffcal.testing.reference.max_phi_reference``).

Run: .venv/bin/python benchmarks/bench_spatial.py [--random-arms N]   (about a minute, plus ~10 s an arm)
"""

import sys

from bench_plans import ROOT, baseline_src, run

KUKA = """
import json, time
import numpy as np
from stiffcal.planning.certificate import approximate_design
from stiffcal.planning.problem import Problem
from stiffcal.planning.plans import optimise_plan, round_design
from stiffcal.model.robot import load_robot
robot = load_robot("config/robots/kuka_kr210_r2700.yaml")
force, qt, sigma, m = np.array([500.0, -300.0, -800.0]), np.radians([20, -60, 110, 30, 45, -20]), 1e-5, 6
t0 = time.process_time()
design = approximate_design(Problem(robot, force, "ot", 1, qt, None, sigma))
t1 = time.process_time()
plan = optimise_plan(Problem(robot, force, "ot", m, qt, None, sigma), starts=[round_design(design, m)])
t2 = time.process_time()
print(json.dumps(dict(cpu=t2 - t0, design=t1 - t0, plan=t2 - t1, O_t=plan.loss, bound=design.lower_bound(m, sigma),
                      gap=design.max_phi / design.phi - 1)))
"""

IRB140 = """
import json, time
import numpy as np
from stiffcal.planning.certificate import approximate_design
from stiffcal.planning.problem import Problem
from stiffcal.planning.plans import optimise_plan, round_design
from stiffcal.model.robot import load_robot
robot = load_robot("tests/data/irb140_no_limits.yaml")
force, qt, m = np.array([100.0, 0.0, -100.0]), np.radians([0, 20, -20, 0, 45, 0]), 6
t0 = time.process_time()
design = approximate_design(Problem(robot, force, "ot", 1, qt))
t1 = time.process_time()
plan = optimise_plan(Problem(robot, force, "ot", m, qt), starts=[round_design(design, m)])
print(json.dumps(dict(cpu=t1 - t0, O_t=plan.loss, bound=design.lower_bound(m), gap=design.max_phi / design.phi - 1)))
"""

RANDOM_ARM = """
import json, time
import numpy as np
from stiffcal.planning.certificate import approximate_design
from stiffcal.planning.problem import Problem
from stiffcal.testing.reference import max_phi_reference
from stiffcal.model.robot import spatial_robot
rng = np.random.default_rng({seed})
rows = np.column_stack([rng.uniform(-0.5, 0.8, 6), rng.choice([-90, 0, 90, 37], 6), rng.uniform(-0.4, 0.6, 6),
                        rng.uniform(-60, 60, 6)])
centre, half = rng.uniform(-60, 60, 6), rng.uniform(60, 200, 6)
robot = spatial_robot(rows, rng.uniform(-0.2, 0.3, 3), joint_limits_deg=np.column_stack([centre - half, centre + half]))
lo, hi = robot.joint_limits_rad.T
prob = Problem(robot, rng.normal(size=3) * 100, "ot", 1, rng.uniform(lo, hi))
t0 = time.process_time()
d = approximate_design(prob)
cpu = time.process_time() - t0
top, _ = max_phi_reference(prob, np.radians(d.support_deg), d.weights, searches=500_000, polish_top=100)
print(json.dumps(dict(cpu=cpu, gap=d.equivalence_gap, converged=d.converged, excess=top / d.max_phi - 1)))
"""


def random_arms(count: int) -> None:
    bad = 0
    for seed in range(count):
        r = run(ROOT / "src", RANDOM_ARM.format(seed=seed))
        ok = r["converged"] and r["excess"] <= 1e-6
        bad += not ok
        print(f"  random arm {seed:2d}: {r['cpu']:.2f} s, equivalence gap {r['gap']:.1e}, independent search above our "
              f"maximum of phi by {max(r['excess'], 0.0):.1e} {'' if ok else '  <-- FAILS'}", flush=True)
    print(f"random 6-axis arms with limits: {count - bad} of {count} converged and certified")


if __name__ == "__main__":
    if "--random-arms" in sys.argv:
        random_arms(int(sys.argv[sys.argv.index("--random-arms") + 1]))
        sys.exit(0)
    base = baseline_src()
    print("CPU seconds, one BLAS thread; baseline = stiffcal before issue 16 (bench_plans.BASELINE_COMMIT)")
    ours, old = run(ROOT / "src", KUKA), run(base, KUKA)
    print(f"6-axis KR 210, M = 6 with certificate: ours {ours['cpu']:.2f} s (design {ours['design']:.2f} + plan "
          f"{ours['plan']:.2f}), baseline {old['cpu']:.2f} s (design {old['design']:.2f} + plan {old['plan']:.2f}): "
          f"{old['cpu'] / ours['cpu']:.1f}x faster; target 3 s: {'meets' if ours['cpu'] <= 3.0 else 'MISSES'}")
    for who, r in (("ours", ours), ("baseline", old)):
        print(f"  {who:8s} O_t {r['O_t']:.6g} m^2, bound {r['bound']:.6g}, "
              f"plan {r['O_t'] / r['bound'] - 1:.2%} above it, equivalence gap {r['gap']:.2e}")
    ours, old = run(ROOT / "src", IRB140), run(base, IRB140)
    print(f"ABB IRB 140 case, M = 6: design + certificate ours {ours['cpu']:.2f} s, baseline {old['cpu']:.2f} s "
          f"({old['cpu'] / ours['cpu']:.1f}x)")
    for who, r in (("ours", ours), ("baseline", old)):
        print(f"  {who:8s} equivalence gap {r['gap']:.2e} ({'converged' if r['gap'] <= 1e-3 else 'NOT converged'}), "
              f"bound {r['bound']:.6g} (independently certified: about 0.1345), 6-pose plan O_t {r['O_t']:.6g} "
              f"= {r['O_t'] / r['bound'] - 1:.1%} above the bound")
