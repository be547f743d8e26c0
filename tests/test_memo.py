"""The workflow's memos (stiffcal.memo): code versions and checked data files kept between runs give what the
computation gives, and any change of what they depend on makes them compute again."""

import json
import shutil
from pathlib import Path

import pytest

from stiffcal import memo
from stiffcal.workflow import codeversion
from stiffcal.workflow import config
from stiffcal.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
STEPS = [("approximate_design",), ("study_plans",), ("discrepancy",), ("table2", "table3"), ("report_html",)]


@pytest.fixture
def remembered(tmp_path):
    """Code versions remembered in tmp_path for the test, then forgotten again."""
    path = tmp_path / "code-versions.json"
    codeversion.remember_code_versions(path)
    yield path
    codeversion._MEMO = None
    codeversion.code_version.cache_clear()


def test_remembered_code_versions_are_the_computed_ones(remembered, monkeypatch):
    computed = {s: codeversion._code_version(s) for s in STEPS}
    assert {s: codeversion.code_version(*s) for s in STEPS} == computed  # computed and stored
    stored = json.loads(remembered.read_text())
    assert stored["key"] == memo.package_fingerprint() and len(stored["entries"]) == len(STEPS)
    codeversion.remember_code_versions(remembered)  # a new run: read back, nothing parsed
    monkeypatch.setattr(codeversion, "_code_version", lambda steps: pytest.fail("parsed although remembered"))
    assert {s: codeversion.code_version(*s) for s in STEPS} == computed


@pytest.mark.parametrize("damage", ["", "[]", '{"key": "x", "entries": {}}', '{"key": null}', "\u0000"])
def test_a_memo_of_another_package_or_damaged_is_computed_afresh(remembered, damage):
    computed = codeversion._code_version(STEPS[0])
    if damage == '{"key": "x", "entries": {}}':  # another package version: its entries are not read
        damage = json.dumps({"key": "another", "entries": {",".join(STEPS[0]): "0" * 12}})
    remembered.write_text(damage)
    codeversion.remember_code_versions(remembered)
    assert codeversion.code_version(*STEPS[0]) == computed
    assert json.loads(remembered.read_text())["key"] == memo.package_fingerprint()


def test_the_memo_key_follows_the_package_source(monkeypatch, tmp_path):
    """An edit to any module of the package (here a copy of it) changes the package fingerprint."""
    copy = tmp_path / "stiffcal"
    shutil.copytree(ROOT / "src/stiffcal", copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(memo, "__file__", str(copy / "memo.py"))
    memo.package_fingerprint.cache_clear()
    try:
        before = memo.package_fingerprint()
        memo.package_fingerprint.cache_clear()
        with open(copy / "plots.py", "a", encoding="utf-8") as f:
            f.write("\n# an edit\n")
        assert memo.package_fingerprint() != before
    finally:
        memo.package_fingerprint.cache_clear()


def _config_with_data(tmp_path, csv_text):
    """The default config with its first data set replaced by csv_text, written beside copies of its inputs."""
    from stiffcal.validation import read_yaml

    cfg = read_yaml(ROOT / "config/config.yaml")
    shutil.copytree(ROOT / "config", tmp_path / "config")
    shutil.copytree(ROOT / "data", tmp_path / "data")
    data = tmp_path / cfg["measured_data"][0]["data"]
    data.write_text(csv_text, encoding="utf-8")
    return cfg, data


def test_checked_data_are_not_read_again_until_their_bytes_change(tmp_path, monkeypatch):
    """A good data file is read once; the same bytes are not read again; one changed byte is read again (and a
    bad value then refused naming the file), with or without the memo."""
    good = (ROOT / "data/synthetic_paper_2r.csv").read_text(encoding="utf-8")
    cfg, data = _config_with_data(tmp_path, good)
    memo_dir = tmp_path / "memo"
    from stiffcal.measured import measurements

    reads = []
    real = measurements.read_measurements
    monkeypatch.setattr(measurements, "read_measurements", lambda *a, **k: reads.append(a[0]) or real(*a, **k))
    config.check_config(json.loads(json.dumps(cfg)), tmp_path, "config.yaml", memo_dir)
    first = len(reads)
    assert first >= 1
    config.check_config(json.loads(json.dumps(cfg)), tmp_path, "config.yaml", memo_dir)
    assert len(reads) == first  # nothing read again
    lines = good.splitlines()
    header, row = lines[0].split(","), lines[1].split(",")
    row[header.index(next(c for c in header if c.startswith("dx")))] = "not-a-number"
    data.write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n", encoding="utf-8")
    for folder in (memo_dir, None):
        with pytest.raises(InputError) as err:
            config.check_config(json.loads(json.dumps(cfg)), tmp_path, "config.yaml", folder)
        assert data.name in str(err.value)
