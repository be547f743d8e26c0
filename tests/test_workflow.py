"""The Snakemake workflow end to end on a small test config, its determinism, and a bad input."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.workflow
SNAKEMAKE = Path(sys.executable).with_name("snakemake")


def _workdir(root: Path, tmp: Path, **study) -> Path:
    for item in ("Snakefile", "workflow", "config", "paper", "data"):
        src = root / item
        (shutil.copytree if src.is_dir() else shutil.copy)(src, tmp / item)
    shutil.rmtree(tmp / "paper" / "build", ignore_errors=True)
    cfg = yaml.safe_load((root / "config/config.yaml").read_text())
    cfg["study"].update({"search_step_deg": 4.0, "fig5_step_deg": 6.0, **study})
    cfg["monte_carlo"]["samples"] = 500
    cfg["plans"] = {"m_max": 3, "pool_step_deg": 6.0}
    cfg["maps"].update({"step_deg": 10.0, "tile_cells": 200, "statistics_steps_deg": [30, 10]})
    for st in cfg["studies"]:
        st.update({"m_values": [2, 3], "draw_m": 3})
    # adding a robot is adding its YAML file and a study entry (no code change)
    (tmp / "config/robots/added_rrr.yaml").write_text(ADDED_ROBOT)
    cfg["studies"].append({"name": "added-rrr", "robot": "config/robots/added_rrr.yaml", "test_pose_deg": [30, -40, 60],
                           "force_N": [100, 50, -200], "sigma_m": 1e-5, "m_values": [1, 2]})
    # a robot in a cell, measured under pushes in three directions (issue 24)
    cfg["studies"].append({"name": "paper-cell", **CELL_STUDY})
    (tmp / "config" / "test.yaml").write_text(yaml.safe_dump(cfg))
    return tmp


CELL_STUDY = {"robot": "config/robots/paper_2r.yaml", "test_pose_deg": [60, 30], "force_N": [0, -300],
              "loads": "directions:3:100", "m_values": [2, 3],
              "cell": {"floor_m": -0.1, "clearance_m": 0.02, "link_radius_m": 0.04,
                       "boxes": [{"name": "fixture", "center_m": [0.45, 0.25], "size_m": [0.3, 0.2]}]}}

ADDED_ROBOT = """name: added-rrr
kind: spatial
dh_convention: modified
dh:
  - {a_m: 0.0, alpha_deg: 0, d_m: 0.4}
  - {a_m: 0.1, alpha_deg: -90, d_m: 0.0}
  - {a_m: 0.5, alpha_deg: 0, d_m: 0.0}
tool_m: [0.45, 0.0, 0.0]
joint_limits_deg: [[-170, 170], [-120, 60], [-150, 150]]
"""


def _snakemake(wd: Path, *extra):
    return subprocess.run([str(SNAKEMAKE), *extra, "--cores", "2", "--configfile", "config/test.yaml", "--quiet"],
                          cwd=wd, capture_output=True, text=True)


@pytest.fixture(scope="module")
def built(root, tmp_path_factory):
    wd = _workdir(root, tmp_path_factory.mktemp("wf"))
    res = _snakemake(wd)
    assert res.returncode == 0, res.stderr[-3000:]
    return wd


def test_workflow_writes_tables_figures_and_report(built):
    for f in ("results/tables/table2.csv", "results/tables/table3.csv", "results/tables/table4.csv",
              "results/tables/table5.csv", "results/tables/approximate_design.csv", "results/tables/certificate.csv",
              "results/tables/ot_versus_m.csv", "results/tables/paper_comparison.csv",
              "results/tables/validation.csv", "paper/build/report.html", "paper/build/report.pdf"):
        assert (built / f).stat().st_size > 0, f
    for name in ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m", "fig6", "fig7", "fig8", "fig9", "fig10"):
        for ext in ("png", "svg"):
            assert (built / f"figures/{name}.{ext}").stat().st_size > 0
    html = (built / "paper/build/report.html").read_text()
    for needle in ("Table 2", "Table 3", "Table 4", "Table 5", "Figure 3", "Figure 4", "Figure 5",
                   "Optimal approximate design", "made by rule", "Figure 6", "Figure 10", "what they depend on"):
        assert needle in html
    assert (built / "paper/build/report.pdf").read_bytes().startswith(b"%PDF")


def test_maps_have_the_contract_columns_and_every_cell(built):
    import pandas as pd

    for study in ("b0.67", "b0.2", "b0.5", "b0.9"):
        df = pd.read_csv(built / f"results/maps/{study}/map.csv")
        assert list(df.columns) == ["link_ratio", "force_deg", "q1t_deg", "q2t_deg", "q1_opt_deg", "q2_opt_deg",
                                    "O_t", "chi"]
        assert len(df) == 36 * 36 and not df.duplicated(["q1t_deg", "q2t_deg"]).any()
    assert not list((built / "results/maps").rglob("tiles/*.npz"))  # tiles are temporary
    log = (built / "logs/maps/b0.67/tile0.log").read_text()
    assert "cells/s" in log  # progress in the log
    stats = pd.read_csv(built / "results/tables/map_statistics.csv")
    assert {"mean", "median", "harmonic_mean", "white", "dark"} <= set(stats.statistic)


def test_measured_data_get_a_verdict_and_a_report_section(built):
    import json

    v = json.loads((built / "results/discrepancy/synthetic-paper-2r/verdict.json").read_text())
    assert v["cause"] == "backlash" and v["outlier_rows"] == [17]
    html = (built / "paper/build/report.html").read_text()
    assert "Measured data: synthetic-paper-2r" in html and "SYNTHETIC data" in html


def test_every_design_study_gets_plans_figures_and_a_report_section(built):
    import pandas as pd

    html = (built / "paper/build/report.html").read_text()
    for name, ms in (("kuka-kr210-machining", [2, 3]), ("added-rrr", [1, 2])):
        df = pd.read_csv(built / f"results/studies/{name}/versus_m.csv")
        assert list(df.m) == ms and df.within_limits.all() and (df.O_t >= df.lower_bound * (1 - 1e-12)).all()
        long = pd.read_csv(built / f"results/studies/{name}/plans.csv")  # one row per pose
        n = sum(c.startswith("q") and c.endswith("_deg") for c in long.columns)
        assert list(long.columns) == ["plan", "m", "pose", *[f"q{i + 1}_deg" for i in range(n)]]
        assert [len(g) for _, g in long.groupby("m")] == ms and (long.groupby("m").pose.max() == ms).all()
        for fig in ("plan", "versus_m"):
            assert (built / f"figures/studies/{name}/{fig}.png").stat().st_size > 0
        assert f"Design study: {name}" in html
    assert "modified convention" in html and "standard convention" in html


def test_a_study_in_a_cell_keeps_every_pose_feasible_and_is_the_api_s_plan(built):
    """The design study in a cell (capsules, the floor, a fixture; pushes in three directions): plans.csv gains
    each pose's clearance, versus_m.csv the feasible bound, every pose passes the dense-sample check written in
    tests/test_workcell.py, the report describes the cell, and stiffcal.design gives the same plans (one answer
    per input)."""
    import pandas as pd

    import stiffcal
    from stiffcal.model.robot import load_robot
    from test_workcell import _planar_violations, _points_along

    long = pd.read_csv(built / "results/studies/paper-cell/plans.csv")
    assert list(long.columns) == ["plan", "m", "pose", "q1_deg", "q2_deg", "clearance_m", "closest"]
    vm = pd.read_csv(built / "results/studies/paper-cell/versus_m.csv")
    assert vm.feasible.all() and (vm.O_t >= vm.lower_bound).all() and "feasible_lower_bound" in vm.columns
    robot = load_robot(built / "config/robots/paper_2r.yaml")
    for q in long[["q1_deg", "q2_deg"]].to_numpy(float):
        assert _planar_violations(_points_along(robot, q)) == (False, False), q
    html = (built / "paper/build/report.html").read_text()
    assert "The robot stands in a cell" in html and "distance to the nearest body [mm]" in html
    s = CELL_STUDY
    cell = {**s["cell"]}
    for m in s["m_values"]:
        api = stiffcal.design(built / s["robot"], s["test_pose_deg"], s["force_N"], experiments=m, loads=s["loads"],
                              cell=cell)
        assert np.allclose(api.poses_deg, long[long.m == m][["q1_deg", "q2_deg"]].to_numpy(float), atol=5e-5)


def _dry_run_jobs(wd: Path, env: dict | None = None) -> dict[str, int]:
    """rule -> number of jobs that ``snakemake -n`` would run (its 'Job stats' table), without 'all'."""
    import os
    import re

    res = subprocess.run([str(SNAKEMAKE), "-n", "--cores", "2", "--configfile", "config/test.yaml"], cwd=wd,
                         capture_output=True, text=True, env={**os.environ, **(env or {})})
    assert res.returncode == 0, res.stderr[-3000:]
    out = res.stdout + res.stderr
    if "Nothing to be done" in out:
        return {}
    stats = out[out.index("Job stats:"):]
    stats = stats[:stats.index("total")]
    return {r: int(n) for r, n in re.findall(r"^(\w+)\s+(\d+)$", stats, flags=re.M) if r not in ("all", "job")}


def _edit_config(wd: Path, edit) -> str:
    path = wd / "config/test.yaml"
    before = path.read_text()
    cfg = yaml.safe_load(before)
    edit(cfg)
    path.write_text(yaml.safe_dump(cfg))
    return before


REPORT = {"report_html": 1, "report_pdf": 1}


@pytest.mark.parametrize("what,edit,expected", [
    ("one design study's force", lambda c: c["studies"][1].update(force_N=[100, 50, -150]),
     {"study_design": 1, "study_plans": 1, "study_summary": 1, **REPORT}),
    ("one design study's M values", lambda c: c["studies"][1].update(m_values=[1, 2, 3]),
     {"study_plans": 1, "study_summary": 1, **REPORT}),
    ("one map's ratio", lambda c: c["maps"]["studies"][1].update(link_ratio=0.25),
     {"map_tile": 2, "map_merge": 1, "map_statistics": 1, "map_figures": 1, **REPORT}),
    ("the test pose", lambda c: c["study"].update(test_pose_deg=[50, 40]),
     {"table2": 1, "table3": 1, "validation": 1, "chi_map": 1, "approximate_design": 1, "plans_table": 2,
      "ot_versus_m": 1, "paper_comparison": 1, "paper_figures": 1,
      # both measured data sets are of the paper's arm: their gain and their compound plans use the test pose
      "discrepancy": 2, "discriminate": 2, **REPORT}),
    ("the Monte Carlo samples", lambda c: c["monte_carlo"].update(samples=600), {"validation": 1, **REPORT}),
    # a fresh reviewer's edit of the next experiment's size reran the analysis too (its params held the whole entry)
    ("one data set's next experiment", lambda c: c["measured_data"][0].setdefault("discriminate", {}).update(
        experiments=5), {"discriminate": 1, **REPORT}),
    # the map grid: every map (one tile each on a 15-degree grid, computed in its map_merge job), its figures
    # and statistics and the comparison (the Figure-6 numbers of the text), not the pairs (their own
    # pairs_step_deg)
    ("the map step", lambda c: c["maps"].update(step_deg=15.0),
     {"map_merge": 4, "map_grid_statistics": 1, "map_statistics": 1, "map_figures": 1, "paper_comparison": 1,
      **REPORT}),
])
def test_dry_run_after_a_config_edit_lists_exactly_the_affected_jobs(built, what, edit, expected):
    assert _dry_run_jobs(built) == {}
    before = _edit_config(built, edit)
    try:
        # and any config edit rewrites results/config.effective.yaml (the config the run saw)
        assert _dry_run_jobs(built) == {**expected, "effective_config": 1}, what
    finally:
        (built / "config/test.yaml").write_text(before)
    assert _dry_run_jobs(built) == {}


def test_dry_run_after_a_measured_data_edit(built):
    import os

    data = built / "data/synthetic_paper_2r.csv"
    before, stat = data.read_bytes(), data.stat()
    lines = before.decode().splitlines(keepends=True)
    lines[1] = lines[1].replace(",", ", ", 1)  # same numbers, another file
    data.write_text("".join(lines))
    try:
        assert _dry_run_jobs(built) == {"discrepancy": 1, "discriminate": 1, **REPORT}
    finally:
        data.write_bytes(before)
        os.utime(data, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert _dry_run_jobs(built) == {}



def test_report_renders_a_measured_data_entry_without_optional_keys(built, tmp_path):
    """``synthetic`` (and every other optional key) left out of a measured-data entry: the report renders, the
    entry unlabelled (a copy of the built tree; only the report is redrawn)."""
    wd = tmp_path / "wd"
    shutil.copytree(built, wd, symlinks=True)

    def bare(c):
        c["measured_data"][1] = {k: c["measured_data"][1][k] for k in ("name", "data", "robot")}

    _edit_config(wd, bare)
    res = _snakemake(wd, "--rerun-triggers", "mtime", "--forcerun", "report_html", "paper/build/report.html")
    assert res.returncode == 0, res.stderr[-3000:]
    html = (wd / "paper/build/report.html").read_text()
    assert "Measured data: synthetic-paper-2r-hanging</h2>" in html
    assert "Measured data: synthetic-paper-2r <span class=\"synthetic\">(SYNTHETIC data)</span></h2>" in html


def test_dry_run_after_a_library_edit_reruns_the_jobs_that_use_it(built, root, tmp_path):
    """A copy of the package with one comment added to plots.py, first on PYTHONPATH: the figure jobs, the
    discrepancy and discriminate jobs of both measured data sets (they draw the residuals and the plans) and the
    report rerun; no table or map job."""
    pkg = tmp_path / "pkg"
    shutil.copytree(root / "src/stiffcal", pkg / "stiffcal")
    plots = pkg / "stiffcal/report/plots.py"
    plots.write_text(plots.read_text() + "\n# an edit\n")
    jobs = _dry_run_jobs(built, {"PYTHONPATH": str(pkg)})
    assert jobs == {"paper_figures": 1, "map_figures": 1, "study_summary": 3, "discrepancy": 2, "discriminate": 2,
                    **REPORT}


def test_slurm_profile_dry_run(root, tmp_path):
    wd = _workdir(root, tmp_path)
    res = subprocess.run([str(SNAKEMAKE), "--workflow-profile", "workflow/profiles/slurm", "--configfile",
                          "config/test.yaml", "-n"], cwd=wd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-3000:]
    out = res.stdout + res.stderr
    assert "map_tile" in out and "slurm" in out.lower()


def test_rerun_gives_identical_tables_html_and_pdf(built):
    report = [built / "paper/build/report.html", built / "paper/build/report.pdf", *(built / "figures").rglob("*.svg"),
              *(built / "figures").rglob("*.png")]
    before = {p: p.read_bytes() for p in [*(built / "results").rglob("*.csv"), *report]}
    shutil.rmtree(built / "results")
    res = _snakemake(built, "--forcerun", "table2", "chi_map", "approximate_design", "map_tile", "study_design")
    assert res.returncode == 0, res.stderr[-3000:]
    after = {p: p.read_bytes() for p in [*(built / "results").rglob("*.csv"), *report]}
    assert before.keys() == after.keys()
    assert [p for p in before if before[p] != after[p]] == []


def test_every_table_and_figure_is_in_the_report_with_a_provenance_line(built):
    import base64
    import re

    import pandas as pd

    html = (built / "paper/build/report.html").read_text()
    svgs = [*(built / "figures").rglob("*.svg"), *(built / "results/discrepancy").rglob("*.svg")]
    assert len(svgs) >= 15
    for svg in svgs:  # vector figures, embedded
        assert base64.b64encode(svg.read_bytes()).decode() in html, svg
    figures = re.findall(r"<figure>.*?</figure>", html, flags=re.S)
    assert len(figures) == len(svgs) and all("made by rule" in f for f in figures)
    assert "data:image/png" not in html
    html = html[html.index("</nav>"):]  # after the table of contents
    html = re.sub(r'<table class="poses">.*?</table>', "", html, flags=re.S)  # pose tables sit inside tables
    for end in re.finditer(r"</table>", html):  # every table: a provenance line before the next table
        rest = html[end.end():]
        nxt = rest.find("<table")
        assert 'class="prov"' in (rest if nxt == -1 else rest[:nxt]), html[max(0, end.start() - 300):end.start()]
    for heading in ("Table 2", "Table 3", "Table 4", "Table 5", "The paper's numbers beside ours", "certificate"):
        assert heading in html
    # the paper's printed values sit under ours in Tables 2-5: one per printed number of those tables
    cmp = pd.read_csv(built / "results/tables/paper_comparison.csv", dtype=str)
    expected = (cmp.table != "text").sum()
    start, end = html.index("<table", html.index("Table 2 ·")), html.index("How good can a plan be")
    assert html[start:end].count('<span class="paper ') == expected


def test_report_has_a_linked_table_of_contents_and_pose_tables(built):
    import re

    html = (built / "paper/build/report.html").read_text()
    toc = html[html.index('<nav class="toc">'):html.index("</nav>")]
    links = re.findall(r'href="#([^"]+)"', toc)
    headings = re.findall(r'<h[23] id="([^"]+)"', html)
    assert len(links) >= 10 and set(links) == set(headings) - {"contents"}
    assert "Design study: added-rrr" in toc and "Table 5" in toc
    # plans as tables, one row per pose and one column per joint: Table 5 has 4 plans of 3 poses
    body = html[html.index("</nav>"):]
    t5 = body[body.index("Table 5 ·"):body.index("How good can a plan be")]
    assert t5.count('<table class="poses">') == 4 and t5.count("<th>q2 [deg]</th>") == 4


def test_pdf_has_bookmarks(built):
    pypdf = pytest.importorskip("pypdf")
    reader = pypdf.PdfReader(built / "paper/build/report.pdf")

    def titles(outline):
        for item in outline:
            if isinstance(item, list):
                yield from titles(item)
            else:
                yield item.title

    found = list(titles(reader.outline))
    for needle in ("Table 2", "Table 5", "Design study: added-rrr", "Maps over test poses"):
        assert any(needle in t for t in found), (needle, found)


def test_pdf_has_every_page_numbered(built):
    pypdf = pytest.importorskip("pypdf")
    reader = pypdf.PdfReader(built / "paper/build/report.pdf")
    n = len(reader.pages)
    assert n >= 15
    texts = [page.extract_text() for page in reader.pages]
    assert all(f"page {i + 1} of {n}" in t for i, t in enumerate(texts))
    whole = " ".join(texts)
    for needle in ("Table 2", "Table 5", "Figure 10", "Design study: added-rrr", "Measured data"):
        assert needle in whole


def test_archive_verifies_and_names_a_changed_file(built, tmp_path):
    import io
    import tarfile

    res = _snakemake(built, "archive")
    assert res.returncode == 0, res.stderr[-3000:]
    (tgz,) = (built / "results/archive").glob("stiffcal-*.tar.gz")
    again = _snakemake(built, "-n", "archive")  # made, it is up to date (a start time among its params rebuilt it)
    assert again.returncode == 0 and "Nothing to be done" in again.stdout + again.stderr, again.stdout[-2000:]
    cli = Path(sys.executable).with_name("stiffcal")
    ok = subprocess.run([str(cli), "verify-archive", str(tgz)], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    with tarfile.open(tgz) as tar:
        names = tar.getnames()
        prov = json.loads(tar.extractfile(next(n for n in names if n.endswith("provenance.json"))).read())
    for part in ("/paper/build/report.html", "/paper/build/report.pdf", "/results/config.effective.yaml",
                 "/SHA256SUMS", "/results/tables/table2.csv", "/figures/fig3.png", "/logs/table2.log",
                 "/config/robots/paper_2r.yaml", "/data/synthetic_paper_2r.csv", "/paper/printed_values.yaml"):
        assert any(n.endswith(part) for n in names), part
    assert {"commit", "dirty", "python", "packages", "platform", "config_hash", "started", "ended"} <= set(prov)
    html = (built / "paper/build/report.html").read_text()  # the report says the same: libraries, inputs
    assert f"pin {prov['packages']['pin']}" in html and f"python-flint {prov['packages']['python-flint']}" in html
    assert "Untracked inputs (not in the commit): " in html and "config/robots/paper_2r.yaml" in html  # no git here
    bad = tmp_path / "bad.tar.gz"
    with tarfile.open(tgz) as tin, tarfile.open(bad, "w:gz") as tout:
        for m in tin.getmembers():
            data = tin.extractfile(m).read()
            if m.name.endswith("results/tables/table3.csv"):
                data = data.replace(b"0", b"1", 1)
            tout.addfile(m, io.BytesIO(data))
    res = subprocess.run([str(cli), "verify-archive", str(bad)], capture_output=True, text=True)
    assert res.returncode == 1 and "changed: results/tables/table3.csv" in res.stderr


def test_archive_of_a_second_config_holds_its_config_inputs_and_no_stale_output(built, tmp_path, monkeypatch):
    """An archive made with another --configfile holds that config as the run saw it (the hash the report and
    provenance.json show), the robot file and data it names outside config/ and data/, and nothing that the
    first config's run left behind (results, figures, logs of its studies and data sets)."""
    import tarfile

    from stiffcal.workflow.config import workflow_config
    from stiffcal.report.html import config_hash

    wd = tmp_path / "wf"
    shutil.copytree(built, wd, symlinks=True, ignore=shutil.ignore_patterns("locks", "archive"))
    cfg = yaml.safe_load((wd / "config/test.yaml").read_text())
    (wd / "lab").mkdir()
    shutil.copy(wd / "config/robots/paper_2r.yaml", wd / "lab/arm.yaml")
    shutil.copy(wd / "data/synthetic_paper_2r.csv", wd / "lab/run1.csv")
    cfg["studies"] = [st for st in cfg["studies"] if st["name"] == "added-rrr"]
    cfg["measured_data"] = [{**cfg["measured_data"][0], "name": "lab-run1", "data": "lab/run1.csv",
                             "robot": "lab/arm.yaml"}]
    (wd / "config/second.yaml").write_text(yaml.safe_dump(cfg))
    res = subprocess.run([str(SNAKEMAKE), "archive", "--cores", "2", "--configfile", "config/second.yaml", "--quiet",
                          "--config", "seed=7"], cwd=wd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-3000:]
    (tgz,) = (wd / "results/archive").glob("stiffcal-*.tar.gz")
    with tarfile.open(tgz) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames()}
        read = {n: tar.extractfile(m).read().decode() for m in tar.getmembers()
                for n in [m.name.split("/", 1)[1]] if n in ("provenance.json", "results/config.effective.yaml",
                                                             "paper/build/report.html")}
    (tmp_path / "effective.yaml").write_text(read["results/config.effective.yaml"])
    monkeypatch.chdir(wd)  # as the run saw it: --configfile with --config on top, defaults filled in; and the
    # effective config given back as --configfile is that config again
    effective = workflow_config([str(tmp_path / "effective.yaml")])[1]
    assert effective == workflow_config(["config/second.yaml"], {"seed": 7})[1]
    res = subprocess.run([str(SNAKEMAKE), "-n", "--configfile", str(tmp_path / "effective.yaml")], cwd=wd,
                         capture_output=True, text=True)  # a reviewer's rerun of it has nothing to do
    assert res.returncode == 0 and "Nothing to be done" in res.stdout + res.stderr, res.stdout[-2000:]
    digest = config_hash(effective)
    assert json.loads(read["provenance.json"])["config_hash"] == digest and digest in read["paper/build/report.html"]
    assert {"lab/arm.yaml", "lab/run1.csv", "results/discrepancy/lab-run1/verdict.json",
            "logs/discrepancy/lab-run1.log", "results/studies/added-rrr/plans.csv"} <= names
    stale = [n for n in names if any(old in n for old in ("kuka-kr210-machining", "synthetic-paper-2r"))]
    assert stale == [] and (wd / "results/studies/kuka-kr210-machining").is_dir()  # left on disk, not packed
    assert not {"config/robots/kuka_kr210_r2700.yaml", "config/test.yaml", "data/synthetic_paper_2r.csv"} & names
    res = subprocess.run([str(Path(sys.executable).with_name("stiffcal")), "verify-archive", str(tgz)],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_a_changed_intermediate_stops_the_run_and_a_deleted_one_is_rebuilt(built):
    """shared/cases/bad-input/17: a table changed by hand flowed into the report with exit 0, and a deleted one
    was not rebuilt. Now the job that reads it stops with a message naming it; deleted, it is rebuilt, and the
    report comes out as before."""
    csv, html = built / "results/tables/validation.csv", built / "paper/build/report.html"
    good, good_html = csv.read_bytes(), html.read_bytes()
    csv.write_bytes(good.replace(b"eq. 11", b"eq. 12", 1))
    res = _snakemake(built)
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert "results/tables/validation.csv: changed after rule validation wrote it" in res.stderr
    assert not html.exists() or html.read_bytes() == good_html  # never a report made from the changed table
    csv.unlink()
    res = _snakemake(built)
    assert res.returncode == 0, res.stderr[-3000:]
    assert csv.read_bytes() == good and html.read_bytes() == good_html


def test_a_truncated_map_is_refused(built):
    """A map cut in half gave statistics from half the cells without a word. The jobs read map.npz (map.csv
    is for users; the archive verifies it)."""
    m = built / "results/maps/b0.2/map.npz"
    good = m.read_bytes()
    m.write_bytes(good[: len(good) // 2])
    res = _snakemake(built)
    assert res.returncode != 0 and "results/maps/b0.2/map.npz: changed after rule map_merge wrote it" in res.stderr
    m.unlink()
    res = _snakemake(built)
    assert res.returncode == 0, res.stderr[-3000:]
    assert m.read_bytes() == good


def test_make_removes_the_lock_of_an_interrupted_run_only_when_idle(built, root):
    """A killed run leaves .snakemake/locks/; tools/unlock_if_idle.py (run by `make report`) removes it when no
    Snakemake process works in the directory, and the next run goes through."""
    locks = built / ".snakemake/locks"
    locks.mkdir(parents=True, exist_ok=True)
    (locks / "0.output.lock").write_text("results/tables/table2.csv\n")  # as a killed run leaves it
    res = _snakemake(built)
    assert res.returncode != 0 and "cannot be locked" in res.stdout + res.stderr
    res = subprocess.run([sys.executable, str(root / "tools/unlock_if_idle.py"), "--configfile", "config/test.yaml"],
                         cwd=built, capture_output=True, text=True)
    assert res.returncode == 0 and "removed the lock" in res.stderr, res.stderr
    assert not locks.exists() or not any(locks.iterdir())
    res = _snakemake(built)
    assert res.returncode == 0, res.stderr[-3000:]


def test_configfile_replaces_the_default_and_errors_name_it(built, tmp_path):
    cfg = yaml.safe_load((built / "config/test.yaml").read_text())
    cfg["maps"]["step_deg"] = 0.001  # was a MemoryError traceback (966 GiB)
    (built / "config/bad.yaml").write_text(yaml.safe_dump(cfg))
    res = subprocess.run([str(SNAKEMAKE), "-n", "--cores", "2", "--configfile", "config/bad.yaml"], cwd=built,
                         capture_output=True, text=True)
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert "config/bad.yaml: field 'maps.step_deg': expected a number >= 0.25, got 0.001" in res.stderr


BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: headless Chromium on a machine without network: no first-run, sync, component updates or background traffic
#: (without these it floods the closed network with retries), a profile of its own
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.mark.skipif(not any(shutil.which(b) for b in BROWSERS) and not os.environ.get("CI"),
                    reason="headless Chromium is not installed (.ci/run installs Debian's chromium)")
def test_report_renders_in_headless_chromium(built, tmp_path, record_property):
    """The report as a real browser renders it (CI installs Chromium, so this runs there: conftest prints a line
    saying it ran)."""
    browser = next((shutil.which(b) for b in BROWSERS if shutil.which(b)), None)
    if browser is None:
        pytest.fail("CI must run the browser test: .ci/run installs Debian's chromium, but none is on PATH")
    version = subprocess.run([browser, "--version"], capture_output=True, text=True, timeout=60).stdout.strip()
    record_property("browser", version)
    url = (built / "paper/build/report.html").as_uri()
    flags = [browser, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}"]
    res = subprocess.run([*flags, "--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "Design study: kuka-kr210-machining" in res.stdout and "Table 5" in res.stdout
    shot = tmp_path / "report.png"
    res = subprocess.run([*flags, f"--screenshot={shot}", "--window-size=1200,1600", url], capture_output=True,
                         timeout=120)
    assert res.returncode == 0 and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_robot_file_fails_cleanly_without_outputs(root, tmp_path):
    wd = _workdir(root, tmp_path, robot="config/robots/bad.yaml")
    (wd / "config/robots/bad.yaml").write_text("name: bad\nkind: planar\nlinks_m: [0.6, -0.4]\n")
    res = _snakemake(wd)
    assert res.returncode != 0
    assert "config/robots/bad.yaml: field 'links_m[1]': expected a number > 0, got -0.4" in res.stderr
    assert "Traceback" not in res.stderr
    assert not (wd / "results/tables/table2.csv").exists()


def test_bad_config_is_rejected_by_the_schema(root, tmp_path):
    wd = _workdir(root, tmp_path, sigma_m=-1)
    res = _snakemake(wd)
    assert res.returncode != 0
    assert "sigma_m" in res.stderr
    assert not (wd / "results").exists()


@pytest.mark.parametrize("blocker", ["results", "results/discrepancy/synthetic-paper-2r", "figures/studies"])
def test_an_output_folder_that_is_a_file_is_refused_before_any_job(root, tmp_path, blocker):
    """A file where the workflow needs a folder (the results folder, a data set's or the studies' folder) ended
    in Snakemake's traceback (NotADirectoryError) after jobs had run: now one line naming it, before any job."""
    wd = _workdir(root, tmp_path)
    (wd / blocker).parent.mkdir(parents=True, exist_ok=True)
    (wd / blocker).write_text("x\n")
    res = _snakemake(wd)
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert f"stiffcal: error: {blocker}: expected a folder for the workflow's outputs" in res.stderr
    assert not (wd / "results/tables").exists()
