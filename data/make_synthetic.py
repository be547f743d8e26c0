"""Make data/synthetic_paper_2r.csv: SYNTHETIC measured deflections of the paper's arm with one hidden effect,
logged the way calibration labs log them.

The data are simulated, not measured: stiffcal.testing.truth (written from the physics, independent of the
analysis) gives the deflections of the paper's arm (l1 = 0.6 m, l2 = 0.4 m) with joint compliances
k = (1.5, 3.0) 1e-6 rad/(N m), plus a hidden backlash of 5e-5 rad in each joint (a smoothed gap whose sign
follows the torque). Protocol: 30 random configurations within the joint limits, at each a push of 300 N
in four directions 90 deg apart (from a random start), the sequence measured twice on the spot, an
unloaded reference row (zero force, zero displacement) logged before every loaded one, pose_id numbering
the configurations; laser-tracker readings with 10 micrometres of noise per coordinate (every displacement is a
loaded reading less the unloaded reading just before it, the one the reference row logs as zeros), and one gross
blunder (+1 mm in x on the loaded row that is data row 17 of the file). The analysis should name backlash and
list row 17.

Also data/synthetic_paper_2r_hanging.csv: the same arm with a hidden backlash of 1e-4 rad in each joint,
measured the way a lab with hanging weights only would: one mass of 300 N (force -y) at 12 configurations,
twice, each displacement from its own unloaded reading, 10 micrometres of noise per reading. With one load per configuration the data cannot tell the backlash from a
nonlinear joint stiffness (the verdict lists both): the example of `stiffcal discriminate`.

Run: .venv/bin/python data/make_synthetic.py   (deterministic: seeds 20261130 and 20261136)
"""

from pathlib import Path

import numpy as np

from stiffcal.model.robot import load_robot
from stiffcal.testing.truth import Protocol, Truth, lab_csv, lab_log, measure

ROOT = Path(__file__).resolve().parents[1]
SEED = 20261130
PROTOCOL = Protocol("4 pushes of 300 N, twice, unloaded rows", loads="directions", magnitudes_N=(300.0,),
                    repeats=2, unloaded_rows=True, sigma_m=1e-5)


HANGING_SEED = 20261136
HANGING = Protocol("one hanging mass of 300 N, twice", loads="hanging", magnitudes_N=(300.0,), repeats=2, sigma_m=1e-5)


def hanging() -> None:
    """data/synthetic_paper_2r_hanging.csv (module docstring)."""
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    rng = np.random.default_rng(HANGING_SEED)
    log = lab_log(robot, HANGING, rng, n_configs=12)
    truth = Truth(k=np.array([1.5e-6, 3.0e-6]), gap=np.array([1e-4, 1e-4]))
    dp = measure(robot, truth, log, rng)
    (ROOT / "data/synthetic_paper_2r_hanging.csv").write_text(lab_csv(robot, log, dp), encoding="utf-8")


def main() -> None:
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    rng = np.random.default_rng(SEED)
    log = lab_log(robot, PROTOCOL, rng, n_configs=30)
    assert log.loaded[17]  # the blunder falls on a loaded row
    truth = Truth(k=np.array([1.5e-6, 3.0e-6]), gap=np.array([5e-5, 5e-5]))
    dp = measure(robot, truth, log, rng, blunders={17: np.array([1e-3, 0.0])})
    (ROOT / "data/synthetic_paper_2r.csv").write_text(lab_csv(robot, log, dp), encoding="utf-8")
    hanging()


if __name__ == "__main__":
    main()
