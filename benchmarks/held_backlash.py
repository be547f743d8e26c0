"""A backlash held by friction (outside the catalogue) under the lab's protocols: what the analysis says, over seeds.

The simulator's gear (stiffcal.testing.truth.gear_sides) rests on one flank of its gap and moves to the other only
when the total torque passes its friction torque (a fifth of the joint's median load torque): an unloaded reading
after a load keeps the jump unless the arm's weight brings the gear back. For every arm and every protocol with the
lab's own reference readings, SEEDS cases with the effect (sizes log-uniform, as in rates_discrepancy.py) and
CLEAN seeds of clean data, the CSV with pose_id analysed (stiffcal.testing.rates.run_case). Prints per cell, among
the cases where the exact-shape oracle has power >= 0.9, how the verdict names it: the return-to-zero warning
(diagnostics.return_to_zero at alpha), `unexplained`, the catalogue's `backlash` (what the gear is wherever the
weight brings it back), or not at all; and on clean data the return-to-zero warnings at alpha (its level) and the
verdict's false alarms.

Run: .venv/bin/python benchmarks/held_backlash.py [SEEDS] [CLEAN] [JOBS] [ONLY] (defaults 30, 100, 1; seeds from
40,000,000; ONLY: parts of protocol names, as rates_discrepancy.py's, a slice of the cells with the seeds they have
in the whole run)
"""

import multiprocessing
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

from scipy import stats

from rates_discrepancy import _children_cpu, protocol_filter
from stiffcal.testing import rates as R

ROOT = Path(__file__).resolve().parents[1]
ALPHA = 0.01
LAB = [p for p, pr in R.PROTOCOLS.items() if pr.reference in ("visit", "configuration") and pr.passes > 1]


def _cell(args):
    index, arm, protocol, effects, seeds = args
    robot = R.robots(ROOT)[arm]
    with tempfile.TemporaryDirectory() as tmp:
        return [R.run_case(arm, robot, protocol, effects, 40_000_000 + 10_000 * index + s, ALPHA, workdir=tmp,
                           both=False) for s in range(seeds)]


def _how(case) -> str:
    v = case.verdict_with_pose_id
    rz = (v.get("diagnostics") or {}).get("return_to_zero")
    if rz and rz["p_value"] <= v["alpha"]:
        return "warned"
    if v["cause"] == "unexplained":
        return "unexplained"
    return "backlash" if case.named("held_backlash") else "missed"


def main(seeds: int = 30, clean: int = 100, jobs: int = 1, only: str | None = None) -> None:
    start = time.process_time()
    arms = R.robots(ROOT)
    # a gauge held off its axis (a protocol added later) last, so that the other cells keep their seeds
    cells = [(arm, p, effects) for late in (False, True) for arm, robot in arms.items() for p in LAB
             if p in R.protocols_for(robot) and (R.PROTOCOLS[p].gauge_angle_deg > 0) == late
             for effects in (("held_backlash",), ())]
    tasks = [(i, *cell, seeds if cell[2] else clean) for i, cell in enumerate(cells)
             if protocol_filter(only)(cell[1])]
    totals: dict = {}
    with multiprocessing.Pool(jobs) if jobs > 1 else nullcontext() as pool:
        for (_, arm, protocol, effects, _), cases in zip(tasks, (pool.imap if jobs > 1 else map)(_cell, tasks)):
            if effects:
                powered = [c for c in cases if c.power["held_backlash"] >= 0.9]
                how = [_how(c) for c in powered]
                counts = {k: how.count(k) for k in ("warned", "unexplained", "backlash", "missed")}
                t = totals.setdefault(protocol, {"powered": 0, "named": 0, "warnings": 0, "clean": 0, "alarms": 0})
                t["powered"] += len(powered)
                t["named"] += len(powered) - counts["missed"]
                print(f"{arm:7s} {protocol:62s} powered {len(powered):3d}/{len(cases)}: "
                      + ", ".join(f"{k} {n}" for k, n in counts.items()), flush=True)
            else:
                warned = sum(bool((c.verdict_with_pose_id.get("diagnostics") or {}).get("return_to_zero"))
                             and c.verdict_with_pose_id["diagnostics"]["return_to_zero"]["p_value"] <= ALPHA
                             for c in cases)
                alarms = sum(c.false_alarm for c in cases)
                t = totals[protocol]
                t["warnings"] += warned
                t["clean"] += len(cases)
                t["alarms"] += alarms
                print(f"{arm:7s} {protocol:62s} clean: return-to-zero warnings {warned}/{len(cases)}, "
                      f"false alarms {alarms}", flush=True)
    print()
    for protocol, t in totals.items():
        lo, hi = stats.binomtest(t["warnings"], t["clean"]).proportion_ci(0.95)
        print(f"{protocol:62s} named {t['named']:3d}/{t['powered']:3d}; clean: warnings {t['warnings']}/{t['clean']} "
              f"(95 % CI {lo:.1%}-{hi:.1%}), false alarms {t['alarms']}")
    print(f"CPU {time.process_time() - start + (sum(_children_cpu()) if jobs > 1 else 0.0):.0f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:4]), *sys.argv[4:5])
