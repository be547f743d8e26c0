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

Run: .venv/bin/python benchmarks/bench_spatial.py   (about a minute)
"""

from bench_plans import ROOT, baseline_src, run

KUKA = """
import json, time
import numpy as np
from stiffcal.certificate import approximate_design
from stiffcal.design import Problem
from stiffcal.plans import optimise_plan, round_design
from stiffcal.robot import load_robot
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
from stiffcal.certificate import approximate_design
from stiffcal.design import Problem
from stiffcal.plans import optimise_plan, round_design
from stiffcal.robot import load_robot
robot = load_robot("tests/data/irb140_no_limits.yaml")
force, qt, m = np.array([100.0, 0.0, -100.0]), np.radians([0, 20, -20, 0, 45, 0]), 6
t0 = time.process_time()
design = approximate_design(Problem(robot, force, "ot", 1, qt))
t1 = time.process_time()
plan = optimise_plan(Problem(robot, force, "ot", m, qt), starts=[round_design(design, m)])
print(json.dumps(dict(cpu=t1 - t0, O_t=plan.loss, bound=design.lower_bound(m), gap=design.max_phi / design.phi - 1)))
"""

if __name__ == "__main__":
    base = baseline_src()
    print("CPU seconds, one BLAS thread; baseline = stiffcal before issue 16 (bench_plans.BASELINE_COMMIT)")
    ours, old = run(ROOT / "src", KUKA), run(base, KUKA)
    print(f"6-axis KR 210, M = 6 with certificate: ours {ours['cpu']:.2f} s (design {ours['design']:.2f} + plan "
          f"{ours['plan']:.2f}), baseline {old['cpu']:.2f} s (design {old['design']:.2f} + plan {old['plan']:.2f}): "
          f"{old['cpu'] / ours['cpu']:.1f}x faster; target 3 s: {'meets' if ours['cpu'] <= 3.0 else 'MISSES'}")
    for who, r in (("ours", ours), ("baseline", old)):
        print(f"  {who:8s} O_t {r['O_t']:.6g} m^2, bound {r['bound']:.6g}, plan {r['O_t'] / r['bound'] - 1:.2%} above it, "
              f"equivalence gap {r['gap']:.2e}")
    ours, old = run(ROOT / "src", IRB140), run(base, IRB140)
    print(f"ABB IRB 140 case, M = 6: design + certificate ours {ours['cpu']:.2f} s, baseline {old['cpu']:.2f} s "
          f"({old['cpu'] / ours['cpu']:.1f}x)")
    for who, r in (("ours", ours), ("baseline", old)):
        print(f"  {who:8s} equivalence gap {r['gap']:.2e} ({'converged' if r['gap'] <= 1e-3 else 'NOT converged'}), "
              f"bound {r['bound']:.6g} (independently certified: about 0.1345), 6-pose plan O_t {r['O_t']:.6g} "
              f"= {r['O_t'] / r['bound'] - 1:.1%} above the bound")
