"""The next experiment (stiffcal.measured.discrimination): predicted power against the simulated rate of separation,
the plans' efficiency, and the exchange against a naive random search given the same CPU time.

Cases: old data in which the analysis cannot tell two causes apart (each simulated with stiffcal.testing.truth, or
the repository's SYNTHETIC data set), in the paper's 2-link arm, a 3-link arm and the 6-axis KUKA. For every
case the discriminating plan of 6 points (stiffcal discriminate's defaults), the best plans of 1, 2 and 3
points, and random plans whose predicted power lies between 0.2 and 0.9 are measured on simulated truth:
each rival in turn as the truth (its fitted model; link bending, coupled joints and an offset simulated by
stiffcal.testing.truth's physics), the analysis run on old and new data together, REPS repetitions. A row prints
the predicted power of the separating F-test, the simulated rate of separation (the verdict lists the truth's
combination and not the rival's) and the difference in binomial standard errors.

Run: .venv/bin/python benchmarks/discrimination.py [REPS]     (default 300; about 15 minutes of CPU)
"""

import sys
import time
from pathlib import Path

import numpy as np

from stiffcal.measured import discrepancy as D
from stiffcal.measured import discrimination as X
from stiffcal.testing import separation as S
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T
from stiffcal.measured.measurements import Measurements, read_measurements
from stiffcal.model.robot import load_robot, planar_robot

ROOT = Path(__file__).resolve().parents[1]


def simulated(robot, protocol, effect, seed, n_configs, size, k):
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, protocol, rng, n_configs)
    truth = R._scaled_truth(effect, R._unit_truth(effect, robot, k, rng, log), T.Truth(k), robot, log,
                            size * protocol.sigma_m)
    dp = T.measure(robot, truth, log, rng)
    return Measurements.from_arrays(log.q, log.force, dp, config=log.config)


def cases():
    paper = load_robot(ROOT / "config/robots/paper_2r.yaml")
    three = planar_robot([0.5, 0.4, 0.3], "3-link")
    kuka = load_robot(ROOT / "config/robots/kuka_kr210_r2700.yaml")
    yield ("2-link, data/synthetic_paper_2r_hanging.csv", paper,
           read_measurements(ROOT / "data/synthetic_paper_2r_hanging.csv", paper), "hanging:100,300,600")
    yield ("3-link, one hanging mass, backlash", three,
           simulated(three, T.Protocol("h", magnitudes_N=(400.0,)), "backlash", 3, 16, 1.0, R.compliances(three)),
           "hanging:400,800")
    yield ("3-link, hanging x2, joint coupling", three,
           simulated(three, T.Protocol("h", magnitudes_N=(200.0, 500.0)), "joint_coupling", 0, 12, 3.0,
                     R.compliances(three)), "directions:4:300")
    yield ("6-axis, 3-D pushes, link bending", kuka,
           simulated(kuka, T.Protocol("p", loads="pushes3d", n_directions=2, magnitudes_N=(600.0,)),
                     "link_compliance", 1, 8, 1.0, R.compliances(kuka)), "directions:6:600")


def naive_delta(crit, m, seconds, seed=0):
    """The best Delta of random m-point plans from the pool drawn for ``seconds`` of CPU."""
    rng = np.random.default_rng(seed)
    best, start = 0.0, time.process_time()
    while time.process_time() - start < seconds:
        best = max(best, float(crit.deltas(rng.choice(crit.size, m)).min()))
    return best


def main(reps: int = 300) -> None:
    rows = []
    for label, robot, meas, loads in cases():
        v = D.analyse(robot, meas, 0.01, gain=False)
        start = time.process_time()
        res = X.discriminate(robot, meas, 6, X.load_set(loads, robot.task_dim, meas.force), verdict=v)
        cpu = time.process_time() - start
        rm = res.rivals
        names = " vs ".join(m.label for m in rm.models)
        print(f"\n{label}: {names}; design pairs {[(rm.models[t].label, rm.models[j].label) for t, j in res.pairs]}")
        print(f"  discriminate (M = 6, default effort): {cpu:.1f} s CPU; power {res.power}; certificate: "
              f"efficiency {res.certificate.efficiency:.3f}, power bound {res.certificate.power_bound:.4f}")
        pool = X.make_pool(robot, X.pose_pool(robot), res.loads.forces, {c for m in rm.models for c in m.causes})
        crit = X.build_criterion(rm, pool, list(res.pairs))
        start = time.process_time()
        ex = X.exchange(crit, 6)
        t_ex = time.process_time() - start
        ours = crit.deltas(ex.indices).min()
        naive = naive_delta(crit, 6, t_ex)
        print(f"  exchange over the pool: {t_ex:.2f} s CPU, Delta {ours:.4g}; naive random plans in the same CPU: "
              f"Delta {naive:.4g} (ratio {naive / ours:.3f})")
        plans = [("discriminating M=6", np.radians(res.plan.poses_deg), res.plan.forces_N)]
        for m in (1, 2, 3):
            idx = X.exchange(crit, m, 1).indices
            plans.append((f"best M={m}", pool.q[idx], pool.force[idx]))
        rng = np.random.default_rng(1)
        for _ in range(400):
            idx = rng.choice(len(pool), 2)
            p = min(pp.power for t in range(len(rm.models))
                    for pp in X.plan_power(rm, pool.q[idx], pool.force[idx], 1, t))
            if 0.2 < p < 0.9:
                plans.append(("random M=2", pool.q[idx], pool.force[idx]))
                if len(plans) == 6:
                    break
        for name, q, F in plans:
            for t in range(len(rm.models)):
                for s in S.simulate_separation(rm, q, F, 1, t, reps, seed=len(rows)):
                    se = np.sqrt(max(s.predicted * (1 - s.predicted), 1.0 / reps) / reps)
                    z = (s.rate - s.predicted) / se
                    rows.append((s.predicted, s.rate, z))
                    print(f"  {name:20s} truth {'+'.join(s.truth):26s} rival {'+'.join(s.rival):26s} predicted "
                          f"{s.predicted:.3f}  simulated {s.rate:.3f}  ({z:+.1f} SE)", flush=True)
    p, r, z = (np.array(c) for c in zip(*rows))
    print(f"\n{len(rows)} comparisons of {reps} repetitions: "
          f"mean |simulated - predicted| {np.mean(np.abs(r - p)):.3f}, "
          f"largest {np.max(np.abs(r - p)):.3f}; within 3 SE: {np.mean(np.abs(z) <= 3):.0%}; "
          f"mean (simulated - predicted) {np.mean(r - p):+.3f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
