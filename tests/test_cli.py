"""`stiffcal design` as DESIGN.md specifies, with the numbers the issue checks (paper, 4 digits)."""

import json
import subprocess
import sys

import pytest

from stiffcal.cli import main

PAPER = ["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,30", "--force-N", "0,-1",
         "--experiments", "1"]


def run(args, capsys):
    code = main(["design", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def sig4(x):
    return float(f"{x:.4g}")


def test_design_default_criterion_is_ot(root, capsys, monkeypatch):
    monkeypatch.chdir(root)
    code, out, _ = run(PAPER, capsys)
    d = json.loads(out)
    assert code == 0 and d["criterion"] == "ot"
    assert sig4(d["O_t"]) == 0.3869 and sig4(d["chi"]) == 5.169
    assert len(d["poses_deg"]) == 1 and len(d["poses_deg"][0]) == 2
    assert 0 < d["lower_bound"] <= d["O_t"]  # certified bound for any single pose (issue 3)
    for key in ("criterion", "poses_deg", "O_t", "chi", "cov_diag", "lower_bound"):
        assert key in d


@pytest.mark.parametrize("crit,expected", [("a", (13.73, 53.41)), ("d", (5.321, 113.3)), ("mdc", (44.30, 44.30))])
def test_design_cov_diag_matches_paper(crit, expected, root, capsys, monkeypatch):
    monkeypatch.chdir(root)
    code, out, _ = run([*PAPER, "--criterion", crit], capsys)
    d = json.loads(out)
    assert code == 0
    assert tuple(sig4(v) for v in d["cov_diag"]) == expected


def test_design_t_optimality_reports_inf_as_string(root, capsys, monkeypatch):
    monkeypatch.chdir(root)
    _, out, _ = run([*PAPER, "--criterion", "t"], capsys)
    d = json.loads(out)
    assert d["cov_diag"] == ["inf", "inf"] and d["O_t"] == "inf"


@pytest.mark.parametrize("args,needle", [
    (["--robot", "missing.yaml", "--test-pose-deg", "60,30", "--force-N", "0,-1"], "missing.yaml: cannot read file"),
    (["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60", "--force-N", "0,-1"],
     "'--test-pose-deg': expected 2 joint angles"),
    (["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,x", "--force-N", "0,-1"],
     "expected comma-separated numbers"),
    (["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,30", "--force-N", "0,0"],
     "expected a nonzero force"),
    (["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,nan", "--force-N", "0,-1"],
     "expected finite numbers"),
    (["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "60,30", "--force-N", "0,-1", "--sigma", "0"],
     "expected sigma > 0"),
])
def test_bad_input_is_one_line_and_exit_2(args, needle, root, capsys, monkeypatch):
    monkeypatch.chdir(root)
    code, out, err = run(args, capsys)
    assert code == 2 and out == ""
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err


def test_installed_console_script(root):
    exe = [sys.executable, "-m", "stiffcal.cli"]
    res = subprocess.run([*exe, "design", *PAPER, "--criterion", "d"], cwd=root, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert sig4(json.loads(res.stdout)["cov_diag"][0]) == 5.321
