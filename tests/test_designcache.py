"""The cache of approximate designs and candidate pools (stiffcal.planning.designcache): a design read back is the one
computed, every input that changes the design changes the key, a damaged entry is recomputed, and the CLI's
options are checked before any work."""

import dataclasses
import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

import stiffcal
from stiffcal.planning import certificate
from stiffcal.planning import designcache
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.model.robot import load_robot
from stiffcal.planning.study import Study

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


def _plan(cache=None) -> dict:
    """The paper arm's 2-pose plan (to_dict), with the cache folder ``cache`` or none."""
    return stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2, progress=False, cache_dir=cache).to_dict()


def _entries(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file())


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
    from stiffcal.model.workcell import with_cell

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
    fresh = _plan(cache)
    for entry in _entries(cache):
        entry.write_bytes(damage)
    again = _plan(cache)
    assert json.dumps(again) == json.dumps(fresh)
    assert all(e.read_bytes() != damage for e in _entries(cache))


def test_a_cache_folder_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError) as err:
        stiffcal.design(PAPER, [60, 30], [0, -1], experiments=2, cache_dir=blocker / "cache")
    assert err.value.field == "cache_dir"
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--experiments", "2"]
    assert main(base + ["--cache-dir", str(blocker)]) == 2
    assert main(base + ["--cache-dir", str(tmp_path / "c"), "--no-cache"]) == 2
    assert main(base + ["--cache-dir", ""]) == 2
    err = capsys.readouterr().err
    assert err.count("field '--cache-dir'") == 3 and "not both" in err and "empty path" in err
    assert not (tmp_path / "c").exists() and not any(Path.cwd().glob("approximate-design"))


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
    assert capsys.readouterr().out == afresh and any(_entries(folder))
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
    assert not cache or not any(_entries(Path(os.environ[designcache.CACHE_ENV])))


@pytest.mark.parametrize("value, needle", [("2-", "expected a whole number M, a range A-B"),
                                           ("3-2", "A <= B"), ("0-4", "in [1, 1000]"), ("1-5000", "at most 1000 poses"),
                                           ("1-1000", "at most 100 values of M")])
def test_bad_experiment_lists_are_refused_naming_the_option(capsys, value, needle):
    base = ["design", "--robot", str(PAPER), "--test-pose-deg", "60,30", "--force-N", "0,-1", "--quiet"]
    assert main(base + ["--experiments", value]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "'--experiments'" in captured.err and needle in captured.err


def _forge(entry: Path, payload: bytes) -> None:
    """Replace an entry's content by payload with a checksum that matches (a damage the checksum cannot see)."""
    kind, key = entry.parent.name, entry.name
    entry.write_bytes(designcache._entry(key, kind, payload))


@pytest.mark.parametrize("edit", ["weights", "phi_lower", "region"])
def test_an_edited_entry_is_recomputed(tmp_path, edit):
    """An entry edited by hand (a weight, the bound's phi, the region) no longer matches its checksum: recomputed,
    the output that of a fresh computation."""
    cache = tmp_path / "cache"
    fresh = _plan()
    _plan(cache)
    entry = next(e for e in _entries(cache) if e.parent.name == "approximate-design")
    head, _, payload = entry.read_bytes().partition(b"\n")
    doc = json.loads(payload)
    doc[edit] = {"weights": [w * 0.5 for w in doc["weights"]], "phi_lower": 1e-4, "region": "candidate poses"}[edit]
    entry.write_bytes(head + b"\n" + json.dumps(doc).encode())
    again = _plan(cache)
    assert json.dumps(again, sort_keys=True) == json.dumps(fresh, sort_keys=True)


def _design_payload(**raw) -> bytes:
    """A design entry's JSON with some values given as raw JSON text (a one-pose design at the paper's optimum
    otherwise, which this code would read back)."""
    doc = {"support_deg": "[[60.0, 30.0]]", "weights": "[1.0]", "phi": "1.0", "max_phi": "1.0", "phi_lower": "1.0",
           "iterations": "1", "region": '"joint space"', "n_candidates": "0", "near_singular": "false", **raw}
    return ("{" + ", ".join(f'"{k}": {v}' for k, v in doc.items()) + "}").encode()


@pytest.mark.parametrize("payload, used", [
    (_design_payload(), True),  # the control: a forged design that is well formed is read (the forge works)
    (_design_payload(iterations="1e999"), False), (_design_payload(n_candidates="Infinity"), False),
    (_design_payload(phi="1" + "0" * 400), False), (_design_payload(region="[" * 100000 + "]" * 100000), False),
    (_design_payload(support_deg="[]", weights="[]"), False), (_design_payload(weights="[-1.0]"), False),
    (_design_payload(support_deg="[[60.0]]"), False), (_design_payload(iterations="-1"), False),
    (_design_payload(phi="0.0"), False), (_design_payload(near_singular="1"), False)])
def test_a_well_formed_entry_that_no_computation_gives_is_recomputed(tmp_path, payload, used):
    cache = tmp_path / "cache"
    fresh = _plan()
    _plan(cache)
    _forge(next(e for e in _entries(cache) if e.parent.name == "approximate-design"), payload)
    again = _plan(cache)
    assert (json.dumps(again, sort_keys=True) == json.dumps(fresh, sort_keys=True)) is not used


@pytest.mark.parametrize("pool", ["empty", "huge header", "wrong width", "nan"])
def test_a_pool_entry_that_no_computation_gives_is_recomputed(tmp_path, pool):
    """An empty pool, a .npy header that claims 10^12 rows (never allocated), another width, a NaN: recomputed."""
    cache = tmp_path / "cache"
    fresh = _plan()
    _plan(cache)
    arrays = {"empty": np.zeros((0, 2)), "wrong width": np.zeros((5, 3)), "nan": np.full((5, 2), np.nan),
              "huge header": np.zeros((3, 2))}
    payload = designcache._pool_bytes(arrays[pool])
    if pool == "huge header":  # the same header length (padded with spaces), 10^12 rows claimed
        head_len = 10 + int.from_bytes(payload[8:10], "little")
        head = payload[10:head_len].replace(b"(3, 2)", b"(1000000000000, 2)")
        payload = payload[:10] + head[:head_len - 10 - 1].ljust(head_len - 10 - 1) + b"\n" + payload[head_len:]
        assert np.lib.format.read_array_header_1_0(io.BytesIO(payload[8:]))[0] == (10**12, 2)
    _forge(next(e for e in _entries(cache) if e.parent.name == "candidate-pool"), payload)
    again = _plan(cache)
    assert json.dumps(again, sort_keys=True) == json.dumps(fresh, sort_keys=True)


def test_the_cells_srdf_is_part_of_the_key(tmp_path):
    """The SRDF names the body pairs a cell leaves unchecked: editing it gives a new key."""
    srdf = tmp_path / "arm.srdf"
    srdf.write_text('<robot name="a"><disable_collisions link1="l1" link2="l2" reason="Adjacent"/></robot>')
    from stiffcal.model.workcell import WorkCell

    robot = dataclasses.replace(load_robot(PAPER), cell=WorkCell(srdf=str(srdf)))
    key = designcache.fingerprint(_problem(robot))
    srdf.write_text('<robot name="a"></robot>')
    assert designcache.fingerprint(_problem(robot)) != key


def test_a_fifo_in_place_of_an_entry_is_not_read(tmp_path):
    """A FIFO where an entry should be would block a reader: it is passed over (computed afresh)."""
    cache = tmp_path / "cache"
    fresh = _plan(cache)
    for entry in _entries(cache):
        entry.unlink()
        os.mkfifo(entry)
    again = _plan(cache)
    assert json.dumps(again, sort_keys=True) == json.dumps(fresh, sort_keys=True)
