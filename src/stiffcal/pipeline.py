"""One function per workflow step: paths in, files out. The Snakemake scripts only unpack
``snakemake.input/output/config`` and call these, so every step is testable without Snakemake and also
runs standalone (``python -m stiffcal.pipeline STEP ...`` is not needed: import and call).

Each step writes its outputs only after everything is computed, so a failure leaves no partial file.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from . import maps, plots, report, reproduction, tables
from .study import Study, study_from_config


def _study(config: dict) -> Study:
    return study_from_config(config, ".", "config/config.yaml")


def _read(path) -> pd.DataFrame:
    return pd.read_csv(path, keep_default_na=False, na_values=[""])


def _log(msg: str) -> None:
    print(f"[stiffcal {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def table2(config: dict, out_csv: str) -> None:
    """Table 2 for the study of ``config``."""
    study = _study(config)
    _log(f"Table 2: optimising {len(study.criteria)} criteria for {study.robot.name}")
    tables.write_csv(tables.table2(study), out_csv)


def table3(config: dict, table2_csv: str, out_csv: str) -> None:
    tables.write_csv(tables.table3(_study(config), _read(table2_csv)), out_csv)


def comparison(config: dict, table2_csv: str, table3_csv: str, table4_csv: str, table5_csv: str,
               printed_yaml: str, out_csv: str) -> None:
    """Every printed number of Tables 2-5 beside ours, with a status and a reason."""
    study = _study(config)
    printed = reproduction.load_printed(printed_yaml)
    parts = [reproduction.compare_tables(study, _read(table2_csv), _read(table3_csv), printed)]
    for name, path in (("table4", table4_csv), ("table5", table5_csv)):
        parts.append(reproduction.compare_plans(study, _read(path), printed[name], name,
                                                printed.get("explain", {}), seed=int(config["seed"])))
    cmp = pd.concat(parts, ignore_index=True)
    s = reproduction.summary(cmp)
    _log(f"paper comparison: {s['reproduced']} of {s['total']} printed numbers reproduced; reasons {s['reasons']}")
    tables.write_csv(cmp, out_csv)


def _optimal_poses(t2: pd.DataFrame, n: int) -> dict[str, np.ndarray]:
    cols = [f"q{i + 1}_deg" for i in range(n)]
    return {r["criterion"]: r[cols].to_numpy(float) for _, r in t2.iterrows() if not r["degenerate"]}


def validation(config: dict, table2_csv: str, out_csv: str) -> None:
    """Monte Carlo check of eqs. 11 and 16 on the O_t- and A-optimal single poses."""
    study = _study(config)
    poses = _optimal_poses(_read(table2_csv), study.robot.n_joints)
    plans = {f"{k}-optimal pose": poses[k][None, :] for k in ("ot", "a") if k in poses}
    df = tables.monte_carlo_check(study, plans, int(config["monte_carlo"]["samples"]), int(config["seed"]))
    tables.write_csv(df, out_csv)


def chi_map(config: dict, out_csv: str) -> None:
    tables.write_csv(tables.chi_map(_study(config)), out_csv)


def approximate_design(config: dict, out_json: str, out_support_csv: str, out_certificate_csv: str,
                       name: str | None = None) -> None:
    """The optimal approximate design for O_t and its certificate (one run serves every m), for the paper's
    study or, with ``name``, for the design study of that name."""
    import json

    from .certificate import approximate_design as compute

    study = _study(config) if name is None else _design_study(config, name)[0]
    _log(f"approximate design for {study.name} ({study.robot.n_joints} joints): multiplicative algorithm, "
         "polish, equivalence-theorem bound")
    step = config.get("plans", {}).get("pool_step_deg") if name is None else None
    d = compute(study.problem("ot"), pool_step_deg=step)
    _log(f"Phi = {d.phi:.9g}, bound Phi* >= {d.phi_lower:.9g}, equivalence gap {d.equivalence_gap:.2e}, "
         f"{len(d.weights)} support poses")
    tables.write_csv(tables.design_table(d), out_support_csv)
    tables.write_csv(tables.certificate_table(d, study.sigma), out_certificate_csv)
    Path(out_json).write_text(json.dumps({"support_deg": d.support_deg.tolist(), "weights": d.weights.tolist(),
                                          "phi": d.phi, "max_phi": d.max_phi, "phi_lower": d.phi_lower,
                                          "iterations": d.iterations}, indent=1) + "\n", encoding="utf-8")


def _design_study(config: dict, name: str):
    from .study import design_studies

    return design_studies(config, ".", "config/config.yaml")[name]


def study_plan(config: dict, name: str, m: int, design_json: str, out_csv: str) -> None:
    """One row of a design study: the best m-pose plan, its O_t, chi, bound and gap."""
    study, _ = _design_study(config, name)
    _log(f"{name}: best plan of {m} poses")
    row = tables.best_plan_row(study, m, int(config["seed"]), _design(design_json))
    _log(f"{name}: m = {m}, O_t = {row['O_t']:.6g} (RMS {row['rms_m']:.4g}), bound {row['lower_bound']:.6g}, "
         f"gap {100 * row['gap']:.2f} %, within limits: {row['within_limits']}")
    tables.write_csv(pd.DataFrame([row]), out_csv)


def study_plans(plan_csvs: list[str], out_csv: str) -> None:
    """The rows of every m, sorted by m."""
    tables.write_csv(pd.concat([_read(p) for p in plan_csvs]).sort_values("m", kind="stable"), out_csv)


def fig_study_plan(config: dict, name: str, plans_csv: str, out_png: str) -> None:
    study, entry = _design_study(config, name)
    df = _read(plans_csv).set_index("m")
    m = int(entry["draw_m"])
    plots.save(plots.fig_study_plan(study, tables.parse_plan(df.loc[m, "poses_deg"]), m), Path(out_png).with_suffix(""))


def fig_study_versus_m(config: dict, name: str, plans_csv: str, out_png: str) -> None:
    study, _ = _design_study(config, name)
    plots.save(plots.fig_study_versus_m(_read(plans_csv), study.sigma), Path(out_png).with_suffix(""))


def _design(path: str):
    import json

    from .certificate import ApproximateDesign

    d = json.loads(Path(path).read_text(encoding="utf-8"))
    return ApproximateDesign(np.array(d["support_deg"]), np.array(d["weights"]), d["phi"], d["max_phi"],
                             d["phi_lower"], d["iterations"])


def plans_table(config: dict, m: int, design_json: str, table2_csv: str, out_csv: str) -> None:
    """Table 4 (m = 2) or 5 (m = 3): the paper's plans (i)-(iv) with the certified bound."""
    study = _study(config)
    single = _optimal_poses(_read(table2_csv), study.robot.n_joints)["ot"]
    _log(f"plans (i)-(iv) of {m} poses")
    df = tables.plans_table(study, m, int(config["seed"]), _design(design_json), single)
    tables.write_csv(df, out_csv)


def ot_versus_m(config: dict, design_json: str, out_csv: str) -> None:
    """Best O_t against the number of poses, beside the bound."""
    study = _study(config)
    m_max = int(config.get("plans", {}).get("m_max", 10))
    _log(f"best plans for m = 1..{m_max}")
    tables.write_csv(tables.ot_versus_m(study, range(1, m_max + 1), int(config["seed"]), _design(design_json)),
                     out_csv)


def phi_map(config: dict, design_json: str, out_csv: str) -> None:
    tables.write_csv(tables.phi_map(_study(config), _design(design_json)), out_csv)


def fig_design(support_csv: str, phi_csv: str, out_png: str) -> None:
    plots.save(plots.fig_design(_read(support_csv), _read(phi_csv)), Path(out_png).with_suffix(""))


def fig_ot_versus_m(ot_m_csv: str, out_png: str) -> None:
    plots.save(plots.fig_ot_versus_m(_read(ot_m_csv)), Path(out_png).with_suffix(""))


def _map_study(config: dict, name: str) -> maps.MapStudy:
    by_name = {m.name: m for m in maps.map_studies(config, ".", "config/config.yaml")}
    return by_name[name]


def map_tile(config: dict, name: str, tile: int, out_npz: str) -> None:
    """One job of a map (Figures 6-10): the symmetry classes of tile ``tile``, every member cell written to
    a tile file (binary, layout in :mod:`stiffcal.maps`)."""
    st = _map_study(config, name)
    _log(f"map {name} (b = {st.link_ratio:.4g}, step {st.step_deg:g} deg): tile {tile + 1} of {st.n_tiles}")
    arrays = maps.map_tile(st.link_ratio, st.force_deg, st.step_deg, st.tile_cells, tile,
                           progress=maps.log_progress(f"map {name} tile {tile + 1}"))
    counts = np.bincount(arrays["status"], minlength=len(maps.STATUS))
    _log(f"map {name} tile {tile + 1}: " + ", ".join(f"{maps.STATUS[k]} {c}" for k, c in enumerate(counts) if c))
    maps.save_arrays(out_npz, arrays)


def map_merge(config: dict, name: str, tile_npzs: list[str], out_npz: str, out_csv: str) -> None:
    """results/maps/<study>/map.npz (for the other jobs) and map.csv (for users) from its tiles, checked
    complete."""
    st = _map_study(config, name)
    tiles = [maps.load_arrays(p, maps.TILE_ARRAYS) for p in tile_npzs]
    mp = maps.merge_tiles(tiles, st.link_ratio, st.force_deg, st.step_deg)
    _log(f"map {name}: {mp.O_t.size} cells, O_t in [{mp.O_t.min():.4g}, {mp.O_t.max():.4g}]")
    maps.save_map(out_npz, mp)
    tables.write_csv(maps.map_frame(mp), out_csv)


def map_statistics(config: dict, map_npzs: dict, printed_yaml: str, out_csv: str) -> None:
    """The statistics the paper quotes for Figure 6, ours beside theirs, and their grid dependence."""
    studies = maps.map_studies(config, ".", "config/config.yaml")
    steps = [float(s) for s in {**maps.MAP_DEFAULTS, **config["maps"]}["statistics_steps_deg"]]
    printed = {k: float(v) for k, v in reproduction.load_printed(printed_yaml).get("figure6", {}).items()}
    df = maps.statistics_table({n: maps.load_map(p) for n, p in map_npzs.items()}, studies, steps, printed)
    for _, r in df[df.statistic == "mean"].iterrows():
        _log(f"map {r.study}: mean chi {r.ours:.4g} on the {r.grid_deg:g} deg grid (paper: {r.paper})")
    tables.write_csv(df, out_csv)


def map_pairs(config: dict, name: str, out_npz: str, out_csv: str) -> None:
    """The best plan of two poses (case iv of Table 4) over the test poses of one map study, on the grid of
    ``maps.pairs_step_deg``: results/maps/<study>/pairs.npz and pairs.csv."""
    st = _map_study(config, name)
    step = float({**maps.MAP_DEFAULTS, **config["maps"]}["pairs_step_deg"])
    _log(f"map {name} (b = {st.link_ratio:.4g}): best plans of two poses on the {step:g} deg grid")
    pm = maps.pair_map(st.link_ratio, st.force_deg, step)
    g = pm.gain
    _log(f"map {name}: a designed pair beats the single optimum measured twice by up to {100 * g.max():.1f} %; "
         f"by more than 1 % on {100 * np.mean(g > 0.01):.0f} % of the test poses")
    maps.save_pair_map(out_npz, pm)
    tables.write_csv(maps.pair_frame(pm), out_csv)


def fig_map_pairs(pairs_npz: str, out_png: str) -> None:
    plots.save(plots.fig_map_pairs(maps.load_pair_map(pairs_npz)), Path(out_png).with_suffix(""))


def fig6(map_npz: str, out_png: str) -> None:
    plots.save(plots.fig6_inverse_chi(maps.load_map(map_npz)), Path(out_png).with_suffix(""))


def fig_map_poses(map_npz: str, figure: int, out_png: str) -> None:
    plots.save(plots.fig_optimal_poses(maps.load_map(map_npz), figure), Path(out_png).with_suffix(""))


def discrepancy(config: dict, name: str, out_verdict: str) -> None:
    """One measured data set: verdict.json and residuals.png/svg beside it (stiffcal discrepancy)."""
    from .discrepancy import run
    from .robot import load_robot

    entry = next(m for m in config["measured_data"] if m["name"] == name)
    study = _study(config)
    robot = load_robot(entry["robot"])
    force = np.asarray(entry.get("force_N", config["study"]["force_N"]), float)
    qt = study.test_pose if robot.n_joints == study.robot.n_joints else None
    label = f"{name} ({'SYNTHETIC data' if entry.get('synthetic') else entry['data']})"
    v = run(robot, entry["data"], str(Path(out_verdict).parent), float(entry.get("alpha", 0.01)), qt,
            force if qt is not None else None, label)
    _log(f"{name}: cause {v['cause']} (p = {v['p_value']:.3g}), indistinguishable from "
         f"{v['indistinguishable_from'] or 'none'}, outlier rows {v['outlier_rows']}")


def _optimal_set(t2: pd.DataFrame, key: str) -> np.ndarray:
    text = t2.set_index("criterion").loc[key, "optimal_set_deg"]
    return np.array([[float(v) for v in p.split()] for p in str(text).split(";")])


def fig3(table2_csv: str, out_png: str) -> None:
    plots.save(plots.fig3_accuracy(_read(table2_csv)), Path(out_png).with_suffix(""))


def fig4(config: dict, table2_csv: str, out_png: str) -> None:
    study = _study(config)
    pose = _optimal_poses(_read(table2_csv), study.robot.n_joints)["ot"]
    plots.save(plots.fig4_poses(study, pose), Path(out_png).with_suffix(""))


def fig5(table2_csv: str, chi_csv: str, out_png: str) -> None:
    t2 = _read(table2_csv)
    pose = _optimal_poses(t2, 2)["ot"]
    plots.save(plots.fig5_chi_map(_read(chi_csv), _optimal_set(t2, "ot"), pose), Path(out_png).with_suffix(""))


#: the rules behind each table and figure of the report (its provenance lines)
REPORT_RULES = {
    "table2": "table2", "table3": "table3", "table4": "plans_table (m = 2)", "table5": "plans_table (m = 3)",
    "design": "approximate_design", "ot_versus_m": "ot_versus_m", "comparison": "paper_comparison",
    "validation": "validation", "fig3": "fig3", "fig4": "fig4", "fig5": "chi_map + fig5",
    "fig_design": "approximate_design + phi_map + fig_design", "fig_ot_versus_m": "ot_versus_m + fig_ot_versus_m",
    "map_statistics": "map_tile + map_merge + map_statistics", "fig6": "map_tile + map_merge + fig6",
    "fig_map": "map_tile + map_merge + fig_map_poses", "fig_map_pairs": "map_pairs + fig_map_pairs",
    "discrepancy": "discrepancy",
    "study_design": "study_design", "study_plans": "study_design + study_plan + study_plans",
    "fig_study_plan": "study_plans + fig_study_plan", "fig_study_versus_m": "study_plans + fig_study_versus_m"}
REPORT_TABLES = ("table2", "table3", "table4", "table5", "design", "certificate", "ot_versus_m", "comparison",
                 "validation", "map_statistics")
REPORT_FIGURES = ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m", "fig6", "fig7", "fig8", "fig9", "fig10",
                  "fig_map_pairs")
STUDY_PARTS = ("studycert", "studyplans", "studyfigplan", "studyfigm")


def report_inputs(named: dict[str, str]) -> tuple[dict, dict, dict, dict]:
    """Sort the report rule's named inputs (``common.smk`` names them) into tables, figures (with the residual
    figures ``residuals__<data set>``), verdicts (``verdict__<data set>``) and design studies
    (``<part>__<study>`` for the parts of :data:`STUDY_PARTS`): name -> path each."""
    def prefixed(prefix):
        return {k.split("__", 1)[1]: v for k, v in named.items() if k.startswith(prefix + "__")}

    tables = {k: named[k] for k in REPORT_TABLES if k in named}
    figures = {k: named[k] for k in REPORT_FIGURES if k in named}
    figures |= {k: v for k, v in named.items() if k.startswith("residuals__")}
    parts = {part: prefixed(part) for part in STUDY_PARTS}
    studies = {name: {part: parts[part][name] for part in STUDY_PARTS} for name in parts["studyplans"]}
    return tables, figures, prefixed("verdict"), studies


def report_html_from_inputs(config: dict, named: dict[str, str], out_html: str) -> None:
    """The report rule: :func:`report_html` from the rule's named inputs (see :func:`report_inputs`)."""
    tables, figures, verdicts, studies = report_inputs(named)
    report_html(config, tables, figures, named["printed"], REPORT_RULES, str(Path(named["template"]).parent),
                out_html, verdicts, studies)


def report_html(config: dict, tables_in: dict, figures_in: dict, printed_yaml: str, rules: dict,
                template_dir: str, out_html: str, verdicts: dict | None = None, studies: dict | None = None) -> None:
    """Render the HTML report from the generated tables, figures, discrepancy verdicts and design studies
    (name -> paths of 'studycert', 'studyplans', 'studyfigplan', 'studyfigm')."""
    import json

    from .study import design_studies

    prov = {"commit": report.git_commit(), "config_hash": report.config_hash(config), **rules}
    ctx = report.build_context(config, tables_in, figures_in, printed_yaml, prov)
    ctx["verdicts"] = {k: json.loads(Path(v).read_text(encoding="utf-8")) for k, v in (verdicts or {}).items()}
    ctx["measured"] = {m["name"]: m for m in config.get("measured_data", [])}
    loaded = design_studies(config, ".", "config/config.yaml") if studies else {}
    ctx["studies"] = {name: report.study_context(*loaded[name], paths) for name, paths in (studies or {}).items()}
    html = report.render_html(ctx, template_dir)
    Path(out_html).parent.mkdir(parents=True, exist_ok=True)
    Path(out_html).write_text(html, encoding="utf-8")


def report_pdf(html: str, out_pdf: str) -> None:
    pages = report.write_pdf(html, out_pdf)
    _log(f"{out_pdf}: {pages} pages")


def archive(config: dict, started: str, out_tgz: str) -> None:
    """results/archive/stiffcal-<commit>.tar.gz: config, data, results, figures, logs and the report, with
    provenance.json and SHA256SUMS (``stiffcal verify-archive`` checks it)."""
    import datetime

    from . import archive as arc

    files = arc.archive_files(".")
    ended = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    prov = arc.provenance(report.config_hash(config), started, ended)
    arc.write_archive(out_tgz, files, prov)
    _log(f"{out_tgz}: {len(files)} files + provenance.json + SHA256SUMS (commit {prov['commit'][:12]}, "
         f"dirty: {prov['dirty']})")


def run(snakemake, step, *args) -> None:
    """Run one step from a Snakemake script, with its output in the rule's log.

    A bad input (:class:`InputError`) is one clear line on stderr and in the log, exit status 1. Any
    other failure is a bug: its traceback goes to the log and stderr names the log. Never a silent
    failure, never a traceback in place of a message for the user's own mistakes.
    """
    import contextlib
    import sys
    import traceback

    from .errors import InputError

    log = Path(snakemake.log[0]) if snakemake.log else None
    if log:
        log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "w", encoding="utf-8") if log else contextlib.nullcontext(sys.stdout) as fh:
        with contextlib.redirect_stdout(fh):
            try:
                step(*args)
            except InputError as err:
                print(f"stiffcal: error: {err}", file=fh)
                print(f"stiffcal: error: {err}", file=sys.stderr)
                sys.exit(1)
            except Exception as err:  # noqa: BLE001 - report any bug with its traceback in the log
                traceback.print_exc(file=fh)
                print(f"stiffcal: internal error in {step.__name__}: {type(err).__name__}: {err} "
                      f"(traceback in {log})", file=sys.stderr)
                sys.exit(1)
