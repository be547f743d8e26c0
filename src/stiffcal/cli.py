"""The ``stiffcal`` command: a thin layer over the Python API (:mod:`stiffcal.api`); contract in
docs/contracts.md.

``stiffcal design --robot FILE --test-pose-deg Q1,Q2,... (--force-N FX,FY[,FZ] | --wrench F..,M..)
[--experiments M] [--criterion ot|a|t|d|g|mdc|o1|o2|o3|o4] [--sigma S] [--targets A,B] [--orientation
--sigma-rad S] [--test-target T] [--orientation-length-m L] [--loads SPEC] [--cell FILE] [--joint-limits-deg
LO:HI,...] [--candidates CSV] [--seed N] [--cache-dir DIR | --no-cache] [--quiet]`` prints one JSON object (an
array of them for several M: ``--experiments 2-8``).

Bad input gives one line on stderr naming the file or option and what was expected, and exit code 2;
never a traceback. An internal error (a bug) is one line too, with exit code 1 (``STIFFCAL_TRACEBACK=1``
shows the traceback). List options take negative numbers with or without ``=`` (``--test-pose-deg -35,120``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # before numpy is imported: the
    os.environ.setdefault(_var, "1")  # matrices are small, and threads only cost CPU time (set one to override)

from . import __version__  # noqa: E402
from .errors import MAX_MESSAGE, InputError  # noqa: E402
from .progress import write  # noqa: E402

#: a value that starts with '-' but is a number or a comma-separated list of numbers
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


def _option_name(field: str | None) -> str | None:
    """API argument -> CLI option in messages: 'test_pose_deg[0]' -> '--test-pose-deg[0]'."""
    if not field or field.startswith("--"):
        return field
    head, sep, rest = field.partition("[")
    return "--" + head.replace("_", "-") + sep + rest


def join_negative_values(argv: list[str], parser: argparse.ArgumentParser) -> list[str]:
    """``--opt -35,120`` -> ``--opt=-35,120`` for every option that takes a value (argparse would read
    ``-35,120`` as an option and fail with 'expected one argument')."""
    parsers = [parser, *(parser._subparsers._group_actions[0].choices.values() if parser._subparsers else ())]
    takes_value = {s for p in parsers for a in p._actions if a.option_strings and a.nargs is None
                   for s in a.option_strings}
    out, i = [], 0
    while i < len(argv):
        a = argv[i]
        if a in takes_value and i + 1 < len(argv) and _NEGATIVE_VALUE.match(argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
        else:
            out.append(a)
            i += 1
    return out


def joint_limits(text: str | None, option: str = "--joint-limits-deg"):
    """``LO:HI,LO:HI,...`` [deg] -> [[LO, HI], ...] (None stays None); InputError naming ``option``."""
    from .errors import InputError

    if text is None:
        return None
    out = []
    for j, part in enumerate(text.split(",")):
        lo, sep, hi = part.partition(":")
        try:
            if not sep:
                raise ValueError
            out.append([float(lo), float(hi)])
        except ValueError:
            raise InputError(f"expected LOWER:UPPER in degrees, one pair per joint, comma-separated "
                             f"(-180:180,-90:0,...), got {part!r}", field=f"{option}[{j}]") from None
    return out


#: the most values of M one ``stiffcal design --experiments`` may ask for
MAX_EXPERIMENT_VALUES = 100


def experiment_values(text) -> list[int]:
    """``--experiments``: ``M``, a range ``A-B`` or a comma-separated list of both (``2-8``, ``2,4,6``, ``2-4,8``)
    -> the values of M, ascending, without repeats; InputError naming ``--experiments`` otherwise."""
    from .api import whole_number
    from .limits import MAX_DESIGN_EXPERIMENTS

    values: set[int] = set()
    for part in str(text).split(","):
        m = re.fullmatch(r"\s*([0-9]{1,12})\s*(?:-\s*([0-9]{1,12})\s*)?", part, re.ASCII)
        if not m or int(m[2] or m[1]) < int(m[1]):
            raise InputError(f"expected a whole number M, a range A-B (A <= B) or a comma-separated list of them (6, "
                             f"2-8, 2,4,6), got {text!r}", field="--experiments")
        lo, hi = (whole_number(int(v), "--experiments", 1, MAX_DESIGN_EXPERIMENTS, "poses")
                  for v in (m[1], m[2] or m[1]))
        values.update(range(lo, hi + 1))
    if len(values) > MAX_EXPERIMENT_VALUES:
        raise InputError(f"expected at most {MAX_EXPERIMENT_VALUES} values of M, got {len(values)} ({text!r})",
                         field="--experiments")
    return sorted(values)


def design(args) -> dict | list:
    """Run ``stiffcal design``; returns the JSON-ready dict (a list of them, in M order, for several M)."""
    import tempfile

    from .api import design as run
    from .model.robot import load_robot

    ms = experiment_values(args.experiments)
    if args.prior is not None:
        if len(ms) > 1:
            raise InputError("expected one M with --prior", field="--experiments")
        return next_round(args, ms[0])
    cache = _cache_dir(args)
    robot = load_robot(args.robot) if len(ms) > 1 else args.robot  # several M: the robot file read once
    with tempfile.TemporaryDirectory(prefix="stiffcal-design-") if cache is None and len(ms) > 1 else \
            contextlib.nullcontext(cache) as folder, _plans_progress(args, ms) as progress:
        out = []  # several M share one approximate design, even with --no-cache
        for m in ms:
            out.append(run(robot, args.test_pose_deg, args.force_N, wrench=args.wrench, experiments=m,
                           criterion=args.criterion, sigma=1.0 if args.sigma is None else args.sigma,
                           targets=args.targets, orientation=args.orientation, sigma_rad=args.sigma_rad,
                           test_target=args.test_target, orientation_length_m=args.orientation_length_m,
                           joint_limits_deg=joint_limits(args.joint_limits_deg), loads=args.loads, cell=args.cell,
                           candidates=args.candidates, seed=args.seed,
                           progress=False if args.quiet or len(ms) > 1 else None, cache_dir=folder).to_dict())
            if progress is not None:
                progress.advance()
    return out[0] if len(ms) == 1 else out


def _plans_progress(args, ms):
    """The progress of a design of several M (one stage a plan, the first with the approximate design they share,
    :func:`stiffcal.api.design_estimate_s`; the elapsed time and the estimate over the whole call), or None for one
    M (its own progress reports it)."""
    from .progress import Progress

    if len(ms) == 1:
        return contextlib.nullcontext(None)
    from .api import design_estimate_s
    from .model.observation import measurement_loads
    from .model.robot import load_robot

    robot = load_robot(args.robot)
    n_loads = 1 if args.loads is None else len(measurement_loads(robot, args.loads).wrenches)
    stages = []
    for k, m in enumerate(ms):
        est = design_estimate_s(robot, m, single=False, n_loads=n_loads)
        stages.append((f"plan of {m} poses ({k + 1} of {len(ms)} plans)",
                       sum(w for name, w in est if k == 0 or name.startswith("plan"))))
    return Progress("design", stages, enabled=False if args.quiet else None)


def _cache_dir(args):
    """The folder of the approximate-design cache (:mod:`stiffcal.planning.designcache`): ``--cache-dir``, None with
    ``--no-cache``, else the default folder when it can be written (else None: computed afresh)."""
    from .planning.designcache import default_cache_dir
    from .safeio import check_out_dir

    if args.no_cache:
        if args.cache_dir is not None:
            raise InputError("expected --cache-dir or --no-cache, not both", field="--cache-dir")
        return None
    if args.cache_dir is not None:
        return check_out_dir(args.cache_dir, field="--cache-dir")
    try:
        return check_out_dir(default_cache_dir())
    except InputError:
        return None


_O_T_OF_THE_TOOL = "it plans the tool point's position under the test load with the O_t criterion"
#: design options the next round (``--prior``) does not take (their default) and why
_NOT_WITH_PRIOR = {"criterion": ("ot", _O_T_OF_THE_TOOL), "targets": (None, _O_T_OF_THE_TOOL),
                   "orientation": (False, _O_T_OF_THE_TOOL), "sigma_rad": (None, _O_T_OF_THE_TOOL),
                   "test_target": ("tool", _O_T_OF_THE_TOOL), "orientation_length_m": (0.0, _O_T_OF_THE_TOOL),
                   "candidates": (None, "its candidate poses are those of the measured-data plans"),
                   "cache_dir": (None, "it computes no approximate design, so there is nothing to cache")}


def next_round(args, m: int) -> dict:
    """``stiffcal design --prior CALIBRATED``: the next round's plan of m poses given the calibration's
    information."""
    from .api import plan_next_round, positive_number
    from .model.robot import load_robot

    given = {k: why for k, (default, why) in _NOT_WITH_PRIOR.items() if getattr(args, k) not in (default, str(default))}
    if given:
        reasons = {why: [f"--{k.replace('_', '-')}" for k in given if given[k] == why] for why in given.values()}
        raise InputError("the next round does not take " + "; ".join(f"{', '.join(opts)} ({why})"
                                                                    for why, opts in reasons.items()),
                         field="--prior")
    out = plan_next_round(load_robot(args.prior), args.test_pose_deg, args.force_N, wrench=args.wrench,
                          experiments=m,
                          sigma_m=None if args.sigma is None else positive_number(args.sigma, "--sigma"),
                          joint_limits_deg=joint_limits(args.joint_limits_deg), cell=args.cell, seed=args.seed,
                          robot=load_robot(args.robot), loads=args.loads)
    for note in out["notes"]:
        write(f"stiffcal design: note: {note}")
    return out


def discrepancy(args) -> dict:
    """``stiffcal discrepancy``: what the model gets wrong in measured data (writes DIR/verdict.json)."""
    from .api import analyse_measurements, check_out_dir

    check_out_dir(args.out, "--out")  # before any work
    v = analyse_measurements(args.robot, args.data, alpha=args.alpha, test_pose_deg=args.test_pose_deg,
                             force_N=args.force_N, wrench=args.wrench, out=args.out,
                             angle_resolution_deg=args.angle_resolution_deg, force_resolution_N=args.force_resolution_N,
                             moment_resolution_Nm=args.moment_resolution_Nm, sigma_m=args.sigma_m,
                             sigma_rad=args.sigma_rad, joint_limits_deg=joint_limits(args.joint_limits_deg),
                             cell=args.cell, figures=not args.no_figures)
    for note in v["notes"]:
        write(f"stiffcal discrepancy: note: {note}")
    return {k: v[k] for k in ("cause", "causes", "indistinguishable_from", "p_value", "outlier_rows")} | {
        "verdict": os.path.join(args.out, "verdict.json")}


def discriminate(args) -> dict:
    """``stiffcal discriminate``: the next experiment that tells rival causes apart (writes DIR/plan.json)."""
    from .api import check_out_dir, plan_discrimination

    check_out_dir(args.out, "--out")  # before any work
    out = plan_discrimination(args.robot, args.data, args.experiments, loads=args.loads, repeats=args.repeats,
                              weight=args.weight, truth=args.truth, alpha=args.alpha,
                              test_pose_deg=args.test_pose_deg, force_N=args.force_N, out=args.out,
                              angle_resolution_deg=args.angle_resolution_deg,
                              force_resolution_N=args.force_resolution_N, seed=args.seed,
                              joint_limits_deg=joint_limits(args.joint_limits_deg), cell=args.cell)
    for note in out["notes"]:
        write(f"stiffcal discriminate: note: {note}")
    plan, comp = out["plan"] or {}, out["compound"] or {}
    cert = plan.get("certificate") or {}
    return {"truth": out["models"][0]["causes"], "rivals": [m["causes"] for m in out["models"][1:]],
            "separable": out["separable"],
            "needs": sorted({n for s in out["separability"] if not s["separable"] for n in s["needs"]}),
            "poses_deg": plan.get("poses_deg"), "forces_N": plan.get("forces_N"), "power": plan.get("power"),
            "efficiency": cert.get("efficiency"), "power_bound": cert.get("power_bound"),
            "compound": None if not comp else {k: comp[k] for k in ("weight", "poses_deg", "forces_N", "power",
                                                                     "O_t_rms_m", "t_efficiency", "ot_efficiency")},
            "plan": os.path.join(args.out, "plan.json")}


def predict(args) -> dict:
    """``stiffcal predict``: the calibrated model's deflection at the poses of a CSV (writes --out)."""
    from .api import predict_deflection

    out = predict_deflection(args.robot, args.poses, out=args.out, orientation=args.orientation)
    for note in out["notes"]:
        write(f"stiffcal predict: note: {note}")
    return out


def compensate(args) -> dict:
    """``stiffcal compensate``: a path compensated with the calibrated model (writes --out)."""
    from .api import compensate_path

    out = compensate_path(args.robot, args.path, out=args.out)
    for note in out["notes"]:
        write(f"stiffcal compensate: note: {note}")
    return out


def verify_archive(args) -> dict:
    """``stiffcal verify-archive FILE``: every file of the archive against its SHA256SUMS."""
    from .workflow.archive import verify_archive as verify

    ok, problems = verify(args.file)
    for p in problems:
        write(f"stiffcal verify-archive: {args.file}: {p}")
    return {"archive": args.file, "verified_files": ok, "problems": problems, "ok": not problems}


def _with_progress(args):
    """``args.func(args)``, with a progress line every few seconds on stderr while it runs (a bar on a terminal;
    :mod:`stiffcal.progress`) unless ``--quiet``; a step that reports its own progress (design) silences it."""
    from .progress import Progress

    with Progress(args.command, enabled=False if getattr(args, "quiet", False) else None):
        return args.func(args)


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors as one line and exit status 2 (like every other bad input)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


def _cell_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cell", help="YAML file of the cell the robot stands in (docs/contracts.md, 'The cell'), "
                                  "replacing the robot file's: every pose of the plan is feasible in it")
    p.add_argument("--joint-limits-deg", help="joint limits LO:HI,LO:HI,... [deg], one pair per joint, replacing the "
                                              "robot file's")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="stiffcal", description=__doc__.split("\n")[0])
    p.add_argument("--version", action="version", version=f"stiffcal {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _design_parser(sub)
    _discrepancy_parser(sub)
    _discriminate_parser(sub)
    _predict_parser(sub)
    _compensate_parser(sub)
    _verify_archive_parser(sub)
    return p


def _design_parser(sub) -> None:
    """``stiffcal design``: optimal measurement poses for a test pose."""
    from .model.criteria import CRITERIA_KEYS  # the registry (stiffcal.model.criteria.CRITERIA)

    d = sub.add_parser("design", help="optimal measurement poses for a test pose (prints JSON)")
    d.add_argument("--robot", required=True, help="robot YAML file (docs/contracts.md)")
    d.add_argument("--test-pose-deg", required=True, help="test pose q*, comma-separated degrees")
    d.add_argument("--force-N", help="force F [N] at the tool point, comma-separated (or --wrench)")
    d.add_argument("--wrench", help="force and moment about the tool point [N, N m]: FX,FY,MZ (planar) or "
                                    "FX,FY,FZ,MX,MY,MZ (spatial), instead of --force-N")
    d.add_argument("--experiments", default="1", help="number of measurement poses M (default 1); a range A-B or a "
                                                      "list 2,4,6 prints one plan per M (a JSON array)")
    d.add_argument("--criterion", default="ot", help=f"{' '.join(CRITERIA_KEYS)} (default ot)")
    d.add_argument("--sigma", default=None, help="position noise s.t.d. [m] (default 1; with --prior the "
                                                 "calibration's)")
    d.add_argument("--prior", help="a calibrated robot file (DIR/calibrated.yaml of stiffcal discrepancy): plan the "
                                   "next round with its data's information added (docs/contracts.md)")
    d.add_argument("--targets", help="targets whose positions are measured at every pose, comma-separated names of "
                                     "the robot file's targets and 'tool' (default tool)")
    d.add_argument("--orientation", action="store_true", help="the tool's orientation is measured too")
    d.add_argument("--sigma-rad", default=None, help="orientation noise s.t.d. [rad] (with --orientation)")
    d.add_argument("--test-target", default="tool", help="the target whose error at the test pose O_t measures")
    d.add_argument("--orientation-length-m", default=0.0,
                   help="length scale L [m] that adds the tool's rotation to the test pose's error (default 0)")
    d.add_argument("--loads", help="loads every measurement pose is measured under (then --force-N/--wrench is the "
                                   "test pose's only): 'hanging:M1,M2' [N] along the robot file's gravity, "
                                   "'directions:K:M1,M2', 'forces:FX,FY,FZ;...', 'wrenches:FX,..,MZ;...', "
                                   "'bar:AX,AY,AZ:M1,M2' (a loading bar)")
    _cell_options(d)
    d.add_argument("--candidates", help="CSV of candidate poses (columns q1_deg.. or the joint names in radians): the "
                                        "plan is chosen among those the cell allows")
    d.add_argument("--seed", type=int, default=0, help="seed of the random starts of M-pose plans (default 0)")
    d.add_argument("--cache-dir", help="folder where the optimal approximate design (the same for every M, criterion "
                                       "and seed) is kept for later calls with the same inputs (default "
                                       "$STIFFCAL_CACHE_DIR, else ~/.cache/stiffcal; not with --prior)")
    d.add_argument("--no-cache", action="store_true", help="compute the approximate design afresh, store nothing")
    d.add_argument("--quiet", action="store_true", help="no progress on stderr (a bar on a terminal, else a line "
                                                        "every few seconds with an estimate)")
    d.set_defaults(func=design)


def _discrepancy_parser(sub) -> None:
    """``stiffcal discrepancy``: what the stiffness model gets wrong in measured data."""
    x = sub.add_parser("discrepancy",
                       help="what the stiffness model gets wrong in measured data (writes DIR/verdict.json)")
    x.add_argument("--robot", required=True, help="robot YAML file")
    x.add_argument("--data", required=True, help="measured-data CSV (docs/measured-data.md)")
    x.add_argument("--out", required=True, help="output directory (verdict.json, calibrated.yaml, the figures "
                                                "residuals, heldout and machining as .png and .svg; an earlier "
                                                "run's files of these names are replaced or removed)")
    x.add_argument("--alpha", default=0.01, help="family-wise false-alarm rate (default 0.01)")
    x.add_argument("--test-pose-deg", help="test pose for the predicted compensation error (optional)")
    x.add_argument("--force-N", help="force at the test pose, comma-separated newtons (with --test-pose-deg)")
    x.add_argument("--wrench", help="force and moment at the test pose [N, N m], instead of --force-N")
    x.add_argument("--angle-resolution-deg", default=None,
                   help="joint angles within this are one configuration (encoder resolution; default 0.01)")
    x.add_argument("--force-resolution-N", default=None,
                   help="forces within this (per component) are one load; below it a row is unloaded (load-cell "
                        "resolution; default 0.5)")
    x.add_argument("--moment-resolution-Nm", default=None,
                   help="moments within this (per component) are one load (default 0.05)")
    x.add_argument("--sigma-m", default=None, help="position noise [m] (with --sigma-rad: weights the rotation rows)")
    x.add_argument("--sigma-rad", default=None, help="rotation noise [rad] (default: the ratio is estimated)")
    _cell_options(x)
    x.add_argument("--no-figures", action="store_true",
                   help="write verdict.json and calibrated.yaml without the figures (batch runs over many data sets: "
                        "the figures are about half of a small data set's CPU)")
    x.add_argument("--quiet", action="store_true", help="no progress on stderr")
    x.set_defaults(func=discrepancy)


def _discriminate_parser(sub) -> None:
    """``stiffcal discriminate``: the next experiment that tells rival causes apart."""
    t = sub.add_parser("discriminate", help="the next experiment that tells rival causes apart (writes DIR/plan.json)")
    t.add_argument("--robot", required=True, help="robot YAML file")
    t.add_argument("--data", required=True, help="measured-data CSV (docs/measured-data.md)")
    t.add_argument("--experiments", type=int, required=True, help="number of measurements M in the plan")
    t.add_argument("--out", required=True, help="output directory (plan.json, plan.png/svg)")
    t.add_argument("--loads", help="loads the lab can apply: 'hanging:M1,M2' [N], 'directions:K:M1,M2', "
                                   "'forces:FX,FY;...', 'wrenches:FX,..,MZ;...' or 'bar:AX,AY,AZ:M1,M2' (a loading "
                                   "bar; default: the loads of the data, a loading bar's masses at its lever)")
    t.add_argument("--repeats", type=int, default=1, help="times each point of the plan is measured (default 1)")
    t.add_argument("--weight", default=0.5,
                   help="weight kappa of the discrimination in the compound plan, in [0, 1] (default 0.5)")
    t.add_argument("--truth", choices=("best", "each"), default="best",
                   help="design for the best-fitting model as the truth (T-optimality, default) or each in turn")
    t.add_argument("--alpha", default=0.01, help="family-wise false-alarm rate (default 0.01)")
    t.add_argument("--test-pose-deg", help="test pose for the compound plan's O_t (optional)")
    t.add_argument("--force-N", help="force at the test pose, comma-separated newtons (with --test-pose-deg)")
    t.add_argument("--angle-resolution-deg", default=None, help="encoder resolution (default 0.01)")
    t.add_argument("--force-resolution-N", default=None, help="load-cell resolution (default 0.5)")
    t.add_argument("--seed", type=int, default=0, help="seed of the random starts of the exchange (default 0)")
    _cell_options(t)
    t.add_argument("--quiet", action="store_true", help="no progress on stderr")
    t.set_defaults(func=discriminate)


def _predict_parser(sub) -> None:
    """``stiffcal predict``: the calibrated model's deflection at given poses."""
    r = sub.add_parser("predict", help="the calibrated model's deflection at given poses under given loads (CSV)")
    r.add_argument("--robot", required=True, help="calibrated robot file (DIR/calibrated.yaml of stiffcal discrepancy)")
    r.add_argument("--poses", required=True, help="CSV of poses and loads: q1_deg.., fx_N.. (mx_Nm.., target)")
    r.add_argument("--out", help="CSV to write: the poses with dx_m.. and sd_dx_m.. (default: nothing written)")
    r.add_argument("--orientation", action="store_true", help="predict the tool's rotation too (rx_rad..)")
    r.add_argument("--quiet", action="store_true", help="no progress on stderr")
    r.set_defaults(func=predict)


def _compensate_parser(sub) -> None:
    """``stiffcal compensate``: a path compensated with the calibrated model."""
    c = sub.add_parser("compensate", help="a path compensated with the calibrated model (CSV)")
    c.add_argument("--robot", required=True, help="calibrated robot file (DIR/calibrated.yaml of stiffcal discrepancy)")
    c.add_argument("--path", required=True, help="CSV of the path's poses and loads: q1_deg.., fx_N.. (mx_Nm..)")
    c.add_argument("--out", help="CSV to write: corrected targets and joint angles, residuals (default: nothing)")
    c.add_argument("--quiet", action="store_true", help="no progress on stderr")
    c.set_defaults(func=compensate)


def _verify_archive_parser(sub) -> None:
    """``stiffcal verify-archive``: a results archive checked against its SHA256SUMS."""
    v = sub.add_parser("verify-archive",
                       help="check a results archive against its SHA256SUMS (exit 1 names each changed file)")
    v.add_argument("file", help="results/archive/stiffcal-<commit>.tar.gz")
    v.add_argument("--quiet", action="store_true", help="no progress on stderr")
    v.set_defaults(func=verify_archive)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    command_line = argv is None  # the installed command (not a call from Python: a test, a notebook)
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(join_negative_values(argv, parser))
    try:
        if command_line:
            from .limits import cap_memory

            cap_memory()  # a hard cap per command (docs/contracts.md, 'Limits'); an allocation past it is one line
        out = _with_progress(args)
    except MemoryError:
        from .limits import memory_message

        print(f"stiffcal {args.command}: error: {memory_message()}", file=sys.stderr)
        return 2
    except InputError as err:
        if err.source is None:  # an argument of the API: name it as the option it came from
            err = err.renamed(_option_name(err.field))
        print(f"stiffcal {args.command}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - a bug, not the user's input: one line (a traceback on request)
        if os.environ.get("STIFFCAL_TRACEBACK"):
            raise
        msg = " ".join(f"{type(err).__name__}: {err}".split())[:MAX_MESSAGE]
        print(f"stiffcal {args.command}: internal error (please report; STIFFCAL_TRACEBACK=1 shows where): {msg}",
              file=sys.stderr)
        return 1
    try:
        from .jsonsafe import json_safe

        print(json.dumps(json_safe(out), indent=2, allow_nan=False))
        sys.stdout.flush()
    except BrokenPipeError:  # the reader went away (`| head`): no traceback, the usual exit status
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    return 0 if not isinstance(out, dict) or out.get("ok", True) else 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
