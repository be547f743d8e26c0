"""The ``stiffcal`` command (contract in DESIGN.md).

``stiffcal design --robot FILE --test-pose-deg Q1,Q2,... --force-N FX,FY[,FZ] --experiments M
[--criterion ot|a|t|d|g|mdc|o1|o2|o3|o4] [--sigma S]`` prints one JSON object.

Bad input gives one line on stderr naming the file or option and what was expected, and exit code 2;
never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from . import criteria
from .certificate import approximate_design
from .design import Problem, optimal_single_pose
from .plans import optimise_plan, round_design
from .errors import InputError
from .robot import load_robot
from .study import Study, check_test_inputs
from .tables import plan_summary


def _floats(option: str, text: str) -> np.ndarray:
    try:
        vals = np.array([float(v) for v in text.split(",")], float)
    except ValueError:
        raise InputError(f"expected comma-separated numbers, got {text!r}", field=option) from None
    if not np.all(np.isfinite(vals)):
        raise InputError(f"expected finite numbers, got {text!r}", field=option)
    return vals


def _json_number(x: float):
    """JSON has no inf: an infinite value (unidentifiable) is written as the string 'inf'."""
    x = float(x)
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def design(args) -> dict:
    """Run ``stiffcal design``; returns the JSON-ready dict."""
    robot = load_robot(args.robot)
    force = _floats("--force-N", args.force_N)
    q_t = check_test_inputs(robot, _floats("--test-pose-deg", args.test_pose_deg), force, "--test-pose-deg",
                            "--force-N")
    if args.experiments < 1:
        raise InputError(f"expected a number of experiments >= 1, got {args.experiments}", field="--experiments")
    if not args.sigma > 0:
        raise InputError(f"expected sigma > 0, got {args.sigma}", field="--sigma")
    if args.experiments < robot.min_poses:
        raise InputError(f"expected at least {robot.min_poses} poses: {args.experiments} give "
                         f"{args.experiments * robot.task_dim} equations for {robot.n_params} compliances",
                         field="--experiments")
    m = args.experiments
    study = Study(robot.name, robot, np.radians(q_t), force, args.sigma, (args.criterion,), 1.0, 1.0)
    notes, optimal_set, degenerate = [], [], False
    single = None
    try:
        res1 = optimal_single_pose(Problem(robot, force, args.criterion, 1, np.radians(q_t), None, args.sigma))
        single, notes, degenerate = res1.pose_deg, res1.notes, res1.degenerate
        optimal_set = res1.optimal_set_deg
    except InputError:
        if m == 1:
            raise
    design = approximate_design(Problem(robot, force, "ot", 1, np.radians(q_t), None, args.sigma))
    if m == 1:
        poses = single[None, :]
    else:
        prob = Problem(robot, force, args.criterion, m, np.radians(q_t), None, args.sigma)
        starts = [round_design(design, m)] + ([np.repeat(single[None], m, 0)] if single is not None else [])
        plan = optimise_plan(prob, starts=starts, seed=args.seed)
        poses, optimal_set, degenerate = plan.poses_deg, [], False
    summ = plan_summary(study, poses)
    bound = design.lower_bound(m, args.sigma) if args.criterion == "ot" else None
    n = robot.n_joints
    notes = list(notes) + [f"joint {j + 1}'s axis passes through the measured point at every pose: its compliance never "
                           "deflects that point, cannot be identified from its position and is left out of the model "
                           "(cov_diag 'inf'); measure a point off that axis (tool_m) to identify it"
                           for j in robot.inert_joints]
    return {
        "criterion": args.criterion,
        "criterion_label": criteria.label(args.criterion),
        "robot": robot.name,
        "experiments": m,
        "poses_deg": [[round(float(a), 6) + 0.0 for a in p] for p in poses],
        "O_t": _json_number(summ["O_t"]),
        "O_t_star": criteria.o_t_star(robot.n_params, m, args.sigma),
        "chi": _json_number(summ["chi"]),
        "cov_diag": [_json_number(summ[f"E_dk{i + 1}"]) for i in range(n)],
        "lower_bound": bound,
        "gap": None if bound is None else _json_number(float(summ["O_t"]) / bound - 1.0),
        "optimal_set_deg": [[round(float(a), 6) for a in p] for p in optimal_set],
        "degenerate": degenerate,
        "approximate_design": {"support_deg": design.support_deg.round(6).tolist(),
                               "weights": design.weights.round(9).tolist(),
                               "equivalence_gap": design.equivalence_gap},
        "notes": notes,
        "sigma": args.sigma,
        "seed": args.seed,
        "test_pose_deg": q_t.tolist(),
        "force_N": force.tolist(),
    }


def _test_pose(args, robot):
    """(test pose (n,) [rad], its force (d,) [N]) from --test-pose-deg and --force-N, or (None, None)."""
    if (args.test_pose_deg is None) != (args.force_N is None):
        raise InputError("expected both --test-pose-deg and --force-N (the test pose and its force), or neither",
                         field="--test-pose-deg")
    if args.test_pose_deg is None:
        return None, None
    ft = _floats("--force-N", args.force_N)
    return np.radians(check_test_inputs(robot, _floats("--test-pose-deg", args.test_pose_deg), ft, "--test-pose-deg",
                                        "--force-N")), ft


def discrepancy(args) -> dict:
    """``stiffcal discrepancy``: what the model gets wrong in measured data (writes DIR/verdict.json)."""
    from .discrepancy import run

    robot = load_robot(args.robot)
    qt, ft = _test_pose(args, robot)
    v = run(robot, args.data, args.out, args.alpha, qt, ft, angle_resolution_deg=args.angle_resolution_deg,
            force_resolution_N=args.force_resolution_N)
    for note in v["notes"]:
        print(f"stiffcal discrepancy: note: {note}", file=sys.stderr)
    return {k: v[k] for k in ("cause", "causes", "indistinguishable_from", "p_value", "outlier_rows")} | {
        "verdict": f"{args.out}/verdict.json"}


def discriminate(args) -> dict:
    """``stiffcal discriminate``: the next experiment that tells rival causes apart (writes DIR/plan.json)."""
    from .discrimination import run

    robot = load_robot(args.robot)
    qt, ft = _test_pose(args, robot)
    out = run(robot, args.data, args.out, args.experiments, args.loads, args.repeats, args.weight, args.truth,
              args.alpha, qt, ft, args.angle_resolution_deg, args.force_resolution_N, args.seed)
    for note in out["notes"]:
        print(f"stiffcal discriminate: note: {note}", file=sys.stderr)
    plan, comp = out["plan"] or {}, out["compound"] or {}
    cert = plan.get("certificate") or {}
    return {"truth": out["models"][0]["causes"], "rivals": [m["causes"] for m in out["models"][1:]],
            "separable": out["separable"],
            "needs": sorted({n for s in out["separability"] if not s["separable"] for n in s["needs"]}),
            "poses_deg": plan.get("poses_deg"), "forces_N": plan.get("forces_N"), "power": plan.get("power"),
            "efficiency": cert.get("efficiency"), "power_bound": cert.get("power_bound"),
            "compound": None if not comp else {k: comp[k] for k in ("weight", "poses_deg", "forces_N", "power",
                                                                     "O_t_rms_m", "t_efficiency", "ot_efficiency")},
            "plan": f"{args.out}/plan.json"}


def verify_archive(args) -> dict:
    """``stiffcal verify-archive FILE``: every file of the archive against its SHA256SUMS."""
    from .archive import verify_archive as verify

    ok, problems = verify(args.file)
    for p in problems:
        print(f"stiffcal verify-archive: {args.file}: {p}", file=sys.stderr)
    return {"archive": args.file, "verified_files": ok, "problems": problems, "ok": not problems}


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="stiffcal", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("design", help="optimal measurement poses for a test pose (prints JSON)")
    d.add_argument("--robot", required=True, help="robot YAML file")
    d.add_argument("--test-pose-deg", required=True, help="test pose q*, comma-separated degrees")
    d.add_argument("--force-N", required=True, help="force F in newtons, comma-separated")
    d.add_argument("--experiments", type=int, default=1, help="number of measurement poses M (default 1)")
    d.add_argument("--criterion", default="ot", choices=criteria.CRITERIA_KEYS, help="criterion (default ot)")
    d.add_argument("--sigma", type=float, default=1.0, help="measurement noise s.t.d. (default 1)")
    d.add_argument("--seed", type=int, default=0, help="seed of the random starts of M-pose plans (default 0)")
    d.set_defaults(func=design)
    x = sub.add_parser("discrepancy", help="what the stiffness model gets wrong in measured data (writes DIR/verdict.json)")
    x.add_argument("--robot", required=True, help="robot YAML file")
    x.add_argument("--data", required=True, help="measured-data CSV (DESIGN.md contract)")
    x.add_argument("--out", required=True, help="output directory (verdict.json, residuals.png/svg)")
    x.add_argument("--alpha", type=float, default=0.01, help="family-wise false-alarm rate (default 0.01)")
    x.add_argument("--test-pose-deg", help="test pose for the predicted compensation error (optional)")
    x.add_argument("--force-N", help="force at the test pose, comma-separated newtons (with --test-pose-deg)")
    x.add_argument("--angle-resolution-deg", type=float, default=None,
                   help="joint angles within this are one configuration (encoder resolution; default 0.01)")
    x.add_argument("--force-resolution-N", type=float, default=None,
                   help="forces within this (per component) are one load; below it a row is unloaded (load-cell "
                        "resolution; default 0.5)")
    x.set_defaults(func=discrepancy)
    t = sub.add_parser("discriminate", help="the next experiment that tells rival causes apart (writes DIR/plan.json)")
    t.add_argument("--robot", required=True, help="robot YAML file")
    t.add_argument("--data", required=True, help="measured-data CSV (docs/measured-data.md)")
    t.add_argument("--experiments", type=int, required=True, help="number of measurements M in the plan")
    t.add_argument("--out", required=True, help="output directory (plan.json, plan.png/svg)")
    t.add_argument("--loads", help="loads the lab can apply: 'hanging:M1,M2' [N], 'directions:K:M1,M2' or "
                                   "'forces:FX,FY;...' (default: the loads of the data)")
    t.add_argument("--repeats", type=int, default=1, help="times each point of the plan is measured (default 1)")
    t.add_argument("--weight", type=float, default=0.5,
                   help="weight kappa of the discrimination in the compound plan, in [0, 1] (default 0.5)")
    t.add_argument("--truth", choices=("best", "each"), default="best",
                   help="design for the best-fitting model as the truth (T-optimality, default) or each in turn")
    t.add_argument("--alpha", type=float, default=0.01, help="family-wise false-alarm rate (default 0.01)")
    t.add_argument("--test-pose-deg", help="test pose for the compound plan's O_t (optional)")
    t.add_argument("--force-N", help="force at the test pose, comma-separated newtons (with --test-pose-deg)")
    t.add_argument("--angle-resolution-deg", type=float, default=None, help="encoder resolution (default 0.01)")
    t.add_argument("--force-resolution-N", type=float, default=None, help="load-cell resolution (default 0.5)")
    t.add_argument("--seed", type=int, default=0, help="seed of the random starts of the exchange (default 0)")
    t.set_defaults(func=discriminate)
    v = sub.add_parser("verify-archive", help="check a results archive against its SHA256SUMS (exit 1 names each changed file)")
    v.add_argument("file", help="results/archive/stiffcal-<commit>.tar.gz")
    v.set_defaults(func=verify_archive)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        out = args.func(args)
    except InputError as err:
        print(f"stiffcal {args.command}: error: {err}", file=sys.stderr)
        return 2
    print(json.dumps(out, indent=2))
    return 0 if out.get("ok", True) else 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
