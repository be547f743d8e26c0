"""How often the blunder screen flags rows of clean simulated logs (no blunder), and how often a cause is named, per
protocol of the rate matrix (stiffcal.testing.rates.protocols_for), for one arm: a change of the screen must not
flag more rows of clean data.
Run: .venv/bin/python benchmarks/blunder_flags.py ARM [SEEDS] [FIRST_SEED]   (ARM: 2-link, 3-link or 6-axis; defaults
40 seeds from 7000)
"""
import sys
import tempfile
import time
from pathlib import Path

from stiffcal.measured import discrepancy as D
from stiffcal.measured.measurements import read_measurements
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T

ROOT = Path(__file__).resolve().parents[1]


def main(arm: str, seeds: int = 40, first: int = 7000) -> None:
    start = time.process_time()
    robot = R.robots(ROOT)[arm]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log.csv"
        for protocol in R.protocols_for(robot):
            flagged = named = 0
            for seed in range(first, first + seeds):
                log, dp, _ = R.simulate_case(robot, protocol, (), seed)
                path.write_text(T.lab_csv(robot, log, dp, pose_id=True), encoding="utf-8")
                v = D.analyse(robot, read_measurements(path, robot), 0.01, gain=False)
                flagged += bool(v["outlier_rows"])
                named += v["cause"] != "none"
            print(f"{arm}, {protocol}: rows flagged in {flagged} of {seeds} clean logs, a cause named in {named}",
                  flush=True)
    print(f"{time.process_time() - start:.0f} s of CPU")


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:4]))
