"""From measured deflections to a compensated path: what the stiffness model gets wrong in a lab log, the
calibrated model it writes, its predictions and compensation of a path, and the next round's plan.

The data: data/synthetic_paper_2r.csv, SYNTHETIC deflections of the paper's arm with a hidden backlash of 5e-5 rad
per joint and one blunder (data/README.md). Run from the repository:
    .venv/bin/python examples/measured_data.py [OUT_DIR]
(OUT_DIR: where verdict.json, calibrated.yaml and the CSVs go; default a new temporary folder, left there for
you to read: the last line names it).
"""
import sys
import tempfile
from pathlib import Path

import stiffcal

ROOT = Path(__file__).resolve().parents[1]


def main(out: Path) -> None:
    """The four steps, their files in ``out``."""
    # 1. the analysis: verdict.json and the calibrated model (calibrated.yaml) in out/
    verdict = stiffcal.analyse_measurements(ROOT / "config/robots/paper_2r.yaml", ROOT / "data/synthetic_paper_2r.csv",
                                            test_pose_deg=[60, 30], force_N=[0, -300], out=out, figures=False)
    print(f"cause: {verdict.cause}; blunders at data rows {verdict.outlier_rows}")
    print(verdict.p_value_statement)
    ext = verdict.extended
    print("the extended model's parameters (backlash b_i: the joint's jump either way, half the gap of "
          "data/README.md):")
    for name, value, half in zip(ext["parameter_names"], ext["parameters"], ext["parameters_ci95"]):
        print(f"  {name} = {value:.4g} +- {half:.2g} (95 %)")
    gain = verdict.gain
    print(f"held-out configurations, RMS error: nominal model {gain['loco_rms_nominal_m'] * 1e6:.3g} um, "
          f"calibrated {gain['loco_rms_extended_m'] * 1e6:.3g} um")

    # 2. the calibrated model in use: predicted deflections and a compensated path (poses and loads per row)
    path = out / "path.csv"
    path.write_text("q1_deg,q2_deg,fx_N,fy_N\n60,30,0,-300\n10,80,0,-300\n-40,100,50,-200\n", encoding="utf-8")
    model = out / "calibrated.yaml"
    stiffcal.predict_deflection(model, path, out=out / "predicted.csv")
    compensated = stiffcal.compensate_path(model, path, out=out / "compensated.csv")
    print(f"compensated path: deflection up to {compensated['max_deflection_m'] * 1e6:.3g} um, left after compensation "
          f"{compensated['max_residual_m'] * 1e6:.3g} um (95 % band {compensated['max_band95_m'] * 1e6:.3g} um)")

    # 3. the next round: three more poses, with the information these data already hold
    nxt = stiffcal.plan_next_round(model, test_pose_deg=[60, 30], force_N=[0, -300], experiments=3)
    print(f"next round: {nxt['poses_deg']} deg; test-pose RMS error {nxt['rms_prior_m'] * 1e6:.3g} um now, "
          f"{nxt['rms_m'] * 1e6:.3g} um after")
    print(f"files in {out}: {', '.join(sorted(p.name for p in out.iterdir()))}")


if __name__ == "__main__":
    try:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="stiffcal-example-")))
    except stiffcal.InputError as err:  # a bad OUT_DIR, or an input file edited into a bad one: one line
        sys.exit(f"measured_data.py: error: {err}")
