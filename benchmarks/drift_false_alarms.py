"""The drift test's false alarms on clean logs of a fresh user's protocol (tests/data/newuser/ur5_smr_sim.py, its own
Pinocchio simulator of the exact statics: a UR5, two SMRs, 5-15 kg hung at the flange, a reference per configuration
reused on a shuffled second pass, no drift), seed by seed: the drift's p-value (``diagnostics.time.p_value``) as the
analysis computes it (Kenward-Roger's F-test where the rows share estimated errors) beside the plug-in F-test that
takes the estimated variance components as known (the one it replaced), and whether any cause is named. At alpha
both counts should be about alpha times the seeds.
Run: .venv/bin/python benchmarks/drift_false_alarms.py [SEEDS] [FIRST_SEED] [ALPHA]   (defaults 200 from 2000, 0.01)
"""
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from unittest import mock

from scipy import stats

from stiffcal.measured import discrepancy as D
from stiffcal.measured.measurements import read_measurements
from stiffcal.model.robot import load_robot

ROOT = Path(__file__).resolve().parents[1]
SIM = ROOT / "tests" / "data" / "newuser" / "ur5_smr_sim.py"


def robot_file(tmp: Path) -> Path:
    """The user's robot file: its URDF, two SMRs and a data sheet's compliances (3e-6 rad/(N m) each)."""
    import example_robot_data

    root = Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf"))
    path = tmp / "ur5.yaml"
    path.write_text(f"name: ur5\nkind: urdf\nurdf: {root}/ur_description/urdf/ur5_robot.urdf\nbase_frame: base_link\n"
                    "tip_frame: tool0\ntool_m: [0, 0, 0]\ntargets:\n  A: [0.03, 0.0, 0.05]\n  B: [-0.03, 0.0, 0.05]\n"
                    "compliances_rad_per_Nm: [3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6]\ngravity: [0, 0, -1]\n",
                    encoding="utf-8")
    return path


def main(seeds: int = 200, first: int = 2000, alpha: float = 0.01) -> None:
    start = time.process_time()
    plain, kr, causes = [], [], 0
    seen = []
    real = D._drift_p

    def spy(pre, em, C, chosen, p_plain):
        p = real(pre, em, C, chosen, p_plain)
        seen.append((p_plain, p))
        return p

    with tempfile.TemporaryDirectory() as tmp, mock.patch.object(D, "_drift_p", spy):
        robot = load_robot(robot_file(Path(tmp)))
        for seed in range(first, first + seeds):
            path = Path(tmp) / "log.csv"
            subprocess.run([sys.executable, str(SIM), "--seed", str(seed), "--out", str(path)], check=True,
                           cwd=tmp)
            seen.clear()
            v = D.analyse(robot, read_measurements(path, robot), alpha, gain=False)
            causes += v["cause"] != "none"
            if seen:  # the first call is the chosen model's test
                plain.append(seen[0][0])
                kr.append(seen[0][1])
    n = len(kr)
    for name, ps in (("plug-in F-test", plain), ("Kenward-Roger (the analysis)", kr)):
        hits = sum(p < alpha for p in ps)
        test = stats.binomtest(hits, n, alpha)
        lo, hi = test.proportion_ci(0.95, method="exact")
        print(f"{name}: drift p < {alpha:g} in {hits} of {n} clean logs ({100 * hits / n:.1f} %, 95 % interval "
              f"{100 * lo:.2f}-{100 * hi:.2f} %, binomial p {test.pvalue:.2g} against {alpha:g})")
    print(f"a cause named on {causes} of {seeds}; {time.process_time() - start:.0f} s of CPU (the simulator's "
          "processes not counted)")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(*(int(a) for a in args[:2]), *(float(a) for a in args[2:3]))
