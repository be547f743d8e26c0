"""CPU of the measured-data analysis (``stiffcal.measured.discrepancy.analyse``) on the 6-axis arm, beside a baseline
commit in the same run (issue 23: within 1.5x of the analysis before the error model of the rows' reference readings).

The data sets are simulated once by this tree's stiffcal.testing.truth (the lab's protocols: references per load, per
visit and per configuration with revisits) and written as CSVs; both codes read the same files. Each analysis
runs in its own process (the baseline's src/ first on PYTHONPATH: ``git archive``, no checkout), timed in CPU
seconds of that process after its imports (the median of REPEATS runs), with ``gain=False`` (as the rate matrix
and ``stiffcal discriminate`` call it) and with the gain (as ``stiffcal discrepancy`` does).

Then the whole ``stiffcal discrepancy`` process (interpreter, imports, reading, analysis, files; issue 27, item 3:
a 200-row 6-axis data set at most 1/3 of the baseline's CPU) on 200 rows of hanging masses with a reference per
visit: with its figures, and with ``--no-figures`` (the baseline always draws its one figure), CPU of the child
process (user + system), median of REPEATS.

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

from stiffcal.testing import rates as R  # noqa: E402
from stiffcal.testing import truth as T  # noqa: E402

CASES = ("3-D pushes x 2, repeated", "hanging x3, reference per visit, 2 passes",
         "gauge +-axes, reference per visit, half revisited", "hanging x3, reference per configuration, half revisited")

TIMER = """
import json, sys, time, os
try:
    from stiffcal.model.robot import load_robot
    from stiffcal.measured import discrepancy as D
    from stiffcal.measured import measurements as M
except ImportError:  # a baseline before the subpackages (0fbeb92)
    from stiffcal.robot import load_robot
    from stiffcal import discrepancy as D
    from stiffcal import measurements as M
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


def cli_cpu(src: Path, args: list[str], repeats: int) -> float:
    """Median CPU seconds (user + system of the child) of ``python -c 'stiffcal.cli.main()' ARGS`` with src first
    on the path."""
    env = {**os.environ, "PYTHONPATH": str(src), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    times = []
    for _ in range(repeats):
        before = os.times()
        out = subprocess.run([sys.executable, "-c", "import sys; from stiffcal.cli import main; sys.exit(main())",
                              *args], capture_output=True, text=True, env=env)
        after = os.times()
        if out.returncode != 0:
            sys.exit(out.stderr[-2000:])
        times.append((after.children_user - before.children_user) + (after.children_system - before.children_system))
    return sorted(times)[len(times) // 2]


def whole_process(base: Path, robot_file: Path, tmp: Path, repeats: int, baseline: str) -> None:
    """The CLI's CPU on a 200-row 6-axis data set, now (with and without figures) against the baseline."""
    arm = R.robots(ROOT)["6-axis"]
    rng = np.random.default_rng(7)
    log = T.lab_log(arm, R.PROTOCOLS["hanging x3, reference per visit, 2 passes"], rng, 20)
    dp = T.measure(arm, T.Truth(R.compliances(arm)), log, rng)
    data = tmp / "cli200.csv"
    data.write_text(T.lab_csv(arm, log, dp), encoding="utf-8")
    common = ["discrepancy", "--robot", str(robot_file), "--data", str(data)]
    old = cli_cpu(base / "src", common + ["--out", str(tmp / "b")], repeats)
    print(f"\nthe whole `stiffcal discrepancy` process, {len(log.q)} rows of the 6-axis arm "
          f"(CPU s, median of {repeats})")
    print(f"{'call':40s} {'CPU s':>7s} {'/ ' + baseline:>10s}")
    print(f"{baseline + ' (one figure)':40s} {old:7.2f} {1.0:10.2f}")
    for name, extra in (("now, three figures", []), ("now, --no-figures", ["--no-figures"])):
        now = cli_cpu(ROOT / "src", common + ["--out", str(tmp / "n"), "--quiet", *extra], repeats)
        print(f"{name:40s} {now:7.2f} {now / old:10.2f}")
    print("(goal: at most 1/3 of the baseline)")


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
        whole_process(base, robot_file, tmp, args.repeats, args.baseline)


if __name__ == "__main__":
    main()
