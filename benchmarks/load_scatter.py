"""A load whose direction scatters push by push (a hand-held gauge held off the axis it logs): false alarms and the
``diagnostics.load_scatter`` warning, over seeds.

For every arm, the gauge protocol of the test matrix held 3 deg off its axis (RMS; stiffcal.testing.truth.Protocol
.gauge_angle_deg) and, for the warning's level, the same gauge held on its axis and every other protocol of the lab's
own reference readings and the old matrix's pushes, SEEDS clean logs each (the CSV with pose_id, analysed by
stiffcal.testing.rates.run_case). Prints per cell the verdict's false alarms, the load_scatter warnings at alpha =
1 %, the false alarms the warning accompanies, and the median RMS angle it finds.

Run: .venv/bin/python benchmarks/load_scatter.py [SEEDS] [JOBS] (defaults 100, 1; seeds from 60,000,000)
"""

import multiprocessing
import statistics
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

from scipy import stats

from rates_discrepancy import _children_cpu
from stiffcal.testing import rates as R

ROOT = Path(__file__).resolve().parents[1]
ALPHA = 0.01
OFF_AXIS = "gauge +-axes 3 deg off axis, reference per visit, half revisited"
LEVEL = [p for p, pr in R.PROTOCOLS.items() if p != OFF_AXIS and (pr.passes > 1 or pr.loads in ("directions",
                                                                                                   "pushes3d"))]


def _cell(args):
    index, arm, protocol, seeds = args
    robot = R.robots(ROOT)[arm]
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in range(seeds):
            v = R.run_case(arm, robot, protocol, (), 60_000_000 + 10_000 * index + s, ALPHA, workdir=tmp,
                           both=False).verdict_with_pose_id
            scatter = v["diagnostics"]["load_scatter"]
            out.append((v["cause"] != "none", bool(scatter and scatter["p_value"] <= ALPHA),
                        None if scatter is None else scatter["angle_rms_deg"]))
    return out


def main(seeds: int = 100, jobs: int = 1) -> None:
    start = time.process_time()
    arms = R.robots(ROOT)
    cells = [(arm, p) for arm, robot in arms.items() for p in [OFF_AXIS, *LEVEL] if p in R.protocols_for(robot)]
    level = [0, 0]
    with multiprocessing.Pool(jobs) if jobs > 1 else nullcontext() as pool:
        tasks = [(i, arm, p, seeds) for i, (arm, p) in enumerate(cells)]
        for (arm, protocol), cases in zip(cells, (pool.imap if jobs > 1 else map)(_cell, tasks)):
            alarms = sum(a for a, _, _ in cases)
            warned = sum(w for _, w, _ in cases)
            both = sum(a and w for a, w, _ in cases)
            angles = [g for _, w, g in cases if w]
            if protocol != OFF_AXIS:
                level[0] += warned
                level[1] += len(cases)
            print(f"{arm:7s} {protocol:66s} false alarms {alarms:3d}/{len(cases)}, warned {warned:3d}, of the false "
                  f"alarms warned {both}, median angle found "
                  f"{statistics.median(angles) if angles else float('nan'):.2f} deg", flush=True)
    lo, hi = stats.binomtest(level[0], level[1]).proportion_ci(0.95)
    print(f"warning's level (every protocol but the gauge off its axis): {level[0]} of {level[1]} "
          f"({level[0] / level[1]:.2%}, 95 % CI {lo:.2%}-{hi:.2%}; alpha 1 %)")
    print(f"CPU {time.process_time() - start + (sum(_children_cpu()) if jobs > 1 else 0.0):.0f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
