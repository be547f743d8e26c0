"""Coverage of the analysis's 95 % intervals of the joint compliances on simulated lab logs (``stiffcal.testing``):
the share of the true compliances within ``k +- k_ci95``, of the nominal model on clean logs, or of the extended
model on logs with one catalogue effect large enough to be named (4-8 times the noise). Per joint and over all.

Run: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/interval_coverage.py [--arm 6-axis]
     [--protocol "hanging x3, reference per configuration, half revisited"] [--effect measurement_offset | none]
     [--seeds 100] [--configurations 15] [--first 8000000]
"""

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from stiffcal.measured import discrepancy as D  # noqa: E402
from stiffcal.measured.measurements import read_measurements  # noqa: E402
from stiffcal.testing import rates as R  # noqa: E402
from stiffcal.testing import truth as T  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arm", default="6-axis", choices=("2-link", "3-link", "6-axis"))
    ap.add_argument("--protocol", default="hanging x3, reference per configuration, half revisited")
    ap.add_argument("--effect", default="measurement_offset", help="a catalogue cause, or none (clean logs)")
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--configurations", type=int, default=15)
    ap.add_argument("--first", type=int, default=8_000_000)
    args = ap.parse_args()
    arm = R.robots(ROOT)[args.arm]
    k = R.compliances(arm)
    effects = () if args.effect == "none" else (args.effect,)
    inside, named = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log.csv"
        for seed in range(args.first, args.first + args.seeds):
            log, dp, _ = R.simulate_case(arm, args.protocol, effects, seed, args.configurations, size_range=(4.0, 8.0))
            path.write_text(T.lab_csv(arm, log, dp), encoding="utf-8")
            v = D.analyse(arm, read_measurements(path, arm), 0.01, gain=False)
            model = v["extended"] if effects else v["nominal"]
            if effects and (not model or args.effect not in model["causes"]):
                continue
            named += 1
            est, half = np.array(model["k"], float), np.array(model["k_ci95"], float)
            joints = np.array(v["nominal"]["k_joints"]) - 1
            row = np.full(len(k), np.nan)
            row[joints] = np.abs(est - k[joints]) <= half
            inside.append(row)
    inside = np.array(inside)
    print(f"{args.arm}, {args.protocol}, effect {args.effect}: {named} of {args.seeds} logs used "
          f"({'named' if effects else 'clean'})")
    print("coverage per joint:", " ".join("-" if np.isnan(c) else f"{c:.3f}" for c in np.nanmean(inside, axis=0)))
    print(f"all: {np.nanmean(inside):.4f} of {int(np.sum(~np.isnan(inside)))} intervals")


if __name__ == "__main__":
    main()
