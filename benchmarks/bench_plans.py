"""Benchmark: M-pose plans, ours against the baseline (stiffcal before issue 16) in the same run.

Figures (issue 16, item 2): ``ot_versus_m`` of the paper's arm (the workflow rule: the best plan for every
m = 1..m_max, the approximate design given) for m_max = 5, 10, 20, and an M = 10 plan of a 3-link planar arm.
The baseline is the code of commit ``BASELINE_COMMIT`` (general-inverse / per-candidate Woodbury scoring of
the exchange step, and its certificate), extracted with ``git archive`` and run in a subprocess by the same
measuring code as ours. Each figure is CPU seconds (``time.process_time`` of the job, one BLAS thread), printed
beside the baseline's as a ratio, with whether both give the same plans (same O_t to 1e-9, poses to 1e-3 deg).

Run: .venv/bin/python benchmarks/bench_plans.py   (about 2 minutes; the baseline's m_max = 20 alone ~50 s)
"""

import json
import os
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: stiffcal before issue 16 (the baseline of every figure)
BASELINE_COMMIT = "80d2fc9"


def baseline_src(commit: str = BASELINE_COMMIT) -> Path:
    """The ``src`` of the baseline commit (with its schemas) and its ``config/config.yaml`` (which its schema
    accepts; the keys the benchmarks read are unchanged since) extracted from git into a temporary directory."""
    out = Path(tempfile.mkdtemp(prefix="stiffcal-baseline-"))
    for part in ("src", "workflow/schemas", "config/config.yaml"):
        blob = subprocess.run(["git", "-C", str(ROOT), "archive", commit, part], check=True,
                              capture_output=True).stdout
        with tarfile.open(fileobj=BytesIO(blob)) as tar:
            tar.extractall(out, filter="data")
    schemas = out / "src/stiffcal/schemas"
    if schemas.is_symlink() or not schemas.exists():
        schemas.unlink(missing_ok=True)
        schemas.symlink_to(out / "workflow/schemas", target_is_directory=True)
    return out / "src"


def run(src: Path, code: str) -> dict:
    """Run ``code`` (which prints one JSON object) with stiffcal imported from ``src``, one BLAS thread."""
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True)
    if res.returncode:
        raise RuntimeError(f"benchmark job failed:\n{res.stderr}")
    return json.loads(res.stdout.strip().splitlines()[-1])


OT_VERSUS_M = """
import json, time
import numpy as np
from stiffcal.paper import tables
from stiffcal.planning.certificate import approximate_design
from stiffcal.planning.study import load_config, study_from_config
study = study_from_config(load_config("{config}"), ".")
design = approximate_design(study.problem("ot", 1))
t0 = time.process_time()
df = tables.ot_versus_m(study, range(1, {m_max} + 1), 0, design)
print(json.dumps(dict(cpu=time.process_time() - t0, O_t=df.O_t.tolist(), poses=df.poses_deg.tolist())))
"""

THREE_LINK = """
import json, time
import numpy as np
from stiffcal.planning.certificate import approximate_design
from stiffcal.planning.problem import Problem
from stiffcal.planning.plans import optimise_plan, round_design
from stiffcal.model.robot import planar_robot
robot = planar_robot([0.5, 0.35, 0.15])
prob = Problem(robot, np.array([0.0, -1.0]), "ot", 10, np.radians([30.0, 40.0, -20.0]))
design = approximate_design(Problem(robot, prob.force, "ot", 1, prob.test_pose))
t0 = time.process_time()
plan = optimise_plan(prob, starts=[round_design(design, 10)])
print(json.dumps(dict(cpu=time.process_time() - t0, O_t=[plan.loss], poses=[plan.poses_deg.round(4).tolist()])))
"""


def _poses(p) -> np.ndarray:
    return np.array([[float(v) for v in q.split()] for q in p.split(";")]) if isinstance(p, str) else np.array(p)


def same(a: dict, b: dict) -> bool:
    """Same O_t (to 1e-9) and poses (to 1e-3 deg) for every plan."""
    close = all(abs(x - y) <= 1e-9 * abs(y) for x, y in zip(a["O_t"], b["O_t"]))
    return close and len(a["O_t"]) == len(b["O_t"]) and all(
        _poses(p).shape == _poses(q).shape and np.allclose(_poses(p), _poses(q), atol=1e-3)
        for p, q in zip(a["poses"], b["poses"]))


def compare(name: str, code: str, base: Path) -> tuple[float, float]:
    """Run one job with ours and the baseline, print the line; returns both CPU times."""
    ours = run(ROOT / "src", code.replace("{config}", "config/config.yaml"))
    old = run(base, code.replace("{config}", str(base.parent / "config/config.yaml")))
    print(f"{name:34s} {ours['cpu']:9.2f} {old['cpu']:12.2f} {old['cpu'] / ours['cpu']:9.1f}x   "
          f"{'same plans' if same(ours, old) else 'PLANS DIFFER'}", flush=True)
    return ours["cpu"], old["cpu"]


if __name__ == "__main__":
    base = baseline_src()
    print(f"CPU seconds, one BLAS thread; baseline = stiffcal at {BASELINE_COMMIT} (before issue 16)")
    print(f"{'job':34s} {'ours [s]':>9s} {'baseline [s]':>12s} {'speed-up':>9s}")
    cpu = [compare(f"ot_versus_m, m_max = {m_max}", OT_VERSUS_M.replace("{m_max}", str(m_max)), base)
           for m_max in (5, 10, 20)]
    growth = [[b[k] / a[k] for a, b in zip(cpu, cpu[1:])] for k in (0, 1)]
    print(f"ot_versus_m growth as m_max doubles (5 -> 10, 10 -> 20; linear: x2.0): ours "
          f"x{growth[0][0]:.2f}, x{growth[0][1]:.2f}; baseline x{growth[1][0]:.2f}, x{growth[1][1]:.2f}", flush=True)
    compare("3-link planar arm, M = 10", THREE_LINK, base)
