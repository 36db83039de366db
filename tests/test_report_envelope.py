"""Long series are drawn from their envelope (adcs_sim.app.report.envelope): a bounded number of
points whatever the run's length, each time column keeping its first, last, smallest, largest and
first NaN sample, so that the drawn line covers the same pixels; short series are drawn as they are."""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from adcs_sim.app.report.envelope import COLUMNS, MAX_POINTS, kept_indices, reduced


def _series(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    y = np.exp(-t / (0.02 * n)) * np.sin(t / (0.003 * n)) + 0.05 * rng.standard_normal(n)
    y[n // 2:n // 2 + 10] = np.nan
    return t, y


def test_short_series_are_drawn_as_they_are():
    t, y = _series(MAX_POINTS)
    rt, ry = reduced(t, y)
    assert rt is t and ry is y


def test_each_column_keeps_its_extremes_ends_and_gaps():
    t, y = _series(300_001)
    idx = kept_indices(t, y)
    assert idx[0] == 0 and idx[-1] == t.size - 1 and np.all(np.diff(idx) > 0)
    assert idx.size <= 5 * COLUMNS
    column = np.minimum(((t - t[0]) * (COLUMNS / (t[-1] - t[0]))).astype(np.int64), COLUMNS - 1)
    for c in (0, 1, 2047, COLUMNS // 2, COLUMNS - 1):
        whole, kept = y[column == c], y[idx[column[idx] == c]]
        assert np.nanmin(kept) == np.nanmin(whole) and np.nanmax(kept) == np.nanmax(whole)
        assert np.isnan(kept).any() == np.isnan(whole).any()
    rt, ry, r2 = reduced(t, y, np.column_stack([y, -y]))   # a 2-D series keeps each column's envelope
    assert rt.size == ry.size == r2.shape[0] and r2.shape[1] == 2


def _raster(t, y) -> np.ndarray:
    fig = Figure(figsize=(10.0, 3.5), dpi=110, layout='constrained')
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.plot(t, y, color='C0', linewidth=1.6)
    ax.set_xlim(t[0], t[-1])
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)


def test_the_envelope_draws_the_same_picture():
    """A day at 10 Hz of a noisy decaying oscillation (the worst case: every pixel column spans
    many samples' zigzag): the envelope's PNG differs by a few antialiasing levels on the line's
    edges only, the line covering the same pixels."""
    t, y = _series(864_001)
    full, env = _raster(t, y), _raster(*reduced(t, y))
    ink_full, ink_env = (full < 200).any(axis=2), (env < 200).any(axis=2)
    assert (ink_full != ink_env).sum() < 0.01 * ink_full.sum()
    assert (np.abs(full - env).max(axis=2) > 0).mean() < 0.02
