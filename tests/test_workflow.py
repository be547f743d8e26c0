"""The Snakemake workflow end to end on a small test config, its determinism, and a bad input."""

import shutil
import subprocess
import sys
from pathlib import Path

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
    (tmp / "config" / "test.yaml").write_text(yaml.safe_dump(cfg))
    return tmp


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
    return subprocess.run([str(SNAKEMAKE), "--cores", "2", "--configfile", "config/test.yaml", "--quiet", *extra],
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
    assert not list((built / "results/maps").rglob("tiles/*.csv"))  # tiles are temporary
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
        df = pd.read_csv(built / f"results/studies/{name}/plans.csv")
        assert list(df.m) == ms and df.within_limits.all() and (df.O_t >= df.lower_bound * (1 - 1e-12)).all()
        for fig in ("plan", "versus_m"):
            assert (built / f"figures/studies/{name}/{fig}.png").stat().st_size > 0
        assert f"Design study: {name}" in html
    assert "modified convention" in html and "standard convention" in html


def test_slurm_profile_dry_run(root, tmp_path):
    wd = _workdir(root, tmp_path)
    res = subprocess.run([str(SNAKEMAKE), "--workflow-profile", "workflow/profiles/slurm", "--configfile",
                          "config/test.yaml", "-n"], cwd=wd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-3000:]
    out = res.stdout + res.stderr
    assert "map_tile" in out and "slurm" in out.lower()


def test_rerun_gives_identical_tables(built):
    before = {p: p.read_bytes() for p in (built / "results").rglob("*.csv")}
    shutil.rmtree(built / "results")
    res = _snakemake(built, "--forcerun", "table2", "chi_map", "approximate_design", "map_tile")
    assert res.returncode == 0, res.stderr[-3000:]
    after = {p: p.read_bytes() for p in (built / "results").rglob("*.csv")}
    assert before.keys() == after.keys()
    assert all(before[p] == after[p] for p in before)


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
