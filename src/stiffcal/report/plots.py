"""The paper's figures from our generated tables (matplotlib, Agg backend, deterministic output).

Plot functions only draw: they read data frames produced by :mod:`stiffcal.paper.tables` and never compute a
design, so restyling a figure never reruns an optimisation.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..model.robot import as_xyz  # noqa: E402
from ..planning.study import Study  # noqa: E402

if TYPE_CHECKING:  # annotations only: a figure job that reads no table does not load pandas
    import pandas as pd

STYLE = {"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8,
         "figure.dpi": 100, "savefig.dpi": 150, "svg.hashsalt": "stiffcal", "svg.fonttype": "none"}
#: resolution of the PNG figures [dots per inch]: a print resolution (the PDF report prints them, the HTML report
#: shows the SVG)
PNG_DPI = 200


def save(fig, stem: str | Path) -> list[Path]:
    """Write ``<stem>.png`` and ``<stem>.svg`` without timestamps (reproducible bytes), each atomically (a
    temporary file moved into place when complete), cropped to the figure's drawn extent as
    ``bbox_inches="tight"`` does. The layout (constrained, or tight_layout's) and the extent are computed by one
    draw and then kept for both files: each file is drawn once (``bbox_inches="tight"`` draws twice a file and
    redoes the layout at every draw: four draws and layouts, against three draws and one)."""
    from matplotlib.transforms import Bbox

    from ..integrity import atomic_path

    stem = Path(stem)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    fig.canvas.draw()
    extent = fig.get_tightbbox(fig.canvas.get_renderer())
    pad = plt.rcParams["savefig.pad_inches"]
    box = Bbox(extent.padded(pad).get_points())
    fig.set_layout_engine("none")  # the positions the draw computed, kept
    with atomic_path(paths[0]) as tmp:
        fig.savefig(tmp, format="png", dpi=PNG_DPI, metadata={"Software": None}, bbox_inches=box)
    with plt.rc_context({"svg.hashsalt": STYLE["svg.hashsalt"]}), atomic_path(paths[1]) as tmp:
        fig.savefig(tmp, format="svg", metadata={"Date": None, "Creator": None}, bbox_inches=box)
    plt.close(fig)
    return paths


def fig3_accuracy(t2: pd.DataFrame):
    """Figure 3: identification accuracy E[dk_i^2] of the optimal single pose per criterion (log bars;
    an unidentifiable compliance is drawn as a hatched bar at the top marked 'inf')."""
    with plt.rc_context(STYLE):
        n = sum(c.startswith("E_dk") for c in t2.columns)
        rows = t2[~t2["degenerate"].astype(bool)]
        vals = rows[[f"E_dk{i + 1}" for i in range(n)]].to_numpy(float)
        finite = vals[np.isfinite(vals)]
        top = finite.max() * 4 if finite.size else 10.0
        fig, ax = plt.subplots(figsize=(6.4, 3.2))
        x = np.arange(len(rows))
        w = 0.8 / n
        for i in range(n):
            v = vals[:, i]
            bars = ax.bar(x + (i - (n - 1) / 2) * w, np.where(np.isfinite(v), v, top), w,
                          label=f"E[dk{i + 1}²]", color=f"C{i}")
            for b, vi in zip(bars, v):
                if not np.isfinite(vi):
                    b.set_hatch("//")
                    b.set_alpha(0.4)
                    ax.text(b.get_x() + b.get_width() / 2, top, "inf", ha="center", va="bottom", fontsize=7)
        ax.set_yscale("log")
        ax.set_xticks(x, rows["label"], rotation=30, ha="right")
        ax.set_ylabel("E[δk²]  [rad²/N², σ = 1]")
        ax.set_title("Identification accuracy at each criterion's optimal pose (one experiment)")
        ax.set_ylim(top=top * 3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
        ax.grid(axis="y", which="major", alpha=0.3)
        return fig


def _draw_arm(ax, points, style, label):
    ax.plot(points[:, 0], points[:, 1], style, lw=2.5, ms=6, label=label)
    ax.plot(points[0, 0], points[0, 1], "ks", ms=8)


def fig4_poses(study: Study, measure_pose_deg: np.ndarray):
    """Figure 4: the arm at the test pose and at the O_t-optimal measurement pose, with the force."""
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(4.6, 4.6))
        reach = float(study.robot.links_m.sum())
        test = study.robot.link_points(study.test_pose)
        meas = study.robot.link_points(np.radians(measure_pose_deg))
        test_label = ", ".join(f"{a:.0f}" for a in np.degrees(study.test_pose))
        _draw_arm(ax, test, "o-C0", f"test pose q* = ({test_label})°")
        meas_label = ", ".join(f"{a:.2f}" for a in measure_pose_deg)
        _draw_arm(ax, meas, "o-C3", f"optimal measurement pose ({meas_label})°")
        f = study.force / np.linalg.norm(study.force) * 0.25 * reach
        for pts in (test, meas):
            ax.annotate("", xy=pts[-1] + f, xytext=pts[-1],
                        arrowprops=dict(arrowstyle="-|>", color="C2", lw=1.5))
        ax.plot([], [], color="C2", label="force F")
        circle = plt.Circle((0, 0), reach, fill=False, ls=":", color="0.6")
        ax.add_patch(circle)
        ax.set_xlim(-1.15 * reach, 1.15 * reach)
        ax.set_ylim(-1.15 * reach, 1.15 * reach)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(loc="lower left", fontsize=7)
        ax.set_title("Test pose and O_t-optimal measurement pose")
        ax.grid(alpha=0.3)
        return fig


def fig5_chi_map(chi: pd.DataFrame, optimal_set_deg: np.ndarray, representative_deg: np.ndarray):
    """Figure 5: chi (eq. 27) over the measurement-pose plane; the optimal poses marked."""
    with plt.rc_context(STYLE):
        q1 = np.unique(chi["q1_deg"])
        q2 = np.unique(chi["q2_deg"])
        Z = chi["chi"].to_numpy(float).reshape(len(q1), len(q2)).T
        fig, ax = plt.subplots(figsize=(5.6, 4.4))
        mesh = _grid_image(ax, q1, q2, Z, cmap="viridis", vmin=0, vmax=np.nanmax(Z))
        ax.contour(q1, q2, Z, levels=[1, 2, 3, 4, 5], colors="w", linewidths=0.5)
        fig.colorbar(mesh, ax=ax, label="χ = O_t* / O_t")
        ax.plot(optimal_set_deg[:, 0], optimal_set_deg[:, 1], "o", mfc="none", mec="r", ms=9,
                label="equally optimal poses")
        ax.plot(representative_deg[0], representative_deg[1], "r*", ms=12, label="reported optimum")
        ax.set_xlabel("q1 [deg]")
        ax.set_ylabel("q2 [deg]")
        ax.set_title("Accuracy gain χ of one measurement pose")
        ax.legend(loc="lower right", fontsize=7)
        return fig


def fig_design(support: pd.DataFrame, phi_map: pd.DataFrame):
    """The optimal approximate design: support poses on the measurement-pose plane, sized by weight,
    over the map of phi(x, xi) / Phi(xi) (equivalence theorem: <= 1 everywhere, = 1 on the support)."""
    with plt.rc_context(STYLE):
        q1 = np.unique(phi_map["q1_deg"])
        q2 = np.unique(phi_map["q2_deg"])
        Z = phi_map["ratio"].to_numpy(float).reshape(len(q1), len(q2)).T
        fig, ax = plt.subplots(figsize=(5.6, 4.4))
        mesh = _grid_image(ax, q1, q2, Z, cmap="magma", vmin=0, vmax=1.0)
        fig.colorbar(mesh, ax=ax, label="φ(x, ξ*) / Φ(ξ*)")
        ax.scatter(support["q1_deg"], support["q2_deg"], s=1500 * support["weight"], facecolors="none",
                   edgecolors="c", linewidths=2, label="support of ξ* (area ∝ weight)")
        for _, r in support.iterrows():
            ax.annotate(f"{r.weight:.3f}", (r.q1_deg, r.q2_deg), xytext=(8, 8), textcoords="offset points",
                        color="c", fontsize=8)
        ax.set_xlabel("q1 [deg]")
        ax.set_ylabel("q2 [deg]")
        ax.set_title("Optimal approximate design for O_t")
        ax.legend(loc="lower right", fontsize=7)
        return fig


def fig_ot_versus_m(df: pd.DataFrame):
    """Best O_t of an m-pose plan against m, beside the certified lower bound and the repeated single
    optimum; the second panel shows the gap to the bound."""
    with plt.rc_context(STYLE):
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.2, 3.0))
        ax.plot(df.m, df.O_t, "o-", label="best plan (iv)")
        ax.plot(df.m, df.O_t_repeat, "s--", label="single optimum repeated (i)")
        ax.plot(df.m, df.lower_bound, "k:", label="certified lower bound")
        ax.set_yscale("log")
        ax.set_xlabel("number of measurement poses m")
        ax.set_ylabel("O_t  [σ = 1]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3, which="both")
        ax2.bar(df.m, 100 * df.gap, color="C2")
        ax2.set_xlabel("m")
        ax2.set_ylabel("gap to bound  O_t / bound − 1  [%]")
        ax2.grid(axis="y", alpha=0.3)
        fig.tight_layout()
        return fig


def _map_axes(ax, title: str):
    ax.set_xlabel("test pose q1* [deg]")
    ax.set_ylabel("test pose q2* [deg]")
    ax.set_xticks(np.arange(-180, 181, 90))
    ax.set_yticks(np.arange(-180, 181, 90))
    ax.set_title(title)


def _grid_image(ax, x: np.ndarray, y: np.ndarray, Z: np.ndarray, **kw):
    """Z (len(y), len(x)) drawn as cells centred on the grid points x, y [deg]: what ``pcolormesh(x, y, Z,
    shading="auto")`` draws, as one image instead of one quadrilateral per cell when both axes are regular (a
    map of 129,600 cells draws in a fraction of the time). NaN cells are left blank."""
    def edges(a):
        a = np.asarray(a, float)
        h = (a[-1] - a[0]) / max(len(a) - 1, 1)
        regular = len(a) < 2 or np.allclose(np.diff(a), h, rtol=1e-9, atol=0.0)
        return (a[0] - h / 2, a[-1] + h / 2) if regular and h > 0 else None

    ex, ey = edges(x), edges(y)
    if ex is None or ey is None:
        return ax.pcolormesh(x, y, Z, shading="auto", rasterized=True, **kw)
    return ax.imshow(Z, origin="lower", extent=(*ex, *ey), interpolation="nearest", aspect="auto", **kw)


#: colour of the map cells without an optimal pose (a grey that none of the map colour maps contains)
NO_POSE_COLOUR = "#9a9a9a"


def _mark_no_pose(ax, mp, mask: np.ndarray) -> None:
    """Draw the cells of mask (n, n) in NO_POSE_COLOUR (Figures 7-10: no optimal measurement pose)."""
    from matplotlib.colors import ListedColormap

    if mask.any():
        _grid_image(ax, mp.axis, mp.axis, np.where(mask, 1.0, np.nan).T, cmap=ListedColormap([NO_POSE_COLOUR]),
                    vmin=0, vmax=1)


def fig6_inverse_chi(mp):
    """Figure 6: 1/chi over the test-pose plane of a map (:class:`stiffcal.planning.maps.MapArrays`) (dark: little
    to gain over measuring at the test pose; white: large gain). Cells with A_t = 0 (chi infinite) are
    white; on the rows where the test arm is straight or folded chi is its supremum (module docstring of
    :mod:`stiffcal.planning.maps`)."""
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(5.6, 4.4))
        mesh = _grid_image(ax, mp.axis, mp.axis, (1.0 / mp.chi).T, cmap="gray_r", vmin=0, vmax=1)
        fig.colorbar(mesh, ax=ax, label="1 / χ")
        _map_axes(ax, f"Maximum accuracy improvement, b = l2/l1 = {mp.link_ratio:.2f}")
        return fig


def fig_optimal_poses(mp, figure: int):
    """Figures 7-10: the optimal measurement pose (q1, q2) for every test pose of a map (q1 is defined
    modulo 180 deg, so its colour map is cyclic). Cells without an optimal pose (the infimum of O_t is
    reached only by a singular pose, or A_t = 0) are grey and named in the legend."""
    from matplotlib.patches import Patch

    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, 2, figsize=(9.6, 4.3), layout="constrained")
        no_pose = np.isnan(mp.q1_opt_deg)
        for ax, Z, label, (lo, hi), cmap in zip(axes, (mp.q1_opt_deg, mp.q2_opt_deg), ("q1", "q2"),
                                               ((-90, 90), (0, 180)), ("twilight", "viridis")):
            mesh = _grid_image(ax, mp.axis, mp.axis, Z.T, cmap=cmap, vmin=lo, vmax=hi)
            _mark_no_pose(ax, mp, no_pose)
            fig.colorbar(mesh, ax=ax, label=f"optimal {label} [deg]")
            _map_axes(ax, f"Optimal measurement {label}")
        if no_pose.any():
            rows = sorted({f"{v:g}" for v in mp.axis[np.nonzero(no_pose.all(axis=0) | (no_pose.sum(axis=0) > 2))[0]]})
            where = f" (rows q2* = {', '.join(rows)} deg)" if rows else ""
            fig.legend(handles=[Patch(color=NO_POSE_COLOUR, label="no optimal pose: only a singular measurement "
                                      f"pose reaches the infimum of O_t{where}")],
                       loc="lower center", bbox_to_anchor=(0.5, -0.07), frameon=False)
        fig.suptitle(f"Figure {figure}: optimal measurement pose, b = l2/l1 = {mp.link_ratio:.2f}, "
                     f"φ = {mp.force_deg:g} deg")
        return fig


def fig_map_pairs(pm):
    """Where a second, designed pose pays: 1 - O_t(best pair) / (O_t(single optimum) / 2) [%] over the
    test-pose plane of a :class:`stiffcal.planning.maps.PairMap` (case iv of Table 4 against case i), with contours."""
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(5.8, 4.4))
        G = 100 * np.clip(pm.gain, 0, None).T
        mesh = ax.pcolormesh(pm.axis, pm.axis, G, shading="gouraud", cmap="magma_r", vmin=0, vmax=max(G.max(), 1e-9),
                             rasterized=True)
        cs = ax.contour(pm.axis, pm.axis, G, levels=[1, 5, 10, 20], colors="k", linewidths=0.6)
        ax.clabel(cs, fmt="%g %%", fontsize=7)
        fig.colorbar(mesh, ax=ax, label="gain of the best pair over the single optimum twice [%]")
        _map_axes(ax, f"Best plan of two poses against repeating the single optimum, b = {pm.link_ratio:.2f}")
        return fig


#: at most this many configurations are labelled on the residual figure's axis (every k-th beyond)
MAX_CONFIG_TICKS = 40
#: blunder rows of the residual figure: a marker and colour no other point uses
OUTLIER_STYLE = {"marker": "X", "s": 42, "color": "C3", "edgecolors": "k", "linewidths": 0.5, "zorder": 5}


def _config_ticks(ax, meas, n_cfg: int) -> str:
    """Label the configuration axis: the data's pose_id labels (every k-th when there are more than
    :data:`MAX_CONFIG_TICKS`), else integers 0 .. n_cfg - 1 in file order. Returns the axis label's note."""
    from matplotlib.ticker import MaxNLocator

    if not meas.labelled:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        return "numbered in file order from 0"
    step = int(np.ceil(n_cfg / MAX_CONFIG_TICKS))
    at = np.arange(0, n_cfg, step)
    labels = [meas.config_labels[c] for c in at]
    ax.set_xticks(at, labels, fontsize=7, rotation=0 if len(at) * max(map(len, labels)) <= 60 else 90)
    return "pose_id" + (f", one in {step} labelled" if step > 1 else "")


def _outliers(ax, x: np.ndarray, resid_um: np.ndarray, lim: float | None, label: str | None = None,
              rows: np.ndarray | None = None):
    """Draw the blunder rows' residuals (M, d) [um] at x (M,) with :data:`OUTLIER_STYLE`, one collection per
    component; values beyond +-lim [um] are drawn at the limit and, with the rows' data-row numbers ``rows``
    (M,), labelled with them (one label per row and side: 'row 72: dx 268, dz 260 µm')."""
    y = resid_um if lim is None else np.clip(resid_um, -lim, lim)
    for j in range(resid_um.shape[1]):
        ax.scatter(x, y[:, j], label=label if j == 0 else None, **OUTLIER_STYLE)
    if lim is None or rows is None:
        return
    for xi, v, r in zip(x, resid_um, rows):
        for sign in (1, -1):
            off = [f"d{'xyz'[j]} {v[j]:.0f}" for j in range(len(v)) if sign * v[j] > lim]
            if off:
                ax.annotate(f"row {r}: {', '.join(off)} µm", (xi, sign * lim), xytext=(6, 0),
                            textcoords="offset points", fontsize=6, color=OUTLIER_STYLE["color"],
                            va="top" if sign > 0 else "bottom")


def _rows_label(rows) -> str:
    rows = [int(r) for r in rows]
    shown = ", ".join(map(str, rows[:8])) + (f" and {len(rows) - 8} more" if len(rows) > 8 else "")
    return f"blunder (outlier_rows): data row{'s' if len(rows) > 1 else ''} {shown}"


#: beyond this many points a residual panel is drawn as an image inside the SVG (vector text and axes), and beyond
#: MAX_BARS configurations the held-out check is a step line: a log of 10^5 rows draws in seconds, not minutes
RASTER_POINTS = 2000
MAX_BARS = 200


def _config_slots(meas, fmag: np.ndarray, n_cfg: int) -> np.ndarray:
    """The x of each row in the per-configuration panel: its configuration's slot, its rows spread by load
    (sorted by force magnitude, then row) across 0.7 of the slot."""
    config = np.asarray(meas.config)
    by = np.lexsort((np.arange(len(fmag)), fmag, config))
    counts = np.bincount(config, minlength=n_cfg)
    rank = np.arange(len(by)) - (np.cumsum(counts) - counts)[config[by]]
    slot = np.zeros(len(fmag))
    slot[by] = config[by] - 0.35 + 0.7 * (rank + 0.5) / counts[config[by]]
    return slot


def _feature_panels(fig, grid, cols: int, features: dict, um: np.ndarray, ok: np.ndarray, out: np.ndarray, lim,
                    sigma: float, dense: bool) -> None:
    """One panel of the residuals [µm] against each feature, from the second row of ``grid`` on."""
    for i, (name, v) in enumerate(features.items()):
        ax = fig.add_subplot(grid[1 + i // cols, i % cols])
        for j, (lab, mk) in enumerate(zip("xyz", "o^s")):
            if j < um.shape[1]:
                ax.plot(v[ok], um[ok, j], mk, ms=3, alpha=0.7, label=f"d{lab}", rasterized=dense or None)
        if out.any():
            _outliers(ax, v[out], um[out], lim)
        ax.axhspan(-2e6 * sigma, 2e6 * sigma, color="0.85", zorder=0)
        ax.set_xlabel(name)
        ax.set_ylabel("residual [µm]")


def fig_residuals(meas, features: dict[str, np.ndarray], resid: np.ndarray, sigma: float, title: str,
                  outlier_rows=()):
    """Residuals of the nominal fit [m]: first per robot configuration (every load of a configuration side by
    side, coloured by the force magnitude, so that a response that grows with the load, or a step that
    follows the load's sign, shows; the axis labelled by the data's pose_id when they have one), then against
    pose, force magnitude, force direction and joint torque (one panel per feature; x, y (z) components; the
    +-2 sigma band of the noise). Blunder rows are drawn with their own marker (:data:`OUTLIER_STYLE`) and
    listed in the legend; the axes are scaled to the other rows, a blunder beyond them is drawn at the edge (with
    its row, component and value in the first panel).

    meas: :class:`stiffcal.measured.measurements.Measurements` of the rows plotted (N rows); features: name -> (N,);
    resid: (N, d) [m]; sigma [m]; outlier_rows: 0-based data rows (``meas.rows``) of the blunders, the verdict's
    ``outlier_rows`` (rows not among ``meas.rows`` are ignored)."""
    features = {k: v for k, v in features.items() if np.ptp(v) > 1e-3 * max(np.abs(v).max(), 1e-12)}  # not constant
    out = np.isin(meas.rows, np.asarray(outlier_rows, int))
    ok = ~out if (~out).any() else out
    um = resid * 1e6
    lim = 1.15 * max(np.abs(um[ok]).max(initial=0.0), 2e6 * sigma)
    lim = lim if out.any() and np.abs(um[out]).max() > lim else None  # scale to the others when a blunder is off it
    with plt.rc_context(STYLE):
        k = len(features) + 1
        cols = min(3, k)
        rows = int(np.ceil((k + cols - 1) / cols))
        fig = plt.figure(figsize=(3.2 * cols, 2.5 * rows), layout="constrained")
        grid = fig.add_gridspec(rows, cols)
        ax0 = fig.add_subplot(grid[0, :])
        fmag = np.linalg.norm(meas.force, axis=1)
        # colour by what varies between the loads: the magnitude (hanging weights), else the direction
        by_magnitude = np.ptp(fmag) > 0.05 * fmag.mean()
        colour = fmag if by_magnitude else np.degrees(np.arctan2(meas.force[:, 1], meas.force[:, 0]))
        order = np.argsort(meas.config, kind="stable")
        order = order[ok[order]]
        n_cfg = max(meas.n_configurations, 1)
        slot = _config_slots(meas, fmag, n_cfg)
        dense = len(fmag) > RASTER_POINTS  # many points: drawn as an image inside the SVG, the text stays vector
        norm = (plt.Normalize(fmag.min(), fmag.max()) if by_magnitude else plt.Normalize(-180.0, 180.0))
        for j, (lab, mk) in enumerate(zip("xyz", "o^s")):
            if j < resid.shape[1]:
                sc = ax0.scatter(slot[order], um[order, j], c=colour[order],
                                 cmap="viridis" if by_magnitude else "twilight", norm=norm,
                                 marker=mk, s=9, alpha=0.85, label=f"d{lab}", rasterized=dense or None)
        if out.any():
            _outliers(ax0, slot[out], um[out], lim, _rows_label(meas.rows[out]), meas.rows[out])
        ax0.axhspan(-2e6 * sigma, 2e6 * sigma, color="0.85", zorder=0)
        ax0.set_xlim(-0.6, n_cfg - 0.4)
        how = _config_ticks(ax0, meas, n_cfg)
        ax0.set_xlabel(f"robot configuration ({n_cfg}, {how}; the loads of each side by side)")
        ax0.set_ylabel("residual [µm]")
        fig.colorbar(sc, ax=ax0, label="|F| [N]" if by_magnitude else "force direction [deg]", pad=0.01)
        ax0.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=4, frameon=False, borderaxespad=0.2)
        _feature_panels(fig, grid, cols, features, um, ok, out, lim, sigma, dense)
        if lim is not None:
            for ax in fig.axes:
                if ax.get_ylabel() == "residual [µm]":
                    ax.set_ylim(-1.08 * lim, 1.08 * lim)
        fig.suptitle(title)
        return fig


def draw_cell(ax, robot, lo: np.ndarray, hi: np.ndarray) -> None:
    """The robot's cell (:mod:`stiffcal.model.workcell`) on 3-D axes spanning [lo, hi] (3,) [m]: each half-space as a
    translucent patch of its plane, boxes and cylinders as wire frames (a planar arm's in its plane z = 0)."""
    cell = robot.cell
    if cell is None:
        return
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    planar = robot.planar
    for o in cell.obstacles:
        if o.kind == "half_space":
            n = o.normal
            if planar:  # a line in the plane
                t = np.array([-n[1], n[0], 0.0])
                p0 = n * o.offset
                s = np.linspace(-1, 1, 2)[:, None] * np.max(hi - lo) * 1.5
                pts = p0 + s * t
                ax.plot(*pts.T, "-", color="0.45", lw=2)
                continue
            a = np.eye(3)[np.argmin(np.abs(n))]
            u = np.cross(n, a)
            u /= np.linalg.norm(u)
            v = np.cross(n, u)
            c = 0.5 * (lo + hi)
            c = c - (c @ n - o.offset) * n
            r = 0.75 * np.max(hi - lo)
            quad = [c + r * (x * u + y * v) for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            ax.add_collection3d(Poly3DCollection([quad], alpha=0.12, facecolor="0.5", edgecolor="0.5"))
        elif o.kind == "box":
            half = o.half.copy()
            if planar:
                half[2] = 0.0
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
            corners = o.center + corners @ o.rotation.T
            for i in range(8):
                for j in range(i + 1, 8):
                    if bin(i ^ j).count("1") == 1:
                        ax.plot(*corners[[i, j]].T, "-", color="0.35", lw=0.8)
        else:
            a = np.eye(3)[np.argmin(np.abs(o.axis))]
            u = np.cross(o.axis, a)
            u /= np.linalg.norm(u)
            v = np.cross(o.axis, u)
            t = np.linspace(0, 2 * np.pi, 48)
            ring = o.radius * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
            ends = (0.0,) if planar else (-o.half_length, o.half_length)
            for e in ends:
                ax.plot(*(o.center + e * o.axis + ring).T, "-", color="0.35", lw=0.8)
            if not planar:
                for k in range(0, 48, 12):
                    seg = o.center + ring[k] + np.outer([-o.half_length, o.half_length], o.axis)
                    ax.plot(*seg.T, "-", color="0.35", lw=0.8)


def draw_cell_2d(ax, robot, extent: float) -> None:
    """A planar robot's cell on 2-D axes: half-planes as grey lines, rectangles and discs as outlines."""
    cell = robot.cell
    if cell is None:
        return
    from matplotlib.patches import Circle, Polygon

    for o in cell.obstacles:
        if o.kind == "half_space":
            t = np.array([-o.normal[1], o.normal[0]])
            p0 = o.normal[:2] * o.offset
            ax.plot(*np.array([p0 - 2 * extent * t, p0 + 2 * extent * t]).T, "-", color="0.45", lw=2)
        elif o.kind == "box":
            c = np.array([[sx, sy, 0.0] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]) * o.half
            ax.add_patch(Polygon((o.center + c @ o.rotation.T)[:, :2], closed=True, fill=False, color="0.35"))
        else:
            ax.add_patch(Circle(tuple(o.center[:2]), o.radius, fill=False, color="0.35"))


def fig_study_plan(study: Study, plan_deg: np.ndarray, m: int, clearance_m=None):
    """A design study's m-pose plan drawn in 3-D (a planar arm in its plane): the arm at the test pose with
    the force, and at every measurement pose of the plan; for a robot in a cell, the cell too
    (:func:`draw_cell`) and every pose labelled with its clearance ``clearance_m`` (m,) [m]."""
    robot = study.robot
    reach = robot.reach_m
    with plt.rc_context(STYLE):
        fig = plt.figure(figsize=(6.4, 5.2))
        ax = fig.add_subplot(projection="3d")

        test = as_xyz(robot.link_points(study.test_pose))
        ax.plot(*test.T, "o-", color="k", lw=2.5, ms=3, label="test pose q*")
        f = as_xyz(study.force)
        f = f / np.linalg.norm(f) * 0.25 * reach
        ax.quiver(*test[-1], *f, color="C2", lw=2, label="force F")
        every = [test, test[-1:] + f]
        for i, pose in enumerate(np.atleast_2d(plan_deg)):
            pts = as_xyz(robot.link_points(np.radians(pose)))
            every.append(pts)
            ax.plot(*pts.T, "o-", color=f"C{i % 10}", lw=1.2, ms=2, alpha=0.85,
                    label="measurement poses" if i == 0 else None)
            label = f" {i + 1}" if clearance_m is None else f" {i + 1} ({1e3 * clearance_m[i]:.0f} mm)"
            ax.text(*pts[-1], label, fontsize=7, color=f"C{i % 10}")
        allp = np.concatenate(every)
        lo, hi = allp.min(0), allp.max(0)
        half = 0.55 * max(np.max(hi - lo), 0.2 * reach)
        mid = 0.5 * (lo + hi)
        if robot.cell is not None:
            draw_cell(ax, robot, mid - half, mid + half)
            ax.plot([], [], "-", color="0.45", label=f"cell (clearance {robot.cell.clearance_m:g} m, between links "
                    f"{robot.cell.self_margin:g} m" + (": pose (distance to the nearest body, link or cell)"
                                                       if clearance_m is not None else "") + ")")
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_zlim(mid[2] - half, mid[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.view_init(elev=22, azim=-60)
        ax.legend(loc="upper left", fontsize=7)
        ax.set_title(f"{study.name}: O_t-optimal plan of {m} poses")
        return fig


def fig_study_versus_m(df: pd.DataFrame, sigma: float):
    """A design study: the RMS compensation error sqrt(O_t) of the best plan and the certified bound
    against the number of poses M (left), and chi (eq. 27) against M (right)."""
    with plt.rc_context(STYLE):
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.2, 3.0))
        unit, scale = ("µm", 1e6) if sigma < 1e-2 else ("σ units", 1.0)
        ax.plot(df.m, scale * np.sqrt(df.O_t), "o-", label="best plan")
        ax.plot(df.m, scale * np.sqrt(df.lower_bound), "k:", label="certified lower bound")
        ax.set_xlabel("number of measurement poses M")
        ax.set_ylabel(f"RMS compensation error √O_t [{unit}]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        ax2.plot(df.m, df.chi, "s-", color="C3")
        ax2.set_xlabel("M")
        ax2.set_ylabel("χ = O_t* / O_t  (eq. 27)")
        ax2.grid(alpha=0.3)
        fig.tight_layout()
        return fig


def _draw_session(ax, robot, session: dict | None, planar: bool) -> None:
    """The plan to measure on ``ax``: each pose's arm with its load's arrow (a point measured several times drawn
    once, labelled with every number), the base, the reach and the cell."""
    reach = robot.reach_m
    if session:
        fmax = max(np.linalg.norm(session["forces_N"], axis=1).max(), 1e-300)
        points: dict = {}  # a point measured several times is drawn once, labelled with every number
        for i, (pose, f) in enumerate(zip(session["poses_deg"], session["forces_N"])):
            points.setdefault((tuple(np.round(pose, 3)), tuple(np.round(f, 3))), []).append(i + 1)
        for k, ((pose, f), numbers) in enumerate(points.items()):
            pts = as_xyz(robot.link_points(np.radians(pose)))
            arrow = as_xyz(np.asarray(f)) / fmax * 0.25 * reach
            c = f"C{k % 10}"
            text = " " + ",".join(map(str, numbers))
            if planar:
                ax.plot(pts[:, 0], pts[:, 1], "o-", color=c, lw=1.4, ms=3, alpha=0.85)
                ax.annotate("", xy=pts[-1, :2] + arrow[:2], xytext=pts[-1, :2],
                            arrowprops=dict(arrowstyle="-|>", color=c, lw=1.0))
                ax.text(*pts[-1, :2], text, fontsize=7, color=c)
            else:
                ax.plot(*pts.T, "o-", color=c, lw=1.2, ms=2, alpha=0.85)
                ax.quiver(*pts[-1], *arrow, color=c, lw=1)
                ax.text(*pts[-1], text, fontsize=7, color=c)
    if planar:
        ax.plot(0, 0, "ks", ms=7)
        ax.add_patch(plt.Circle((0, 0), reach, fill=False, ls=":", color="0.6"))
        draw_cell_2d(ax, robot, 1.3 * reach)
        ax.set_xlim(-1.3 * reach, 1.3 * reach)
        ax.set_ylim(-1.3 * reach, 1.3 * reach)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    else:
        draw_cell(ax, robot, -reach * np.ones(3), reach * np.ones(3))
        for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            set_lim(-reach, reach)
        ax.set_box_aspect((1, 1, 1))
        ax.set_zlabel("z [m]")
        ax.view_init(elev=22, azim=-60)


def fig_discrimination(robot, plan: dict, title: str):
    """The next experiment (``stiffcal discriminate``, plan.json as ``plan``): the plan to measure (the compound
    plan when there is one, else the discriminating plan) drawn with its loads (left; in the plane for a planar
    arm, in 3-D for a spatial one), and the predicted power of the best discriminating plan against the number
    of points M, with the certified bound at the chosen M (right)."""
    which = "compound" if plan.get("compound") else ("plan" if plan.get("plan") else "ot_plan")
    session = plan.get(which)
    with plt.rc_context(STYLE):
        fig = plt.figure(figsize=(8.4, 3.8))
        planar = robot.task_dim == 2
        ax = fig.add_subplot(1, 2, 1) if planar else fig.add_subplot(1, 2, 1, projection="3d")
        _draw_session(ax, robot, session, planar)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        label = {"compound": f"compound plan (κ = {plan['compound']['weight'] if plan.get('compound') else ''})",
                 "plan": "discriminating plan", "ot_plan": "O_t-optimal plan"}[which]
        none = ("no rival: nothing to discriminate" if len(plan["models"]) == 1 else
                "no plan of these measurements separates the rivals")
        ax.set_title(f"{label}, M = {plan['experiments']}" if session else none, fontsize=9)
        ax2 = fig.add_subplot(1, 2, 2)
        curve = plan.get("power_against_m") or []
        if curve:
            ax2.plot([c["m"] for c in curve], [c["power"] for c in curve], "o-", label="best discriminating plan")
            cert = (plan.get("plan") or {}).get("certificate")
            if cert:
                ax2.plot([plan["experiments"]], [cert["power_bound"]], "k^", label="certified bound at M")
            ax2.axhline(0.9, color="0.6", ls=":", lw=1)
            ax2.legend(fontsize=7, loc="lower right")
        else:
            ax2.text(0.5, 0.5, none.replace(": ", ":\n"), ha="center", va="center", transform=ax2.transAxes)
        ax2.set_ylim(0, 1.02)
        ax2.set_xlabel("number of measurements M")
        ax2.set_ylabel("predicted power of the separating F-test")
        ax2.grid(alpha=0.3)
        fig.suptitle(title, fontsize=9)
        fig.tight_layout()
        return fig


def _message_figure(text: str):
    """A figure that holds one sentence (a figure of the workflow that its data cannot draw)."""
    fig, ax = plt.subplots(figsize=(7.2, 3.0))
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()
    return fig


def fig_held_out(held: dict | None, sigma: float, title: str):
    """The verdict's ``held_out`` (leave-one-configuration-out): per configuration the RMS error [µm] of the
    position predicted for it by the nominal and by the calibrated model, each fitted without it, against the
    noise σ [m]. ``held`` None (fewer than two configurations): a figure that says so."""
    with plt.rc_context(STYLE):
        if held is None:
            return _message_figure("held-out check: needs measurements at two or more configurations")
        fig, ax = plt.subplots(figsize=(7.2, 3.0))
        table = held["per_configuration"]
        x = np.arange(len(table))
        cal = " + ".join(held["calibrated_causes"]) or "nominal"
        labels = (f"nominal (all: {1e6 * held['rms_nominal_m']:.3g} µm)",
                  f"calibrated: {cal} (all: {1e6 * held['rms_calibrated_m']:.3g} µm)")
        values = [[1e6 * r[key] for r in table] for key in ("rms_nominal_m", "rms_calibrated_m")]
        many = len(table) > MAX_BARS  # too many for bars: a step line per model, drawn as an image in the SVG
        for shift, colour, label, v in zip((-0.2, 0.2), ("0.6", "C0"), labels, values):
            if many:
                ax.plot(x, v, drawstyle="steps-mid", color=colour, lw=0.6, label=label, rasterized=True)
            else:
                ax.bar(x + shift, v, 0.4, color=colour, label=label)
        ax.axhline(1e6 * sigma, color="k", ls=":", lw=1, label="noise σ")
        step = max(1, len(table) // 24)
        ax.set_xticks(x[::step], [r["configuration"] for r in table][::step], rotation=60, ha="right", fontsize=6)
        ax.set_xlabel("held-out configuration")
        ax.set_ylabel("RMS prediction error [µm]")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, lo + 1.25 * (hi - lo))  # headroom: the legend's row above every bar
        ax.legend(fontsize=7, loc="upper left", ncol=3, frameon=False)
        ax.grid(alpha=0.3, axis="y")
        ax.set_title(title, fontsize=9)
        fig.tight_layout()
        return fig


def fig_machining(check: dict | None, causes, title: str):
    """A simulated machining path (the verdict's ``machining_path``): the tool's deflection [µm] along it without
    compensation, the error left by compensating with the nominal model and with the calibrated model (the
    calibrated model taken as the truth), and the calibrated model's 95 % band. ``check`` None (no test pose): a
    figure that says so."""
    with plt.rc_context(STYLE):
        if check is None:
            return _message_figure("machining path: needs the data set's test pose (test_pose_deg)")
        fig, ax = plt.subplots(figsize=(7.2, 3.0))
        x = np.arange(len(check["before"]))
        um = {k: 1e6 * np.asarray(check[k]) for k in ("before", "after_nominal", "after_calibrated", "band95")}
        ax.fill_between(x, 0, um["band95"], color="C0", alpha=0.2, label="calibrated model: 95 % band")
        ax.plot(x, um["before"], "k-", label="no compensation")
        ax.plot(x, um["after_nominal"], "C3--", label="compensated, nominal model")
        ax.plot(x, um["after_calibrated"], "C0-", label=f"compensated, calibrated ({' + '.join(causes) or 'nominal'})")
        ax.set_yscale("symlog", linthresh=max(1e-3, float(um["band95"].min()) if um["band95"].size else 1e-3))
        ax.set_xlabel("pose along the path (every joint swept ±20° about the test pose)")
        ax.set_ylabel("tool position error [µm]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        ax.set_title(title, fontsize=9)
        fig.tight_layout()
        return fig
