"""The paper's arm (l1 = 0.6 m, l2 = 0.4 m): the O_t-optimal measurement poses for the test pose q* = (60, 30) deg
under F = (0, -1) N with sigma = 1, for M = 1, 2 and 3 poses (the paper's Tables 3, 4 and 5, plan (iv)), each with
the certified lower bound on O_t of any M-pose plan (the equivalence theorem).

Run from the repository: .venv/bin/python examples/design_paper_arm.py
"""
from pathlib import Path

import stiffcal

ROOT = Path(__file__).resolve().parents[1]

robot = stiffcal.load_robot(ROOT / "config/robots/paper_2r.yaml")
for m in (1, 2, 3):
    res = stiffcal.design(robot, test_pose_deg=[60, 30], force_N=[0, -1], experiments=m)
    poses = "; ".join(f"({q1:.2f}, {q2:.2f})" for q1, q2 in res.poses_deg.round(2) + 0.0)  # + 0.0: no "-0.00"
    print(f"M = {m}: O_t = {res.O_t:.4f}, lower bound {res.lower_bound:.4f} (gap {100 * res.gap:.1f} %), "
          f"E[dk^2] = {', '.join(f'{e:.4f}' for e in res.cov_diag)}, poses [deg] {poses}")
