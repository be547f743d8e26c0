"""CPU of the whole default pipeline, per rule, from the jobs' own timing, beside a baseline of the same run.

Copies the workflow (Snakefile, workflow/, config/, paper/, data/) into a temporary directory, runs
``snakemake --cores 2 --workflow-profile workflow/profiles/default`` there from scratch, and prints

* the CPU of every rule: the sum over its jobs of each job's own ``time.process_time()`` at its end
  (interpreter, Snakemake's script preamble, imports and the step; the last line of every job's log,
  written by :func:`stiffcal.workflow.pipeline.run`), the number of jobs, and the mean CPU spent before the step
  began (start-up);
* the whole run's CPU (``resource.getrusage(RUSAGE_CHILDREN)``: Snakemake itself, its job wrappers and
  every job; what ``/usr/bin/time`` reports for ``make clean report``), and what Snakemake and the wrappers
  cost beyond the jobs;
* the CPU of ``snakemake -n`` with nothing to do after the run (median of 3: the config check, the code
  versions and the DAG; issue 27 asks for at most 2 s);
* as the baseline of the same run, the CPU of one bare job start-up (Python importing numpy and pandas,
  which every numeric job needs), and each rule's mean job CPU as a multiple of it; with ``--baseline REF``
  also the whole pipeline of the git commit REF (its workflow and its ``src/``, first on ``PYTHONPATH``; same
  interpreter and packages), run in the same way first, rule by rule beside this one, as ratios.

Snakemake's own ``benchmark:`` files sample CPU every 30 s and miss short jobs; this does not.

    .venv/bin/python benchmarks/bench_pipeline.py [--baseline REF] [--configfile FILE] [--keep DIR]
"""

from __future__ import annotations

import argparse
import collections
import os
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
WORKFLOW = ("Snakefile", "workflow", "config", "paper", "data")


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def copy_workflow(dest: Path) -> None:
    for item in WORKFLOW:
        src = ROOT / item
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dest / item)
    shutil.rmtree(dest / "paper" / "build", ignore_errors=True)


def export_commit(ref: str, dest: Path) -> None:
    """The workflow and src/ of the git commit ``ref`` into ``dest`` (git archive: no checkout)."""
    res = subprocess.run(["git", "-C", str(ROOT), "archive", ref, *WORKFLOW, "src"], capture_output=True)
    if res.returncode != 0:
        sys.exit(f"--baseline {ref}: git archive failed: {res.stderr.decode(errors='replace').strip()}")
    archive = res.stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    shutil.rmtree(dest / "paper" / "build", ignore_errors=True)


def bare_startup() -> float:
    """CPU [s] of a Python process that imports numpy and pandas (what every numeric job must load)."""
    before = children_cpu()
    subprocess.run([sys.executable, "-c", "import numpy, pandas"], check=True)
    return children_cpu() - before


def run_pipeline(wd: Path, extra: list[str], env: dict | None = None) -> tuple[float, dict]:
    """(whole run's CPU [s], rule -> [(job CPU, CPU before the step)]) of one run from scratch in ``wd``."""
    before = children_cpu()
    res = subprocess.run([str(BIN / "snakemake"), "--cores", "2", "--workflow-profile", "workflow/profiles/default",
                          "--quiet", *extra], cwd=wd, capture_output=True, text=True, env=env)
    total = children_cpu() - before
    if res.returncode != 0:
        sys.exit(f"the pipeline failed in {wd}:\n{res.stderr[-3000:]}")
    per_rule = collections.defaultdict(list)
    for log in sorted((wd / "logs").rglob("*.log")):
        for m in LINE.finditer(log.read_text(encoding="utf-8")):
            per_rule[m.group(1)].append((float(m.group(3)), float(m.group(4))))
    return total, per_rule


def dry_run_cpu(wd: Path, extra: list[str], env: dict | None = None, repeats: int = 3) -> float:
    """Median CPU [s] of ``snakemake -n`` with nothing to do in ``wd`` (after a complete run there)."""
    runs = []
    for _ in range(repeats):
        before = children_cpu()
        res = subprocess.run([str(BIN / "snakemake"), "-n", "--cores", "2", "--workflow-profile",
                              "workflow/profiles/default", "--quiet", *extra], cwd=wd, capture_output=True, text=True,
                             env=env)
        runs.append(children_cpu() - before)
        if res.returncode != 0:
            sys.exit(f"the dry run failed in {wd}:\n{res.stderr[-3000:]}")
    return sorted(runs)[len(runs) // 2]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", metavar="REF", help="also run the pipeline of this git commit (e.g. main) first")
    ap.add_argument("--configfile", help="a config replacing config/config.yaml (default: the default pipeline)")
    ap.add_argument("--keep", help="run in this directory (created) and keep it")
    args = ap.parse_args()
    if args.baseline and subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet",
                                         f"{args.baseline}^{{commit}}"], capture_output=True).returncode != 0:
        sys.exit(f"--baseline {args.baseline}: not a commit of {ROOT}")
    wd = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="stiffcal-bench-"))
    wd.mkdir(parents=True, exist_ok=True)
    copy_workflow(wd)
    extra = ["--configfile", str(Path(args.configfile).resolve())] if args.configfile else []
    base_total, base_rules = None, {}
    if args.baseline:
        bd = Path(tempfile.mkdtemp(prefix="stiffcal-bench-baseline-"))
        export_commit(args.baseline, bd)
        path = os.pathsep.join(filter(None, [str(bd / "src"), os.environ.get("PYTHONPATH")]))
        env = {**os.environ, "PYTHONPATH": path}
        base_total, base_rules = run_pipeline(bd, extra, env)
        base_dry = dry_run_cpu(bd, extra, env)
        shutil.rmtree(bd, ignore_errors=True)
    base = bare_startup()
    total, per_rule = run_pipeline(wd, extra)
    dry = dry_run_cpu(wd, extra)

    def cpu(v):
        return sum(t for t, _ in v)

    jobs_cpu = sum(cpu(v) for v in per_rule.values())
    head = f"{'rule':<20} {'jobs':>4} {'CPU [s]':>8} {'share':>6} {'start-up [s]':>13} {'job / bare start-up':>20}"
    print(head + (f" {'baseline jobs':>14} {'CPU [s]':>8} {'now/base':>9}" if args.baseline else ""))
    for rule in sorted(set(per_rule) | set(base_rules), key=lambda r: -cpu(per_rule.get(r, base_rules.get(r)))):
        v = per_rule.get(rule, [])
        line = f"{rule:<20} {len(v):>4} {cpu(v):>8.2f} {100 * cpu(v) / total:>5.1f}%"
        line += (f" {sum(b for _, b in v) / len(v):>13.3f} {cpu(v) / len(v) / base:>20.1f}" if v else f" {'':>34}")
        if args.baseline:
            b = base_rules.get(rule, [])
            ratio = f"{cpu(v) / cpu(b):>9.2f}" if v and b else f"{'':>9}"
            line += f" {len(b):>14} {cpu(b):>8.2f} {ratio}"
        print(line)
    n_jobs = sum(len(v) for v in per_rule.values())
    rows = [("jobs (sum)", n_jobs, jobs_cpu, sum(len(v) for v in base_rules.values()),
             sum(cpu(v) for v in base_rules.values())),
            ("snakemake + wrappers", "", total - jobs_cpu, "",
             None if base_total is None else base_total - sum(cpu(v) for v in base_rules.values())),
            ("whole run", "", total, "", base_total)]
    for name, n, c, bn, bc in rows:
        line = f"{name:<20} {n:>4} {c:>8.2f} {100 * c / total:>5.1f}%"
        if args.baseline:
            line += f" {'':>34} {bn:>14} {bc:>8.2f} {c / bc:>9.2f}"
        print(line)
    print(f"whole run: {total:.1f} s of CPU (target {TARGET_CPU_S:g} s: {total / TARGET_CPU_S:.2f} x the target)"
          + (f"; baseline {args.baseline}: {base_total:.1f} s" if args.baseline else ""))
    print(f"snakemake -n with nothing to do: {dry:.2f} s of CPU (median of 3; target 2 s)"
          + (f"; baseline {args.baseline}: {base_dry:.2f} s ({dry / base_dry:.2f}x)" if args.baseline else ""))
    print(f"baseline in this run: a bare job start-up (python -c 'import numpy, pandas') = {base:.3f} s CPU")
    if not args.keep:
        shutil.rmtree(wd, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
