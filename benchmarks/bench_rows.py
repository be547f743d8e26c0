"""How the measured-data analysis grows with the rows (issue 28): a lab log of hanging masses (4 loads, repeated:
8 rows a configuration, so 10^5 rows are 12,500 configurations) simulated by stiffcal.testing.truth for the 2-link
and the 6-axis arm at 400 .. 200,000 rows (stiffcal.limits.MAX_MEASURED_ROWS; beyond it a log is refused at the read),
read and analysed in this process (one BLAS thread) as `stiffcal discrepancy` does
(stiffcal.measured.discrepancy.run: the verdict with the leave-one-configuration-out check, the figures and the
calibrated model written); prints the CPU seconds of the read and the run, the peak memory, and the CPU per row
against the smallest size in the same run (1.0: linear).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_rows.py [ARM ...]   (default 2-link 6-axis; about
ten minutes)
"""

import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from stiffcal.measured import discrepancy as D
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T
from stiffcal.measured.measurements import read_measurements

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = (50, 1250, 12500, 25000)  # x 8 rows: 400, 10,000, 100,000, 200,000


def main(arms) -> None:
    robots = R.robots(ROOT)
    for arm in arms:
        robot, base = robots[arm], None
        for n_cfg in CONFIGS:
            rng = np.random.default_rng(0)
            log = T.lab_log(robot, R.PROTOCOLS["hanging x4, repeated"], rng, n_cfg)
            dp = T.measure(robot, T.Truth(R.compliances(robot)), log, rng)
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "log.csv"
                path.write_text(T.lab_csv(robot, log, dp), encoding="utf-8")
                t0 = time.process_time()
                meas = read_measurements(path, robot)
                t1 = time.process_time()
                verdict = D.run(robot, str(path), str(Path(tmp) / "out"), 0.01)
                t2 = time.process_time()
            per_row = (t2 - t0) / meas.n_rows
            base = base or per_row
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024
            print(f"{arm:7s} {meas.n_rows:7d} rows  read {t1 - t0:6.2f} s  run (read, analyse, write) "
                  f"{t2 - t1:6.2f} s  peak {peak:5d} MB  CPU per row {per_row / base:5.2f} x the smallest  "
                  f"verdict {verdict['cause']}",
                  flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["2-link", "6-axis"])
