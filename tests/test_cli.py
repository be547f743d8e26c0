"""`stiffcal design` as docs/contracts.md specifies, with the numbers the issue checks (paper, 4 digits)."""

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
    # a fresh user's Baxter: a T plan that identifies nothing came with no word
    assert any("do not identify the compliances of joint(s) 1, 2" in n for n in d["notes"]), d["notes"]
    _, out, _ = run([*PAPER, "--criterion", "a"], capsys)
    assert not any("do not identify" in n for n in json.loads(out)["notes"])


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
     "'--sigma': expected a number in [1e-100"),
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


def test_negative_angles_without_equals_sign(root, capsys, monkeypatch):
    """``--test-pose-deg -35,120`` (a negative first angle, no '=') is a value, not an option."""
    monkeypatch.chdir(root)
    code, out, err = run(["--robot", "config/robots/paper_2r.yaml", "--test-pose-deg", "-35,120", "--force-N",
                          "-1,-1"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["test_pose_deg"] == [-35.0, 120.0] and d["force_N"] == [-1.0, -1.0]
    assert err == ""  # no progress bar when stderr is not a terminal


@pytest.mark.parametrize("option,value,needle", [("--seed", "-1", "'--seed': expected a whole number"),
                                                 ("--sigma", "-1e-3", "'--sigma': expected a number in"),
                                                 ("--experiments", "-2", "'--experiments': expected a whole number")])
def test_negative_scalars_are_values_with_a_clear_message(root, capsys, monkeypatch, option, value, needle):
    monkeypatch.chdir(root)
    code, out, err = run([*PAPER[:6], option, value], capsys)
    assert code == 2 and out == "" and needle in err and err.count("\n") == 1


def test_version(capsys):
    import stiffcal

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"stiffcal {stiffcal.__version__}"


def test_python_dash_m_runs_the_command_line(root):
    """``python -m stiffcal`` is the installed ``stiffcal`` (a fresh user's first try): its version line, and a bad
    option's one-line message and status 2."""
    import os
    import subprocess
    import sys

    import stiffcal

    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    ok = subprocess.run([sys.executable, "-m", "stiffcal", "--version"], capture_output=True, text=True, env=env)
    assert ok.returncode == 0 and ok.stdout.strip() == f"stiffcal {stiffcal.__version__}"
    bad = subprocess.run([sys.executable, "-m", "stiffcal", "design", "--experiments", "x"], capture_output=True,
                         text=True, env=env)
    assert bad.returncode == 2 and bad.stderr.startswith("stiffcal design: error") and "Traceback" not in bad.stderr


def test_progress_bar_on_a_terminal_and_quiet(root):
    """A progress bar goes to stderr when it is a terminal (a pseudo-terminal here), never with --quiet."""
    import fcntl
    import os
    import pty
    import struct
    import termios

    def stderr_on_tty(extra):
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal of 100 columns
        proc = subprocess.Popen([sys.executable, "-m", "stiffcal.cli", "design", *PAPER, *extra], cwd=root,
                                stdout=subprocess.PIPE, stderr=slave)
        os.close(slave)
        chunks = []
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                break
            if not data:
                break
            chunks.append(data)
        proc.wait()
        os.close(master)
        return proc.returncode, b"".join(chunks).decode(errors="replace")

    code, err = stderr_on_tty([])
    assert code == 0 and "stages" in err
    code, err = stderr_on_tty(["--quiet"])
    assert code == 0 and err == ""


def _strict_json(text: str):
    """Parse as strict JSON: the bare tokens Infinity, -Infinity and NaN are refused."""
    def refuse(token):
        raise ValueError(f"not JSON: {token}")

    return json.loads(text, parse_constant=refuse)


def test_every_json_writer_is_strict(root):
    """Every json.dump / json.dumps call of the package, the workflow scripts and the tools refuses NaN and
    infinity (allow_nan=False): an infinite value must be written as the string 'inf', never as a bare
    Infinity token that JSON parsers reject."""
    import ast

    calls = []
    for path in [*(root / "src/stiffcal").rglob("*.py"), *(root / "workflow").rglob("*.py"),
                 *(root / "tools").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in
                    ("dump", "dumps") and isinstance(node.func.value, ast.Name) and node.func.value.id == "json"):
                strict = any(k.arg == "allow_nan" and isinstance(k.value, ast.Constant) and k.value.value is False
                             for k in node.keywords)
                calls.append((f"{path.relative_to(root)}:{node.lineno}", strict))
    assert len(calls) >= 6  # cli, api, discrepancy, discrimination, pipeline, archive, report
    assert [c for c, strict in calls if not strict] == []


def test_design_json_writes_every_infinity_as_a_string(root, capsys, monkeypatch):
    """O_t* infinite (the test pose alone cannot identify the compliances; the Franka Panda case of the user
    test), a gap of inf / inf, an infinite equivalence gap and -0.0 angles: the CLI prints strict JSON with "inf",
    null for the undefined gap and 0.0."""
    import dataclasses

    import numpy as np

    import stiffcal
    import stiffcal.api

    res = stiffcal.design(root / "config/robots/paper_2r.yaml", [60, 30], [0, -1])
    odd = dataclasses.replace(res, O_t_star=float("inf"), chi=float("inf"), lower_bound=float("inf"),
                              gap=float("nan"), poses_deg=np.array([[-0.0, 45.0]]),
                              approximate_design={**res.approximate_design, "equivalence_gap": float("inf"),
                                                  "support_deg": np.array([[-1e-9, 30.0]])})
    monkeypatch.setattr(stiffcal.api, "design", lambda *a, **k: odd)
    monkeypatch.chdir(root)
    code, out, _ = run(PAPER, capsys)
    d = _strict_json(out)
    assert code == 0 and d["O_t_star"] == d["chi"] == d["lower_bound"] == "inf" and d["gap"] is None
    assert d["approximate_design"]["equivalence_gap"] == "inf"
    assert d["poses_deg"] == [[0.0, 45.0]] and "-0.0" not in out
    assert _strict_json(json.dumps(odd.to_dict(), allow_nan=False)) == d


@pytest.mark.parametrize("sigmas,needle", [
    (["--sigma-m", "1.5e-5"], "'--sigma-rad': expected both noise levels (sigma_m and sigma_rad) or neither: their "
                              "ratio weighs the rotation rows"),
    (["--sigma-m", "1.5e-5", "--sigma-rad", "1e-5"], "'--sigma-m': sigma_m and sigma_rad only weigh the rotation "
                                                     "rows against the positions, and the data "
                                                     "(data/synthetic_paper_2r.csv) have no rotation columns")])
def test_noise_levels_for_data_without_rotation_columns_are_refused_not_ignored(root, capsys, monkeypatch, tmp_path,
                                                                                sigmas, needle):
    """A user gave --sigma-m to set the position noise: it sets only the rotation rows' weight, so on data without
    rotation columns it used to be ignored without a word (the verdict's sigma_m still the replicates'). One line,
    exit 2, nothing written."""
    monkeypatch.chdir(root)
    out_dir = tmp_path / "out"
    code = main(["discrepancy", "--robot", "config/robots/paper_2r.yaml", "--data", "data/synthetic_paper_2r.csv",
                 "--out", str(out_dir), "--no-figures", *sigmas])
    err = capsys.readouterr().err
    assert code == 2 and needle in err and err.count("\n") == 1, err
    assert not out_dir.exists()


def test_the_one_json_walk_writes_each_contract_s_non_finite_numbers():
    """stiffcal.jsonsafe.json_safe, the walk every written JSON goes through: json.dumps(allow_nan=False) then
    holds; "inf" where the design's contract gives an infinite value a meaning, and in a verdict's (notes given)
    null with a note naming the field, also inside numpy arrays; -0.0 is 0.0; a 'notes' key is left alone."""
    import json

    import numpy as np

    from stiffcal.jsonsafe import json_safe

    obj = {"cov": np.array([1.0, np.inf, -0.0]), "p": np.float64(np.nan), "n": np.int64(3), "ok": np.bool_(True),
           "rows": [{"x": -np.inf}], "notes": ["kept"]}
    plain = json_safe(obj)
    assert plain == {"cov": [1.0, "inf", 0.0], "p": None, "n": 3, "ok": True, "rows": [{"x": "-inf"}],
                     "notes": ["kept"]}
    assert str(plain["cov"][2]) == "0.0"
    notes = []
    noted = json_safe(obj, notes)
    assert noted["cov"] == [1.0, None, 0.0] and noted["p"] is None and noted["rows"] == [{"x": None}]
    assert noted["notes"] == ["kept"] and type(noted["n"]) is int and noted["ok"] is True
    assert [n.split(" ")[0] for n in notes] == ["cov[1]", "p", "rows[0].x"]
    for out in (plain, noted):
        json.dumps(out, allow_nan=False)
