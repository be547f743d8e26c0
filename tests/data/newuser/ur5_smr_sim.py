"""A fresh user's lab simulator (kept as written, but for the URDF's path): the UR5 of example-robot-data, exact
statics with pinocchio (the URDF's weights, 5-15 kg hung at the flange), a laser tracker (10 um + 5 ppm of distance,
an optional drift along x), two SMRs, one reference per configuration at the first visit reused on a shuffled second
pass (the robot returning within 10 um). It made tests/data/newuser/ur5_smr_clean_s12.csv (seed 12) and the drift
figures of benchmarks/drift_false_alarms.py.
Usage: ur5_smr_sim.py --seed S --out FILE [--drift-um-per-10min D] [--backlash-rad B] [--nconf N]
Writes the CSV a lab would log, and FILE.truth.json."""
import argparse, json
import numpy as np
import pinocchio as pin

import example_robot_data  # noqa: E402 (the package's own path of its UR5)

URDF = example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf") + "/ur_description/urdf/ur5_robot.urdf"
G = 9.80665
K_TRUE = np.array([2.0e-6, 1.2e-6, 1.8e-6, 3.5e-6, 4.0e-6, 5.0e-6])
TARGETS = {"A": np.array([0.03, 0.0, 0.05]), "B": np.array([-0.03, 0.0, 0.05])}
TRACKER = np.array([2.2, 0.6, 0.4])
MASSES = [5.0, 10.0, 15.0]

model = pin.buildModelFromUrdf(URDF)
model.gravity.linear = np.array([0, 0, -G])
data = model.createData()
FID = model.getFrameId("tool0")
assert model.nq == 6


def fk(q):
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[FID]


def points(q):
    M = fk(q)
    return {n: M.translation + M.rotation @ r for n, r in TARGETS.items()}, M.translation.copy()


def ext_torque(q, mass):
    """generalized force on the joints: weight of the arm + hanging mass at tool0 origin"""
    g = pin.computeGeneralizedGravity(model, data, q)  # torque the motors need; weight acts as -g
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    J = pin.getFrameJacobian(model, data, FID, pin.LOCAL_WORLD_ALIGNED)
    F = np.array([0, 0, -mass * G, 0, 0, 0])
    return -g + J.T @ F


def equilibrium(theta, mass, k, backlash):
    """solve dq = k*tau(theta+dq) + b*sign(tau_2) exactly by fixed-point iteration"""
    dq = np.zeros(6)
    for it in range(200):
        tau = ext_torque(theta + dq, mass)
        new = k * tau
        if backlash:
            new[1] += backlash * np.sign(tau[1])
        if np.max(np.abs(new - dq)) < 1e-15:
            dq = new
            break
        dq = new
    return theta + dq, tau


def true_displacement(theta, mass, k=K_TRUE, backlash=0.0):
    """noise-free loaded minus unloaded position of each target"""
    q0, _ = equilibrium(theta, 0.0, k, backlash)
    q1, _ = equilibrium(theta, mass, k, backlash)
    p0, _ = points(q0)
    p1, _ = points(q1)
    return {n: p1[n] - p0[n] for n in TARGETS}


def random_pose(rng):
    while True:
        th = np.deg2rad(np.array([
            rng.uniform(-90, 90), rng.uniform(-170, -10), rng.uniform(-150, 150),
            rng.uniform(-180, 0), rng.uniform(-120, 120), rng.uniform(-90, 90)]))
        th = np.round(np.rad2deg(th), 3)
        q = np.deg2rad(th)
        pts, flange = points(q)
        # flange above the table, SMRs reachable, not too close to the base column
        if flange[2] < 0.15 or np.hypot(flange[0], flange[1]) < 0.25:
            continue
        # every body origin above the table
        pin.forwardKinematics(model, data, q)
        if min(data.oMi[j].translation[2] for j in range(2, 7)) < 0.02:
            continue
        return th


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--drift-um-per-10min", type=float, default=0.0)
    ap.add_argument("--backlash-rad", type=float, default=0.0)
    ap.add_argument("--nconf", type=int, default=14)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    k = K_TRUE
    b = a.backlash_rad
    drift_rate = a.drift_um_per_10min * 1e-6 / 600.0  # m/s along tracker x (= base x here)
    confs = [random_pose(rng) for _ in range(a.nconf)]
    order = list(range(a.nconf)) + list(rng.permutation(a.nconf))
    t = 0.0
    refs = {}
    rows = []
    reversals = 0

    def read(p, t):
        sig = 10e-6 + 5e-6 * np.linalg.norm(p - TRACKER)
        return p + rng.normal(0, sig, 3) + np.array([drift_rate * t, 0, 0])

    seen = set()
    for vi, c in enumerate(order):
        theta_deg = confs[c]
        theta = np.deg2rad(theta_deg)
        first = c not in seen
        seen.add(c)
        if not first:
            # robot returns with 10 um repeatability (joint error scaled to 10 um RMS per coordinate at the flange)
            pin.computeJointJacobians(model, data, theta)
            pin.framesForwardKinematics(model, data, theta)
            J = pin.getFrameJacobian(model, data, FID, pin.LOCAL_WORLD_ALIGNED)[:3]
            s = 10e-6 / np.sqrt(np.trace(J @ J.T) / 3)
            theta = theta + rng.normal(0, s, 6)
        pid = f"C{c + 1:02d}"
        visit = 1 if first else 2
        q0, tau0 = equilibrium(theta, 0.0, k, b)
        if first:
            p0, _ = points(q0)
            refs[c] = {}
            for n in TARGETS:
                refs[c][n] = read(p0[n], t)
                rows.append([pid, visit, n, t, *theta_deg, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
                t += 15
        for m in MASSES:
            t += 45  # hang the mass, let it settle
            q1, tau1 = equilibrium(theta, m, k, b)
            if np.sign(tau1[1]) != np.sign(tau0[1]):
                reversals += 1
            p1, _ = points(q1)
            for n in TARGETS:
                d = read(p1[n], t) - refs[c][n]
                rows.append([pid, visit, n, t, *theta_deg, 0.0, 0.0, round(-m * G, 3), *d])
                t += 15
        t += 120  # unload, move on
    hdr = ["pose_id", "visit", "target", "timestamp_s"] + [f"q{i}_deg" for i in range(1, 7)] + \
        ["fx_N", "fy_N", "fz_N", "dx_m", "dy_m", "dz_m"]
    with open(a.out, "w") as f:
        f.write(",".join(hdr) + "\n")
        for r in rows:
            out = [r[0], str(r[1]), r[2], f"{r[3]:.0f}"] + [f"{x:.3f}" for x in r[4:10]] + \
                [f"{x:.3f}" for x in r[10:13]] + [f"{x:.7e}" if x != 0 else "0" for x in r[13:16]]
            f.write(",".join(out) + "\n")
    json.dump({"k_true": K_TRUE.tolist(), "backlash_joint2_rad": b, "drift_um_per_10min": a.drift_um_per_10min,
               "seed": a.seed, "campaign_h": t / 3600, "joint2_reversals_loaded_rows_per_visit": reversals,
               "rows": len(rows), "configs": [list(map(float, c)) for c in confs]},
              open(a.out + ".truth.json", "w"), indent=1)


if __name__ == "__main__":
    main()
