# Shared names and parameter helpers for the rule files. Logic lives in src/stiffcal; this file only names
# paths and picks, for every rule, exactly the config values it uses (its `params:`), so that Snakemake
# reruns a job when, and only when, one of them changed (docs/workflow.md, "When a job reruns").
import dataclasses as _dc
import sys as _sys

from stiffcal.workflow.codeversion import code_version, remember_code_versions as _remember_code_versions
from stiffcal.errors import InputError as _InputError
from stiffcal.planning.maps import MAP_DEFAULTS as _MAP_DEFAULTS
from stiffcal.planning.maps import map_studies as _map_studies
from stiffcal.measured.measurements import ANGLE_RESOLUTION_DEG as _ANGLE_RESOLUTION_DEG
from stiffcal.measured.measurements import FORCE_RESOLUTION_N as _FORCE_RESOLUTION_N
from stiffcal.measured.measurements import MOMENT_RESOLUTION_NM as _MOMENT_RESOLUTION_NM
from stiffcal.model.robot import robot_inputs
from stiffcal.planning.study import DEFAULTS as _STUDY_DEFAULTS
from stiffcal.planning.study import DESIGN_KEYS as _DESIGN_KEYS
from stiffcal.planning.study import PROBLEM_KEYS as _PROBLEM_KEYS
from stiffcal.model.workcell import cell_inputs as _cell_inputs
from stiffcal.planning.study import design_studies as _design_studies

# code versions kept between runs (.snakemake/stiffcal/code-versions.json): no parsing of the package's source
# when it did not change (stiffcal.memo)
_remember_code_versions(_MEMO_DIR / "code-versions.json")

TABLES = "results/tables"
# the config as the run saw it (rule effective_config); its hash is the one the report shows
EFFECTIVE_CONFIG = "results/config.effective.yaml"
FIGURES = "figures"
LOGS = "logs"
PRINTED = config["paper_values"]
# the software of every rule, for --software-deployment-method conda (`make report` uses .venv instead)
ENV = "../envs/stiffcal.yaml"

# The paper's study (config `study`), defaults filled in.
STUDY = {**_STUDY_DEFAULTS, **config["study"]}
ROBOT = STUDY["robot"]
PLANS = {"m_max": 10, "pool_step_deg": None, **(config.get("plans") or {})}
SEED = config["seed"]


def study_params(*keys):
    """The values of config `study` that a rule uses (defaults filled in)."""
    return {k: STUDY[k] for k in keys}


# what every computation of the study's plans depends on: test pose, load, what is measured and how precisely
POSE_FORCE = _PROBLEM_KEYS

# Maps over test poses (Figures 6-10): the studies of config `maps`, each split into tiles (one job each).
try:
    MAP_STUDIES = {m.name: m for m in _map_studies(config, ".", CONFIG_SOURCE)}
    # Design studies (config `studies`), by name, defaults filled in; checked here so that a bad entry
    # stops the run before any job.
    STUDIES = {k: e for k, (_, e) in _design_studies(config, ".", CONFIG_SOURCE).items()}
except _InputError as _err:
    _sys.exit(f"stiffcal: error: {_err}")
MAPS = "results/maps"
MAP_FIGURES = {m.figure: m.name for m in MAP_STUDIES.values()}
MAP_SETTINGS = {**_MAP_DEFAULTS, **(config.get("maps") or {})}


def map_params(name):
    """One map study as the rule's parameters (name, link_ratio, figure, step_deg, force_deg, tile_cells)."""
    return _dc.asdict(MAP_STUDIES[name])


def map_tiles(name):
    """The tile files of a map study, one per `map_tile` job; none for a map of one tile (its `map_merge` job
    computes it)."""
    n = MAP_STUDIES[name].n_tiles
    return [f"{MAPS}/{name}/tiles/{tile}.npz" for tile in range(n)] if n > 1 else []


def map_report_inputs(wildcards):
    """The map statistics and Figures 6-10, when the config has map studies."""
    if not MAP_STUDIES:
        return {}
    return {"map_statistics": f"{TABLES}/map_statistics.csv",
            **{k: v.removesuffix(".png") + ".svg" for k, v in map_figure_outputs().items()}}


def map_figure_outputs():
    """fig<k> -> PNG of every map figure: Figures 7-10 of the config's map studies, Figure 6 with Figure 7."""
    figs = {f"fig{n}": f"{FIGURES}/fig{n}.png" for n in sorted(MAP_FIGURES)}
    if 7 in MAP_FIGURES:
        figs["fig6"] = f"{FIGURES}/fig6.png"
        figs["fig_map_pairs"] = f"{FIGURES}/fig_map_pairs.png"
    return figs


# Measured data sets (config `measured_data`), by name, defaults filled in.
MEASURED = {m["name"]: {"synthetic": False, "alpha": 0.01, "force_N": STUDY["force_N"],
                        "moment_Nm": STUDY["moment_Nm"], "angle_resolution_deg": _ANGLE_RESOLUTION_DEG,
                        "force_resolution_N": _FORCE_RESOLUTION_N,
                        "moment_resolution_Nm": _MOMENT_RESOLUTION_NM, **m}
            for m in config.get("measured_data") or []}


def discrepancy_report_inputs(wildcards):
    """verdict.json, the residual figure, plan.json and the plan figure of every measured data set."""
    out = {}
    for name in MEASURED:
        out[f"verdict__{name}"] = f"results/discrepancy/{name}/verdict.json"
        out[f"residuals__{name}"] = f"results/discrepancy/{name}/residuals.svg"
        out[f"heldout__{name}"] = f"results/discrepancy/{name}/heldout.svg"
        out[f"machining__{name}"] = f"results/discrepancy/{name}/machining.svg"
        out[f"plan__{name}"] = f"results/discrepancy/{name}/plan.json"
        out[f"planfig__{name}"] = f"results/discrepancy/{name}/plan.svg"
    return out


STUDY_DIR = "results/studies"


wildcard_constraints:
    name="[A-Za-z0-9_.-]+",
    m="[0-9]+",


def study_entry(wildcards):
    """The values of a design study's entry that its design and plans depend on (the keys of a study without a
    cell, its loads or candidates only when given, so that adding them to stiffcal reruns nothing)."""
    e = STUDIES[wildcards.name]
    return {k: e[k] for k in ("name", *_DESIGN_KEYS) if k in _PROBLEM_KEYS or e[k] is not None}


def study_files(wildcards):
    """The files a design study reads besides its robot file: its robot's URDF and SRDF, its cell file (and the
    SRDF it names), its candidate CSV; an edit of any reruns the study's jobs."""
    e = STUDIES[wildcards.name]
    return (robot_inputs(e["robot"], cell=e.get("cell") is not None) + _cell_inputs(e.get("cell"), ".")
            + ([e["candidates"]] if e.get("candidates") else []))


def report_inputs(wildcards):
    """Every file the report shows or reads, by name (the report rule's inputs; the archive verifies them)."""
    return {
        **map_report_inputs(wildcards), **discrepancy_report_inputs(wildcards), **study_report_inputs(wildcards),
        "table2": f"{TABLES}/table2.csv", "table3": f"{TABLES}/table3.csv",
        "comparison": f"{TABLES}/paper_comparison.csv", "validation": f"{TABLES}/validation.csv",
        "table4": f"{TABLES}/table4.csv", "table5": f"{TABLES}/table5.csv",
        "design": f"{TABLES}/approximate_design.csv", "certificate": f"{TABLES}/certificate.csv",
        "ot_versus_m": f"{TABLES}/ot_versus_m.csv",
        **{name: f"{FIGURES}/{name}.svg" for name in ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m")},
        "printed": PRINTED, "template": "paper/templates/report.html.j2", "css": "paper/templates/report.css",
    }


def report_figures(wildcards):
    """The SVG figures the HTML report embeds, and their PNG renditions, which the PDF prints instead (drawing
    an SVG is most of WeasyPrint's work; docs/workflow.md)."""
    svgs = sorted(v for v in report_inputs(wildcards).values() if v.endswith(".svg"))
    return {"svgs": svgs, "pngs": [v.removesuffix(".svg") + ".png" for v in svgs]}


def all_outputs(wildcards):
    """Every file the workflow makes (except the temporary map tiles), as inputs of the target all. Snakemake
    rebuilds a deleted intermediate only when something asks for it, so everything is asked for."""
    out = [v for k, v in report_inputs(wildcards).items() if k not in ("printed", "template", "css")]
    out += [f"{FIGURES}/{name}.{ext}" for name in ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m")
            for ext in ("png", "svg")]
    out += list(map_figure_outputs().values())
    out += ["results/maps/fig5_chi.csv", "results/design/approximate_design.json", "results/maps/design_phi.csv",
            EFFECTIVE_CONFIG]
    out += [f"{MAPS}/{name}/map.{ext}" for name in MAP_STUDIES for ext in ("csv", "npz")]
    if 7 in MAP_FIGURES:
        out += [f"{MAPS}/{MAP_FIGURES[7]}/pairs.{ext}" for ext in ("csv", "npz")]
        out += [f"{MAPS}/{MAP_FIGURES[7]}/grid_statistics.npz"]
    for name in MEASURED:
        out += [f"results/discrepancy/{name}/{f}" for f in ("verdict.json", "residuals.png", "residuals.svg",
                                                             "heldout.png", "heldout.svg", "machining.png",
                                                             "machining.svg", "calibrated.yaml",
                                                             "plan.json", "plan.png", "plan.svg")]
    for name in STUDIES:
        out += [f"{STUDY_DIR}/{name}/{f}" for f in ("approximate_design.json", "approximate_design.csv", "pool.npy",
                                                    "best_plans.csv")]
        out += [f"{FIGURES}/studies/{name}/{f}.png" for f in ("plan", "versus_m")]
    return sorted(set(out))


def study_report_inputs(wildcards):
    """Per design study: certificate, plans (long form), O_t against M and the two figures."""
    out = {}
    for name in STUDIES:
        out[f"studycert__{name}"] = f"{STUDY_DIR}/{name}/certificate.csv"
        out[f"studyplans__{name}"] = f"{STUDY_DIR}/{name}/plans.csv"
        out[f"studym__{name}"] = f"{STUDY_DIR}/{name}/versus_m.csv"
        out[f"studyfigplan__{name}"] = f"{FIGURES}/studies/{name}/plan.svg"
        out[f"studyfigm__{name}"] = f"{FIGURES}/studies/{name}/versus_m.svg"
    return out


def job_logs(files):
    """The log file of every job that makes one of ``files`` (the rule whose output matches, its wildcards
    applied), sorted: the logs of exactly this config's jobs, for the archive."""
    logs = set()
    for f in files:
        for r in workflow.rules:
            if r.name not in ("all", "archive") and any(o.match(f) for o in r.output):
                logs.update(str(x) for x in r.expand_log(r.get_wildcards(f)))
                break
    return sorted(logs)


def archive_files(wildcards):
    """What the archive packs besides the files the config refers to: every output of this config's workflow
    (the list `all` asks for), the report, and the logs of their jobs (map tiles included: temporary files,
    not packed, but their jobs' logs are)."""
    made = [*all_outputs(wildcards), "paper/build/report.html", "paper/build/report.pdf"]
    tiles = [t for name in MAP_STUDIES for t in map_tiles(name)]
    return sorted({*made, *job_logs(made + tiles)})
