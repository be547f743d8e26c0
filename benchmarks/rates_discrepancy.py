"""The test matrix of the discrepancy analysis: how often the verdict names a hidden effect, over seeds.

Every catalogue cause, two effects outside the catalogue (a tracker drift; a compliance that varies over the
joint's turn) and clean data, hidden under every measurement protocol that suits the robot (hanging weights,
pushes in four directions, 3-D pushes, one random load; repeated on the spot, interleaved, not repeated;
unloaded reference rows; tracker noise growing with distance) in the 2-link, 3-link and 6-axis arms. Each
case is written as a lab's CSV with and without pose_id and analysed both ways (stiffcal.rates). Effect
sizes are drawn log-uniformly; a case counts for an effect when the oracle test that knows the effect's
exact shape has power >= 0.9 (stiffcal.rates); the rates are also printed against a weaker oracle that
knows which cause is present but not its parameters (the F-test of that cause's regressors). Also printed,
for two effects at once, the rate at which both are named.

Run: .venv/bin/python benchmarks/rates_discrepancy.py [SEEDS] [ALPHA] [JOBS]     (defaults 20 seeds, alpha
0.01, 1 process; about 10 minutes of CPU at 20 seeds; JOBS processes share the cells, with the same seeds and
output). Prints one row per robot x protocol x effect: named / qualifying (rate), or for clean data false
alarms / cases; then the totals per effect and the share of cases where the two CSV variants give the same
verdict. Requirements (issue 12): every catalogue cause >= 95 %, clean data
<= alpha, the variants agree.
"""

import multiprocessing
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

from scipy import stats

from stiffcal import discrepancy as D
from stiffcal import rates as R

ROOT = Path(__file__).resolve().parents[1]
PAIRS = {"2-link": ("backlash", "measurement_offset"), "3-link": ("joint_coupling", "nonlinear_joint_stiffness"),
         "6-axis": ("link_compliance", "backlash")}


def _cell(args):
    """The cases of one robot x protocol x effects cell (seeds as in the serial order: cell index x seeds + s)."""
    index, arm, protocol, effects, seeds, alpha = args
    robot = R.robots(ROOT)[arm]
    with tempfile.TemporaryDirectory() as tmp:
        cases = [R.run_case(arm, robot, protocol, effects, 1000 * index * seeds + s, alpha, workdir=tmp)
                 for s in range(seeds)]
    return cases


def main(seeds: int = 20, alpha: float = 0.01, jobs: int = 1) -> None:
    arms = R.robots(ROOT)
    start = time.process_time()
    cells = [(arm, protocol, effects) for arm, robot in arms.items() for protocol in R.protocols_for(robot)
             for effects in [(e,) for e in R.EFFECTS] + [()] + [PAIRS[arm]]]
    tasks = [(i, *cell, seeds, alpha) for i, cell in enumerate(cells)]
    everything = []
    with multiprocessing.Pool(jobs) if jobs > 1 else nullcontext() as pool:
        results = pool.imap(_cell, tasks) if jobs > 1 else map(_cell, tasks)
        for (arm, protocol, effects), cases in zip(cells, results):
            everything += cases
            table = R.rates(cases)
            label = " + ".join(effects) or "clean"
            if not effects:
                cell = f"false alarms {table['clean']['false_alarms']}/{table['clean']['cases']}"
            elif len(effects) == 2:
                both = [c for c in cases if min(c.power.values()) >= 0.9]
                hit = sum(all(c.named(e) for e in effects) for c in both)
                cell = f"both named {hit}/{len(both)}"
            else:
                row = table[effects[0]]
                cell = f"named {row['named']}/{row['qualifying']}"
            print(f"{arm:7s} {protocol:40s} {label:45s} {cell:24s} variants agree "
                  f"{table['variants_agree']:.0%}", flush=True)
    print()
    single = [c for c in everything if len(c.effects) <= 1]
    for oracle, what in (("exact", "exact-shape oracle (1 degree of freedom)"),
                         ("block", "cause-block oracle (the cause's regressors, no multiplicity)")):
        print(f"Cases where the {what} has power >= 0.9:")
        total = R.rates(single, oracle=oracle)
        for key in [*D.CAUSES, *R.OUTSIDE]:
            row = total.get(key)
            if row and row["qualifying"]:
                lo, hi = stats.binomtest(row["named"], row["qualifying"]).proportion_ci(0.95)
                goal = ">= 95 %" if key in D.CAUSES else "(outside the catalogue: no goal)"
                print(f"  {key:28s} named {row['named']:4d} of {row['qualifying']:4d} ({row['rate']:.1%}, 95 % CI "
                      f"{lo:.1%}-{hi:.1%}) {goal}")
    total = R.rates(single)
    clean = total["clean"]
    print(f"{'clean data':28s} false alarms {clean['false_alarms']} of {clean['cases']} ({clean['rate']:.2%}; alpha "
          f"{alpha:.0%})")
    pairs = [c for c in everything if len(c.effects) == 2 and min(c.power.values()) >= 0.9]
    print(f"{'two effects at once':28s} both named in {sum(all(c.named(e) for e in c.effects) for c in pairs)} of "
          f"{len(pairs)} qualifying cases")
    print(f"{'variants agree':28s} {R.rates(everything)['variants_agree']:.1%} of {len(everything)} cases")
    cpu = time.process_time() - start + (sum(_children_cpu()) if jobs > 1 else 0.0)
    print(f"CPU {cpu:.0f} s ({jobs} process{'es' if jobs > 1 else ''})")


def _children_cpu():
    import resource
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime, usage.ru_stime


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, float(sys.argv[2]) if len(sys.argv) > 2 else 0.01,
         int(sys.argv[3]) if len(sys.argv) > 3 else 1)
