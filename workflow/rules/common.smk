# Shared names for the rule files. Logic lives in src/stiffcal; this file only names paths.

TABLES = "results/tables"
FIGURES = "figures"
LOGS = "logs"
PRINTED = config["paper_values"]
# the software of every rule, for --software-deployment-method conda (`make report` uses .venv instead)
ENV = "../envs/stiffcal.yaml"
ROBOT = config["study"]["robot"]

# Maps over test poses (Figures 6-10): the studies of config `maps`, each split into tiles (one job each).
import sys as _sys

from stiffcal.errors import InputError as _InputError
from stiffcal.maps import map_studies as _map_studies

try:
    _cfg_files = getattr(workflow, "configfiles", None) or ["config/config.yaml"]
    MAP_STUDIES = {m.name: m for m in _map_studies(config, ".", str(_cfg_files[-1]))}
except _InputError as _err:
    _sys.exit(f"stiffcal: error: {_err}")
MAPS = "results/maps"
MAP_FIGURES = {m.figure: m.name for m in MAP_STUDIES.values()}


def map_report_inputs(wildcards):
    """The map statistics and Figures 6-10, when the config has map studies."""
    if not MAP_STUDIES:
        return {}
    figs = {f"fig{n}": f"{FIGURES}/fig{n}.png" for n in sorted(MAP_FIGURES)}
    if 7 in MAP_FIGURES:
        figs["fig6"] = f"{FIGURES}/fig6.png"
        figs["fig_map_pairs"] = f"{FIGURES}/fig_map_pairs.png"
        figs["map_pairs_table"] = f"{MAPS}/{MAP_FIGURES[7]}/pairs.csv"   # results for users, rebuilt with the report
    return {"map_statistics": f"{TABLES}/map_statistics.csv", **figs}

# Measured data sets (config `measured_data`), by name.
MEASURED = {m["name"]: m for m in config.get("measured_data", [])}


def discrepancy_report_inputs(wildcards):
    """verdict.json and the residual figure of every measured data set."""
    out = {}
    for name in MEASURED:
        out[f"verdict__{name}"] = f"results/discrepancy/{name}/verdict.json"
        out[f"residuals__{name}"] = f"results/discrepancy/{name}/residuals.png"
    return out

# Design studies (config `studies`), by name; validated here so that a bad entry stops the run at once.
from stiffcal.study import design_studies as _design_studies

try:
    STUDIES = {k: e for k, (_, e) in _design_studies(config, ".", str(_cfg_files[-1])).items()}
except _InputError as _err:
    _sys.exit(f"stiffcal: error: {_err}")
STUDY_DIR = "results/studies"


wildcard_constraints:
    name="[A-Za-z0-9_.-]+",
    m="[0-9]+",


def study_report_inputs(wildcards):
    """Per design study: certificate, plans table and the two figures."""
    out = {}
    for name in STUDIES:
        out[f"studycert__{name}"] = f"{STUDY_DIR}/{name}/certificate.csv"
        out[f"studyplans__{name}"] = f"{STUDY_DIR}/{name}/plans.csv"
        out[f"studyfigplan__{name}"] = f"{FIGURES}/studies/{name}/plan.png"
        out[f"studyfigm__{name}"] = f"{FIGURES}/studies/{name}/versus_m.png"
    return out
