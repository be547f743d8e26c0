"""CPU of the measured-data analysis (``stiffcal.discrepancy.analyse``) on the 6-axis arm, beside a baseline commit
in the same run (issue 23: within 1.5x of the analysis before the error model of the rows' reference readings).

The data sets are simulated once by this tree's stiffcal.truth (the lab's protocols: references per load, per
visit and per configuration with revisits) and written as CSVs; both codes read the same files. Each analysis
runs in its own process (the baseline's src/ first on PYTHONPATH: ``git archive``, no checkout), timed in CPU
seconds of that process after its imports (the median of REPEATS runs), with ``gain=False`` (as the rate matrix
and ``stiffcal discriminate`` call it) and with the gain (as ``stiffcal discrepancy`` does).

Run: .venv/bin/python benchmarks/bench_analysis.py [--baseline 0fbeb92] [--repeats 3]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from stiffcal import rates as R  # noqa: E402
from stiffcal import truth as T  # noqa: E402

CASES = ("3-D pushes x 2, repeated", "hanging x3, reference per visit, 2 passes",
         "gauge +-axes, reference per visit, half revisited", "hanging x3, reference per configuration, half revisited")

TIMER = """
import json, sys, time, os
from stiffcal.robot import load_robot
from stiffcal import discrepancy as D, measurements as M
robot = load_robot(sys.argv[1])
gain = sys.argv[3] == "gain"
qt = [20, -60, 110, 30, 45, -20]
import numpy as np
times = []
for _ in range(int(sys.argv[4])):
    t = time.process_time()
    meas = M.read_measurements(sys.argv[2], robot)
    v = D.analyse(robot, meas, 0.01, np.radians(qt) if gain else None, np.array([500.0, -300, -800]) if gain else None,
                  gain=gain)
    times.append(time.process_time() - t)
print(json.dumps({"cpu": sorted(times)[len(times) // 2], "cause": v["cause"]}))
"""


def export(ref: str, dest: Path) -> None:
    res = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "src"], capture_output=True)
    if res.returncode != 0:
        sys.exit(f"--baseline {ref}: git archive failed: {res.stderr.decode(errors='replace').strip()}")
    subprocess.run(["tar", "-x", "-C", str(dest)], input=res.stdout, check=True)


def run(src: Path, robot: Path, data: Path, gain: bool, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(src), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", TIMER, str(robot), str(data), "gain" if gain else "plain",
                          str(repeats)], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        sys.exit(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="0fbeb92")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    robot_file = ROOT / "config/robots/kuka_kr210_r2700.yaml"
    arm = R.robots(ROOT)["6-axis"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = tmp / "base"
        base.mkdir()
        export(args.baseline, base)
        print(f"analysis of 6-axis data sets (CPU s of one analysis, median of {args.repeats}; one BLAS thread)")
        print(f"{'protocol':58s} {'rows':>5s} {'gain':>5s} {'now':>7s} {args.baseline:>8s} {'now/base':>9s}  verdicts")
        ratios = []
        for i, protocol in enumerate(CASES):
            rng = np.random.default_rng(7 + i)
            log = T.lab_log(arm, R.PROTOCOLS[protocol], rng, 40)
            dp = T.measure(arm, T.Truth(R.compliances(arm)), log, rng)
            data = tmp / f"case{i}.csv"
            data.write_text(T.lab_csv(arm, log, dp), encoding="utf-8")
            for gain in (False, True):
                now = run(ROOT / "src", robot_file, data, gain, args.repeats)
                old = run(base / "src", robot_file, data, gain, args.repeats)
                ratios.append(now["cpu"] / old["cpu"])
                print(f"{protocol:58s} {len(log.q):5d} {str(gain):>5s} {now['cpu']:7.2f} {old['cpu']:8.2f} "
                      f"{ratios[-1]:9.2f}  {now['cause']} / {old['cause']}")
        print(f"geometric mean now/base {np.exp(np.mean(np.log(ratios))):.2f}, largest {max(ratios):.2f} (goal <= 1.5)")


if __name__ == "__main__":
    main()
