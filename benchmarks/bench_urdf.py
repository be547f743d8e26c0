"""Benchmark: the kinematics of a URDF arm (config/robots/kuka_kr210_r2700_urdf.yaml), batched in numpy from
the chain that Pinocchio reads (stiffcal.model.urdf), against Pinocchio called once per pose from Python (the
baseline), in the same run; and against the DH file of the same arm.

What is timed: position and Jacobian of the measured point at 32768 random poses, the size of one call of the
searches over one pose (stiffcal.planning.problem.sampled_minimise, the certificate), which need the Jacobian only.
CPU seconds (time.process_time), reported as ratios.

Run: .venv/bin/python benchmarks/bench_urdf.py   (single-threaded BLAS is forced below)
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from stiffcal.model.robot import load_robot  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
POSES = 32768


def cpu(fn, repeat: int = 3) -> float:
    """Least CPU time [s] of ``repeat`` runs of fn()."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def pinocchio_per_pose(robot, q: np.ndarray):
    """Position and Jacobian of the measured point with one Pinocchio call per pose (no batching)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(ROOT / "config/robots" / robot.urdf))
    tip = model.getFrameId("tool0")
    point = model.addFrame(pin.Frame("point", model.frames[tip].parentJoint, tip,
                                     model.frames[tip].placement * pin.SE3(np.eye(3), robot.tool_m),
                                     pin.FrameType.OP_FRAME))
    data = model.createData()
    p, J = np.empty((len(q), 3)), np.empty((len(q), 3, 6))
    for i, qi in enumerate(q):
        J[i] = pin.computeFrameJacobian(model, data, qi, point, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        p[i] = data.oMf[point].translation  # computeFrameJacobian updates the frame's placement
    return p, J


if __name__ == "__main__":
    urdf = load_robot(ROOT / "config/robots/kuka_kr210_r2700_urdf.yaml")
    dh = load_robot(ROOT / "config/robots/kuka_kr210_r2700.yaml")
    q = np.random.default_rng(0).uniform(*urdf.joint_limits_rad.T, (POSES, 6))
    p_ref, J_ref = pinocchio_per_pose(urdf, q)
    err = max(np.abs(urdf.fk(q) - p_ref).max(), np.abs(urdf.jacobian(q) - J_ref).max())
    t_jac = cpu(lambda: urdf.jacobian(q))
    t_both = cpu(lambda: (urdf.fk(q), urdf.jacobian(q)))
    t_dh = cpu(lambda: dh.jacobian(q))
    t_pin = cpu(lambda: pinocchio_per_pose(urdf, q))
    print(f"{POSES} poses (CPU seconds, one thread, best of 3):")
    print(f"  Jacobian, stiffcal URDF chain (numpy, batched): {t_jac:.3f} s")
    print(f"  Jacobian, stiffcal DH table (numpy, batched):   {t_dh:.3f} s  (URDF chain / DH = {t_jac / t_dh:.2f})")
    print(f"  position and Jacobian, stiffcal URDF chain:     {t_both:.3f} s")
    print(f"  position and Jacobian, Pinocchio per pose:      {t_pin:.3f} s  (Pinocchio / stiffcal: "
          f"{t_pin / t_jac:.2f} against the Jacobian alone, {t_pin / t_both:.2f} against both)")
    print(f"  largest difference from Pinocchio: {err:.1e} m (m/rad)")

    # the same plans from both files: the design of every M of the KUKA study (test pose, force, sigma of
    # config/config.yaml's kuka study), poses compared as printed
    from stiffcal.api import design  # noqa: E402

    print("M-pose plans from the DH file and from the URDF (stiffcal.design, test pose 20,-60,110,30,45,-20 deg, "
          "force 500,-300,-800 N, sigma 10 um):")
    for m in range(2, 9):
        a, b = (design(r, test_pose_deg=[20, -60, 110, 30, 45, -20], force_N=[500, -300, -800], sigma=1e-5,
                       experiments=m, progress=False) for r in (dh, urdf))
        dq = np.abs(np.asarray(a.poses_deg) - np.asarray(b.poses_deg)).max()
        print(f"  M = {m}: largest pose difference {dq:.1e} deg, O_t {a.O_t:.6e} / {b.O_t:.6e} m^2 "
              f"(relative difference {abs(a.O_t / b.O_t - 1):.1e}), gap to the bound {a.gap:.2%}")
