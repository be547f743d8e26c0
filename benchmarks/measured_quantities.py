"""Benchmark: what moments, orientation and several targets change (issue 15), on data simulated by
stiffcal.testing.truth and written as the CSVs a lab would write.

1. Moments: hanging weights on a loading bar 0.3 m from the tool point (a moment r x F about it), the 2-link
   arm and the 6-axis arm. Prints the relative error of the identified compliances with the moment columns,
   and without them (what the reader did before issue 15: the moments dropped), beside their 95 % intervals.
2. A bending link and joint coupling of the planar 2-link arm: over seeds, how often the verdict names
   link_compliance alone (separated) with the position of one point, with two targets, and with the
   orientation.
3. CPU time of the O_t-optimal 6-pose plan with its certificate for the 6-axis arm, with a force and the tool
   point's position (the paper's problem) and with a wrench, two targets and the orientation.

Run: .venv/bin/python benchmarks/measured_quantities.py   (single-threaded BLAS is forced below; CPU seconds)
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from stiffcal.measured import discrepancy as D  # noqa: E402
from stiffcal.testing import rates as R  # noqa: E402
from stiffcal.testing import truth as T  # noqa: E402
from stiffcal.api import design  # noqa: E402
from stiffcal.measured.measurements import read_measurements  # noqa: E402
from stiffcal.model.robot import load_robot, with_targets  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _verdict(robot, protocol, truth, seed, drop=(), n_configs=30):
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, protocol, rng, n_configs)
    text = T.lab_csv(robot, log, T.measure(robot, truth, log, rng))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.csv"
        path.write_text(text)
        if drop:
            pd.read_csv(path, dtype=str).drop(columns=list(drop)).to_csv(path, index=False)
        return D.analyse(robot, read_measurements(path, robot), 0.01, gain=False)


def moments():
    print("1. moments (loading bar 0.3 m; compliance errors in %, 95 % interval in brackets)")
    for name, protocol in (("paper_2r", "hanging x4, repeated"), ("kuka_kr210_r2700", "3-D pushes x 2, repeated")):
        robot = load_robot(ROOT / f"config/robots/{name}.yaml")
        k = R.compliances(robot)
        prot = replace(R.PROTOCOLS[protocol], lever_m=0.3)
        cols = ["mz_Nm"] if robot.kind == "planar" else ["mx_Nm", "my_Nm", "mz_Nm"]
        for label, drop in (("with the moment columns", ()), ("moments dropped       ", cols)):
            v = _verdict(robot, prot, T.Truth(k), 0, drop)
            err = 100 * (np.array(v["nominal"]["k"]) / k - 1)
            ci = 100 * np.array(v["nominal"]["k_ci95"]) / k
            cells = " ".join(f"k{i + 1} {e:+6.1f} ({c:.1f})" for i, (e, c) in enumerate(zip(err, ci)))
            print(f"   {robot.name:18s} {label}: {cells}; verdict {v['cause']}")


def separation(seeds=20):
    print(f"2. 2-link arm, bending links (1/(EI) = 2e-6 1/(N m^2)), 4 directions x 2 loads at 30 configurations: "
          f"verdicts of {seeds} seeds (link alone / link with coupling indistinguishable / other)")
    base = load_robot(ROOT / "config/robots/paper_2r.yaml")
    robot = with_targets(base, {"A": [-0.1, 0.05], "B": [-0.3, 0.1]}, "benchmark")
    truth = T.Truth(R.compliances(robot), link_bending=np.full(robot.n_segments, 2e-6))
    prot = R.PROTOCOLS["4 directions x 2, repeated"]
    for label, variant in (("position of the tool point", {}),
                           ("tool and A (0.11 m away)", {"targets": ("tool", "A")}),
                           ("tool and B (0.32 m away)", {"targets": ("tool", "B")}),
                           ("tool point and orientation", {"orientation": True, "sigma_rad": 1e-5})):
        counts = [0, 0, 0]
        for s in range(seeds):
            v = _verdict(robot, replace(prot, **variant), truth, s)
            if v["causes"] == ["link_compliance"] and not v["indistinguishable_from"]:
                counts[0] += 1
            elif "link_compliance" in v["causes"] + v["indistinguishable_from"] and "joint_coupling" in (
                    v["causes"] + v["indistinguishable_from"]):
                counts[1] += 1
            else:
                counts[2] += 1
        print(f"   {label:28s}: {counts[0]:2d} / {counts[1]:2d} / {counts[2]:2d}")


def cpu_design():
    print("3. 6-axis arm, M = 6 plan with its certificate (CPU seconds, one thread)")
    robot = with_targets(load_robot(ROOT / "config/robots/kuka_kr210_r2700.yaml"), {"A": [0.1, 0.1, 0.25]}, "bench")
    kw = dict(test_pose_deg=[20, -60, 110, 30, 45, -20], sigma=1e-5, experiments=6, progress=False)
    for label, extra in (("force, tool point        ", dict(force_N=[500, -300, -800])),
                         ("wrench, 2 targets, orient.", dict(wrench=[500, -300, -800, 40, -25, 60],
                                                            targets=["tool", "A"], orientation=True,
                                                            sigma_rad=2e-5))):
        t = time.process_time()
        res = design(robot, **kw, **extra)
        cpu = time.process_time() - t
        print(f"   {label}: {cpu:5.1f} s, O_t {res.O_t:.4g} m^2, {100 * res.gap:.2f} % above the certified bound")


if __name__ == "__main__":
    moments()
    separation()
    cpu_design()
