"""Golden outputs of the measured-data analysis, the discrimination planner and the design engine, written by this
tree's code and by a baseline commit's, compared byte for byte: the check of a refactor that must not change a
result (issue 26: "freeze golden verdict.json, plan.json, design JSON and the tables first").

What is written, per tree (each by a child process whose PYTHONPATH puts that tree's src/ first):

- the verdicts of simulated lab logs (stiffcal.testing.rates.simulate_case: the 2-link, 3-link and 6-axis arms under
  every protocol of the rate matrix, clean and with a hidden backlash, joint coupling or tracker drift; the log
  written as a CSV with pose_id and analysed as a lab would), as JSON without the fields of the files and the
  calibrated model;
- ``stiffcal discrepancy`` (verdict.json, calibrated.yaml) on the two synthetic data sets of data/ (with the test
  pose), a 6-axis case of tests/data/discrepancy and two lab-reference logs;
- ``stiffcal discriminate`` (plan.json) on the two synthetic data sets;
- ``stiffcal design`` (its JSON) for every criterion on the paper's arm at M = 1 and 3, and four criteria on the
  6-axis arm at M = 3.

The simulated logs and the command lines are this tree's (the baseline analyses the same files). The pipeline's
tables are checked by tests/test_workflow.py (byte-identical reruns) and tests/test_paper.py (the paper's digits).

Run: .venv/bin/python tools/golden.py [--baseline COMMIT] [--cases N] [--keep DIR]
(default 3b438d5, every case: about 5 minutes; --keep copies both trees' outputs into DIR). Exit status 0 when every
output is identical, 1 otherwise (naming each file that differs, and the verdicts among them that name other causes).
"""

import argparse
import filecmp
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FILE_FIELDS = ("data", "robot", "next_round", "machining_path", "calibrated_model")
DISCREPANCY = {
    "synthetic": ["--robot", "config/robots/paper_2r.yaml", "--data", "data/synthetic_paper_2r.csv",
                  "--test-pose-deg", "60,30", "--force-N", "0,-300"],
    "hanging": ["--robot", "config/robots/paper_2r.yaml", "--data", "data/synthetic_paper_2r_hanging.csv",
                "--test-pose-deg", "60,30", "--force-N", "0,-300"],
    "kuka": ["--robot", "tests/data/discrepancy/case4_kuka_coupling.robot.yaml",
             "--data", "tests/data/discrepancy/case4_kuka_coupling.a.csv"],
    "lab-c3": ["--robot", "tests/data/lab-references/C3_measurement_offset_1/robot.yaml",
               "--data", "tests/data/lab-references/C3_measurement_offset_1/data.csv"],
    "lab-s1": ["--robot", "tests/data/lab-references/S1_none_3/robot.yaml",
               "--data", "tests/data/lab-references/S1_none_3/data.csv"],
}
DISCRIMINATE = {
    "hanging": ["--robot", "config/robots/paper_2r.yaml", "--data", "data/synthetic_paper_2r_hanging.csv",
                "--experiments", "6"],
    "synthetic": ["--robot", "config/robots/paper_2r.yaml", "--data", "data/synthetic_paper_2r.csv",
                  "--experiments", "4", "--loads", "directions:4:300", "--test-pose-deg", "60,30",
                  "--force-N", "0,-300"],
}
PAPER_DESIGN = ["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,30", "--force-N", "0,-1"]
KUKA_DESIGN = ["--robot", "config/robots/kuka_kr210_r2700.yaml", "--test-pose-deg", "20,-60,110,30,45,-20",
               "--force-N", "500,-300,-800", "--experiments", "3"]


def _module(path: str):
    """The module ``stiffcal.<path>`` of the tree on sys.path, or its flat path before the subpackages (a baseline
    such as 0fbeb92 has ``stiffcal.rates`` where this tree has ``stiffcal.testing.rates``): no deprecation warning
    from this tree, and older baselines still run."""
    import importlib

    try:
        return importlib.import_module(f"stiffcal.{path}")
    except ModuleNotFoundError:
        return importlib.import_module(f"stiffcal.{path.rsplit('.', 1)[-1]}")


def write_cases(folder: Path, limit: int | None) -> list[str]:
    """The simulated lab logs as CSVs in ``folder`` (this tree's simulator); returns their names."""
    R, T = _module("testing.rates"), _module("testing.truth")
    arms = R.robots(ROOT)
    names = []
    for arm in ("2-link", "3-link", "6-axis"):
        for i, protocol in enumerate(R.protocols_for(arms[arm])):
            for effects in ((), ("backlash",), ("joint_coupling",), ("drift",)):
                if limit is not None and len(names) >= limit:
                    return names
                log, dp, _ = R.simulate_case(arms[arm], protocol, effects, 900 + i, 40, (0.3, 1.0))
                name = f"{arm}__{i}__{'+'.join(effects) or 'clean'}"
                (folder / f"{name}.csv").write_text(T.lab_csv(arms[arm], log, dp, pose_id=True), encoding="utf-8")
                names.append(name)
    return names


def dump(cases: Path, out: Path) -> None:
    """Every golden output of the stiffcal on sys.path into ``out`` (run in the child process)."""
    D, R = _module("measured.discrepancy"), _module("testing.rates")
    CRITERIA_KEYS = _module("model.criteria").CRITERIA_KEYS  # the registry of the tree on sys.path (the child's)
    read_measurements = _module("measured.measurements").read_measurements

    arms = R.robots(ROOT)
    out.mkdir(parents=True, exist_ok=True)
    for csv in sorted(cases.glob("*.csv")):
        arm = csv.stem.split("__")[0]
        try:
            v = D.analyse(arms[arm], read_measurements(csv, arms[arm]), 0.01, gain=arm != "6-axis")
            v = {k: x for k, x in (v.to_dict() if hasattr(v, "to_dict") else v).items() if k not in FILE_FIELDS}
        except Exception as err:  # a refusal is an output too
            v = {"error": f"{type(err).__name__}: {err}"}
        text = json.dumps(v, indent=1, sort_keys=True, allow_nan=False)
        (out / f"case-{csv.stem}.json").write_text(text + "\n", encoding="utf-8")
    cli = [sys.executable, "-m", "stiffcal.cli"]
    env = {**os.environ, "STIFFCAL_CACHE_DIR": str(out / ".cache")}
    runs = [(f"discrepancy-{n}", ["discrepancy", *a, "--out", str(out / f"discrepancy-{n}"), "--no-figures"])
            for n, a in DISCREPANCY.items()]
    runs += [(f"discriminate-{n}", ["discriminate", *a, "--out", str(out / f"discriminate-{n}")])
             for n, a in DISCRIMINATE.items()]
    runs += [(f"design-2r-{c}-{m}", ["design", *PAPER_DESIGN, "--criterion", c, "--experiments", str(m)])
             for c in CRITERIA_KEYS for m in (1, 3)]
    runs += [(f"design-kuka-{c}", ["design", *KUKA_DESIGN, "--criterion", c]) for c in ("ot", "d", "a", "mdc")]
    for name, args in runs:
        res = subprocess.run(cli + args, cwd=ROOT, capture_output=True, text=True, env=env)
        text = res.stdout if name.startswith("design") else ""
        (out / f"{name}.out").write_text(f"exit {res.returncode}\n{text}", encoding="utf-8")
    for png in out.rglob("plan.png"):  # the figure's bytes carry matplotlib's metadata; its SVG and JSON stay
        png.unlink()


def _tree(commit: str, folder: Path) -> Path:
    """src/ of ``commit`` extracted into ``folder`` (git archive: no checkout)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "src"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder / "src"


def _differences(a: Path, b: Path) -> list[str]:
    names = {p.relative_to(a) for p in a.rglob("*") if p.is_file() and ".cache" not in p.parts}
    names |= {p.relative_to(b) for p in b.rglob("*") if p.is_file() and ".cache" not in p.parts}
    return sorted(str(n) for n in names if not ((a / n).is_file() and (b / n).is_file()
                                                 and filecmp.cmp(a / n, b / n, shallow=False)))


def _verdict_changes(a: Path, b: Path, names: list[str]) -> list[str]:
    """For the outputs that differ and are verdicts (JSON with a ``cause``): the ones whose named causes changed,
    as ``name: baseline's -> this tree's`` (the others differ in their numbers only)."""
    out = []
    for name in names:
        try:
            va, vb = (json.loads((d / name).read_text(encoding="utf-8")) for d in (a, b))
        except (OSError, ValueError):
            continue
        if isinstance(va, dict) and isinstance(vb, dict) and "cause" in va and "cause" in vb:
            ca = (va["cause"], tuple(va.get("indistinguishable_from") or ()))
            cb = (vb["cause"], tuple(vb.get("indistinguishable_from") or ()))
            if ca != cb:
                out.append(f"{name}: {ca[0]} {list(ca[1]) or ''} -> {cb[0]} {list(cb[1]) or ''}")
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default="3b438d5", help="the commit to compare with (default 3b438d5)")
    ap.add_argument("--cases", type=int, default=None, help="at most this many simulated logs (default all)")
    ap.add_argument("--keep", metavar="DIR", help="copy both trees' outputs into DIR (baseline/, this-tree/)")
    ap.add_argument("--dump", nargs=2, metavar=("CASES", "OUT"), help=argparse.SUPPRESS)  # the child's job
    args = ap.parse_args()
    if args.dump:
        dump(Path(args.dump[0]), Path(args.dump[1]))
        return 0
    CRITERIA_KEYS = _module("model.criteria").CRITERIA_KEYS

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "cases").mkdir()
        names = write_cases(tmp / "cases", args.cases)
        print(f"golden: {len(names)} simulated logs, {len(DISCREPANCY)} discrepancy, {len(DISCRIMINATE)} discriminate "
              f"and {2 * len(CRITERIA_KEYS) + 4} design runs, at {args.baseline} and in this tree", file=sys.stderr)
        (tmp / "baseline").mkdir()
        trees = {"baseline": _tree(args.baseline, tmp / "baseline"), "this tree": ROOT / "src"}
        outs = {}
        for label, src in trees.items():
            outs[label] = tmp / label.replace(" ", "-") / "out"
            env = {**os.environ, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
            subprocess.run([sys.executable, __file__, "--dump", str(tmp / "cases"), str(outs[label])], env=env,
                           check=True)
        diff = _differences(outs["baseline"], outs["this tree"])
        count = sum(1 for p in outs["this tree"].rglob("*") if p.is_file() and ".cache" not in p.parts)
        if args.keep:
            for label, folder in outs.items():
                shutil.copytree(folder, Path(args.keep) / label.replace(" ", "-"), dirs_exist_ok=True)
        if diff:
            print(f"golden: {len(diff)} of {count} outputs differ from {args.baseline}'s: {', '.join(diff)}")
            changed = _verdict_changes(outs["baseline"], outs["this tree"], diff)
            print(f"golden: of those, {len(changed)} verdicts name other causes" + "".join(f"\n  {c}" for c in changed))
            return 1
        print(f"golden: all {count} outputs identical to {args.baseline}'s")
        return 0


if __name__ == "__main__":
    sys.exit(main())
