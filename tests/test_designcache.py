"""The cache of approximate designs and candidate pools (stiffcal.designcache): a design read back is the one
computed, every input that changes the design changes the key, a damaged entry is recomputed, and the CLI's
options are checked before any work."""

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest

import stiffcal
from stiffcal import certificate, designcache
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.robot import load_robot
from stiffcal.study import Study

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config/robots/paper_2r.yaml"
CELL = """name: paper-2r-cell
kind: planar
links_m: [0.6, 0.4]
joint_limits_deg: [[-180, 180], [-150, 150]]
cell:
  floor_m: -0.05
  clearance_m: 0.02
  link_radius_m: 0.04
"""


def _forbid_computing(monkeypatch):
    """From now on computing an approximate design or a candidate pool fails the test."""
    def refuse(*_, **__):
        raise AssertionError("computed although the cache holds it")

    monkeypatch.setattr(certificate, "approximate_design", refuse)
    monkeypatch.setattr(certificate, "candidate_pool", refuse)


@pytest.mark.parametrize("robot_text, m", [(None, 3), (CELL, 2)])
def test_a_design_read_back_gives_the_plan_computed_without_the_cache(tmp_path, monkeypatch, robot_text, m):
    """Fresh, stored, read back (nothing recomputed: the certificate's functions are made to fail) and without the
    cache: the same result, every number; in a cell both the feasible and the unconstrained design are kept."""
    path = PAPER
    if robot_text:
        path = tmp_path / "robot.yaml"
        path.write_text(robot_text)
    cache = tmp_path / "cache"
    args = dict(experiments=m, progress=False)
    fresh = stiffcal.design(path, [60, 30], [0, -1], **args).to_dict()
    stored = stiffcal.design(path, [60, 30], [0, -1], cache_dir=cache, **args).to_dict()
    entries = sorted(p.parent.name for p in cache.rglob("*") if p.is_file())
    assert entries == (["approximate-design"] * (2 if robot_text else 1) + ["candidate-pool"])
    _forbid_computing(monkeypatch)
    for k in (m, m + 2):  # another M, another criterion: the same entries
        again = stiffcal.design(path, [60, 30], [0, -1], experiments=k, cache_dir=cache, progress=False).to_dict()
        assert json.dumps(again, sort_keys=True) == json.dumps(fresh if k == m else again, sort_keys=True)
    assert json.dumps(stored, sort_keys=True) == json.dumps(fresh, sort_keys=True)
    monkeypatch.undo()
    other = stiffcal.design(path, [60, 30], [0, -1], experiments=m + 2, progress=False).to_dict()
    assert json.dumps(other, sort_keys=True) == json.dumps(again, sort_keys=True)


def _problem(robot, **change):
    study = Study("s", robot, np.radians([60.0, 30.0]), np.array([0.0, -1.0]), 1.0, ("ot",), 1.0, 1.0)
    return dataclasses.replace(study.problem("ot"), **change)


def test_every_input_of_the_design_changes_the_key(paper_robot):
    """The same inputs give the same key; a change of the test pose by 1e-12 rad, of the force, the sigma, a
    link length, a joint limit, a cell, a candidate set or the targets gives a new one (the design could differ)."""
    base = designcache.fingerprint(_problem(paper_robot))
    assert designcache.fingerprint(_problem(load_robot(PAPER))) == base
    from stiffcal.workcell import with_cell

    changed = [_problem(paper_robot, test_pose=np.radians([60.0, 30.0]) + 1e-12),
               _problem(paper_robot, force=np.array([0.0, -2.0])),
               _problem(paper_robot, sigma=2.0),
               _problem(dataclasses.replace(paper_robot, links_m=np.array([0.6, 0.4 + 1e-9]))),
               _problem(dataclasses.replace(paper_robot, joint_limits_rad=paper_robot.joint_limits_rad * 0.5)),
               _problem(with_cell(load_robot(PAPER), {"floor_m": -0.05, "link_radius_m": 0.04}, "test")),
               _problem(paper_robot, candidates=np.radians([[60.0, 30.0], [10.0, 80.0], [-30.0, 45.0]])),
               _problem(dataclasses.replace(paper_robot, targets={"smr": np.array([0.1, 0.0, 0.0])}))]
    keys = [designcache.fingerprint(p) for p in changed]
    assert base not in keys and len(set(keys)) == len(keys)


def test_the_key_changes_with_the_code(paper_robot, monkeypatch):
    base = designcache.fingerprint(_problem(paper_robot))
    monkeypatch.setattr(designcache, "package_fingerprint", lambda: "another version")
    assert designcache.fingerprint(_problem(paper_robot)) != base


@pytest.mark.parametrize("damage", [b"", b"{not json", b'{"format": 1}', b"[1, 2]", b"\xff\xfe",
                                    b'{"format": 1, "support_deg": [[NaN, 0]], "weights": [1], "phi": 1, '
                                    b'"max_phi": 1, "phi_lower": 1, "iterations": 1, "region": "x", '
                                    b'"n_candidates": 0}'])
def test_a_damaged_entry_is_recomputed_and_rewritten(tmp_path, damage):
    cache = tmp_path / "cache"
    fresh = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2, progress=False, cache_dir=cache)
    for entry in cache.rglob("*.*"):
        entry.write_bytes(damage)
    again = stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2, progress=False, cache_dir=cache)
    assert json.dumps(again.to_dict()) == json.dumps(fresh.to_dict())
    assert all(e.read_bytes() != damage for e in cache.rglob("*.*"))


def test_a_cache_folder_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError) as err:
        stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2, cache_dir=blocker / "cache")
    assert err.value.field == "cache_dir"
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--experiments", "2"]
    assert main(base + ["--cache-dir", str(blocker)]) == 2
    assert main(base + ["--cache-dir", str(tmp_path / "c"), "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "cache_dir" in err and "not both" in err and not (tmp_path / "c").exists()


def test_the_cli_uses_the_default_folder_and_no_cache_leaves_it_empty(tmp_path, monkeypatch, capsys):
    """STIFFCAL_CACHE_DIR names the default folder; --no-cache computes afresh and writes nothing; the printed
    plan is the same either way."""
    folder = tmp_path / "default"
    monkeypatch.setenv(designcache.CACHE_ENV, str(folder))
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--experiments", "2",
            "--quiet"]
    assert main(base + ["--no-cache"]) == 0
    afresh = capsys.readouterr().out
    assert not folder.exists()
    assert main(base) == 0
    assert capsys.readouterr().out == afresh and any(folder.rglob("*.json"))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv(designcache.CACHE_ENV, str(blocker / "cache"))  # a default that cannot be a folder
    assert main(base) == 0  # no cache, no error
    assert capsys.readouterr().out == afresh


def test_a_urdf_arm_in_a_cell_is_keyed_by_its_collision_meshes_too(tmp_path):
    """The cell's collision checks read the URDF's meshes from files that no robot field holds: replacing one
    mesh (by another valid one) gives a new key, restoring it the old one."""
    import shutil
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    import real_arms

    root = real_arms.robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed (requirements-test.lock pins it)")
    ur = tmp_path / "example-robot-data/robots/ur_description"  # where its package:// URIs point
    shutil.copytree(root / "ur_description/urdf", ur / "urdf")
    shutil.copytree(root / "ur_description/meshes/ur10", ur / "meshes/ur10")
    urdf, _, base, tip, tool, pose, force = real_arms.ARMS["ur10"]
    robot_file = tmp_path / "ur10.yaml"
    robot_file.write_text(f"name: ur10-cell\nkind: urdf\nurdf: {ur.parent / urdf}\nbase_frame: {base}\n"
                          f"tip_frame: {tip}\ntool_m: {tool}\ncell:\n  floor_m: 0.0\n  self_collision: true\n")
    robot = load_robot(robot_file)
    study = Study("s", robot, np.radians(pose), np.array(force, float), 1.0, ("ot",), 1.0, 1.0)
    key = designcache.fingerprint(study.problem("ot"))
    mesh = ur / "meshes/ur10/collision/wrist1.stl"
    original = mesh.read_bytes()
    mesh.write_bytes((ur / "meshes/ur10/collision/wrist2.stl").read_bytes())
    assert designcache.fingerprint(study.problem("ot")) != key
    mesh.write_bytes(original)
    assert designcache.fingerprint(study.problem("ot")) == key


@pytest.mark.parametrize("cache", [[], ["--no-cache"]])
def test_several_m_in_one_call_are_the_plans_of_separate_calls(tmp_path, capsys, cache):
    """``--experiments 2-3,5``: a JSON array of the plans of M = 2, 3 and 5 in that order, each the object a call
    for that M alone prints (the approximate design computed once, with --no-cache too, which then stores
    nothing)."""
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--quiet"]
    assert main(base + ["--experiments", "5,2-3", *cache]) == 0
    several = json.loads(capsys.readouterr().out)
    alone = []
    for m in (2, 3, 5):
        assert main(base + ["--experiments", str(m), "--no-cache"]) == 0
        alone.append(json.loads(capsys.readouterr().out))
    assert several == alone
    assert not cache or not any(Path(os.environ[designcache.CACHE_ENV]).rglob("*.json"))


@pytest.mark.parametrize("value, needle", [("2-", "expected a whole number M, a range A-B"),
                                           ("3-2", "A <= B"), ("0-4", "in [1, 1000]"), ("1-5000", "at most 1000 poses"),
                                           ("1-1000", "at most 100 values of M")])
def test_bad_experiment_lists_are_refused_naming_the_option(capsys, value, needle):
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--quiet"]
    assert main(base + ["--experiments", value]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "'--experiments'" in captured.err and needle in captured.err
