"""The scripts of examples/ run as a user runs them (``python examples/NAME.py`` from a fresh process) and print
what the paper, the data's own truth and an independent reader say they should."""

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]


def _run(name: str, *args: str, cwd: Path) -> str:
    res = subprocess.run([sys.executable, str(ROOT / "examples" / name), *args], cwd=cwd, capture_output=True,
                         text=True)
    assert res.returncode == 0, res.stderr[-3000:]
    return res.stdout


def test_every_example_is_run_by_a_test():
    tested = set(re.findall(r'_run\("([a-z_]+\.py)"', Path(__file__).read_text(encoding="utf-8")))
    assert {p.name for p in (ROOT / "examples").glob("*.py")} == tested


def test_design_example_prints_the_paper_s_o_t_for_one_two_and_three_poses(tmp_path):
    """Tables 3 (row O_t), 4 and 5 (plan iv, both poses optimised) of the seed paper, at their printed digits."""
    out = _run("design_paper_arm.py", cwd=tmp_path)
    printed = yaml.safe_load((ROOT / "paper/printed_values.yaml").read_text(encoding="utf-8"))
    paper = {1: printed["table3"]["ot"]["O_t"], 2: printed["table4"]["iv"]["O_t"], 3: printed["table5"]["iv"]["O_t"]}
    found = {int(m): (ot, bound) for m, ot, bound in re.findall(r"M = (\d): O_t = ([\d.]+), lower bound ([\d.]+)", out)}
    assert {m: ot for m, (ot, _) in found.items()} == paper, out
    assert all(float(bound) <= float(ot) for ot, bound in found.values())


def test_measured_data_example_finds_the_hidden_backlash_and_writes_its_files(tmp_path):
    """data/README.md: backlash of 5e-5 rad per joint and a blunder at data row 17. The simulator's joint jumps
    gap/2 tanh(tau / tau_gap) (stiffcal.testing.truth), the catalogue's b sign(tau): each identified b's 95 % interval
    must hold gap/2, and the compensated path must be left with less than a tenth of its deflection."""
    out = _run("measured_data.py", str(tmp_path / "out"), cwd=tmp_path)
    assert "cause: backlash; blunders at data rows [17]" in out, out
    gaps = re.findall(r"(b\d_rad) = (\S+) \+- (\S+) \(95 %\)", out)
    assert len(gaps) == 2, out
    for _, value, half in gaps:
        assert abs(float(value) - 5e-5 / 2) <= float(half), out
    before, after = (float(x) for x in re.search(r"deflection up to (\S+) um, left after compensation (\S+) um",
                                                   out).groups())
    assert after < 0.1 * before, out
    assert {"verdict.json", "calibrated.yaml", "path.csv", "predicted.csv", "compensated.csv"} <= {
        p.name for p in (tmp_path / "out").iterdir()}


def test_measured_data_example_refuses_an_output_folder_that_is_a_file_in_one_line(tmp_path):
    """Bad input never gives a traceback: OUT_DIR naming a file stops the script with one message naming it, and
    nothing is written."""
    taken = tmp_path / "taken"
    taken.write_text("a file", encoding="utf-8")
    res = subprocess.run([sys.executable, str(ROOT / "examples" / "measured_data.py"), str(taken)], cwd=tmp_path,
                         capture_output=True, text=True)
    assert res.returncode == 1, res.stderr
    assert res.stderr.strip().splitlines() == [f"measured_data.py: error: {taken}: expected a directory to write "
                                               "into, but it is a file"], res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"] and taken.read_text(encoding="utf-8") == "a file"


def test_urdf_example_plans_within_the_urdf_s_limits_and_as_the_dh_file_does(tmp_path):
    """The poses printed for the URDF arm lie within the joint limits the URDF itself states (read here with
    xml.etree, not through stiffcal), O_t is above its certified bound, and the DH file of the same arm gives
    the same O_t to the printed digits."""
    out = _run("urdf_arm.py", cwd=tmp_path)
    poses = np.array([[float(a) for a in line.split(":", 1)[1].split(",")]
                      for line in out.splitlines() if line.startswith("pose [deg]:")])
    limits = np.degrees([[float(j.find("limit").get("lower")), float(j.find("limit").get("upper"))]
                         for j in ET.parse(ROOT / "config/robots/kuka_kr210_r2700.urdf").getroot().iter("joint")
                         if j.get("type") == "revolute"])
    assert poses.shape == (4, 6)
    assert np.all(poses >= limits[:, 0] - 0.01) and np.all(poses <= limits[:, 1] + 0.01), (poses, limits)
    ot, bound = (float(x) for x in re.search(r"O_t = (\S+) m\^2 \(RMS .*lower bound (\S+) m\^2", out).groups())
    assert bound <= ot
    assert re.search(r"the DH file of the same arm: O_t = (\S+) m\^2", out).group(1) == f"{ot:.4e}", out
