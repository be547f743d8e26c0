"""Benchmark: one map over test poses (Figures 6-10) against the naive method, in the same run.

Targets (issue 4): a 1-degree map (129,600 cells) in at most 10 s on one core; at least 5,000 times faster
per cell than the naive method (a multi-start local search per cell, here 10 Nelder-Mead starts), at equal
or better accuracy; peak memory at most 2 GB. Accuracy: the worst relative excess of each method's O_t over
an independent brute force (every pose of a 1-degree grid, then Nelder-Mead from the three best), on random
cells, half of them next to the singular test poses.

Run: .venv/bin/python benchmarks/bench_maps.py [--cells N]   (single-threaded BLAS is forced below)
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import argparse  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from stiffcal import maps  # noqa: E402
from stiffcal.reference import brute_force_cell, naive_cell  # noqa: E402

B, PHI, STEP, TILE = 0.4 / 0.6, -90.0, 1.0, 8192


def main(n_cells: int) -> None:
    force = maps.force_vector(PHI)
    t0 = time.perf_counter()
    tiles = [maps.map_tile(B, PHI, STEP, TILE, k) for k in range(maps.n_tiles(STEP, PHI, TILE))]
    full = maps.merge_tiles(tiles, STEP)
    t_map = time.perf_counter() - t0
    per_cell = t_map / len(full)

    rng = np.random.default_rng(2026)
    cells = np.vstack([rng.integers(-180, 180, (n_cells - n_cells // 2, 2)),
                       np.column_stack([rng.integers(-180, 180, n_cells // 2), rng.integers(-10, 11, n_cells // 2)])])
    cells = cells.astype(float)
    ours = maps.solve_cells(B, PHI, cells).ot
    t0 = time.perf_counter()
    maps.map_frame(B, PHI, maps.test_pose_grid(STEP))  # every cell solved on its own, no symmetry classes
    per_cell_raw = (time.perf_counter() - t0) / len(full)
    t0 = time.perf_counter()
    naive = np.array([naive_cell(B, force, c, seed=i) for i, c in enumerate(cells)])
    t_naive = (time.perf_counter() - t0) / len(cells)
    ref = np.array([brute_force_cell(B, force, c) for c in cells])
    excess_ours = np.max((ours - ref) / ref)
    excess_naive = np.max((naive - ref) / ref)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    print(f"map b = {B:.4f}, {STEP:g} deg grid: {len(full)} cells in {t_map:.2f} s on one core "
          f"(target <= 10 s): {per_cell * 1e6:.1f} us per cell")
    print(f"naive multi-start local search: {t_naive:.3f} s per cell (mean of {len(cells)} cells)")
    print(f"speed-up per cell: {t_naive / per_cell:,.0f}x (target >= 5,000x)")
    print(f"  without the symmetry classes (every cell solved on its own): {per_cell_raw * 1e6:.1f} us per cell, "
          f"{t_naive / per_cell_raw:,.0f}x")
    print(f"worst relative excess over the brute force on {len(cells)} cells: ours {excess_ours:.2e} "
          f"(target <= 1e-6), naive {excess_naive:.2e}; cells where the naive search misses by more than "
          f"1e-6: {np.sum((naive - ref) / ref > 1e-6)}")
    print(f"peak memory: {peak_mb:.0f} MB (target <= 2048 MB)")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=40, help="random cells for the naive method and the accuracy check")
    main(ap.parse_args().cells)
