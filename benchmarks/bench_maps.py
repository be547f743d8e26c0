"""Benchmark: the maps over test poses (Figures 6-10), every figure beside its baseline in the same run.

The baseline is the solver and hand-over of commit 8afcc70 (``stiffcal.testing._map_baseline``): the exact method
on every class, symmetry classes recomputed over the whole grid by every tile, tiles and maps handed over as
CSV. Times are CPU seconds of this process (``time.process_time``, single-threaded BLAS), printed as ratios.

Targets (issue 16, item 4): a 1-degree map (129,600 cells) in at most 0.5 s of CPU per link ratio
including table building; every cell within 1e-9 (relative) of the optimum, next to straight and folded
test poses too; 0.5-degree maps practical. Accuracy is measured against an independent long-double brute
force (``stiffcal.testing.reference.brute_force_cell_ld``) on random cells, three quarters of them next to singular
test poses (within 1e-3..3 deg of a straight or folded arm, within 2 deg of the force through joint 2 or
joint 1). The 0.5-degree maps are timed per link ratio with their hand-over and figures, to judge them as a
default.

Run: .venv/bin/python benchmarks/bench_maps.py [--cells N] [--skip-half]
"""

import os
import time

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"
T_START = time.process_time()

import argparse  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from stiffcal.testing import _map_baseline as base  # noqa: E402
from stiffcal.planning import _map_solver as solver  # noqa: E402
from stiffcal.planning import maps  # noqa: E402
from stiffcal.testing.reference import brute_force_cell_ld, brute_force_pair  # noqa: E402
from stiffcal.paper.tables import write_csv  # noqa: E402

T_IMPORT = time.process_time() - T_START
T0 = time.process_time()
import flint  # noqa: E402,F401  (python-flint: the exact method imports it on its first hard cell)

T_FLINT = time.process_time() - T0

PHI = -90.0
LINK_RATIOS = (0.4 / 0.6, 0.2, 0.5, 0.9)   # the default studies (Figures 7-10)
BASE_TILE = 8192                            # the baseline's default tile_cells


def cpu(fn, *args, **kw):
    t0 = time.process_time()
    out = fn(*args, **kw)
    return time.process_time() - t0, out


def new_map(b, step):
    return maps.solve_map(b, PHI, step)


def baseline_solve(b, step):
    """The baseline's solver on one representative per class (its own classes, computed once)."""
    _, reps, inverse = base.symmetry_classes(step, PHI)
    return base.map_frame(b, PHI, reps), inverse


def handover_new(mp, tmp, n_reads, parts=None):
    """Tiles written and read back, merged, map.npz and map.csv written, map.npz read by n_reads jobs;
    parts (a dict) receives the CPU of writing map.csv and the files' sizes [MB]."""
    h = len(mp.axis) // 2
    reps, cells, cls = maps.class_members(mp.step_deg, mp.force_deg, 0, h)
    tile = {"cell": cells, "O_t": mp.O_t.ravel()[cells], "q1_opt_deg": mp.q1_opt_deg.ravel()[cells],
            "q2_opt_deg": mp.q2_opt_deg.ravel()[cells], "status": mp.status.ravel()[cells]}
    maps.save_arrays(tmp / "t.npz", tile)
    merged = maps.merge_tiles([maps.load_arrays(tmp / "t.npz", maps.TILE_ARRAYS)], mp.link_ratio, mp.force_deg,
                              mp.step_deg)
    maps.save_map(tmp / "map.npz", merged)
    t_csv, _ = cpu(lambda: write_csv(maps.map_frame(merged), tmp / "map.csv"))
    if parts is not None:
        parts.update(csv=t_csv, **{f: (tmp / f).stat().st_size / 1e6 for f in ("map.csv", "map.npz")})
    for _ in range(n_reads):
        maps.load_map(tmp / "map.npz")


def handover_baseline(df, tmp, n_reads):
    """The same through CSV: tiles written and read, merged, map.csv written and read by n_reads jobs."""
    write_csv(df, tmp / "t.csv")
    merged = base.merge_tiles([pd.read_csv(tmp / "t.csv")], df.attrs["step"])
    write_csv(merged, tmp / "map.csv")
    for _ in range(n_reads):
        pd.read_csv(tmp / "map.csv")


def figures_by_step(b):
    """CPU and bytes of the figures a map feeds (Figure 6 and its Figure 7-10 panel, PNG + SVG) at 1 and
    0.5 degrees (matplotlib imported beforehand, as the figure job does once)."""
    from stiffcal.report import plots

    out = {}
    for step in (1.0, 0.5):
        mp = maps.solve_map(b, PHI, step)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.process_time()
            plots.save(plots.fig6_inverse_chi(mp), Path(tmp) / "fig6")
            plots.save(plots.fig_optimal_poses(mp, 7), Path(tmp) / "fig7")
            out[step] = (time.process_time() - t0, sum(f.stat().st_size for f in Path(tmp).iterdir()) / 1e6)
    print(f"  figures 6 and 7 of one map (b = {b:.3f}, PNG + SVG): {out[1.0][0]:.2f} s and {out[1.0][1]:.1f} MB at "
          f"1 degree, {out[0.5][0]:.2f} s and {out[0.5][1]:.1f} MB at 0.5 degree")


def line(label, ours, baseline, unit="s", target=""):
    ratio = baseline / ours if ours > 0 else float("inf")
    print(f"  {label:<58} {ours:9.3f} {unit}   baseline {baseline:9.3f} {unit}   {ratio:7.1f}x{target}")


def main(n_cells: int, skip_half: bool, n_pairs: int = 30) -> None:
    print("Maps over test poses: CPU seconds of this process, ours beside the baseline (commit 8afcc70)")
    print(f"(importing numpy, pandas, stiffcal.planning.maps and the baseline took {T_IMPORT:.2f} s once per process; "
          f"python-flint, imported by a map job on its first cell that needs the exact method, {T_FLINT:.3f} s)")
    # --- 1. a 1-degree map per link ratio, table building included --------------------------------------
    print("\n1-degree maps (129,600 cells), solving one cell per symmetry class; ours includes building the table")
    worst, uncertified = 0.0, 0
    for b in LINK_RATIOS:
        solver.polynomials.cache_clear()
        t_new, mp = cpu(new_map, b, 1.0)
        t_old, _ = cpu(baseline_solve, b, 1.0)
        worst = max(worst, t_new)
        counts = np.bincount(mp.status.ravel(), minlength=len(maps.STATUS))
        line(f"b = {b:.3f}", t_new, t_old, target="   (target <= 0.5 s)")
        print("    cells by status: " + ", ".join(f"{maps.STATUS[k]} {c}" for k, c in enumerate(counts) if c))
        uncertified += int(counts[maps.UNCERTIFIED])
    print(f"  worst of the four: {worst:.3f} s (target <= 0.5 s: {'met' if worst <= 0.5 else 'NOT met'}); "
          f"uncertified cells: {uncertified} (target: none)")

    # --- 2. symmetry classes: once per map against every tile recomputing the whole grid's ------------
    b = LINK_RATIOS[0]
    for step in (1.0, 0.5):
        n_tiles = base.n_tiles(step, PHI, BASE_TILE)
        t_new, _ = cpu(maps.class_members, step, PHI, 0, int(round(180 / step)))
        t0 = time.process_time()
        for _ in range(n_tiles):
            base.symmetry_classes(step, PHI)
        t_old = time.process_time() - t0
        line(f"symmetry classes, {step:g}-degree map ({n_tiles} baseline tiles)", t_new, t_old)

    # --- 3. the hand-over between jobs: binary against CSV ----------------------------------------------
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        mp = maps.solve_map(b, PHI, 1.0)
        df = maps.map_frame(mp)
        df.attrs["step"] = 1.0
        # map.npz is read by map_statistics, fig6 and fig7 (3 jobs); the baseline read map.csv as often
        t_new, _ = cpu(handover_new, mp, tmp, 3)
        t_old, _ = cpu(handover_baseline, df, tmp, 3)
        line("hand-over of a 1-degree map (tiles, merge, map.csv, 3 reads)", t_new, t_old)

    # --- 4. the 0.5-degree maps: solving, and the hand-over a map job adds (tiles, merge, map.npz, map.csv) ---
    if not skip_half:
        print("\n0.5-degree maps (518,400 cells): solving (table included), then the hand-over; baseline: its "
              "solver (b = 0.667 only)")
        t_old, _ = cpu(baseline_solve, LINK_RATIOS[0], 0.5)
        uncertified = 0
        for bh in LINK_RATIOS:
            solver.polynomials.cache_clear()
            t_new, mp = cpu(new_map, bh, 0.5)
            parts = {}
            with tempfile.TemporaryDirectory() as tmp:
                t_hand, _ = cpu(handover_new, mp, Path(tmp), 3, parts)
            counts = np.bincount(mp.status.ravel(), minlength=len(maps.STATUS))
            uncertified += int(counts[maps.UNCERTIFIED])
            print(f"  b = {bh:.3f}: solving {t_new:6.3f} s, hand-over {t_hand:6.3f} s (map.csv {parts['csv']:.2f} s, "
                  f"{parts['map.csv']:.0f} MB; map.npz {parts['map.npz']:.0f} MB), together {t_new + t_hand:6.3f} s"
                  + (f"   (baseline solver {t_old:.3f} s, {t_old / t_new:.1f}x)" if bh == LINK_RATIOS[0] else ""))
            print("    cells by status: " + ", ".join(f"{maps.STATUS[k]} {c}" for k, c in enumerate(counts) if c))
        print(f"  uncertified cells: {uncertified} (target: none)")
        figures_by_step(LINK_RATIOS[0])

    # --- 5. accuracy against the long-double brute force -------------------------------------------------
    rng = np.random.default_rng(2026)
    k = n_cells // 4
    generic = rng.uniform(-180, 180, (n_cells - 3 * k, 2))
    off = 10 ** rng.uniform(-3, np.log10(3), k) * rng.choice([-1, 1], k)
    straight = np.column_stack([rng.uniform(-180, 180, k), off + 180 * rng.integers(0, 2, k)])
    q1 = rng.uniform(-180, 180, k)
    diagonal = np.column_stack([q1, (90 - q1 + rng.uniform(-2, 2, k) + 180) % 360 - 180])
    # next to the force through joint 1 (cos q1* + b cos(q1* + q2*) = 0), where the exact method is needed
    u = rng.uniform(-min(1, b), min(1, b), k)
    q1 = np.arccos(u) * rng.choice([-1, 1], k)
    q12 = np.arccos(-u / b) * rng.choice([-1, 1], k)
    joint1 = (np.degrees(np.stack([q1, q12 - q1], -1)) + rng.uniform(-2, 2, (k, 2)) + 180) % 360 - 180
    cells = np.vstack([generic, straight, diagonal, joint1])
    force = maps.force_vector(PHI)
    t_new, ours = cpu(maps.solve_cells, b, PHI, cells)
    t_old, old = cpu(base.solve_cells, b, PHI, cells)
    ref = np.array([brute_force_cell_ld(b, force, c) for c in cells])
    attained = ours.status != maps.NO_OPTIMUM
    ex_new = np.max((ours.ot - ref) / ref)
    ex_old = np.max(((old.ot - ref) / ref)[attained])
    print(f"\naccuracy on {len(cells)} random cells (b = {b:.3f}; {3 * k} next to singular test poses: straight or "
          f"folded arms, the force through joint 2 or joint 1), relative excess over the long-double brute force:")
    counts = np.bincount(ours.status, minlength=len(maps.STATUS))
    print("  cells by status: " + ", ".join(f"{maps.STATUS[k]} {c}" for k, c in enumerate(counts) if c))
    print(f"  ours: worst {ex_new:.1e}, cells above 1e-9: {int(np.sum((ours.ot - ref) / ref > 1e-9))} "
          f"(target: none)   baseline: worst {ex_old:.1e}, cells above 1e-9: "
          f"{int(np.sum(((old.ot - ref) / ref)[attained] > 1e-9))}, above 1e-6: "
          f"{int(np.sum(((old.ot - ref) / ref)[attained] > 1e-6))}")
    line(f"solving these {len(cells)} cells one by one (no classes)", t_new, t_old)
    # --- 6. plans of two poses (case iv) over the test poses: no earlier solver; against a brute force ----
    t_map, pm = cpu(maps.pair_map, b, PHI, 6.0)
    sample = rng.uniform(-180, 180, (n_pairs, 2))
    single = maps.solve_cells(b, PHI, sample)
    t_ours, (ot2, _) = cpu(maps.best_pairs, b, PHI, sample, single.pose_deg)
    t_ref, ref2 = cpu(lambda: np.array([brute_force_pair(b, force, c) for c in sample]))
    print(f"\nbest plans of two poses (case iv), b = {b:.3f}: the 6-degree map ({pm.O_t2.size} cells) in "
          f"{t_map:.2f} s; "
          f"on {n_pairs} random cells against a brute force over every pair of a 6-degree grid + Nelder-Mead:")
    print(f"  worst relative excess {np.max((ot2 - ref2) / ref2):.1e} (tests require <= 1e-6); "
          f"per cell {1e3 * t_ours / n_pairs:.1f} ms against {1e3 * t_ref / n_pairs:.0f} ms ({t_ref / t_ours:.0f}x)")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak memory: {peak_mb:.0f} MB")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=300, help="random cells for the accuracy check")
    ap.add_argument("--skip-half", action="store_true", help="skip the 0.5-degree map (the baseline takes ~6 s)")
    ap.add_argument("--pairs", type=int, default=30, help="random cells for the two-pose brute-force check")
    args = ap.parse_args()
    main(args.cells, args.skip_half, args.pairs)
