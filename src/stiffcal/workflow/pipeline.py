"""One function per workflow step: parameters and paths in, files out. The Snakemake scripts only unpack
``snakemake.params/input/output`` and call these, so every step is testable without Snakemake.

Every step takes exactly the config values its rule declares in ``params:`` (never the whole config), so
that Snakemake reruns a job when, and only when, something it uses changed (docs/workflow.md). Modules
are imported inside the steps: a job loads only what it uses (a figure job never imports SciPy's
optimisers, a table job never imports matplotlib).

Each step writes its outputs only after everything is computed, so a failure leaves no partial file.
"""

from __future__ import annotations

import time
from pathlib import Path


def _study(p: dict, robot: str, where: str = "study"):
    """The :class:`~stiffcal.planning.study.Study` of a rule's study parameters (a subset of config ``study`` or an
    entry of ``studies``, defaults filled in; keys a study does not have, such as ``seed``, are ignored) and
    its robot file."""
    from ..planning.study import study_from_entry

    return study_from_entry({"name": "study", **p, "robot": robot}, ".", "config", where)


def _read(path):
    import pandas as pd

    return pd.read_csv(path, keep_default_na=False, na_values=[""])


def _write(df, path) -> None:
    from ..paper.tables import write_csv

    write_csv(df, path)


def _log(msg: str) -> None:
    print(f"[stiffcal {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def table2(p: dict, robot: str, out_csv: str) -> None:
    """Table 2 for the paper's study: p = test_pose_deg, force_N, sigma_m, criteria, search_step_deg."""
    from ..paper import tables

    study = _study(p, robot)
    _log(f"Table 2: optimising {len(study.criteria)} criteria for {study.robot.name}")
    _write(tables.table2(study), out_csv)


def table3(p: dict, robot: str, table2_csv: str, out_csv: str) -> None:
    """Table 3: p = test_pose_deg, force_N, sigma_m."""
    from ..paper import tables

    _write(tables.table3(_study(p, robot), _read(table2_csv)), out_csv)


def comparison(p: dict, robot: str, table2_csv: str, table3_csv: str, table4_csv: str, table5_csv: str,
               printed_yaml: str, out_csv: str, figure6_stats_npz: str | None = None) -> None:
    """Every result number the paper prints (Tables 2-5 and its text) beside ours, with a status and a
    reason. p = the study's test_pose_deg, force_N, sigma_m, seed and ``figure6`` (the map study of Figure 7
    and statistics_steps_deg, or None): the Figure 6 numbers of the text are that map's statistics
    (``figure6_stats_npz``, :func:`map_grid_statistics`: of that one map, so that editing another map does not
    rerun this)."""
    from ..planning import maps
    from ..paper import reproduction

    study = _study({k: v for k, v in p.items() if k != "figure6"}, robot)
    stats = None
    if figure6_stats_npz and p.get("figure6"):
        f6 = dict(p["figure6"])
        steps = f6.pop("statistics_steps_deg")
        st = _map_study(f6)
        printed = {k: float(v) for k, v in reproduction.load_printed(printed_yaml).get("figure6", {}).items()}
        stats = maps.statistics_table({}, [st], steps, printed,
                                      {st.name: maps.load_grid_statistics(figure6_stats_npz)})
    cmp = reproduction.comparison_table(study, *(_read(f) for f in (table2_csv, table3_csv, table4_csv, table5_csv)),
                                        reproduction.load_printed(printed_yaml), stats, seed=int(p["seed"]))
    s = reproduction.summary(cmp)
    _log(f"paper comparison: {s['reproduced']} of {s['total']} printed numbers reproduced; reasons {s['reasons']}")
    _write(cmp, out_csv)


def _optimal_poses(t2, robot) -> dict:
    cols = robot.joint_columns("q", "_deg")
    return {r["criterion"]: r[cols].to_numpy(float) for _, r in t2.iterrows() if not r["degenerate"]}


def validation(p: dict, robot: str, table2_csv: str, out_csv: str) -> None:
    """Monte Carlo check of eqs. 11 and 16 on the O_t- and A-optimal single poses; p = test_pose_deg,
    force_N, sigma_m, samples, seed."""
    from ..paper import tables

    study = _study(p, robot)
    poses = _optimal_poses(_read(table2_csv), study.robot)
    plans = {f"{k}-optimal pose": poses[k][None, :] for k in ("ot", "a") if k in poses}
    _write(tables.monte_carlo_check(study, plans, int(p["samples"]), int(p["seed"])), out_csv)


def chi_map(p: dict, robot: str, out_csv: str) -> None:
    """chi over the measurement-pose plane (Figure 5); p = test_pose_deg, force_N, sigma_m, fig5_step_deg."""
    from ..paper import tables

    _write(tables.chi_map(_study(p, robot)), out_csv)


def approximate_design(p: dict, robot: str, out_json: str, out_support_csv: str, out_certificate_csv: str,
                       out_phi_csv: str | None = None, name: str | None = None,
                       out_pool_npy: str | None = None) -> None:
    """The optimal approximate design for O_t and its certificate (one run serves every m), for the paper's
    study (p = test_pose_deg, force_N, sigma_m, pool_step_deg; also the phi map of the design figure) or,
    with ``name``, for the design study of that name (p = its entry). ``out_pool_npy``: also the candidate pool
    of the plans (:func:`stiffcal.planning.certificate.candidate_pool` at the default step, the pool
    :func:`stiffcal.planning.plans.optimise_plan` builds), for the study's plans job (:func:`study_plans`), which then
    does not build it again."""
    import json

    from ..paper import tables
    from ..planning.certificate import approximate_design as compute
    from ..integrity import atomic_write

    from ..planning.certificate import unconstrained

    study = _study(p, robot, "study" if name is None else f"studies.{name}")
    if out_pool_npy:
        _save_pool(out_pool_npy, study)
    _log(f"approximate design for {name or 'the paper study'} ({study.robot.n_joints} joints): multiplicative "
         "algorithm, polish, equivalence-theorem bound")
    d = compute(study.problem("ot"), pool_step_deg=p.get("pool_step_deg"))
    continuum = None
    if study.robot.cell is not None and study.candidates is None:
        _log(f"the cell: {study.robot.cell.describe()}; the design over its feasible candidates, and without it")
        continuum = compute(unconstrained(study.problem("ot")), pool_step_deg=p.get("pool_step_deg"))
    for dd in (continuum, d):
        if dd is not None:
            _log(f"{dd.region}: Phi = {dd.phi:.9g}, bound Phi* >= {dd.phi_lower:.9g}, equivalence gap "
                 f"{dd.equivalence_gap:.2e}, {len(dd.weights)} support poses")
    phi = tables.phi_map(study, d) if out_phi_csv else None
    _write(tables.design_table(d, study.robot), out_support_csv)
    _write(tables.certificate_table(d, study.sigma, continuum), out_certificate_csv)
    if phi is not None:
        _write(phi, out_phi_csv)
    doc = _design_doc(d)
    if continuum is not None:
        doc["continuum"] = _design_doc(continuum)
    atomic_write(out_json, json.dumps(doc, indent=1, allow_nan=False) + "\n")


def _design_doc(d) -> dict:
    """An approximate design as the JSON of approximate_design.json (read back by :func:`_design`)."""
    doc = {"support_deg": d.support_deg.tolist(), "weights": d.weights.tolist(), "phi": d.phi, "max_phi": d.max_phi,
           "phi_lower": d.phi_lower, "iterations": d.iterations}
    if d.region != "joint space":
        doc |= {"region": d.region, "n_candidates": d.n_candidates}
    if d.near_singular:
        doc["near_singular"] = True
    return doc


def _save_pool(path: str, study) -> None:
    """The candidate pool of the study's plans (N, n) [rad] as one .npy file (exact float64)."""
    import io

    import numpy as np

    from ..planning.certificate import candidate_pool, default_pool_step
    from ..integrity import atomic_write

    robot = study.robot
    buf = io.BytesIO()
    np.save(buf, candidate_pool(robot, default_pool_step(robot.n_joints), study.problem("ot")), allow_pickle=False)
    atomic_write(path, buf.getvalue())


def _pool(path: str, n_joints: int):
    """The candidate pool written by :func:`_save_pool`; InputError naming the file when it is not one."""
    import numpy as np

    from ..errors import InputError

    try:
        pool = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise InputError(f"expected a candidate pool (.npy), could not read it: {err}", source=path) from None
    if pool.ndim != 2 or pool.shape[1] != n_joints or not np.isfinite(pool).all():
        raise InputError(f"expected a candidate pool of finite poses (N, {n_joints}), got shape {pool.shape}",
                         source=path)
    return pool


def _design(path: str, part: str | None = None):
    """The approximate design of approximate_design.json (``part`` 'continuum': the design without the cell, or
    None when the file has none)."""
    import json

    import numpy as np

    from ..planning.certificate import ApproximateDesign

    d = json.loads(Path(path).read_text(encoding="utf-8"))
    if part is not None:
        d = d.get(part)
        if d is None:
            return None
    return ApproximateDesign(np.array(d["support_deg"]), np.array(d["weights"]), d["phi"], d["max_phi"],
                             d["phi_lower"], d["iterations"], d.get("region", "joint space"), d.get("n_candidates", 0),
                             d.get("near_singular", False))


def study_plans(p: dict, robot: str, m_values: list[int], seed: int, design_json: str, pool_npy: str,
                out_csv: str) -> None:
    """A design study's best plan for every M of ``m_values``, one row each (sorted by M): its O_t, chi, bound,
    gap and poses (:func:`stiffcal.paper.tables.best_plan_row`); p = the study's entry. One job for every M: the
    design and the candidate pool (pool_npy, written by the study's design job) are read once."""
    import pandas as pd

    from ..model.workcell import test_pose_note
    from ..paper import tables

    study = _study(p, robot, f"studies.{p['name']}")
    design, continuum = _design(design_json), _design(design_json, "continuum")
    pool = _pool(pool_npy, study.robot.n_joints)
    for note in test_pose_note(study.robot, study.problem("ot"), study.test_pose):
        _log(f"{p['name']}: note: {note}")
    rows = []
    for m in sorted(int(m) for m in m_values):
        _log(f"{p['name']}: best plan of {m} poses")
        row = tables.study_plan_row(study, m, seed, design, pool, continuum)
        _log(f"{p['name']}: m = {m}, O_t = {row['O_t']:.6g} (RMS {row['rms_m']:.4g}), bound "
             f"{row['lower_bound']:.6g}, gap {100 * row['gap']:.2f} %, within limits: {row['within_limits']}"
             + (f", feasible: {row['feasible']}, smallest clearance {row['min_clearance_m']:.4f} m"
                if "feasible" in row else ""))
        rows.append(row)
    _write(pd.DataFrame(rows), out_csv)


def study_summary(p: dict, robot: str, plans_csv: str, out_versus_m_csv: str, out_plans_csv: str,
                  out_plan_png: str, out_versus_m_png: str) -> None:
    """A design study's best plans of every M: versus_m.csv (one row per M: O_t, RMS, chi, bound, gap,
    E[dk_i^2], within limits), plans.csv (long form: plan, m, pose, q1_deg..qn_deg), the plan of ``draw_m``
    drawn in 3-D and O_t and chi against M. p = the study's entry with draw_m; plans_csv: the rows of
    :func:`study_plans`."""
    from ..report import plots
    from ..paper import tables

    study = _study(p, robot, f"studies.{p['name']}")
    df = _read(plans_csv)
    plans = {("best", int(r.m)): tables.parse_plan(r.poses_deg) for r in df.itertuples()}
    clear = None
    if "clearance_m" in df.columns:  # a robot in a cell: each pose's smallest distance, from the plans job
        clear = {("best", int(r.m)): ([float(v) for v in str(r.clearance_m).split()], str(r.closest).split(";"))
                 for r in df.itertuples()}
    m = int(p["draw_m"])
    fig_plan = plots.fig_study_plan(study, plans[("best", m)], m, None if clear is None else clear[("best", m)][0])
    fig_m = plots.fig_study_versus_m(df, study.sigma)
    _write(df.drop(columns=[c for c in ("poses_deg", "clearance_m", "closest") if c in df.columns]), out_versus_m_csv)
    _write(tables.plans_long(plans, study.robot, clear), out_plans_csv)
    plots.save(fig_plan, Path(out_plan_png).with_suffix(""))
    plots.save(fig_m, Path(out_versus_m_png).with_suffix(""))


def plans_table(p: dict, robot: str, m: int, design_json: str, table2_csv: str, out_csv: str) -> None:
    """Table 4 (m = 2) or 5 (m = 3): the paper's plans (i)-(iv) with the certified bound; p = test_pose_deg,
    force_N, sigma_m, seed."""
    from ..paper import tables

    study = _study(p, robot)
    single = _optimal_poses(_read(table2_csv), study.robot)["ot"]
    _log(f"plans (i)-(iv) of {m} poses")
    _write(tables.plans_table(study, m, int(p["seed"]), _design(design_json), single), out_csv)


def ot_versus_m(p: dict, robot: str, design_json: str, out_csv: str) -> None:
    """Best O_t against the number of poses, beside the bound; p = test_pose_deg, force_N, sigma_m,
    search_step_deg, m_max, seed."""
    from ..paper import tables

    study = _study(p, robot)
    m_max = int(p["m_max"])
    _log(f"best plans for m = 1..{m_max}")
    _write(tables.ot_versus_m(study, range(1, m_max + 1), int(p["seed"]), _design(design_json)), out_csv)


def paper_figures(p: dict, robot: str, table2_csv: str, chi_csv: str, support_csv: str, phi_csv: str,
                  ot_m_csv: str, out_pngs: dict) -> None:
    """Figures 3-5, the approximate design over the equivalence-theorem map and O_t against m, in one job
    (each is a fraction of a second: one start-up for five); p = test_pose_deg, force_N.
    out_pngs: figure name (fig3, fig4, fig5, fig_design, fig_ot_versus_m) -> PNG path (the SVG beside it)."""
    import numpy as np

    from ..report import plots

    study = _study(p, robot)
    t2 = _read(table2_csv)
    pose = _optimal_poses(t2, study.robot)["ot"]
    opt_set = t2.set_index("criterion").loc["ot", "optimal_set_deg"]
    opt_set = np.array([[float(v) for v in q.split()] for q in str(opt_set).split(";")])
    figs = {"fig3": lambda: plots.fig3_accuracy(t2), "fig4": lambda: plots.fig4_poses(study, pose),
            "fig5": lambda: plots.fig5_chi_map(_read(chi_csv), opt_set, pose),
            "fig_design": lambda: plots.fig_design(_read(support_csv), _read(phi_csv)),
            "fig_ot_versus_m": lambda: plots.fig_ot_versus_m(_read(ot_m_csv))}
    for name, make in figs.items():
        plots.save(make(), Path(out_pngs[name]).with_suffix(""))


def _map_study(p: dict):
    from ..planning.maps import MapStudy

    return MapStudy(**p)


def map_tile(p: dict, tile: int, out_npz: str) -> None:
    """One job of a map (Figures 6-10): the symmetry classes of tile ``tile``, every member cell written to a
    tile file (binary, layout in :mod:`stiffcal.planning.maps`); p = name, link_ratio, figure, step_deg, force_deg,
    tile_cells. Used when the map has more than one tile (:func:`map_merge` computes a map of one tile)."""
    from ..planning import maps

    maps.save_arrays(out_npz, _map_tile_arrays(_map_study(p), tile))


def _map_tile_arrays(st, tile: int) -> dict:
    """The arrays of tile ``tile`` of the map study ``st`` (:func:`stiffcal.planning.maps.map_tile`), logged."""
    import numpy as np

    from ..planning import maps

    _log(f"map {st.name} (b = {st.link_ratio:.4g}, step {st.step_deg:g} deg): tile {tile + 1} of {st.n_tiles}")
    arrays = maps.map_tile(st.link_ratio, st.force_deg, st.step_deg, st.tile_cells, tile,
                           progress=maps.log_progress(f"map {st.name} tile {tile + 1}"))
    counts = np.bincount(arrays["status"], minlength=len(maps.STATUS))
    _log(f"map {st.name} tile {tile + 1}: "
         + ", ".join(f"{maps.STATUS[k]} {c}" for k, c in enumerate(counts) if c))
    return arrays


def map_merge(p: dict, tile_npzs: list[str], out_npz: str, out_csv: str) -> None:
    """results/maps/<study>/map.npz (for the other jobs) and map.csv (for users) from its tiles, checked
    complete; p = the map study. A map of one tile is computed here (``tile_npzs`` empty): one job instead of
    a tile job, its tile file and this job."""
    from ..planning import maps
    from ..csvtext import write_numeric_csv

    st = _map_study(p)
    if tile_npzs:
        tiles = [maps.load_arrays(f, maps.TILE_ARRAYS) for f in tile_npzs]
    elif st.n_tiles == 1:
        tiles = [_map_tile_arrays(st, 0)]
    else:
        raise ValueError(f"map {st.name} has {st.n_tiles} tiles and none was given")
    mp = maps.merge_tiles(tiles, st.link_ratio, st.force_deg, st.step_deg)
    _log(f"map {st.name}: {mp.O_t.size} cells, O_t in [{mp.O_t.min():.4g}, {mp.O_t.max():.4g}]")
    maps.save_map(out_npz, mp)
    write_numeric_csv(maps.map_columns(mp), out_csv)  # no pandas in the map jobs


def map_grid_statistics(p: dict, map_npz: str, out_npz: str) -> None:
    """The statistics of the map of Figure 7 on its grid and on every grid of ``statistics_steps_deg``
    (:func:`stiffcal.planning.maps.grid_statistics`; a finer grid is solved), for :func:`map_statistics` and
    :func:`comparison`, which both show them (one solve instead of two); p = the map study and
    statistics_steps_deg."""
    from ..planning import maps

    p = dict(p)
    steps = [float(s) for s in p.pop("statistics_steps_deg")]
    st = _map_study(p)
    maps.save_grid_statistics(out_npz, maps.grid_statistics(maps.load_map(map_npz), st, steps))


def map_statistics(p: dict, map_npzs: dict, printed_yaml: str, out_csv: str, grid_npz: str | None = None) -> None:
    """The statistics the paper quotes for Figure 6, ours beside theirs, and their grid dependence;
    p = studies (the map studies), statistics_steps_deg; grid_npz: those of the Figure-7 study on every grid
    (:func:`map_grid_statistics`)."""
    from ..planning import maps
    from ..paper import reproduction

    studies = [_map_study(s) for s in p["studies"]]
    steps = [float(s) for s in p["statistics_steps_deg"]]
    printed = {k: float(v) for k, v in reproduction.load_printed(printed_yaml).get("figure6", {}).items()}
    grid = {st.name: maps.load_grid_statistics(grid_npz) for st in studies if st.figure == 7} if grid_npz else None
    loaded = {n: maps.load_map(f) for n, f in map_npzs.items() if not (grid and n in grid)}
    df = maps.statistics_table(loaded, studies, steps, printed, grid)
    for _, r in df[df.statistic == "mean"].iterrows():
        _log(f"map {r.study}: mean chi {r.ours:.4g} on the {r.grid_deg:g} deg grid (paper: {r.paper})")
    _write(df, out_csv)


def map_pairs(p: dict, out_npz: str, out_csv: str) -> None:
    """The best plan of two poses (case iv of Table 4) over the test poses of one map study, on the grid of
    ``maps.pairs_step_deg``: results/maps/<study>/pairs.npz and pairs.csv; p = name, link_ratio, force_deg and
    pairs_step_deg of the map study (what the pairs depend on)."""
    import numpy as np

    from ..planning import maps
    from ..csvtext import write_numeric_csv

    name, b, step = p["name"], float(p["link_ratio"]), float(p["pairs_step_deg"])
    _log(f"map {name} (b = {b:.4g}): best plans of two poses on the {step:g} deg grid")
    pm = maps.pair_map(b, float(p["force_deg"]), step)
    g = pm.gain
    _log(f"map {name}: a designed pair beats the single optimum measured twice by up to {100 * g.max():.1f} %; "
         f"by more than 1 % on {100 * np.mean(g > 0.01):.0f} % of the test poses")
    maps.save_pair_map(out_npz, pm)
    write_numeric_csv(maps.pair_columns(pm), out_csv)


def map_figures(maps_by_figure: dict, out_pngs: dict, pairs_npz: str | None = None) -> None:
    """Figure 6 (1/chi, from the map of Figure 7), Figures 7-10 (optimal poses) and, with ``pairs_npz``, the
    map of the best two-pose plans, in one job. maps_by_figure: figure number -> map.npz; out_pngs: 'fig<k>'
    (and 'fig_map_pairs') -> PNG path (the SVG beside it)."""
    from ..planning import maps
    from ..report import plots

    frames = {int(k): maps.load_map(v) for k, v in maps_by_figure.items()}
    for name, png in out_pngs.items():
        if name == "fig_map_pairs":
            fig = plots.fig_map_pairs(maps.load_pair_map(pairs_npz))
        else:
            k = int(name.removeprefix("fig"))
            fig = plots.fig6_inverse_chi(frames[7]) if k == 6 else plots.fig_optimal_poses(frames[k], k)
        plots.save(fig, Path(png).with_suffix(""))


def _test_pose_rad(p: dict, robot):
    """A data set's test pose [rad]: its own ``test_pose_deg``, else the study's (``study_test_pose_deg``) when the
    data set's robot has as many joints, else None (the gain's test-pose figures are then left out). Here, not in
    :mod:`stiffcal.workflow.config`, whose imports (the maps, the studies) would make every measured-data job rerun
    after an edit of them."""
    import numpy as np

    pose = p.get("test_pose_deg")
    if pose is None and len(p["study_test_pose_deg"]) == robot.n_joints:
        pose = p["study_test_pose_deg"]
    return None if pose is None else np.radians(np.asarray(pose, float))


def discrepancy(p: dict, out_verdict: str) -> None:
    """One measured data set: verdict.json, residuals, heldout and machining .png/.svg and calibrated.yaml beside it
    (stiffcal discrepancy).
    p = the data set's entry (name, data, robot, synthetic, force_N, moment_Nm, alpha, angle_resolution_deg,
    force_resolution_N, moment_resolution_Nm, sigma_m, sigma_rad, test_pose_deg) and the study's test pose
    (``study_test_pose_deg``: the default of the data set's, :func:`_test_pose_rad`)."""
    import numpy as np

    from ..measured.discrepancy import run
    from ..model.robot import load_robot

    robot = load_robot(p["robot"])
    qt = _test_pose_rad(p, robot)
    load = p["force_N"] + list(p.get("moment_Nm") or [])
    force = np.asarray(load, float) if qt is not None else None
    if qt is None:
        _log(f"{p['name']}: note: no test pose for this data set (its robot has another number of joints than the "
             "study's): the gain's test-pose figures are left out; give measured_data[].test_pose_deg")
    label = f"{p['name']} ({'SYNTHETIC data' if p.get('synthetic') else p['data']})"
    v = run(robot, p["data"], str(Path(out_verdict).parent), float(p["alpha"]), qt, force, label,
            p.get("angle_resolution_deg"), p.get("force_resolution_N"), p.get("moment_resolution_Nm"),
            p.get("sigma_m"), p.get("sigma_rad"))
    _log(f"{p['name']}: cause {v['cause']} (causes {v['causes']}, p = {v['p_value']:.3g}), indistinguishable from "
         f"{v['indistinguishable_from'] or 'none'}, outlier rows {v['outlier_rows']}")
    for note in v["notes"]:
        _log(f"{p['name']}: note: {note}")


#: settings of the next experiment of a measured data set (config ``measured_data[].discriminate``)
DISCRIMINATE_DEFAULTS = {"experiments": 6, "loads": None, "repeats": 1, "weight": 0.5, "truth": "best", "seed": 0}


def discriminate(p: dict, out_plan: str) -> None:
    """One measured data set: plan.json and plan.png/svg beside it (stiffcal discriminate). p = the data set's
    entry (name, data, robot, synthetic, alpha, resolutions, ``discriminate`` settings, test_pose_deg), its force_N
    and the study's test pose (``study_test_pose_deg``: :func:`_test_pose_rad`)."""
    import numpy as np

    from ..measured.discrimination import run
    from ..model.robot import load_robot

    robot = load_robot(p["robot"])
    s = {**DISCRIMINATE_DEFAULTS, **p.get("discriminate", {})}
    qt = _test_pose_rad(p, robot)
    force = np.asarray(p["force_N"], float) if qt is not None else None
    label = f"{p['name']} ({'SYNTHETIC data' if p.get('synthetic') else p['data']})"
    out = run(robot, p["data"], str(Path(out_plan).parent), int(s["experiments"]), s["loads"], int(s["repeats"]),
              float(s["weight"]), s["truth"], float(p.get("alpha", 0.01)), qt, force, p.get("angle_resolution_deg"),
              p.get("force_resolution_N"), int(s["seed"]), label)
    plan = out["plan"] or {}
    _log(f"{p['name']}: truth {out['models'][0]['causes']}, rivals {[m['causes'] for m in out['models'][1:]]}, "
         f"separable {out['separable']}, power {plan.get('power')}, efficiency "
         f"{(plan.get('certificate') or {}).get('efficiency')}")
    for note in out["notes"]:
        _log(f"{p['name']}: note: {note}")


#: the rules behind each table and figure of the report (its provenance lines)
REPORT_RULES = {
    "table2": "table2", "table3": "table3", "table4": "plans_table (m = 2)", "table5": "plans_table (m = 3)",
    "design": "approximate_design", "ot_versus_m": "ot_versus_m", "comparison": "paper_comparison",
    "validation": "validation", "fig3": "paper_figures", "fig4": "paper_figures", "fig5": "chi_map + paper_figures",
    "fig_design": "approximate_design + paper_figures", "fig_ot_versus_m": "ot_versus_m + paper_figures",
    "map_statistics": "map_tile + map_merge + map_statistics", "fig6": "map_tile + map_merge + map_figures",
    "fig_map": "map_tile + map_merge + map_figures", "fig_map_pairs": "map_pairs + map_figures",
    "discrepancy": "discrepancy", "discriminate": "discriminate",
    "study_design": "study_design", "study_plans": "study_design + study_plans + study_summary",
    "fig_study_plan": "study_plans + study_summary", "fig_study_versus_m": "study_plans + study_summary"}
REPORT_TABLES = ("table2", "table3", "table4", "table5", "design", "certificate", "ot_versus_m", "comparison",
                 "validation", "map_statistics")
REPORT_FIGURES = ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m", "fig6", "fig7", "fig8", "fig9", "fig10",
                  "fig_map_pairs")
STUDY_PARTS = ("studycert", "studyplans", "studym", "studyfigplan", "studyfigm")


def report_inputs(named: dict[str, str]) -> tuple[dict, dict, dict, dict]:
    """Sort the report rule's named inputs (``common.smk`` names them) into tables, figures (with the residual
    figures ``residuals__<data set>``), verdicts (``verdict__<data set>``) and design studies
    (``<part>__<study>`` for the parts of :data:`STUDY_PARTS`): name -> path each."""
    def prefixed(prefix):
        return {k.split("__", 1)[1]: v for k, v in named.items() if k.startswith(prefix + "__")}

    tables = {k: named[k] for k in REPORT_TABLES if k in named}
    figures = {k: named[k] for k in REPORT_FIGURES if k in named}
    figures |= {k: v for k, v in named.items()
                if k.startswith(("residuals__", "heldout__", "machining__", "planfig__"))}
    parts = {part: prefixed(part) for part in STUDY_PARTS}
    studies = {name: {part: parts[part][name] for part in STUDY_PARTS} for name in parts["studyplans"]}
    return tables, figures, prefixed("verdict"), studies


def report_html_from_inputs(config: dict, named: dict[str, str], out_html: str) -> None:
    """The report rule: :func:`report_html` from the rule's named inputs (see :func:`report_inputs`). The config
    file is named by its hash, not its path: the same config given back as another file (a reviewer's
    ``--configfile results/config.effective.yaml``) reruns nothing."""
    tables, figures, verdicts, studies = report_inputs(named)
    plans = {k.split("__", 1)[1]: v for k, v in named.items() if k.startswith("plan__")}
    report_html(config, tables, figures, named["printed"], REPORT_RULES, str(Path(named["template"]).parent),
                out_html, verdicts, studies, plans)


def report_html(config: dict, tables_in: dict, figures_in: dict, printed_yaml: str, rules: dict,
                template_dir: str, out_html: str, verdicts: dict | None = None, studies: dict | None = None,
                plans: dict | None = None) -> None:
    """Render the HTML report from the generated tables, figures, discrepancy verdicts, design studies
    (name -> paths of 'studycert', 'studyplans', 'studyfigplan', 'studyfigm') and next experiments (data set
    name -> plan.json). Its provenance (:func:`stiffcal.workflow.archive.run_status`): the commit, '-dirty' when a
    file the config names is untracked or modified, those files, and the libraries."""
    import json

    from ..report import html as report
    from .archive import run_status
    from ..planning.study import design_studies

    prov = {**run_status(config, "."), "config_hash": report.config_hash(config), **rules}
    ctx = report.build_context(config, tables_in, figures_in, printed_yaml, prov)
    ctx["verdicts"] = {k: json.loads(Path(v).read_text(encoding="utf-8")) for k, v in (verdicts or {}).items()}
    ctx["measured"] = {m["name"]: m for m in config.get("measured_data", [])}
    ctx["plans"] = {k: json.loads(Path(v).read_text(encoding="utf-8")) for k, v in (plans or {}).items()}
    loaded = design_studies(config, ".", "the workflow's config (--configfile)") if studies else {}
    ctx["studies"] = {name: report.study_context(*loaded[name], paths) for name, paths in (studies or {}).items()}
    html = report.render_html(ctx, template_dir)
    from ..integrity import atomic_write

    atomic_write(out_html, html)


def report_pdf(html: str, out_pdf: str, svgs: list[str] = ()) -> None:
    """The PDF of the HTML report; every figure of ``svgs`` (SVG embedded in the HTML) printed from the PNG
    beside it (:func:`stiffcal.report.html.write_pdf`)."""
    from ..report import html as report

    pages = report.write_pdf(html, out_pdf, report.print_images(svgs))
    _log(f"{out_pdf}: {pages} pages")


def effective_config(config: dict, out: str) -> None:
    """results/config.effective.yaml: the config as the run saw it (after ``--configfile`` and ``--config``),
    as sorted YAML, without the keys whose default is none (the schema takes no null): given back as
    ``--configfile`` it is that config again (:func:`stiffcal.workflow.config.workflow_config` sorts its keys), whose
    :func:`stiffcal.report.html.config_hash` the report and provenance.json show (the first line says so), and the
    rules' parameters are unchanged, so nothing reruns."""
    import yaml

    from ..report import html as report
    from ..integrity import atomic_write

    def written(doc):
        if isinstance(doc, dict):
            return {k: written(v) for k, v in doc.items() if v is not None}
        return [written(v) for v in doc] if isinstance(doc, list) else doc

    text = yaml.safe_dump(written(config), sort_keys=True, default_flow_style=False, allow_unicode=True)
    atomic_write(out, f"# the config this run used; config hash {report.config_hash(config)} (report, "
                      f"provenance.json)\n{text}")


def archive(config: dict, out_tgz: str, files: list[str], config_source: str | None = None) -> None:
    """results/archive/stiffcal-<commit>.tar.gz: the files of this config's run (``files``: its outputs, the
    logs of their jobs, the report, the effective config) and every file the config refers to
    (:func:`stiffcal.workflow.archive.config_files`), with provenance.json and SHA256SUMS (``stiffcal verify-archive``
    checks it). provenance.json names every input git does not vouch for (``config_source``, the config file the
    run read, and the files the config names; :func:`stiffcal.workflow.archive.input_status`), and the start and end of
    this archiving job (not a parameter of the rule: a start time among its params made every run rebuild the archive,
    `snakemake -n` never up to date)."""
    import datetime

    from . import archive as arc
    from ..report import html as report

    started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    inputs = arc.config_files(config, ".")
    members = sorted({*map(Path, files), *inputs}, key=lambda p: p.as_posix())
    ended = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    prov = arc.provenance(report.config_hash(config), started, ended, ".",
                          [*inputs, *([config_source] if config_source else [])])
    arc.write_archive(out_tgz, members, prov)
    _log(f"{out_tgz}: {len(members)} files + provenance.json + SHA256SUMS (commit {prov['commit'][:12]}, "
         f"dirty: {prov['dirty']}; untracked inputs: {', '.join(prov['untracked_inputs']) or 'none'}; modified "
         f"inputs: {', '.join(prov['modified_inputs']) or 'none'})")


def cpu_line(rule: str, wildcards: dict, before_step: float) -> str:
    """The line every job ends its log with: its own CPU time (user + system, ``time.process_time``, from the
    start of the process: interpreter, Snakemake's script preamble, imports and the step), and the CPU
    spent before the step began. ``benchmarks/bench_pipeline.py`` adds these up per rule."""
    wc = ",".join(f"{k}={v}" for k, v in wildcards.items())
    return (f"[stiffcal] cpu rule={rule} wildcards={wc or '-'} total={time.process_time():.3f} "
            f"before_step={before_step:.3f}")


def run(snakemake, step, *args) -> None:
    """Run one step from a Snakemake script, with its output in the rule's log.

    A bad input (:class:`InputError`) is one clear line on stderr and in the log, exit status 1. Any
    other failure is a bug: its traceback goes to the log and stderr names the log. Never a silent
    failure, never a traceback in place of a message for the user's own mistakes. The log ends with the
    job's CPU time (:func:`cpu_line`).
    """
    import contextlib
    import sys
    import traceback

    from .. import integrity
    from ..errors import InputError

    import os

    from ..limits import cap_memory, memory_message
    from ..progress import Progress

    before_step = time.process_time()
    integrity.watch_parent()
    log = Path(snakemake.log[0]) if snakemake.log else None
    if log:
        log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "w", encoding="utf-8") if log else contextlib.nullcontext(sys.stdout) as fh:
        with contextlib.redirect_stdout(fh):
            try:
                cap_memory()  # the hard cap per job (docs/contracts.md, 'Limits')
                integrity.verify([str(p) for p in snakemake.input])
                from ..threads import one_blas_thread

                with Progress(f"rule {snakemake.rule}", stream=fh), one_blas_thread():  # a line every few seconds
                    step(*args)
                integrity.record([str(p) for p in snakemake.output], snakemake.rule)
            except MemoryError:
                print(f"stiffcal: error: {memory_message()}", file=fh)
                print(f"stiffcal: error: rule {snakemake.rule}: {memory_message()}", file=sys.stderr)
                sys.exit(1)
            except InputError as err:
                print(f"stiffcal: error: {err}", file=fh)
                print(f"stiffcal: error: {err}", file=sys.stderr)
                sys.exit(1)
            except Exception as err:  # noqa: BLE001 - report any bug with its traceback in the log
                traceback.print_exc(file=fh)
                print(f"stiffcal: internal error in {step.__name__}: {type(err).__name__}: {err} "
                      f"(traceback in {log})", file=sys.stderr)
                sys.exit(1)
            print(cpu_line(snakemake.rule, dict(snakemake.wildcards.items()), before_step), flush=True)
    # The job is complete: its outputs are written (atomically) and recorded, its log closed. End the process
    # here, without the interpreter's teardown (freeing every module and object it loaded: 0.05-0.2 s of CPU a
    # job, a tenth of the whole pipeline's start-ups); nothing runs after the step in a Snakemake script.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
