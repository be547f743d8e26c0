"""The public Python API (``import stiffcal``): the paper's numbers, degrees at the edge, the CLI's checks,
the CLI's JSON, and a wheel installed into a clean virtual environment."""

import json
import os
import subprocess
import sys
import venv
from pathlib import Path

import numpy as np
import pytest

import stiffcal
from stiffcal.cli import main
from stiffcal.errors import InputError

PAPER_ROBOT = "config/robots/paper_2r.yaml"
DATA = "data/synthetic_paper_2r.csv"


def test_import_exposes_the_api_lazily():
    code = ("import sys, stiffcal; heavy = [m for m in ('scipy', 'pandas', 'matplotlib', 'jinja2', 'jsonschema') "
            "if m in sys.modules]; print(heavy, sorted(stiffcal.__all__))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.startswith("[]")  # importing the package loads none of the heavy libraries
    for name in ("load_robot", "design", "analyse_measurements", "DesignResult", "InputError"):
        assert name in out


def test_design_reproduces_the_paper_in_degrees(root):
    """Test pose (60, 30) deg and F = (0, -1) N give Table 2's O_t pose (-27.50, 71.34) and Table 3's O_t and
    chi (0.3869, 5.1694): the angles at the API edge are degrees."""
    robot = stiffcal.load_robot(root / PAPER_ROBOT)
    res = stiffcal.design(robot, test_pose_deg=[60, 30], force_N=[0, -1])
    assert isinstance(res, stiffcal.DesignResult)
    assert np.round(res.poses_deg[0], 2).tolist() == [-27.50, 71.34]
    assert round(res.O_t, 4) == 0.3869 and round(res.chi, 4) == 5.1694
    assert 0 < res.lower_bound <= res.O_t and res.gap == pytest.approx(res.O_t / res.lower_bound - 1)
    assert res.cov_diag.shape == (2,)


def test_a_plan_that_repeats_a_configuration_says_how_to_measure_the_repeats(root):
    """A fresh user measured a plan's repeated poses back to back without a visit column: the analysis read 17 visits
    for the protocol's 24 (back-to-back rows of one configuration are one visit). The design's notes now say to
    measure each repeat as a visit of its own, where the plan repeats a configuration, and only there (the count of
    distinct rows of its poses)."""
    robot = stiffcal.load_robot(root / PAPER_ROBOT)
    seen = set()
    for m in (1, 2, 4, 6):
        res = stiffcal.design(robot, test_pose_deg=[60, 30], force_N=[0, -1], experiments=m)
        repeats = len(np.unique(np.round(res.poses_deg, 6), axis=0)) < m
        seen.add(repeats)
        assert any("measure each repeat as a visit of its own" in n for n in res.notes) == repeats, (m, res.notes)
    assert seen == {True, False}


def test_copies_apart_by_round_off_are_one_configuration():
    """A fresh user's D-optimal Z1 plan printed copies of one pose as 9.172572, 9.172573 and 9.172574 deg, and the note
    on repeats stayed silent: the plan's copies within COPY_TOL_DEG (1e-4 deg) in every joint are now one pose, the
    first, and the note counts them; poses 1e-3 deg apart stay apart."""
    from stiffcal.api import merged_copies, repeated_poses_note

    base = np.array([[9.172572, -40.0, 30.0], [20.0, 10.0, 0.0]])
    poses = np.vstack([base, base[0] + [1e-6, -1e-6, 0.0], base[0] + [2e-6, 0.0, 5e-7], base[1] + [1e-3, 0.0, 0.0]])
    merged = merged_copies(poses)
    assert np.array_equal(merged[[2, 3]], base[[0, 0]]) and np.array_equal(merged[[0, 1, 4]], poses[[0, 1, 4]])
    assert "pose 1 x3" in repeated_poses_note(poses)[0] and "pose 2" not in repeated_poses_note(poses)[0]


def test_design_result_is_the_cli_json(root, capsys, monkeypatch):
    monkeypatch.chdir(root)
    res = stiffcal.design(PAPER_ROBOT, [60, 30], [0, -1], criterion="a", seed=3)
    assert main(["design", "--robot", PAPER_ROBOT, "--test-pose-deg", "60,30", "--force-N", "0,-1",
                 "--criterion", "a", "--seed", "3"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert json.loads(json.dumps(res.to_dict())) == cli
    for key in ("O_t", "chi", "cov_diag", "poses_deg", "lower_bound", "gap"):
        assert key in cli


def test_joint_limits_argument_restricts_the_poses(root):
    lim = [[-180, 180], [0, 40]]
    res = stiffcal.design(root / PAPER_ROBOT, [60, 30], [0, -1], joint_limits_deg=lim)
    assert 0 <= res.poses_deg[0, 1] <= 40 + 1e-9
    free = stiffcal.design(root / PAPER_ROBOT, [60, 30], [0, -1])
    assert res.O_t >= free.O_t  # a restricted search cannot do better than the free one


@pytest.mark.parametrize("kwargs,field", [
    ({"force_N": [0, -1, 5]}, "force_N"),             # a 3-component force on a planar arm
    ({"test_pose_deg": [60, float("nan")]}, "test_pose_deg[1]"),
    ({"sigma": 0}, "sigma"),
    ({"sigma": 1e300}, "sigma"),
    ({"experiments": 0}, "experiments"),
    ({"criterion": "x"}, "criterion"),
    ({"seed": -1}, "seed"),
    ({"joint_limits_deg": [[0, 10]]}, "joint_limits_deg"),
    ({"joint_limits_deg": [[0, 10], [True, 20]]}, "joint_limits_deg[1][0]"),
    # a flat list of numbers: nested lists, bools and scalars are refused (they were accepted silently)
    ({"test_pose_deg": [[60, 30]]}, "test_pose_deg[0]"),
    ({"test_pose_deg": [[60], [30]]}, "test_pose_deg[0]"),
    ({"test_pose_deg": [True, 30]}, "test_pose_deg[0]"),
    ({"test_pose_deg": 60}, "test_pose_deg"),
    ({"test_pose_deg": {"q1": 60, "q2": 30}}, "test_pose_deg"),
    ({"force_N": [0, "-1"]}, "force_N[1]"),
    ({"force_N": [False, -1]}, "force_N[0]"),
    ({"sigma": True}, "sigma"),
    ({"sigma": [1.0]}, "sigma"),
    ({"orientation": "no"}, "orientation"),
    ({"targets": 5}, "targets"),
    ({"targets": ["tool", 5]}, "targets"),
    ({"test_target": None}, "test_target"),
])
def test_bad_arguments_name_the_argument(root, kwargs, field):
    args = {"test_pose_deg": [60, 30], "force_N": [0, -1], **kwargs}
    with pytest.raises(InputError) as err:
        stiffcal.design(root / PAPER_ROBOT, args.pop("test_pose_deg"), args.pop("force_N"), **args)
    assert err.value.field == field


def test_analyse_measurements_writes_nothing_without_out_and_returns_the_file_s_verdict(root, tmp_path, monkeypatch):
    """Without ``out`` nothing is written; with it, verdict.json holds the same fields in the same order and the
    same values (issue 26: 19 keys in memory and 21 in the file before), but ``calibrated_model``, the file
    written beside it."""
    import json

    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    args = (root / PAPER_ROBOT, root / "data/synthetic_paper_2r.csv")
    kw = {"test_pose_deg": [60, 30], "force_N": [0, -300]}
    v = stiffcal.analyse_measurements(*args, **kw)
    assert v["cause"] == "backlash" and v["outlier_rows"] == [17]  # the hidden effect and blunder of data/README.md
    assert list(work.iterdir()) == []
    assert isinstance(v, stiffcal.Verdict) and v.next_round is not None and v.machining_path is not None
    written = stiffcal.analyse_measurements(*args, **kw, out=tmp_path / "out", figures=False)
    on_disk = json.loads((tmp_path / "out/verdict.json").read_text())
    assert list(on_disk) == list(v.to_dict()) == list(written)
    assert on_disk["calibrated_model"] == "calibrated.yaml" and v["calibrated_model"] is None
    assert json.loads(json.dumps({**v.to_dict(), "calibrated_model": "calibrated.yaml"})) == on_disk


def test_analyse_measurements_leaves_one_run_s_files_in_out(root, tmp_path):
    """A second analysis into the same folder replaces the first's files and removes those it does not write
    itself (the figures after figures=False, calibrated.yaml for a robot not given as a file), so the folder
    never holds a verdict beside another run's figures; a file of the user's is left alone."""
    from dataclasses import replace

    from stiffcal.measured.discrepancy import RUN_FILES

    out = tmp_path / "out"
    out.mkdir()
    (out / "my notes.txt").write_text("mine", encoding="utf-8")
    args = (root / PAPER_ROBOT, root / "data/synthetic_paper_2r.csv")
    stiffcal.analyse_measurements(*args, out=out)
    assert sorted(p.name for p in out.iterdir()) == sorted([*RUN_FILES, "my notes.txt"])
    stiffcal.analyse_measurements(*args, out=out, figures=False)
    assert sorted(p.name for p in out.iterdir()) == ["calibrated.yaml", "my notes.txt", "verdict.json"]
    in_memory = replace(stiffcal.load_robot(args[0]), source="<built in code>")
    v = stiffcal.analyse_measurements(in_memory, args[1], out=out, figures=False)
    assert v.calibrated_model is None
    assert sorted(p.name for p in out.iterdir()) == ["my notes.txt", "verdict.json"]
    assert (out / "my notes.txt").read_text(encoding="utf-8") == "mine"


def test_plan_discrimination_returns_the_file_s_plan_with_and_without_out(root, tmp_path):
    """The typed plan (stiffcal.DiscriminationPlan) is plan.json, field for field and in its order, whether or not
    ``out`` is given (before, the in-memory path read the loads another way than the written one)."""
    import json

    args = (root / PAPER_ROBOT, root / "data/synthetic_paper_2r_hanging.csv", 6)
    plan = stiffcal.plan_discrimination(*args)
    assert isinstance(plan, stiffcal.DiscriminationPlan) and plan["models"][0]["role"] == "truth"
    written = stiffcal.plan_discrimination(*args, out=tmp_path / "out")
    on_disk = json.loads((tmp_path / "out/plan.json").read_text())
    assert list(on_disk) == list(plan) == list(written)
    assert plan.to_dict() == on_disk == written.to_dict()


def test_wheel_installs_into_a_clean_venv_and_designs_from_a_robot_file(root, tmp_path):
    """``pip wheel .`` -> a fresh venv; its stiffcal (not the source tree) loads a robot file (schemas are
    package data) and designs, and reads a URDF robot (Pinocchio, a runtime dependency). The fresh venv sees
    the pinned dependencies through a path file pointing at this venv's site-packages (no download), and
    Pinocchio's libraries through cmeel's own path hook; that path file does not load the editable install."""
    import shutil

    src = tmp_path / "src-copy"  # build from a copy: setuptools writes build/ beside pyproject.toml
    shutil.copytree(root / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__"), symlinks=True)
    for f in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(root / f, src / f)
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels),
                    str(src)], check=True, capture_output=True)
    (whl,) = wheels.glob("stiffcal-*.whl")
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    deps = next(p for p in map(Path, sys.path) if p.name == "site-packages" and (p / "numpy").is_dir())
    (site / "deps.pth").write_text(str(deps) + "\nimport cmeel_pth\n")  # cmeel_pth adds Pinocchio's prefix
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(whl)],
                   check=True, capture_output=True)
    work = tmp_path / "elsewhere"
    work.mkdir()
    (work / "arm.yaml").write_text((root / PAPER_ROBOT).read_text())
    for f in ("kuka_kr210_r2700_urdf.yaml", "kuka_kr210_r2700.urdf"):
        shutil.copy(root / "config/robots" / f, work / f)
    code = ("import stiffcal, json; r = stiffcal.design(stiffcal.load_robot('arm.yaml'), [60, 30], [0, -1]); "
            "u = stiffcal.load_robot('kuka_kr210_r2700_urdf.yaml'); "
            "print(json.dumps({'file': stiffcal.__file__, 'O_t': round(r.O_t, 4), 'version': stiffcal.__version__, "
            "'joints': list(u.joint_names)}))")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = json.loads(subprocess.run([str(py), "-c", code], cwd=work, capture_output=True, text=True, check=True,
                                    env=env).stdout)
    assert out["file"].startswith(str(site)) and out["O_t"] == 0.3869 and out["version"] == stiffcal.__version__
    assert out["joints"] == ["a1", "a2", "a3", "a4", "a5", "a6"]
    cli = subprocess.run([str(env_dir / "bin" / "stiffcal"), "--version"], capture_output=True, text=True, env=env)
    assert cli.returncode == 0 and cli.stdout.strip() == f"stiffcal {stiffcal.__version__}"


@pytest.mark.parametrize("call,field", [
    (lambda r, df: stiffcal.analyse_measurements(r, df), "data"),      # a DataFrame instead of the CSV's path
    (lambda r, df: stiffcal.analyse_measurements(r, None), "data"),
    (lambda r, df: stiffcal.analyse_measurements(r, DATA, out=5), "out"),
    (lambda r, df: stiffcal.analyse_measurements(None, DATA), "robot"),
    (lambda r, df: stiffcal.analyse_measurements(r, DATA, test_pose_deg=[[60, 30]], force_N=[0, -1]),
     "test_pose_deg[0]"),
    (lambda r, df: stiffcal.plan_discrimination(r, df, 4), "data"),
    (lambda r, df: stiffcal.plan_discrimination(r, DATA, 4, loads=[300]), "loads"),
    (lambda r, df: stiffcal.load_robot(5), "path"),
    (lambda r, df: stiffcal.load_robot(None), "path"),
    (lambda r, df: stiffcal.design(None, [60, 30], [0, -1]), "robot"),
    (lambda r, df: stiffcal.design(5, [60, 30], [0, -1]), "robot"),
])
def test_api_misuse_names_the_argument(root, monkeypatch, call, field):
    """Wrong types give an InputError naming the argument (they were TypeErrors or AttributeErrors)."""
    import pandas as pd

    monkeypatch.chdir(root)
    robot = stiffcal.load_robot(PAPER_ROBOT)
    with pytest.raises(InputError) as err:
        call(robot, pd.read_csv(DATA))
    assert err.value.field == field


def test_a_compliance_the_plan_leaves_free_is_named():
    """A fresh user's iiwa O_t plan left k3 and k5 at 150 and 22 times their nominal in sd (the test load barely
    turns them; the median joint 0.13) and said nothing; the analysis then fitted k5 = -3.5e-5. A joint whose sd over
    its compliance is above 1 and 3 times the median joint's is named; none without compliances, none where all
    are alike (sigma = 1 in the paper's units makes every ratio large)."""
    from dataclasses import replace

    from stiffcal.planning.problem import weak_compliance_notes
    from stiffcal.model.robot import planar_robot

    robot = replace(planar_robot([0.6, 0.4, 0.3]), compliances=np.array([2e-6, 1e-6, 1e-6]))
    note = weak_compliance_notes(robot, np.array([4e-14, 1e-14, 9e-12]))  # r = 0.1, 0.1, 3
    assert len(note) == 1 and "joint(s) 3 (3 times its nominal)" in note[0] and "the median joint 0.1" in note[0]
    assert weak_compliance_notes(robot, np.array([4e-14, 1e-14, 1e-13])) == []  # r 0.32: determined to a third
    assert weak_compliance_notes(robot, np.array([4e2, 1e2, 4e2])) == []  # sigma = 1: all alike, none named
    assert "joint(s) 3" in weak_compliance_notes(robot, np.array([4e2, 1e2, 9e6]))[0]
    assert weak_compliance_notes(planar_robot([0.6, 0.4, 0.3]), np.array([1e-14, 1e-14, 9e-12])) == []
    # a fresh user's Panda plan (sd over nominal 4.85, 0.05, 0.50, 0.20, 4.27, 1.28, 37.1): k1 and k5 named beside k7,
    # and that the median joint is itself undetermined (its model predicted other poses 4.5x worse than a flat guess)
    panda = replace(planar_robot([0.1] * 7), compliances=np.full(7, 5e-6))
    r = np.array([4.85, 0.0512, 0.496, 0.199, 4.27, 1.28, 37.1])
    note = weak_compliance_notes(panda, (r * 5e-6) ** 2)[0]
    assert "joint(s) 1 (4.8 times its nominal), 5 (4.3 times its nominal), 7 (37 times" in note
    assert "the median joint's sd is itself 1.3 times its nominal" in note and "6 (" not in note
    # the paper's sigma = 1 and F = 1 N: every ratio 1e3 or more, no tracker's; the median's clause is left out
    assert "median joint's sd is itself" not in weak_compliance_notes(panda, (r * 5e-6 * 1e3) ** 2)[0]
