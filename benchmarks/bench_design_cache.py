"""Benchmark: ``stiffcal design`` with the approximate-design cache against the baseline in the same run (issue 27,
item 1).

The command a lab runs, ``stiffcal design`` on the default study's 6-axis arm (config/robots/kuka_kr210_r2700.yaml,
the machining test pose and load of config/config.yaml), as a whole process (imports included): CPU seconds
(user + system of the child, one BLAS thread; medians of REPEATS runs) of

* one call at M = 6: the baseline commit's (``BASELINE_COMMIT``, before the cache), ours with ``--no-cache``,
  and ours with the cache filled by an earlier call (the approximate design, its certificate and the candidate
  pool read back: :mod:`stiffcal.planning.designcache`);
* a study of M = 2..8 as a script runs it (seven calls, the cache empty at the first): the baseline's and ours,
  each beside one call of its own at M = 6; and ours in one call (``--experiments 2-8``).

Also checked: the plan of every call is the same with and without the cache (the JSON byte for byte).
Requirements (issue 27): a 6-axis design at M = 6 <= 1/3 of the baseline's CPU; a study of M = 2..8 <= 2x the
cost of one M.

Run: .venv/bin/python benchmarks/bench_design_cache.py [REPEATS]   (default 3; about 6 minutes)
"""

import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_plans import ROOT, baseline_src

#: stiffcal before the approximate-design cache (the commit issue 27 measured against)
BASELINE_COMMIT = "0fbeb92"
ARGS = ["design", "--robot", "config/robots/kuka_kr210_r2700.yaml", "--test-pose-deg", "20,-60,110,30,45,-20",
        "--force-N", "500,-300,-800", "--quiet"]
MAIN = "import sys; from stiffcal.cli import main; sys.exit(main(sys.argv[1:]))"
STUDY = range(2, 9)


def call(src: Path, m, extra=()) -> tuple[float, str]:
    """(CPU seconds, stdout) of one ``stiffcal design`` process with stiffcal imported from ``src``."""
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    res = subprocess.run([sys.executable, "-c", MAIN, *ARGS, "--experiments", str(m), *extra], cwd=ROOT, env=env,
                         capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if res.returncode:
        raise RuntimeError(f"stiffcal design failed:\n{res.stderr}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), res.stdout


def median(values) -> float:
    return statistics.median(values)


def main(repeats: int = 3) -> None:
    base = baseline_src(BASELINE_COMMIT)
    ours = ROOT / "src"
    with tempfile.TemporaryDirectory() as tmp:
        warm = ["--cache-dir", str(Path(tmp) / "warm")]
        call(ours, 6, warm)  # fills the cache
        one = {"baseline": median(call(base, 6)[0] for _ in range(repeats)),
               "no cache": median(call(ours, 6, ["--no-cache"])[0] for _ in range(repeats)),
               "cache filled": median(call(ours, 6, warm)[0] for _ in range(repeats))}
        studies = {"baseline": [], "ours": [], "one call": []}
        same = True
        for r in range(repeats):
            studies["baseline"].append(sum(call(base, m)[0] for m in STUDY))
            cache = ["--cache-dir", str(Path(tmp) / f"study{r}")]
            total = 0.0
            for m in STUDY:
                cpu, out = call(ours, m, cache)
                total += cpu
                if r == 0:
                    same &= out == call(ours, m, ["--no-cache"])[1]
            studies["ours"].append(total)
            studies["one call"].append(call(ours, "2-8", ["--cache-dir", str(Path(tmp) / f"one{r}")])[0])
    print(f"stiffcal design, 6-axis arm, CPU seconds (medians of {repeats}); baseline {BASELINE_COMMIT}")
    print("| call | CPU s | / baseline |")
    print("|---|---|---|")
    for name, cpu in one.items():
        print(f"| M = 6, {name} | {cpu:.2f} | {cpu / one['baseline']:.2f} |")
    study_base, study_ours = median(studies["baseline"]), median(studies["ours"])
    print(f"| study M = 2..8 (7 calls), baseline | {study_base:.2f} | 1.00 (x{study_base / one['baseline']:.2f} "
          "its one M = 6) |")
    print(f"| study M = 2..8 (7 calls), ours, cache empty at the first | {study_ours:.2f} | "
          f"{study_ours / study_base:.2f} (x{study_ours / one['no cache']:.2f} our one M = 6) |")
    one_call = median(studies["one call"])
    print(f"| study M = 2..8, ours in one call (--experiments 2-8), cache empty | {one_call:.2f} | "
          f"{one_call / study_base:.2f} (x{one_call / one['no cache']:.2f} our one M = 6) |")
    print(f"plans with and without the cache identical (JSON byte for byte, M = 2..8): {same}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
