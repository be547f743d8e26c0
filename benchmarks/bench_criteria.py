"""Benchmark: M-pose plans for the criteria other than O_t, ours against the baseline in the same run (issue 27,
item 2).

``stiffcal.design`` on the default study's 6-axis arm (config/robots/kuka_kr210_r2700.yaml, the machining test
pose and load of config/config.yaml) for D-optimality at M = 2, 3 and 6, T-optimality at M = 6 and O_t at M = 6
(the reference the issue measures D against). The baseline is the code of commit ``BASELINE_COMMIT`` (before the
closed forms of the exchange step for D and T: every candidate's loss from its information matrix's
eigen-decomposition), extracted with ``git archive`` and run in a subprocess by the same measuring code as ours.
Each figure is CPU seconds of the call (``time.process_time``, one BLAS thread), beside the baseline's, each D figure
as a ratio to O_t's at the same M in our code, then det(M) of our plan over the baseline's and whether both give
the same plan (same O_t to 1e-9, poses to 1e-3 deg). D's and T's plans differ from the baseline's: the 'max'
criteria are now polished in the continuum after the exchange, which the baseline skipped (T's M = 6 plan also
differed for an older reason: at 0fbeb92 it is one pose repeated, O_t infinite).

First, one scoring of the pool by the exchange with the other poses' information regular (the Woodbury path: the
exchange's linear-algebra limit) and singular (every plan of M = 2 on a 6-axis arm: Jacobi-scaled Cholesky over
the batch, the eigen-decomposition only for candidates near singular in fact), ours and the baseline's: the
singular path's cost in multiples of the regular one (issue 27: within 3x).

Run: .venv/bin/python benchmarks/bench_criteria.py   (about 6 minutes, the baseline's D at M = 6 alone ~3)
"""

from bench_plans import ROOT, baseline_src, run, same

#: stiffcal before issue 27's closed forms for D and T
BASELINE_COMMIT = "0fbeb92"

DESIGN = """
import json, time
from stiffcal import api
t0 = time.process_time()
r = api.design("config/robots/kuka_kr210_r2700.yaml", [20, -60, 110, 30, 45, -20], [500, -300, -800],
               experiments={m}, criterion="{criterion}", progress=False)
cpu = time.process_time() - t0
from stiffcal.model.robot import load_robot
from stiffcal.model.stiffness import information_matrix, observation_matrix
import numpy as np
robot = load_robot("config/robots/kuka_kr210_r2700.yaml")
A = observation_matrix(robot.model_jacobian(np.radians(r.poses_deg)), np.array([500.0, -300.0, -800.0]))
print(json.dumps(dict(cpu=cpu, O_t=[r.O_t], poses=[r.poses_deg.round(6).tolist()],
                      det=float(np.linalg.det(information_matrix(A))))))
"""

#: one scoring of the 6-axis pool (8192 candidates) in the exchange, with the other poses' information regular
#: (5 poses: the Woodbury path, the exchange's linear-algebra limit) and singular (1 pose: every plan of M = 2)
SCORING = """
import json, time
import numpy as np
from stiffcal.planning.certificate import candidate_pool, default_pool_step
from stiffcal.planning.plans import exchange_scores, pool_forms
from stiffcal.model.robot import load_robot
from stiffcal.model.stiffness import information_matrix, observation_matrix
robot = load_robot("config/robots/kuka_kr210_r2700.yaml")
F = np.array([500.0, -300.0, -800.0])
rng = np.random.default_rng(0)
lo, hi = robot.joint_limits_rad.T
A = lambda q: observation_matrix(robot.model_jacobian(q), F)
forms = pool_forms(A(candidate_pool(robot, default_pool_step(6))))
Xt = A(np.radians([20, -60, 110, 30, 45, -20]))
out = {}
for rest in (5, 1):
    Ms = [information_matrix(A(rng.uniform(lo, hi, (rest, 6)))) for _ in range(20)]
    t0 = time.process_time()
    for M in Ms:
        exchange_scores(forms, M, Xt)
    out[rest] = (time.process_time() - t0) / len(Ms)
print(json.dumps(dict(regular=out[5], singular=out[1])))
"""


def scoring(base) -> None:
    """The singular path (M = 2) against the regular one, per scoring of the pool, ours and the baseline's."""
    ours, old = run(ROOT / "src", SCORING), run(base, SCORING)
    print("one scoring of the 6-axis pool (8192 candidates) [ms]: other poses regular (Woodbury) / singular (M = 2)")
    for name, r in (("ours", ours), ("baseline", old)):
        print(f"  {name:9s} {1e3 * r['regular']:7.2f} {1e3 * r['singular']:8.2f}   singular / regular "
              f"{r['singular'] / r['regular']:5.1f}x")


if __name__ == "__main__":
    base = baseline_src(BASELINE_COMMIT)
    scoring(base)
    print(f"stiffcal.design, 6-axis arm (KR 210 R2700), CPU seconds, one BLAS thread; baseline = {BASELINE_COMMIT}")
    print(f"{'criterion, M':14s} {'ours [s]':>9s} {'baseline [s]':>12s} {'speed-up':>9s} {'/ O_t':>7s}   "
          "det(M) ours / baseline's")
    ot = {}
    for criterion, m in (("ot", 6), ("d", 6), ("t", 6), ("d", 3), ("ot", 2), ("d", 2)):
        code = DESIGN.replace("{m}", str(m)).replace("{criterion}", criterion)
        ours, old = run(ROOT / "src", code), run(base, code)
        if criterion == "ot":
            ot[m] = ours["cpu"]
        ratio = f"{ours['cpu'] / ot[m]:6.2f}x" if criterion == "d" and m in ot else ""
        label = f"{criterion}, M = {m}"
        print(f"{label:14s} {ours['cpu']:9.2f} {old['cpu']:12.2f} {old['cpu'] / ours['cpu']:8.1f}x {ratio:>7s}   "
              f"{ours['det'] / old['det'] if old['det'] else float('inf'):.4g}   "
              f"{'same plan' if same(ours, old) else 'plans differ'}", flush=True)
