"""Where the powered catalogue causes that the analysis does not name are lost, under the lab's reference protocols.

For every arm x lab protocol (the protocols with the lab's own reference readings, stiffcal.testing.rates.PROTOCOLS) x
catalogue cause, SEEDS cases are simulated and analysed as a lab would (stiffcal.testing.rates.run_case, the CSV with
pose_id). A case is *powered* when the exact-shape oracle (a 1-degree-of-freedom test of the effect's noise-free
displacement, the rows' true covariance known) has power >= 0.9; the cause-block oracle knows the cause but not its
parameters (the F-test of its regressors, no multiplicity). Each powered case that the verdict does not name is put
in one of three classes:

- *model*: the cause-block oracle has power < 0.5: the analysis's regressors of that cause cannot represent what the
  simulator's physics did (a catalogue blind spot);
- *test*: the analysis's own closed test on the rows whitened by their true covariance (stiffcal.testing.rates.
  oracle_global_p; the noise scale known, the lack-of-fit test left out) rejects nothing either: the loss is the
  price of not knowing the cause (five causes, their blocks and single parameters, the lack of fit) at this
  effect size, not of the estimated error model;
- *estimation*: that closed test with the true covariance does reject: the estimated noise weights and variance
  components lost it.

Prints per protocol: named / powered under both oracles, the mean exact-oracle power of the powered cases (the rate
the oracle itself would reach), and the misses by class; then the totals. Seeds: 77,000,000 + 1000 x (CRC-32 of
arm|protocol|cause mod 1000) + s, independent of the matrix's (benchmarks/rates_discrepancy.py).
Run: .venv/bin/python benchmarks/powered_misses.py [SEEDS] [JOBS] [ALPHA] [ONLY]   (defaults 30 seeds, 2 processes,
0.01; 3,150 cases, about 37 minutes of CPU at 30 seeds; ONLY: parts of protocol names, as rates_discrepancy.py's (a
slice: "gauge" runs the two hand-held gauge protocols alone))
"""
import multiprocessing
import resource
import sys
import tempfile
import time
import zlib
from collections import defaultdict
from pathlib import Path

from rates_discrepancy import protocol_filter
from stiffcal.measured import discrepancy as D
from stiffcal.testing import rates as R

ROOT = Path(__file__).resolve().parents[1]
LAB = [p for p, pr in R.PROTOCOLS.items() if pr.reference in ("visit", "configuration") and pr.passes > 1]


def _seed(arm: str, protocol: str, cause: str, s: int) -> int:
    return 77_000_000 + 1000 * (zlib.crc32(f"{arm}|{protocol}|{cause}".encode()) % 1000) + s


def _case(args):
    arm, protocol, cause, seed, alpha = args
    robot = R.robots(ROOT)[arm]
    with tempfile.TemporaryDirectory() as tmp:
        case = R.run_case(arm, robot, protocol, (cause,), seed, alpha, workdir=tmp, both=False)
    power, block = case.power[cause], case.power_block[cause]
    kind = None
    if power >= 0.9 and not case.named(cause):
        if block < 0.5:
            kind = "model"
        else:
            log, dp, _ = R.simulate_case(robot, protocol, (cause,), seed)
            kind = "estimation" if R.oracle_global_p(robot, log, dp, alpha) <= alpha else "test"
    return protocol, power, block, case.named(cause), kind


def main(seeds: int = 30, jobs: int = 2, alpha: float = 0.01, only: str | None = None) -> None:
    start = time.process_time()
    arms = R.robots(ROOT)
    lab = [p for p in LAB if protocol_filter(only)(p)]
    tasks = [(arm, p, c, _seed(arm, p, c, s), alpha) for arm, robot in arms.items() for p in lab
             if p in R.protocols_for(robot) for c in D.CAUSES for s in range(seeds)]
    with multiprocessing.Pool(jobs) as pool:
        out = list(pool.imap(_case, tasks, chunksize=4))
    rows = defaultdict(list)
    for r in out:
        rows[r[0]].append(r)
    rows = {p: rows[p] for p in lab if rows[p]} | {"all lab protocols": out}
    print(f"{'protocol':62s} {'exact':>15s} {'block':>15s} {'oracle':>7s}   misses: model / test / estimation")
    for protocol, rs in rows.items():
        exact = [r for r in rs if r[1] >= 0.9]
        block = [r for r in rs if r[2] >= 0.9]
        kinds = [r[4] for r in exact if r[4]]

        def frac(sel):
            named = sum(r[3] for r in sel)
            return f"{named}/{len(sel)} {100 * named / max(len(sel), 1):5.1f}%"
        mean_power = sum(r[1] for r in exact) / max(len(exact), 1)
        print(f"{protocol:62s} {frac(exact):>15s} {frac(block):>15s} {100 * mean_power:6.1f}%   "
              f"{kinds.count('model')} / {kinds.count('test')} / {kinds.count('estimation')}")
    cpu = time.process_time() - start + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    print(f"{len(tasks)} cases, {cpu:.0f} s of CPU in {jobs} processes")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(*(int(x) for x in a[:2]), *(float(x) for x in a[2:3]), *a[3:4])
