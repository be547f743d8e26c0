"""Clean-data false alarms of the analysis with few configurations a log, under every lab protocol of the rate matrix
(``stiffcal.testing.rates``: references per visit and per configuration with revisits, hanging masses, a loading bar,
a hand-held gauge), in the 2-link, 3-link and 6-axis arms: the count of verdicts other than ``none`` at alpha.

Run: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/few_configurations.py [--configurations 12] [--seeds 100]
     [--first 5000000] [--alpha 0.01]
"""

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from stiffcal.testing import rates as R  # noqa: E402

LAB = ("hanging x3, reference per visit, 2 passes", "loading bar x3, reference per visit, 2 passes",
       "gauge +-axes, reference per visit, half revisited", "hanging x3, reference per configuration, half revisited",
       "hanging x3, 2 targets, reference per configuration, 2 passes",
       "one hanging mass, reference per visit, 2 passes")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configurations", type=int, default=12)
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--first", type=int, default=5_000_000)
    ap.add_argument("--alpha", type=float, default=0.01)
    args = ap.parse_args()
    arms = R.robots(ROOT)
    total = cases = 0
    print(f"clean logs of {args.configurations} configurations, seeds {args.first}.. ({args.seeds} a cell), "
          f"alpha {args.alpha}: false alarms (seeds)")
    for protocol in LAB:
        for name in ("2-link", "3-link", "6-axis"):
            if protocol not in R.protocols_for(arms[name]):
                continue
            seeds = range(args.first, args.first + args.seeds)
            causes = {s: R.run_case(name, arms[name], protocol, (), s, args.alpha, n_configs=args.configurations,
                                    both=False).verdict_with_pose_id["cause"] for s in seeds}
            alarms = {s: c for s, c in causes.items() if c != "none"}
            total, cases = total + len(alarms), cases + len(causes)
            print(f"{protocol:62s} {name:7s} {len(alarms):3d} / {len(causes)}  {alarms}", flush=True)
    print(f"all: {total} / {cases} ({100 * total / max(cases, 1):.2f} %)")


if __name__ == "__main__":
    main()
