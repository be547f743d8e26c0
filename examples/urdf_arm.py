"""A real arm from its URDF: the KUKA KR 210 R2700. The URDF alone (config/robots/kuka_kr210_r2700.urdf) loads in
one line, base and tip guessed (the root link and the end of the longest chain of revolute joints); a robot file
that names the URDF (config/robots/kuka_kr210_r2700_urdf.yaml) adds the tracker target on the tool and the joint
compliances. The measurement poses for a machining pose under about 1 kN, with the certified lower bound, and the
same plan's O_t from the arm's DH file (config/robots/kuka_kr210_r2700.yaml).

Run from the repository: .venv/bin/python examples/urdf_arm.py
"""
from pathlib import Path

import numpy as np

import stiffcal

ROOT = Path(__file__).resolve().parents[1]
TEST_POSE_DEG = [20, -60, 110, 30, 45, -20]  # the default config's study "kuka-kr210-machining"
FORCE_N = [500, -300, -800]

bare = stiffcal.load_robot(ROOT / "config/robots/kuka_kr210_r2700.urdf")
print(f"the URDF alone: {bare.n_joints} joints ({', '.join(bare.joint_names)})")
arm = stiffcal.load_robot(ROOT / "config/robots/kuka_kr210_r2700_urdf.yaml")
res = stiffcal.design(arm, TEST_POSE_DEG, FORCE_N, experiments=4, sigma=1e-5)
print(f"O_t = {res.O_t:.4e} m^2 (RMS {np.sqrt(res.O_t) * 1e6:.2f} um), lower bound {res.lower_bound:.4e} m^2 "
      f"(gap {100 * res.gap:.2f} %)")
for q in res.poses_deg:
    print("pose [deg]:", ", ".join(f"{a:.2f}" for a in q))
dh = stiffcal.design(ROOT / "config/robots/kuka_kr210_r2700.yaml", TEST_POSE_DEG, FORCE_N, experiments=4, sigma=1e-5)
print(f"the DH file of the same arm: O_t = {dh.O_t:.4e} m^2")
