"""The test matrix of the discrepancy analysis: how often the verdict names a hidden effect, over seeds.

Every catalogue cause, four effects outside the catalogue (a tracker drift; a compliance that varies over the
joint's turn; a load pulled off its logged direction; a backlash held by friction, whose unloaded readings keep
the jump) and clean data, hidden under every measurement protocol that suits the robot (hanging weights,
pushes in four directions, 3-D pushes, one random load; repeated on the spot, interleaved, not repeated;
unloaded reference rows; tracker noise growing with distance) in the 2-link, 3-link and 6-axis arms. Each
case is written as a lab's CSV with and without pose_id and analysed both ways (stiffcal.testing.rates). Effect
sizes are drawn log-uniformly; a case counts for an effect when the oracle test that knows the effect's
exact shape has power >= 0.9 (stiffcal.testing.rates); the rates are also printed against a weaker oracle that
knows which cause is present but not its parameters (the F-test of that cause's regressors). Also printed,
for two effects at once, the rate at which both are named.

Run: .venv/bin/python benchmarks/rates_discrepancy.py [SEEDS] [ALPHA] [JOBS] [CLEAN_SEEDS] [ONLY] [clean] (defaults 20
seeds, alpha 0.01, 1 process, clean cells with SEEDS seeds too; JOBS processes share the cells, with the same
seeds and output; CLEAN_SEEDS: more seeds for the clean cells, whose false-alarm rate per protocol needs several
hundred cases for its 95 % interval to end below 2 alpha; beyond the first 20 seeds of a clean cell only the
CSV with pose_id is analysed). Two more optional arguments run a slice of the matrix: ONLY, comma-separated parts
of protocol names ("reference per visit,one hanging mass": those protocols alone; separated by | instead when a
part holds a comma: "hanging x3, reference per configuration, half revisited|"), and the word clean (the clean
cells alone, for the false-alarm rate per protocol). Prints one row per robot x protocol x effect: named /
qualifying (rate), or for clean data false alarms / cases; then the totals per effect, the false alarms and
rates per protocol, and the share of cases where the two CSV variants give the same verdict. Requirements
(issues 12, 23): every catalogue cause >= 95 %; on every protocol, clean data at most alpha with the upper end
of the 95 % interval below 2 alpha; the variants agree.
"""

import multiprocessing
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

from scipy import stats

from stiffcal.measured import discrepancy as D
from stiffcal.testing import rates as R

ROOT = Path(__file__).resolve().parents[1]
#: effects and protocols added to the matrix after its first runs (their cells come after the others', which keep
#: their seeds)
LATE = ("held_backlash",)
LATE_PROTOCOLS = ("gauge +-axes 3 deg off axis, reference per visit, half revisited",)
PAIRS = {"2-link": ("backlash", "measurement_offset"), "3-link": ("joint_coupling", "nonlinear_joint_stiffness"),
         "6-axis": ("link_compliance", "backlash")}


def _cell(args):
    """The cases of one robot x protocol x effects cell (seeds: cell index x 1000 x the largest seeds + s)."""
    index, arm, protocol, effects, seeds, alpha, base, both = args
    robot = R.robots(ROOT)[arm]
    with tempfile.TemporaryDirectory() as tmp:
        cases = [R.run_case(arm, robot, protocol, effects, 1000 * index * base + s, alpha, workdir=tmp,
                            both=both or s < 20) for s in range(seeds)]
    return cases


def protocol_filter(only: str | None):
    """``picked(protocol) -> bool`` for an ONLY argument (module docstring): comma-separated parts of protocol
    names, or separated by | when a part holds a comma; None or empty: every protocol."""
    wanted = [w.strip() for w in only.split("|" if "|" in only else ",") if w.strip()] if only else []
    return lambda protocol: not wanted or any(w in protocol for w in wanted)


def main(seeds: int = 20, alpha: float = 0.01, jobs: int = 1, clean_seeds: int | None = None,
         only: str | None = None, effects_only: str | None = None) -> None:
    arms = R.robots(ROOT)
    start = time.process_time()
    clean_seeds = seeds if clean_seeds is None else clean_seeds
    picked = protocol_filter(only)
    grid = sorted([(arm, protocol) for arm, robot in arms.items() for protocol in R.protocols_for(robot)
                   if picked(protocol)],
                  key=lambda cell: cell[1] in LATE_PROTOCOLS)  # stable: the late protocols last, the rest in order
    if effects_only:  # the cells of these effects and the clean ones
        chosen = [e for e in effects_only.split(",") if e != "clean"]
        cells = [(arm, protocol, effects) for arm, protocol in grid
                 for effects in [(e,) for e in chosen] + [()]]
    else:  # effects added after the matrix's first runs (LATE) come last, so that the other cells keep their seeds
        cells = [(arm, protocol, effects) for arm, protocol in grid
                 for effects in [(e,) for e in R.EFFECTS if e not in LATE] + [()] + [PAIRS[arm]]]
        cells += [(arm, protocol, (e,)) for arm, protocol in grid for e in LATE]
    # clean cells beyond SEEDS seeds analyse the pose_id variant alone (the variants' agreement is counted on the
    # first 20 seeds of every cell)
    tasks = [(i, *cell, clean_seeds if not cell[2] else seeds, alpha, max(seeds, clean_seeds), bool(cell[2]))
             for i, cell in enumerate(cells)]
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
    lo, hi = stats.binomtest(clean["false_alarms"], clean["cases"]).proportion_ci(0.95)
    print(f"{'clean data':28s} false alarms {clean['false_alarms']} of {clean['cases']} ({clean['rate']:.2%}, 95 % CI "
          f"{lo:.2%}-{hi:.2%}; alpha {alpha:.0%}); warnings (a drift, a tilted load, a return that keeps the "
          f"jump) {clean['warnings']}")
    print()
    print(f"Per protocol (clean data: false alarms, the upper end of the 95 % interval must be below {2 * alpha:.0%}; "
          "catalogue causes: named where the exact-shape oracle has power >= 0.9):")
    for protocol in R.PROTOCOLS:
        mine = [c for c in single if c.protocol == protocol]
        if not mine:
            continue
        t = R.rates(mine)
        c = t.get("clean", {"false_alarms": 0, "cases": 0, "warnings": 0})
        hi = stats.binomtest(c["false_alarms"], c["cases"]).proportion_ci(0.95)[1] if c["cases"] else float("nan")
        named = sum(t[k]["named"] for k in D.CAUSES if k in t)
        qual = sum(t[k]["qualifying"] for k in D.CAUSES if k in t)
        rate = named / qual if qual else float("nan")
        print(f"  {protocol:58s} false alarms {c['false_alarms']:3d}/{c['cases']:4d} (upper {hi:.2%}) warnings "
              f"{c['warnings']:3d}   causes named {named:4d}/{qual:4d} ({rate:.1%})")
    print()
    pairs = [c for c in everything if len(c.effects) == 2 and min(c.power.values()) >= 0.9]
    print(f"{'two effects at once':28s} both named in {sum(all(c.named(e) for e in c.effects) for c in pairs)} of "
          f"{len(pairs)} qualifying cases")
    print(f"{'variants agree':28s} {R.rates(everything)['variants_agree']:.1%} of "
          f"{sum(c.compared for c in everything)} cases analysed both ways")
    cpu = time.process_time() - start + (sum(_children_cpu()) if jobs > 1 else 0.0)
    print(f"CPU {cpu:.0f} s ({jobs} process{'es' if jobs > 1 else ''})")


def _children_cpu():
    import resource
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime, usage.ru_stime


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, float(sys.argv[2]) if len(sys.argv) > 2 else 0.01,
         int(sys.argv[3]) if len(sys.argv) > 3 else 1, int(sys.argv[4]) if len(sys.argv) > 4 else None,
         sys.argv[5] if len(sys.argv) > 5 else None, sys.argv[6] if len(sys.argv) > 6 else None)
