"""Hostile and oversized inputs (issue 28): every one is refused at once with one line naming the file or the
field (exit 2 from the command, InputError from the API), before any algebra or allocation, and nothing is
written; special files are refused without being read; archives are checked member by member with bounded
decompression; long jobs report progress wherever stderr goes; provenance names every library and every input
git does not vouch for. Ends with a seeded fuzz test over every command (a few dozen generated inputs)."""

import gzip
import hashlib
import io
import json
import os
import random
import re
import subprocess
import sys
import tarfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest

from stiffcal.workflow import archive as A
from stiffcal import limits
from stiffcal.cli import main
from stiffcal.errors import MAX_MESSAGE, InputError
from stiffcal.model.robot import load_robot

ROOT = Path(__file__).resolve().parents[1]
PAPER = str(ROOT / "config/robots/paper_2r.yaml")
DATA = str(ROOT / "data/synthetic_paper_2r.csv")
STIFFCAL = Path(sys.executable).with_name("stiffcal")


def cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse usage errors
            code = e.code
    return code, out.getvalue(), err.getvalue()


def refused(code, out, err, *needles):
    """Exit 2, nothing on stdout, exactly one line on stderr (no traceback) holding every needle."""
    assert code == 2, (code, err)
    assert out == "" and err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err and len(err) < MAX_MESSAGE + 300, err[:300]
    for n in needles:
        assert n in err, (n, err)


def chain_urdf(n: int, *, axis2: str = "0 0 1", origin: str = "0.1 0 0.2", extra: int = 0, head: str = "",
               links_extra: str = "") -> str:
    """A URDF of an n-joint revolute chain l0 -> ln (joint 2's axis ``axis2``, every origin ``origin``) and
    ``extra`` joints hanging off l0, off the chain."""
    s = [head, '<robot name="r">', '<link name="l0"/>', *(f'<link name="l{i}"/>' for i in range(1, n + 1)),
         links_extra]
    for i in range(1, n + 1):
        ax = axis2 if i == 2 else ("0 1 0" if i % 2 else "0 0 1")
        s.append(f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
                 f'<origin xyz="{origin}" rpy="0 0 0"/><axis xyz="{ax}"/>'
                 '<limit lower="-3" upper="3" effort="0" velocity="1"/></joint>')
    for k in range(extra):
        s.append(f'<link name="x{k}"/><joint name="xj{k}" type="revolute"><parent link="l0"/><child link="x{k}"/>'
                 '<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/>'
                 '</joint>')
    return "\n".join([*s, "</robot>"])


def urdf_robot(tmp_path, urdf: str, n: int, name: str = "arm.urdf", body: str = "") -> Path:
    (tmp_path / name).write_text(urdf)
    robot = tmp_path / f"{name}.yaml"
    robot.write_text(f"name: r\nkind: urdf\nurdf: {name}\nbase_frame: l0\ntip_frame: l{n}\ntool_m: [0.1, 0, 0.1]\n"
                     + body)
    return robot


def design_args(robot, n: int = 3) -> list[str]:
    return ["design", "--robot", str(robot), "--test-pose-deg", ",".join(["10"] * n), "--force-N", "1,2,3", "--quiet"]


# --- output folders, checked before any work -------------------------------------------------------------

@pytest.mark.parametrize("command", ["discrepancy", "discriminate"])
@pytest.mark.parametrize("out,needle", [("afile/sub", "afile on its way is a file"),
                                        ("/proc/stiffcal-out", "cannot write into /proc")])
def test_an_output_folder_that_cannot_be_written_is_refused_before_the_inputs_are_read(tmp_path, monkeypatch,
                                                                                      command, out, needle):
    """--out below a file, or in a folder nobody can write (/proc: even root): refused naming --out before the
    robot file or the data are read (they do not exist here, and they are not the error)."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("")
    extra = ["--experiments", "4"] if command == "discriminate" else []
    code, out_, err = cli([command, "--robot", "no-robot.yaml", "--data", "no-data.csv", "--out", out, *extra])
    refused(code, out_, err, out, needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


# --- special files, refused without being read --------------------------------------------------------------

@pytest.mark.parametrize("what", ["robot", "urdf", "data", "archive", "config"])
def test_a_fifo_is_refused_at_once_never_read(tmp_path, what):
    """A FIFO given as a robot file, a URDF, a data CSV, an archive or a config blocked the command forever
    (reading a FIFO waits for a writer). Run in a subprocess with a timeout, so that a regression fails instead
    of hanging the suite."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    if what == "urdf":
        robot = tmp_path / "r.yaml"
        robot.write_text("name: r\nkind: urdf\nurdf: pipe\nbase_frame: a\ntip_frame: b\n")
        argv = design_args(robot)
    elif what == "robot":
        argv = design_args(fifo, 2)
    elif what == "data":
        argv = ["discrepancy", "--robot", PAPER, "--data", str(fifo), "--out", str(tmp_path / "out")]
    elif what == "archive":
        argv = ["verify-archive", str(fifo)]
    if what == "config":
        code = ("from stiffcal.workflow.config import workflow_config; from stiffcal.errors import InputError\n"
                f"try:\n    workflow_config([{str(fifo)!r}], root={str(ROOT)!r})\n"
                "except InputError as e:\n    print(e)\n")
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
        assert "is a FIFO (named pipe): refused without reading it" in res.stdout, res
        return
    res = subprocess.run([str(STIFFCAL), *argv], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    refused(res.returncode, res.stdout, res.stderr, "FIFO (named pipe)", "refused without reading it")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["pipe", *(["r.yaml"] if what == "urdf" else [])])


def test_a_directory_given_as_a_file_is_named_a_directory(tmp_path):
    (tmp_path / "arm.urdf").mkdir()
    robot = tmp_path / "r.yaml"
    robot.write_text("name: r\nkind: urdf\nurdf: arm.urdf\nbase_frame: a\ntip_frame: b\n")
    refused(*cli(design_args(robot)), "field 'urdf'", "it is a directory")
    refused(*cli(design_args(tmp_path, 2)), "it is a directory")
    refused(*cli(["verify-archive", str(tmp_path)]), "it is a directory")


# --- URDFs ------------------------------------------------------------------------------------------------

NJ = limits.MAX_JOINTS + 1


@pytest.mark.parametrize("urdf,needles", [
    (chain_urdf(3, axis2="0 0 0"), ["joint 'j2': <axis xyz> 0 0 0", "not the zero vector"]),  # was LinAlgError
    (chain_urdf(3, axis2="1e308 1e308 0"), ["joint 'j2': <axis xyz>", "expected a direction"]),
    (chain_urdf(3, axis2="nan 0 1"), ["joint 'j2': <axis xyz>", "3 finite numbers"]),
    (chain_urdf(3, origin="1e300 0 0"), ["joint 'j1': <origin xyz> 1e+300 m", "at most 1000 m"]),  # was 'tool_m'
    (chain_urdf(3, links_extra='<link name="l2"/>'), ["two links named 'l2'"]),
    (chain_urdf(3).replace('name="j3"', 'name="j2"'), ["two joints named 'j2'"]),
    (chain_urdf(3).replace('<parent link="l0"/>', '<parent link="l3"/>'), ["the joints form a loop through link"]),
    (chain_urdf(3).replace('<child link="l3"/>', '<child link="l2"/>'), ["link 'l2' is the child of two joints"]),
    (chain_urdf(3).replace('<parent link="l1"/>', '<parent link="l9"/>'), ["joint 'j2': <parent link> 'l9'"]),
    (chain_urdf(3, extra=limits.MAX_URDF_ELEMENTS), [f"expected at most {limits.MAX_URDF_ELEMENTS} in all"]),
    (chain_urdf(NJ), [f"{NJ} joints move between 'l0' and 'l{NJ}'", f"at most {limits.MAX_JOINTS}"]),
    ('<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:macro name="m"/><link name="l0"/></robot>',
     ["a xacro file", "expand it first"]),  # was 'no link or frame'
    ('<robot name="r"><link name="${prefix}l0"/></robot>', ["a xacro file"]),
    ('<robot name="r"><xacro:include filename="x.xacro"/></robot>', ["a xacro file"]),
    ("<!DOCTYPE robot [<!ENTITY a 'b'>]>" + chain_urdf(3), ["entity or DOCTYPE declarations are not allowed"]),
])
def test_hostile_urdfs_are_refused_naming_the_joint_or_the_bound(tmp_path, urdf, needles):
    robot = urdf_robot(tmp_path, urdf, NJ if f'"l{NJ}"' in urdf else 3)
    code, out, err = cli(design_args(robot))
    refused(code, out, err, str(robot), "field '", *needles)


def test_an_arm_of_nothing_names_its_lengths_and_concurrent_axes_need_two_poses(tmp_path):
    """Joint origins of 1e-300 m and a tool point at the tip's origin: the arm has no length (it blamed tool_m);
    with a tool point 0.1 m away, every axis meets in one point, the point moves on a sphere, and no single pose
    identifies the 3 compliances (an IndexError in the single-pose search): 2 poses do."""
    urdf = chain_urdf(3, origin="1e-300 0 1e-300")
    robot = urdf_robot(tmp_path, urdf, 3)
    robot.write_text(robot.read_text().replace("tool_m: [0.1, 0, 0.1]", "tool_m: [1.0e-300, 0, 0]"))
    refused(*cli(design_args(robot)), str(robot), "field 'urdf'", "the arm's lengths add up to", "joint origins")
    robot = urdf_robot(tmp_path, urdf, 3, "sphere.urdf")
    refused(*cli(design_args(robot)), "field '--experiments'", "no single pose identifies all 3 compliances",
            "at least 2 poses")
    code, out, err = cli([*design_args(robot), "--experiments", "3"])
    assert code == 0 and np.isfinite(json.loads(out)["O_t"])


def test_a_comment_that_mentions_a_doctype_is_fine_and_so_is_an_expanded_xacro(tmp_path):
    """'<!DOCTYPE' inside a comment was refused as an entity declaration; a URDF expanded by xacro keeps the xacro
    namespace declaration and no xacro element, and is a URDF."""
    head = '<?xml version="1.0"?>\n<!-- written from <!DOCTYPE html> notes; <!ENTITY> too -->'
    robot = load_robot(urdf_robot(tmp_path, chain_urdf(3, head=head), 3))
    plain = load_robot(urdf_robot(tmp_path, chain_urdf(3), 3, "plain.urdf"))
    q = np.random.default_rng(1).uniform(-2, 2, (8, 3))
    np.testing.assert_array_equal(robot.jacobian(q), plain.jacobian(q))
    expanded = chain_urdf(3).replace('<robot name="r">',
                                     '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">')
    expanded_robot = load_robot(urdf_robot(tmp_path, expanded, 3, "x.urdf"))
    np.testing.assert_array_equal(expanded_robot.jacobian(q), plain.jacobian(q))


def test_many_joints_off_the_chain_are_read_without_pinocchio_data_of_the_whole_model(tmp_path):
    """A URDF with 1,500 joints off the chain (within the bound) is read: Pinocchio's Data of the whole model,
    whose matrices grow with the square of the joints (MemoryError at 5,000), is no longer made; the chain is the
    same as without them."""
    many = load_robot(urdf_robot(tmp_path, chain_urdf(3, extra=1500), 3))
    few = load_robot(urdf_robot(tmp_path, chain_urdf(3), 3, "few.urdf"))
    assert many.joint_names == few.joint_names == ("j1", "j2", "j3")
    np.testing.assert_array_equal(many.chain.placements, few.chain.placements)
    np.testing.assert_array_equal(many.chain.axes, few.chain.axes)


def test_a_long_chain_can_still_move_a_few_of_its_joints(tmp_path):
    """A 15-joint chain is refused as it is, but naming 6 joints that move (the others held) is an arm of 6."""
    body = "joints: [j1, j2, j3, j4, j5, j6]\n"
    robot = load_robot(urdf_robot(tmp_path, chain_urdf(15), 15, body=body))
    assert robot.n_joints == 6


# --- robot files and loads: physical ranges and sizes --------------------------------------------------------

@pytest.mark.parametrize("text,field,needle", [
    ("links_m: [1.0e-300, 0.4]\n", "links_m[0]", "at least 1e-06 m"),  # blamed the force
    ("links_m: [" + ", ".join(["0.1"] * 20) + "]\n", "links_m", "20 joints: expected at most 10"),
    ("links_m: [0.6, 0.4]\ncompliances_rad_per_Nm: [1.0e-300, 1.0e-6]\n", "compliances_rad_per_Nm[0]", "at least"),
])
def test_robot_file_numbers_outside_the_physical_range_name_the_field(tmp_path, text, field, needle):
    robot = tmp_path / "r.yaml"
    robot.write_text("name: r\nkind: planar\n" + text)
    refused(*cli(design_args(robot, 2)), f"field '{field}'", needle)


def test_a_spatial_arm_of_nothing_names_its_lengths(tmp_path):
    robot = tmp_path / "r.yaml"
    robot.write_text("name: r\nkind: spatial\ndh_convention: standard\ndh:\n" +
                     "".join("  - {a_m: 1.0e-300, alpha_deg: 90, d_m: 1.0e-300}\n" for _ in range(3)) +
                     "tool_m: [1.0e-300, 0, 0]\n")
    refused(*cli(design_args(robot)), "field 'dh'", "lengths add up to", "a_m and d_m and tool_m")


@pytest.mark.parametrize("option,value,needle", [
    ("--force-N", "1e300,0", "'--force-N[0]': expected at most 1e+07 N"),  # SVD did not converge
    ("--force-N", "0,1e308", "'--force-N[1]': expected at most 1e+07 N"),
    ("--force-N", "1e-300,0", "'--force-N': expected a load of at least 1e-06"),
    ("--wrench", "0,-1,1e300", "'--wrench[2]': expected at most 1e+07 N m"),
    ("--experiments", "10000", "at most 1000 poses"),
])
def test_design_loads_and_sizes_outside_the_range_are_refused(option, value, needle):
    args = {"--test-pose-deg": "60,30", "--force-N": "0,-1"}
    if option == "--wrench":
        args.pop("--force-N")
    args[option] = value
    refused(*cli(["design", "--robot", PAPER, "--quiet", *[f"{k}={v}" for k, v in args.items()]]), needle)


@pytest.mark.parametrize("loads,needle", [
    ("hanging:1e300", "at most 1e+07 N"), ("hanging:1e308", "at most 1e+07 N"),
    ("forces:1e300,0", "at most 1e+07 N"),
    ("hanging:1e-300", "at least the load-cell resolution 0.5 N"),  # was a silent 'not separable'
    ("hanging:0.2", "at least the load-cell resolution 0.5 N"),
    ("directions:100000:100", f"100000 loads: expected at most {limits.MAX_LOADS}"),  # MemoryError, 7.7 GiB
    ("directions:10000000:100", f"10000000 loads: expected at most {limits.MAX_LOADS}"),  # 772 GiB
    ("hanging:" + ",".join(["10"] * 65), f"65 loads: expected at most {limits.MAX_LOADS}"),
])
def test_load_specs_outside_the_range_are_refused_before_any_allocation(tmp_path, monkeypatch, loads, needle):
    monkeypatch.chdir(tmp_path)
    code, out, err = cli(["discriminate", "--robot", PAPER, "--data", DATA, "--experiments", "4", "--out", "o",
                          "--loads", loads])
    refused(code, out, err, "'--loads'", needle)
    assert list(tmp_path.iterdir()) == []


def test_a_design_load_below_the_smallest_is_refused_naming_the_design_bound(tmp_path, monkeypatch):
    """design has no load cell: its loads are bounded by MIN_LOAD (documented), not by a lab's resolution of 0.5 N,
    and the message named --force-resolution-N, an option design does not have."""
    monkeypatch.chdir(tmp_path)
    base = ["design", "--robot", PAPER, "--test-pose-deg", "60,30", "--force-N", "0,-1", "--quiet", "--no-cache"]
    code, out, err = cli([*base, "--loads", "hanging:0.2"])
    assert code == 0 and json.loads(out)["O_t"] > 0
    refused(*cli([*base, "--loads", f"hanging:{limits.MIN_LOAD / 10:g}"]), "'--loads'", "MIN_LOAD")
    assert "--force-resolution-N" not in cli([*base, "--loads", "hanging:1e-9"])[2]


def test_a_discriminating_plan_is_bounded_in_its_measurements(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    m = limits.MAX_DISCRIMINATE_EXPERIMENTS + 1
    refused(*cli(["discriminate", "--robot", PAPER, "--data", DATA, "--experiments", str(m), "--out", "o"]),
            "'--experiments'", f"at most {limits.MAX_DISCRIMINATE_EXPERIMENTS} measurements")


def test_output_folders_that_are_files_are_named(tmp_path):
    """Every folder of the workflow's outputs (one per data set, study and map too) and every folder above it must
    be a folder or missing; a file, a FIFO or a broken link in its place is named (stiffcal.workflow.config)."""
    from stiffcal.workflow.config import check_output_folders, output_folders

    config = {"studies": [{"name": "s1"}], "maps": {"studies": [{"name": "m1"}]}, "measured_data": [{"name": "d1"}]}
    assert {"results/studies/s1", "figures/studies/s1", "results/maps/m1", "results/discrepancy/d1"} <= set(
        output_folders(config))
    check_output_folders(config, tmp_path)  # nothing there yet: fine
    (tmp_path / "results/discrepancy").mkdir(parents=True)
    (tmp_path / "results/discrepancy/d1").write_text("x")
    with pytest.raises(InputError, match=r"^results/discrepancy/d1: expected a folder .* but it is a file"):
        check_output_folders(config, tmp_path)
    (tmp_path / "results/discrepancy/d1").unlink()
    os.mkfifo(tmp_path / "results/discrepancy/d1")
    with pytest.raises(InputError, match="it is a FIFO"):
        check_output_folders(config, tmp_path)
    (tmp_path / "results/discrepancy/d1").unlink()
    (tmp_path / "results/discrepancy/d1").symlink_to(tmp_path / "nowhere")
    with pytest.raises(InputError, match="a broken symbolic link"):
        check_output_folders(config, tmp_path)
    (tmp_path / "results/discrepancy/d1").unlink()
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "results/discrepancy/d1").symlink_to(tmp_path / "elsewhere")  # a link to a folder is a folder
    check_output_folders(config, tmp_path)


@pytest.mark.parametrize("where", ["study", "studies[0]", "measured_data[0]", "maps.studies[0]"])
def test_a_robot_file_that_does_not_exist_is_named_with_the_config_field(tmp_path, where):
    """'config/robots/nope.yaml: cannot read file' did not say which config entry named it: now the config file and
    the field."""
    import yaml

    from stiffcal.workflow.config import workflow_config

    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    entry = {"study": cfg["study"], "studies[0]": cfg["studies"][0], "measured_data[0]": cfg["measured_data"][0],
             "maps.studies[0]": cfg["maps"]["studies"][0]}[where]
    entry["robot"] = "config/robots/nope.yaml"
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(InputError) as err:
        workflow_config([str(tmp_path / "c.yaml")], root=ROOT)
    assert str(err.value) == (f"{tmp_path / 'c.yaml'}: field '{where}.robot': expected a robot file, but "
                              "config/robots/nope.yaml does not exist")


@pytest.mark.parametrize("command", ["discrepancy", "discriminate"])
def test_an_empty_output_folder_is_refused_not_the_current_folder(tmp_path, monkeypatch, command):
    """--out '' wrote the verdict, figures and calibrated.yaml into the current folder (as --cache-dir '' did not)."""
    monkeypatch.chdir(tmp_path)
    refused(*cli([command, "--robot", PAPER, "--data", DATA, "--out", "", "--quiet",
                  *(["--experiments", "3"] if command == "discriminate" else [])]), "field '--out'", "empty path")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("what", ["fifo", "too many", "angle", "huge field"])
def test_hostile_candidate_files_are_refused_at_once(tmp_path, monkeypatch, what):
    """design --candidates: a FIFO blocked forever, 2,000,000 rows ran out of memory, an angle of 1e300 degrees was
    taken modulo a turn, a field over 128 KiB was an internal error: each one line, exit 2."""
    monkeypatch.setattr(limits, "MAX_CANDIDATES", 50)
    path = tmp_path / "cand.csv"
    if what == "fifo":
        os.mkfifo(path)
    elif what == "too many":
        path.write_text("q1_deg,q2_deg\n" + "10,20\n" * 51)
    elif what == "angle":
        path.write_text("q1_deg,q2_deg\n1,1e300\n2,3\n")
    else:
        path.write_text("q1_deg,q2_deg,note\n1,2," + "x" * 200_000 + "\n")
    needle = {"fifo": "FIFO", "too many": "more than 50 candidate poses", "angle": "row 2, column q2_deg",
              "huge field": "field larger than field limit"}[what]
    refused(*cli(["design", "--robot", PAPER, "--test-pose-deg", "60,30", "--force-N", "0,-1", "--no-cache",
                  "--quiet", "--candidates", str(path)]), "cand.csv", needle)


@pytest.mark.parametrize("what", ["huge field", "huge header", "wide", "long label"])
def test_hostile_measured_data_shapes_are_refused_by_row(tmp_path, what):
    """A field over csv's 128 KiB limit was an internal error; 300,000 extra columns ran for minutes (a quadratic
    check of repeated names): one line naming the file and the row, exit 2, nothing written."""
    lines = Path(DATA).read_text().splitlines()
    if what == "huge field":
        lines[3] = "y" * 200_000 + lines[3][lines[3].index(","):]
    elif what == "huge header":
        lines[0] = lines[0] + "," + "h" * 200_000
        lines[1:] = [x + ",0" for x in lines[1:]]
    elif what == "wide":
        lines = [x + ",0" * (limits.MAX_MEASURED_COLUMNS + 5) for x in lines]
    else:  # a pose_id of 100,000 characters filled the memory cap through the figures' axes
        lines[1:] = ["L" * 100_000 + x[x.index(","):] for x in lines[1:]]
    path = tmp_path / "d.csv"
    path.write_text("\n".join(lines) + "\n")
    row = {"huge field": "row 4", "huge header": "row 1", "wide": "row 1",
           "long label": "row 2 (data row 0), column pose_id"}[what]
    refused(*cli(["discrepancy", "--robot", PAPER, "--data", str(path), "--out", str(tmp_path / "o"), "--quiet"]),
            "d.csv", f"field '{row}'")
    assert not (tmp_path / "o").exists()


# --- archives ---------------------------------------------------------------------------------------------

def _archive(tmp_path, edit=None) -> Path:
    """A small valid archive, optionally with its members rewritten by ``edit(name, data) -> data``."""
    (tmp_path / "t.csv").write_text("a,b\n1,2\n")
    out = A.write_archive(tmp_path / "a/stiffcal-x.tar.gz", [Path("t.csv")], {"source_date_epoch": 0}, tmp_path)
    if edit is None:
        return out
    bad = tmp_path / "bad.tar.gz"
    with tarfile.open(out) as tin, tarfile.open(bad, "w:gz") as tout:
        for m in tin.getmembers():
            data = edit(m.name, tin.extractfile(m).read())
            m.size = len(data)
            tout.addfile(m, io.BytesIO(data))
    return bad


def test_a_non_utf8_byte_in_sha256sums_is_reported_as_damaged(tmp_path):
    bad = _archive(tmp_path, lambda name, data: data.replace(b"t.csv", b"t\xff.csv") if name.endswith("SUMS") else data)
    ok, problems = A.verify_archive(bad)
    assert ok == 0 and problems == ["damaged: SHA256SUMS line 2 is not UTF-8 text (byte 0xff); no file in the archive "
                                    "can be trusted"]
    code, out, err = cli(["verify-archive", str(bad)])
    assert code == 1 and "Traceback" not in err and err.count("\n") == 1


def test_a_gzip_bomb_is_refused_after_the_bound_not_decompressed_in_memory(tmp_path, monkeypatch):
    """The stream is decompressed in blocks and counted: past MAX_UNPACKED_BYTES (2 GiB; made small here) it is
    refused, and no more than a block is held at a time."""
    monkeypatch.setattr(A, "MAX_UNPACKED_BYTES", 4 * 1024**2)
    bomb = tmp_path / "bomb.tar.gz"
    with gzip.open(bomb, "wb", compresslevel=9) as gz:
        for _ in range(8):
            gz.write(bytes(1024**2))
    assert bomb.stat().st_size < 100_000
    with pytest.raises(InputError, match="expands to more than 0 GiB when decompressed: not a stiffcal archive"):
        A.verify_archive(bomb)
    assert A.verify_archive(_archive(tmp_path)) == (2, [])  # a real archive, well within the bound


def test_an_archive_of_too_many_members_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(A, "MAX_MEMBERS", 5)
    bad = tmp_path / "many.tar.gz"
    with tarfile.open(bad, "w:gz") as tar:
        for k in range(10):
            tar.addfile(tarfile.TarInfo(f"top/f{k}"), io.BytesIO(b""))
    with pytest.raises(InputError, match="more than 5 members"):
        A.verify_archive(bad)


def test_a_link_member_in_place_of_a_listed_file_is_named(tmp_path):
    bad = tmp_path / "link.tar.gz"
    good = _archive(tmp_path)
    with tarfile.open(good) as tin, tarfile.open(bad, "w:gz") as tout:
        for m in tin.getmembers():
            if m.name.endswith("t.csv"):
                link = tarfile.TarInfo(m.name)
                link.type, link.linkname = tarfile.SYMTYPE, "/etc/passwd"
                tout.addfile(link)
            else:
                tout.addfile(m, tin.extractfile(m))
    assert A.verify_archive(bad)[1] == ["missing: t.csv (not a regular file in the archive)"]


def _with_members(tmp_path, extra, sums_edit=None, first=False) -> Path:
    """The small valid archive with members added (``first``: before its own): ``extra`` [(TarInfo, data)];
    ``sums_edit(text) -> text`` rewrites its SHA256SUMS (its checksums stay true to the files)."""
    good, bad = _archive(tmp_path), tmp_path / "extra.tar.gz"
    with tarfile.open(good) as tin, tarfile.open(bad, "w:gz", format=tarfile.GNU_FORMAT) as tout:
        for info, data in extra if first else []:
            info.size = len(data)
            tout.addfile(info, io.BytesIO(data))
        for m in tin.getmembers():
            data = tin.extractfile(m).read()
            if sums_edit and m.name.endswith("SHA256SUMS"):
                data = sums_edit(data.decode()).encode()
                m.size = len(data)
            tout.addfile(m, io.BytesIO(data))
        for info, data in [] if first else extra:
            info.size = len(data)
            tout.addfile(info, io.BytesIO(data))
    return bad


def _sum_line(name: str, data: bytes) -> str:
    return f"{hashlib.sha256(data).hexdigest()}  {name}\n"


@pytest.mark.parametrize("member,listed,problem", [
    ("stiffcal-x/../../evil.sh", "../../evil.sh", "unsafe name listed in SHA256SUMS"),
    ("stiffcal-x/../../evil.sh", None, "unsafe member name (absolute, or with '..', '.' or an empty part): "
                                       "stiffcal-x/../../evil.sh"),
    ("/tmp/evil.sh", None, "unsafe member name"),
    ("evil_toplevel.sh", None, "outside the archive's top directory (stiffcal-x): evil_toplevel.sh"),
    ("othertop/t.csv", None, "outside the archive's top directory (stiffcal-x): othertop/t.csv"),
    ("stiffcal-x/t.csv", None, "in the archive twice (extraction keeps one copy, maybe not the one checked): "
                               "stiffcal-x/t.csv"),
    ("stiffcal-x/x\nstiffcal verify-archive: all good", None, "not listed in SHA256SUMS: x\\nstiffcal verify-archive"),
])
def test_members_outside_the_top_directory_or_with_unsafe_names_are_named(tmp_path, member, listed, problem):
    """A '../' name that extraction would write outside the folder (listed in SHA256SUMS or not), an absolute name,
    a member beside or outside the one top directory (a second tree that shadows the first), and a name with a
    newline that would forge a line of the report: each named (control characters escaped), never 'ok'."""
    data = b"echo evil\n"
    bad = _with_members(tmp_path, [(tarfile.TarInfo(member), data)],
                        (lambda text: text + _sum_line(listed, data)) if listed else None)
    ok, problems = A.verify_archive(bad)
    assert any(problem in p for p in problems), problems
    assert all("\n" not in p for p in problems)
    code, out, err = cli(["verify-archive", str(bad)])
    assert code == 1 and "Traceback" not in err and json.loads(out)["ok"] is False
    assert not any(line.startswith("stiffcal verify-archive: all good") for line in (out + err).splitlines())


@pytest.mark.parametrize("member", ["evil.sh", "othertop/t.csv", "stiffcal-x/t.csv"])
def test_members_before_the_archive_s_own_tree_are_named_too(tmp_path, member):
    """A loose file or a second tree before the archive's own members made every later member, its SHA256SUMS too,
    count as outside ('no SHA256SUMS', exit 2); a tampered copy of a listed file before the good one verified as
    'ok' (extraction may keep the tampered copy)."""
    bad = _with_members(tmp_path, [(tarfile.TarInfo(member), b"tampered\n")], first=True)
    ok, problems = A.verify_archive(bad)
    assert problems and (ok == 2 if member != "stiffcal-x/t.csv" else ok <= 2), problems
    assert any(member in p and ("outside" in p or "twice" in p) for p in problems), problems
    assert cli(["verify-archive", str(bad)])[0] == 1


def test_a_sha256sums_that_lists_a_file_twice_is_damaged(tmp_path):
    """The same name listed twice, a wrong checksum then the right one, verified (the last line counted)."""
    bad = _archive(tmp_path, lambda name, data: (b"0" * 64 + b"  t.csv\n" + data) if name.endswith("SUMS") else data)
    ok, problems = A.verify_archive(bad)
    assert ok == 0 and problems == ["damaged: SHA256SUMS line 3 lists t.csv a second time; no file in the archive can "
                                    "be trusted"]


def test_an_archive_that_lists_nothing_is_not_ok(tmp_path):
    """A SHA256SUMS that lists no file (or not provenance.json) verified nothing: it is not a stiffcal archive."""
    bad = tmp_path / "empty_sums.tar.gz"
    with tarfile.open(bad, "w:gz") as tar:
        tar.addfile(tarfile.TarInfo("top/SHA256SUMS"), io.BytesIO(b""))
    assert A.verify_archive(bad) == (0, ["SHA256SUMS does not list provenance.json (it lists no file): not a "
                                         "complete stiffcal archive"])
    assert cli(["verify-archive", str(bad)])[0] == 1


def test_a_sparse_member_counts_as_the_size_its_header_records(tmp_path, monkeypatch):
    """A sparse member of a few hundred bytes can expand to a terabyte of zeros that the gzip bound never sees:
    the members' sizes as their headers record them are bounded too (4 MiB here)."""
    monkeypatch.setattr(A, "MAX_UNPACKED_BYTES", 4 * 1024**2)
    sparse = tmp_path / "zeros.bin"
    with open(sparse, "wb") as fh:
        fh.truncate(64 * 1024**2)
    bad = tmp_path / "sparse.tar.gz"
    made = subprocess.run(["tar", "--sparse", "-C", str(tmp_path), "-czf", str(bad), "zeros.bin"], capture_output=True)
    if made.returncode != 0:
        pytest.skip("GNU tar with --sparse is not installed")
    assert bad.stat().st_size < 10_000
    with pytest.raises(InputError, match="members add up to more than 0 GiB"):
        A.verify_archive(bad)


def test_a_huge_extended_header_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """A GNU long-name header of 2 GB (a few MB compressed) was read whole by tarfile (3.9 GB of memory): refused
    from its size, before reading it."""
    import tracemalloc

    size = 64 * 1024**2
    bad = tmp_path / "longname.tar.gz"
    head = tarfile.TarInfo("././@LongLink")
    head.type, head.size = tarfile.GNUTYPE_LONGNAME, size
    with gzip.open(bad, "wb", compresslevel=1) as gz:
        gz.write(head.tobuf(format=tarfile.USTAR_FORMAT))
        for _ in range(size // 1024**2):
            gz.write(b"a" * 1024**2)
    tracemalloc.start()
    with pytest.raises(InputError, match="extended tar header .* of 67,108,864 bytes"):
        A.verify_archive(bad)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 16 * 1024**2


# --- provenance -------------------------------------------------------------------------------------------

def test_provenance_names_pinocchio_and_flint_and_every_untracked_input(tmp_path, monkeypatch):
    """provenance.json names the libraries that read or computed the data (Pinocchio read every URDF,
    python-flint isolates roots in the maps) and marks inputs that are not committed: an untracked config and
    robot file make the run dirty even when every committed file is clean. Code imported from outside the work
    tree (a fresh user's clone whose venv imported another clone's package: the report named the clone's commit)
    makes it dirty too, and is named."""
    from importlib import metadata

    package = str(Path(A.__file__).resolve().parents[1])
    assert A.code_outside_tree(Path(package).parents[1]) is None
    assert A.code_outside_tree(tmp_path) == package
    assert A.run_status({}, tmp_path)["code_outside_tree"] == package
    monkeypatch.setattr(A, "code_outside_tree", lambda root=".": None)  # below: the tree's own code

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty", "-m", "start")
    (tmp_path / "tracked.yaml").write_text("a: 1\n")
    git("add", "tracked.yaml")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "tracked")
    (tmp_path / "lab").mkdir()
    (tmp_path / "lab/robot.yaml").write_text("b: 2\n")
    (tmp_path / "my.yaml").write_text("c: 3\n")
    clean = A.provenance("h", "s", "e", tmp_path, ["tracked.yaml"])
    assert clean["dirty"] is False and clean["untracked_inputs"] == [] and clean["modified_inputs"] == []
    prov = A.provenance("h", "s", "e", tmp_path, ["tracked.yaml", "lab/robot.yaml", "my.yaml"])
    assert prov["dirty"] is True and prov["untracked_inputs"] == ["lab/robot.yaml", "my.yaml"]
    (tmp_path / "tracked.yaml").write_text("a: 2\n")
    assert A.provenance("h", "s", "e", tmp_path, ["tracked.yaml"])["modified_inputs"] == ["tracked.yaml"]
    for dist in ("pin", "python-flint", "numpy", "defusedxml", "coal"):
        assert prov["packages"][dist] == metadata.version(dist)
    json.dumps(prov, allow_nan=False)
    # what the report and the archive's name say: the commit marked dirty by an untracked input alone
    (tmp_path / "tracked.yaml").write_text("a: 1\n")
    config = {"robot": "lab/robot.yaml"}
    status = A.run_status(config, tmp_path)
    assert status["commit"].endswith("-dirty") and status["untracked_inputs"] == ["lab/robot.yaml"]
    # its content pinned (a fresh reviewer could not tell which of two versions of an untracked data file ran)
    assert status["input_sha256"] == {"lab/robot.yaml": hashlib.sha256(b"b: 2\n").hexdigest()}
    assert status["packages"]["pin"] == metadata.version("pin")
    assert A.run_status({"robot": "tracked.yaml"}, tmp_path, packages=False) == {
        "commit": A.run_status({}, tmp_path)["commit"], "untracked_inputs": [], "modified_inputs": [],
        "code_outside_tree": None, "input_sha256": {}}
    assert not A.run_status({}, tmp_path)["commit"].endswith("-dirty")
    assert A.run_status({}, tmp_path, config_source="my.yaml")["commit"].endswith("-dirty")
    monkeypatch.setattr(A, "code_outside_tree", lambda root=".": package)
    assert A.run_status({}, tmp_path)["commit"].endswith("-dirty")
    assert A.provenance("h", "s", "e", tmp_path, ["tracked.yaml"])["dirty"] is True


# --- progress ----------------------------------------------------------------------------------------------

def test_progress_lines_say_the_stage_the_time_and_an_estimate_scaled_by_the_stages_so_far():
    """The line names the stage and the time elapsed; what is left is the estimate of the stages to come, scaled
    by how the finished ones compared with theirs; a stage past its estimate says so. (A clock of our own.)"""
    from stiffcal.progress import Progress

    now = [100.0]
    p = Progress("job", [("first", 2.0), ("second", 10.0), ("third", 5.0)], clock=lambda: now[0], enabled=False)
    now[0] += 1.0
    assert p.line().endswith("job: first (stage 1/3), 1 s elapsed, about 16 s left (estimate)")
    now[0] += 3.0  # past its estimate: the later stages are scaled by 4 / 2
    assert p.line().endswith("job: first (stage 1/3), 4 s elapsed, this stage taking longer than estimated; about "
                             "30 s left after it (estimate)")
    p.advance()
    now[0] += 5.0  # 'first' took 4 s for 2: 'second' is expected to take 20 s, 'third' 10 s
    assert p.line().endswith("job: second (stage 2/3), 9 s elapsed, about 25 s left (estimate)")
    p.advance("third")
    p.step(1, 4)
    now[0] += 6.0  # a quarter of the steps in 6 s: 18 s more for this stage
    assert p.line().endswith("job: third (stage 3/3) 1/4, 15 s elapsed, about 18 s left (estimate)")


def test_progress_prints_lines_off_a_terminal_only_for_the_innermost_and_not_when_quiet():
    import time

    from stiffcal.progress import Progress

    stream = io.StringIO()
    with Progress("outer", stream=stream, interval=0.01):
        with Progress("inner", [("only", 100.0)], stream=stream, interval=0.01):
            time.sleep(0.2)
    first, *lines = stream.getvalue().splitlines()
    assert first.endswith("] inner: estimated about 1 min 40 s, a progress line every 0 s")  # 60 s or more: said
    assert lines and all(line.startswith("[stiffcal ") and "inner: only (stage 1/1)" in line for line in lines)
    quiet = io.StringIO()
    with Progress("job", [("only", 100.0)], stream=quiet, interval=0.01, enabled=False):
        time.sleep(0.1)
        with Progress("a step inside the quiet job", [("only", 100.0)], stream=quiet, interval=0.01):
            time.sleep(0.1)  # left to its default, it is quiet too (--quiet silences a step's own progress)
    assert quiet.getvalue() == ""
    with Progress("after", [("only", 100.0)], stream=quiet, interval=0.01):  # and loud again once that job ends
        time.sleep(0.1)
    assert "after: only" in quiet.getvalue()


def test_a_note_printed_while_a_bar_is_shown_gets_a_line_of_its_own():
    """On a terminal the bar is cleared before a note and drawn again after it (the note was glued to the bar)."""
    from stiffcal.progress import Progress, write

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    with Progress("job", [("only", 100.0)], stream=term):
        write("stiffcal job: note: something", stream=term)
    text = term.getvalue()
    before, after = text.split("stiffcal job: note: something\n")
    assert "job: only" in before and before.endswith("\r") and "job: only" in after


def test_the_command_reports_progress_when_stderr_is_not_a_terminal(tmp_path):
    """stderr to a pipe (a script, a scheduler): progress lines every STIFFCAL_PROGRESS_S; --quiet: none."""
    env = {**os.environ, "STIFFCAL_PROGRESS_S": "0.02"}
    args = [str(STIFFCAL), "design", "--robot", PAPER, "--test-pose-deg", "60,30", "--force-N", "0,-1",
            "--experiments", "3"]
    res = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0 and json.loads(res.stdout)["experiments"] == 3
    lines = res.stderr.splitlines()
    assert lines and all(line.startswith("[stiffcal ") and "] design" in line and "elapsed" in line for line in lines)
    assert any("design: " in line and "(stage " in line and "estimate" in line for line in lines)
    res = subprocess.run([*args, "--quiet"], capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0 and res.stderr == ""


@pytest.mark.parametrize("command", ["discrepancy", "design several M"])
def test_the_analysis_and_a_design_of_several_m_report_their_stages_over_the_whole_call(tmp_path, command):
    """discrepancy said only 'discrepancy, N s elapsed' (no stage, no estimate), and a design of M = 2-12 restarted
    its elapsed time with each plan: now the stages of the whole call with an estimate; --quiet: nothing."""
    env = {**os.environ, "STIFFCAL_PROGRESS_S": "0.02"}
    if command == "discrepancy":
        args = [str(STIFFCAL), "discrepancy", "--robot", PAPER, "--data", DATA, "--out", str(tmp_path / "o")]
        stages = ("reading the data (stage 1/5)", "figures and files (stage 5/5)")
    else:
        args = [str(STIFFCAL), "design", "--robot", PAPER, "--test-pose-deg", "60,30", "--force-N", "0,-1",
                "--experiments", "2-4", "--no-cache"]
        stages = ("plan of 2 poses (1 of 3 plans) (stage 1/3)", "plan of 4 poses (3 of 3 plans) (stage 3/3)")
    res = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    lines = [x for x in res.stderr.splitlines() if x.startswith("[stiffcal ")]
    assert all(s in res.stderr for s in stages) and all("elapsed" in x for x in lines)
    assert any("left (estimate)" in x for x in lines)
    clock = [re.search(r", (?:(\d+) min )?(\d+) s elapsed", x) for x in lines]
    seconds = [60 * int(m[1] or 0) + int(m[2]) for m in clock if m]
    assert len(seconds) == len(lines) and seconds == sorted(seconds)  # one clock for the whole call
    res = subprocess.run([*args, "--quiet"], capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0 and "[stiffcal " not in res.stderr


def test_a_workflow_job_writes_progress_lines_into_its_log_and_runs_under_the_memory_cap(tmp_path):
    """pipeline.run (every rule's script): a line every STIFFCAL_PROGRESS_S in the job's log while its step runs,
    and the address space capped (the step sees the limit)."""
    code = f"""
import resource, time
from types import SimpleNamespace
from stiffcal.workflow import pipeline

def step(out):
    time.sleep(0.5)
    open(out, "w").write(str(resource.getrlimit(resource.RLIMIT_AS)[0]))

sm = SimpleNamespace(log=[{str(tmp_path / "job.log")!r}], input=[], output=[{str(tmp_path / "out.txt")!r}],
                     rule="slow_rule", wildcards={{}})
pipeline.run(sm, step, {str(tmp_path / "out.txt")!r})
"""
    env = {**os.environ, "STIFFCAL_PROGRESS_S": "0.1", "STIFFCAL_MAX_MEMORY_MB": "2500"}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env,
                         cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    log = (tmp_path / "job.log").read_text().splitlines()
    beats = [line for line in log if line.startswith("[stiffcal ") and "] rule slow_rule, " in line]
    assert beats and all("elapsed" in line for line in beats) and log[-1].startswith("[stiffcal] cpu rule=slow_rule")
    assert (tmp_path / "out.txt").read_text() == str(2500 * 1024**2)


def test_every_command_runs_under_the_memory_cap_and_reports_reaching_it_in_one_line(monkeypatch):
    """The command caps its address space (STIFFCAL_MAX_MEMORY_MB, default 4096 MB; checked in a process of its own,
    where an allocation past it is a MemoryError); a MemoryError is one line naming the cap (exit 2)."""
    code = ("import numpy as np\nfrom stiffcal.limits import cap_memory\nprint(cap_memory())\n"
            "try:\n    np.ones(2**30)\nexcept MemoryError:\n    print('MemoryError')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "STIFFCAL_MAX_MEMORY_MB": "3000"})
    assert res.stdout.split() == ["3000", "MemoryError"]  # 8 GiB asked, 3000 MB allowed
    res = subprocess.run([sys.executable, "-c", "from stiffcal.limits import cap_memory; print(cap_memory())"],
                         capture_output=True, text=True, timeout=60, env={**os.environ, "STIFFCAL_MAX_MEMORY_MB": ""})
    assert res.stdout.split() == [str(limits.DEFAULT_MAX_MEMORY_MB)]
    monkeypatch.setenv("STIFFCAL_MAX_MEMORY_MB", "100")
    with pytest.raises(InputError, match="'STIFFCAL_MAX_MEMORY_MB': expected a whole number of megabytes >= 1024"):
        limits.memory_cap_mb()
    monkeypatch.setenv("STIFFCAL_MAX_MEMORY_MB", "2048")

    def greedy(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr("stiffcal.api.design", greedy)
    refused(*cli(["design", "--robot", PAPER, "--test-pose-deg", "60,30", "--force-N", "0,-1"]),
            "stopped at the memory cap of 2048 MB per job", "STIFFCAL_MAX_MEMORY_MB")


# --- seeded fuzz: every command ----------------------------------------------------------------------------

def _fuzz_inputs(rng: random.Random, tmp: Path):
    """(argv, needles) pairs: hostile robot files, URDFs, options, output folders and load specs, each refused
    with exit 2 and one line holding the needles."""
    n = limits.MAX_JOINTS
    cases = []
    for k in range(12):  # URDFs
        urdf = rng.choice([
            (chain_urdf(3, axis2=rng.choice(["0 0 0", "1e308 1e308 1e308", "x y z", "1 2"])), "<axis xyz>"),
            (chain_urdf(3, origin=rng.choice(["1e300 0 0", "0 0 -5e3", "nan 0 0", "1 2"])), "<origin xyz>"),
            (chain_urdf(3).replace('rpy="0 0 0"', f'rpy="0 {rng.choice(["1e9", "inf", "-200"])} 0"', 1),
             "<origin rpy>"),
            (chain_urdf(3).replace('upper="3"', f'upper="{rng.choice(["nan", "inf", "big"])}"', 1), "<limit upper>"),
            (chain_urdf(rng.randint(n + 1, 3 * n)), "joints move"),
            (chain_urdf(3, links_extra=f'<link name="l{rng.randint(0, 3)}"/>'), "two links named"),
            (chain_urdf(3).replace('<robot name="r">', '<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">'
                                   '<xacro:property name="p" value="1"/>'), "a xacro file"),
            (chain_urdf(3)[: rng.randint(20, 200)], "not well-formed XML"),
        ])
        text, needle = urdf
        nj = 3 if needle != "joints move" else text.count("<joint")
        robot = urdf_robot(tmp, text, nj, f"u{k}.urdf")
        cases.append((design_args(robot, nj), [robot.name, "field 'urdf'" if needle != "joints move" else "field",
                                              needle]))
    for k in range(8):  # robot files
        bad = rng.choice([("links_m: [1.0e-300, 0.4]\n", "links_m[0]"),
                          (f"links_m: [{', '.join(['0.1'] * rng.randint(n + 1, 60))}]\n", "links_m"),
                          ("links_m: [0.6, 0.4]\ncompliances_rad_per_Nm: [1.0e-200, 1.0e-6]\n",
                           "compliances_rad_per_Nm[0]"),
                          ("links_m: [0.6, 1.0e300]\n", "links_m[1]")])
        robot = tmp / f"r{k}.yaml"
        robot.write_text("name: r\nkind: planar\n" + bad[0])
        cases.append((design_args(robot, 2), [robot.name, f"field '{bad[1]}'"]))
    for _ in range(10):  # design options
        option, value = rng.choice([("--force-N", f"{rng.choice(['1e300', '-1e308', '3e7'])},0"),
                                    ("--force-N", f"{rng.choice(['1e-300', '1e-9'])},0"),
                                    ("--wrench", f"0,-1,{rng.choice(['1e300', '-2e7'])}"),
                                    ("--experiments", str(rng.randint(1001, 10**7))),
                                    ("--sigma", rng.choice(["1e300", "1e-300", "-1"]))])
        args = {"--test-pose-deg": "60,30", "--force-N": "0,-1"}
        if option == "--wrench":
            args.pop("--force-N")
        args[option] = value
        cases.append((["design", "--robot", PAPER, "--quiet", *[f"{k}={v}" for k, v in args.items()]], [option]))
    for k in range(10):  # discriminate and discrepancy: loads, sizes, output folders
        choice = rng.randrange(4)
        if choice == 0:
            loads = rng.choice([f"hanging:{rng.choice(['1e300', '1e-300', '0.01', '2e7'])}",
                                f"directions:{rng.randint(65, 10**7)}:100", f"forces:{rng.choice(['1e300', '1e-3'])},0",
                                f"directions:4:{rng.choice(['1e9', '1e-9'])}"])
            cases.append((["discriminate", "--robot", PAPER, "--data", DATA, "--experiments", "4", "--out",
                           str(tmp / f"o{k}"), "--loads", loads], ["'--loads'"]))
        elif choice == 1:
            cases.append((["discriminate", "--robot", PAPER, "--data", DATA, "--out", str(tmp / f"o{k}"),
                           "--experiments", str(rng.randint(limits.MAX_DISCRIMINATE_EXPERIMENTS + 1, 10**6))],
                          ["'--experiments'"]))
        else:
            command = rng.choice(["discrepancy", "discriminate"])
            out = rng.choice([str(tmp / "afile" / "x"), "/proc/stiffcal", str(tmp / "afile")])
            cases.append(([command, "--robot", PAPER, "--data", DATA, "--out", out,
                           *(["--experiments", "4"] if command == "discriminate" else [])], [out]))
    cases += _fuzz_tables(rng, tmp)
    return cases


def _broken_csv(rng: random.Random, text: str) -> tuple[str, list[str]]:
    """``text`` (a CSV) with one hostile edit: a cell made nan, inf, text, 1e400 or blank; a column dropped; a field
    too many on a row. Returns (the CSV, what the message must hold: the column, or 'row')."""
    lines = text.splitlines()
    header = lines[0].split(",")
    r = rng.randrange(1, len(lines))
    c = rng.choice([i for i, name in enumerate(header) if name != "pose_id"])  # pose_id is optional
    cells = [line.split(",") for line in lines]
    how = rng.randrange(3)
    if how == 0:
        cells[r][c] = rng.choice(["nan", "inf", "-inf", "abc", "1e400", "", "1,5"])
        needles = ["row"] if cells[r][c] == "1,5" else [f"column {header[c]}"]
    elif how == 1:
        cells = [row[:c] + row[c + 1:] for row in cells]
        needles = [header[c]]
    else:
        cells[r].append("1")
        needles = ["row"]
    return "\n".join(",".join(row) for row in cells) + "\n", needles


def _fuzz_tables(rng: random.Random, tmp: Path):
    """(argv, needles): the measured data of discrepancy and discriminate, the poses of predict and the path of
    compensate, each a valid file with one hostile edit (:func:`_broken_csv`)."""
    robot = tmp / "calibrated_2r.yaml"  # compliances to predict with
    robot.write_text(Path(PAPER).read_text() + "compliances_rad_per_Nm: [1.0e-6, 2.0e-6]\n")
    data = Path(DATA).read_text()
    data = "\n".join(data.splitlines()[:40]) + "\n"
    poses = "q1_deg,q2_deg,fx_N,fy_N\n60,30,0,-300\n10,80,0,-300\n-40,100,50,-200\n"
    cases = []
    for k in range(12):
        command = ["discrepancy", "discriminate", "predict", "compensate"][k % 4]
        text, needles = _broken_csv(rng, data if command in ("discrepancy", "discriminate") else poses)
        path = tmp / f"table{k}.csv"
        path.write_text(text)
        option = {"discrepancy": "--data", "discriminate": "--data", "predict": "--poses", "compensate": "--path"}
        argv = [command, "--robot", str(robot if command in ("predict", "compensate") else PAPER),
                option[command], str(path), "--out", str(tmp / (f"o{k}.csv" if command in ("predict", "compensate")
                                                                  else f"o{k}"))]
        cases.append((argv + (["--experiments", "4"] if command == "discriminate" else []), [path.name, *needles]))
    return cases


def _fuzz_archives(rng: random.Random, tmp: Path):
    """Hostile archives: (path, expected exit, needle)."""
    good = _archive(tmp).read_bytes()
    cases = []
    for k in range(8):
        p = tmp / f"arch{k}.tar.gz"
        choice = rng.randrange(5)
        if choice == 0:  # not gzip at all
            p.write_bytes(bytes(rng.randrange(256) for _ in range(rng.randint(0, 64))).replace(b"\x1f\x8b", b""))
            cases.append((p, 2, "no gzip header"))
        elif choice == 1:  # cut short
            p.write_bytes(good[: rng.randint(2, len(good) - 1)])
            cases.append((p, 1, "damaged:"))
        elif choice == 2:  # a flipped byte past the header
            raw = bytearray(good)
            raw[rng.randint(10, len(raw) - 1)] ^= 1 << rng.randrange(8)
            p.write_bytes(bytes(raw))
            cases.append((p, 1, "damaged:"))
        elif choice == 3:  # gzip of something that is not a tar
            p.write_bytes(gzip.compress(bytes(rng.randrange(256) for _ in range(rng.randint(1, 4000)))))
            cases.append((p, None, ""))
        else:  # a valid tar without SHA256SUMS
            buf = io.BytesIO()
            with tarfile.open(fileobj=buf, mode="w:gz") as tar:
                info = tarfile.TarInfo("top/x.csv")
                info.size = 3
                tar.addfile(info, io.BytesIO(b"a,b"))
            p.write_bytes(buf.getvalue())
            cases.append((p, 2, "no top directory holds a SHA256SUMS"))
    return cases


def _fuzz_configs(rng: random.Random, tmp: Path):
    """Hostile workflow configs: (config dict, field named)."""
    import yaml

    base = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    cases = []
    for _ in range(8):
        cfg = json.loads(json.dumps(base))
        choice = rng.randrange(5)
        if choice == 0:
            cfg["study"]["force_N"] = [0, rng.choice([-1e300, 5e7, 1e-300])]
            field = "study.force_N"
        elif choice == 1:
            cfg["studies"][0]["force_N"] = [rng.choice([1e300, -3e7]), 0, 1]
            field = "studies[0].force_N[0]"
        elif choice == 2:
            cfg["measured_data"][0]["discriminate"]["loads"] = rng.choice(
                ["directions:100000:100", "hanging:1e-300", "hanging:1e300", "forces:1e300,0"])
            field = "measured_data[0].discriminate.loads"
        elif choice == 3:
            cfg["measured_data"][0]["discriminate"]["experiments"] = rng.randint(101, 10**6)
            field = "measured_data[0].discriminate.experiments"
        else:
            cfg["measured_data"][0]["force_resolution_N"] = rng.choice([1e300, 1e9])
            field = "measured_data[0].force_resolution_N"
        cases.append((cfg, field))
    return cases


def test_fuzz_every_command_with_hostile_inputs(tmp_path, monkeypatch):
    """Seeded and bounded (about 70 inputs, a few seconds): hostile URDFs, robot files, options, output folders and
    load specs through the command line, measured data (discrepancy, discriminate) and pose tables (predict,
    compensate) with one bad cell, column or row, archives through verify-archive, configs through the workflow's
    config check. Every one: exit 2 (verify-archive: 1 for a damaged archive, as documented), one line naming the file
    or the field, no traceback, nothing written."""
    import yaml

    from stiffcal.workflow.config import workflow_config

    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    rng = random.Random(28)
    cases, archives = _fuzz_inputs(rng, tmp_path), _fuzz_archives(rng, tmp_path)
    configs = []
    for k, (cfg, field) in enumerate(_fuzz_configs(rng, tmp_path)):
        path = tmp_path / f"bad_config{k}.yaml"
        path.write_text(yaml.safe_dump(cfg))
        configs.append((path, field))
    assert len(cases) + len(archives) + len(configs) >= 50
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    for argv, needles in cases:
        code, out, err = cli(argv)
        refused(code, out, err, *needles)
    for path, expected, needle in archives:
        code, out, err = cli(["verify-archive", str(path)])
        assert code in ((1, 2) if expected is None else (expected,)), (path, code, err)
        assert out == "" if code == 2 else json.loads(out)["ok"] is False
        assert "Traceback" not in err and err.count("\n") == 1 and needle in err and str(path) in err, err
    for path, field in configs:
        with pytest.raises(InputError) as err:
            workflow_config([str(path)], root=ROOT)
        text = str(err.value)
        assert text.startswith(f"{path}: field '{field}") and "\n" not in text, (field, text)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing written


# --- degenerate measured data (issue 28, item 1) ---------------------------------------------------------------

def _degenerate(tmp_path, how):
    """The paper's synthetic data with its displacements made degenerate: ``zeros`` (every cell 0), ``tiny``
    (scaled by 1e-300), ``copies`` (every replicate group's readings replaced by their mean, written once per
    replicate), ``noisy`` (untouched: the control)."""
    import pandas as pd

    df = pd.read_csv(DATA)
    cols = ["dx_m", "dy_m"]
    if how == "zeros":
        df[cols] = 0.0
    elif how == "tiny":
        df[cols] *= 1e-300
    elif how == "copies":
        df[cols] = df.groupby(["q1_deg", "q2_deg", "fx_N", "fy_N"])[cols].transform("mean")
    elif how in ("exact", "rounded"):  # eq. 2 without noise (k = 1e-6, 2e-6), no replicates: full digits, or 4
        from stiffcal.model.robot import load_robot

        df = df.drop_duplicates(subset=["q1_deg", "q2_deg", "fx_N", "fy_N"]).reset_index(drop=True)
        J = load_robot(PAPER).jacobian(np.radians(df[["q1_deg", "q2_deg"]].to_numpy()))
        F = df[["fx_N", "fy_N"]].to_numpy()
        df[cols] = np.einsum("nij,j,nkj,nk->ni", J, [1e-6, 2e-6], J, F)
        if how == "rounded":  # the displacements printed with 4 digits, as a simulation might write them
            df[cols] = df[cols].map(lambda v: f"{v:.4g}")
    path = tmp_path / f"{how}.csv"
    df.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("how, words", [("zeros", "move nothing measurable"), ("tiny", "move nothing measurable"),
                                        ("copies", "exact copies"), ("exact", "the model fits the rows exactly"),
                                        ("rounded", "no more than the rounding of the displacements")])
def test_degenerate_data_are_refused_never_a_confident_none(tmp_path, how, words):
    """Data that carry no deflection or no noise in fact gave compliances of 0 +- 0 and `none` at p = 1, or
    intervals of zero width; noise-free simulated data got `unexplained` at p = 1e-132 (their scatter is the fits'
    round-off, 1e-8 of the displacements) or, printed with 4 digits, a verdict on their rounding: refused with the
    reason, exit 2, nothing written; the same file untouched gives a verdict (the refusal is the degeneracy's, not
    the file's)."""
    out = tmp_path / "out"
    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        code = main(["discrepancy", "--robot", PAPER, "--data", str(_degenerate(tmp_path, how)), "--out", str(out),
                     "--quiet"])
    lines = [x for x in err.getvalue().splitlines() if "error" in x]
    assert code == 2 and not out.exists() and len(lines) == 1
    assert words in lines[0] and re.search(r"columns? dx_m", lines[0]) and f"{how}.csv" in lines[0]
    with redirect_stderr(io.StringIO()), redirect_stdout(io.StringIO()):
        assert main(["discrepancy", "--robot", PAPER, "--data", str(_degenerate(tmp_path, "noisy")), "--out",
                     str(tmp_path / "control"), "--quiet"]) == 0


def test_a_measured_log_beyond_the_row_limit_is_refused_before_it_is_parsed(tmp_path, monkeypatch):
    """More data rows than MAX_MEASURED_ROWS (here lowered to 10) are refused naming the bound, before pandas
    reads the file."""
    import pandas as pd

    from stiffcal.measured.measurements import read_measurements

    monkeypatch.setattr(limits, "MAX_MEASURED_ROWS", 10)
    path = tmp_path / "big.csv"
    pd.read_csv(DATA).head(11).to_csv(path, index=False)
    calls = []
    monkeypatch.setattr(pd, "read_csv", lambda *a, **k: calls.append(a))
    with pytest.raises(InputError, match=r"big.csv.*more than 10 data rows \(MAX_MEASURED_ROWS"):
        read_measurements(path, load_robot(PAPER))
    assert calls == []
    monkeypatch.undo()
    monkeypatch.setattr(limits, "MAX_MEASURED_ROWS", 10)
    padded = tmp_path / "padded.csv"  # 10 rows and blank lines after them: blank lines are not rows
    padded.write_text("\n".join(Path(DATA).read_text().splitlines()[:11]) + "\n" * 50)
    assert read_measurements(padded, load_robot(PAPER)).n_rows + len(read_measurements(padded, load_robot(PAPER))
                                                                     .zero_rows) == 10
