"""Figures: the map image draws what pcolormesh draws (compared pixel by pixel)."""

import io

import numpy as np
import pytest

plt = pytest.importorskip("matplotlib.pyplot")
from stiffcal.report import plots  # noqa: E402


def _render(draw) -> np.ndarray:
    fig, ax = plt.subplots(figsize=(3, 2.5), dpi=100)
    draw(ax)
    ax.set_xlim(-200, 190)  # fixed, beyond the cells: a cell drawn in the wrong place shows
    ax.set_ylim(-110, 100)
    ax.set_axis_off()
    fig.subplots_adjust(0, 0, 1, 1)
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=100)
    plt.close(fig)
    return np.frombuffer(buf.getvalue(), np.uint8).reshape(250, 300, 4)


def test_grid_image_draws_the_cells_that_pcolormesh_draws(rng):
    x, y = -180.0 + 12.0 * np.arange(30), -90.0 + 9.0 * np.arange(20)
    Z = rng.uniform(0, 1, (len(y), len(x)))
    Z[3:6, 10:14] = np.nan  # blank cells
    kw = dict(cmap="viridis", vmin=0, vmax=1)
    ref = _render(lambda ax: ax.pcolormesh(x, y, Z, shading="auto", **kw))
    got = _render(lambda ax: plots._grid_image(ax, x, y, Z, **kw))
    same = np.all(np.abs(ref.astype(int) - got.astype(int)) <= 2, axis=-1)
    assert same.mean() > 0.95  # only pixels on cell edges (anti-aliasing) may differ


def test_grid_image_falls_back_to_pcolormesh_on_an_irregular_grid():
    fig, ax = plt.subplots()
    artist = plots._grid_image(ax, np.array([0.0, 1.0, 3.0]), np.array([0.0, 1.0]), np.zeros((2, 3)))
    assert type(artist).__name__ == "QuadMesh"
    plt.close(fig)
