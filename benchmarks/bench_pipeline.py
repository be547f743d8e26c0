"""CPU of the whole default pipeline, per rule, from the jobs' own timing.

Copies the workflow (Snakefile, workflow/, config/, paper/, data/) into a temporary directory, runs
``snakemake --cores 2 --workflow-profile workflow/profiles/default`` there from scratch, and prints

* the CPU of every rule: the sum over its jobs of each job's own ``time.process_time()`` at its end
  (interpreter, Snakemake's script preamble, imports and the step; the last line of every job's log,
  written by :func:`stiffcal.pipeline.run`), the number of jobs, and the mean CPU spent before the step
  began (start-up);
* the whole run's CPU (``resource.getrusage(RUSAGE_CHILDREN)``: Snakemake itself, its job wrappers and
  every job), and what Snakemake and the wrappers cost beyond the jobs;
* as the baseline of the same run, the CPU of one bare job start-up (Python importing numpy and pandas,
  which every numeric job needs), and each rule's mean job CPU as a multiple of it.

Snakemake's own ``benchmark:`` files sample CPU every 30 s and miss short jobs; this does not.

    .venv/bin/python benchmarks/bench_pipeline.py [--configfile FILE] [--keep DIR]
"""

from __future__ import annotations

import argparse
import collections
import re
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
LINE = re.compile(r"\[stiffcal\] cpu rule=(\S+) wildcards=(\S+) total=([0-9.]+) before_step=([0-9.]+)")
TARGET_CPU_S = 60.0


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def copy_workflow(dest: Path) -> None:
    for item in ("Snakefile", "workflow", "config", "paper", "data"):
        src = ROOT / item
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dest / item)
    shutil.rmtree(dest / "paper" / "build", ignore_errors=True)


def bare_startup() -> float:
    """CPU [s] of a Python process that imports numpy and pandas (what every numeric job must load)."""
    before = children_cpu()
    subprocess.run([sys.executable, "-c", "import numpy, pandas"], check=True)
    return children_cpu() - before


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--configfile", help="a config replacing config/config.yaml (default: the default pipeline)")
    ap.add_argument("--keep", help="run in this directory (created) and keep it")
    args = ap.parse_args()
    wd = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="stiffcal-bench-"))
    wd.mkdir(parents=True, exist_ok=True)
    copy_workflow(wd)
    extra = ["--configfile", str(Path(args.configfile).resolve())] if args.configfile else []
    base = bare_startup()
    before = children_cpu()
    res = subprocess.run([str(BIN / "snakemake"), "--cores", "2", "--workflow-profile", "workflow/profiles/default",
                          "--quiet", *extra], cwd=wd, capture_output=True, text=True)
    total = children_cpu() - before
    if res.returncode != 0:
        print(res.stderr[-3000:], file=sys.stderr)
        return 1
    per_rule = collections.defaultdict(list)
    for log in sorted((wd / "logs").rglob("*.log")):
        for m in LINE.finditer(log.read_text(encoding="utf-8")):
            per_rule[m.group(1)].append((float(m.group(3)), float(m.group(4))))
    jobs_cpu = sum(t for v in per_rule.values() for t, _ in v)
    print(f"{'rule':<20} {'jobs':>4} {'CPU [s]':>8} {'share':>6} {'start-up [s]':>13} {'mean job / bare start-up':>25}")
    for rule, v in sorted(per_rule.items(), key=lambda kv: -sum(t for t, _ in kv[1])):
        cpu = sum(t for t, _ in v)
        start = sum(b for _, b in v) / len(v)
        ratio = cpu / len(v) / base
        print(f"{rule:<20} {len(v):>4} {cpu:>8.2f} {100 * cpu / total:>5.1f}% {start:>13.3f} {ratio:>25.1f}")
    n_jobs = sum(len(v) for v in per_rule.values())
    print(f"{'jobs (sum)':<20} {n_jobs:>4} {jobs_cpu:>8.2f} {100 * jobs_cpu / total:>5.1f}%")
    print(f"{'snakemake + wrappers':<20} {'':>4} {total - jobs_cpu:>8.2f} {100 * (total - jobs_cpu) / total:>5.1f}%")
    print(f"{'whole run':<20} {'':>4} {total:>8.2f}   (target {TARGET_CPU_S:g} s: {total / TARGET_CPU_S:.2f} x)")
    print(f"baseline in this run: a bare job start-up (python -c 'import numpy, pandas') = {base:.3f} s CPU")
    if not args.keep:
        shutil.rmtree(wd, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
