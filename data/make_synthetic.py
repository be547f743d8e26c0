"""Make data/synthetic_paper_2r.csv: SYNTHETIC measured deflections of the paper's arm with one hidden effect.

The data are simulated, not measured: stiffcal.truth (written from the physics, independent of the
analysis) gives the deflections of the paper's arm (l1 = 0.6 m, l2 = 0.4 m) with joint compliances
k = (1.5, 3.0) 1e-6 rad/(N m), plus a hidden backlash of 5e-5 rad in each joint (a smoothed gap whose sign
follows the torque), 30 random poses within the joint limits, a random force of 100-400 N in any direction
per pose, 3 replicates each, laser-tracker noise of 10 micrometres per coordinate, and one gross blunder
(+1 mm in x on data row 17). The analysis should name backlash and list row 17 as an outlier.

Run: .venv/bin/python data/make_synthetic.py   (deterministic: seed 20261123)
"""

from pathlib import Path

import numpy as np
import pandas as pd

from stiffcal.robot import load_robot
from stiffcal.truth import Truth, random_experiment, simulate

ROOT = Path(__file__).resolve().parents[1]
SEED = 20261123


def main() -> None:
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    rng = np.random.default_rng(SEED)
    q, force, pose = random_experiment(robot, rng, n_poses=30, replicates=3)
    truth = Truth(k=np.array([1.5e-6, 3.0e-6]), gap=np.array([5e-5, 5e-5]))
    dp = simulate(robot, truth, q, force, sigma=1e-5, rng=rng, blunders={17: np.array([1e-3, 0.0])})
    df = pd.DataFrame({"pose_id": pose, "q1_deg": np.degrees(q[:, 0]), "q2_deg": np.degrees(q[:, 1]),
                       "fx_N": force[:, 0], "fy_N": force[:, 1], "dx_m": dp[:, 0], "dy_m": dp[:, 1]})
    df.to_csv(ROOT / "data/synthetic_paper_2r.csv", index=False, float_format="%.9g", lineterminator="\n")


if __name__ == "__main__":
    main()
