"""Long series drawn from their envelope: a figure's line holds a bounded number of points whatever
the run's length (issue #18: a 24 h run at 10 Hz is 864 000 samples a line; a figure is about a
thousand pixels wide).

The time span is cut into :data:`COLUMNS` equal columns (about four per pixel column of the
report's 10-inch figures at 110 dpi) and each column keeps its first and last samples, its
smallest and largest value of each series and its first NaN (where the line breaks), in time
order: drawn, the line covers the same pixels as the whole series. A series of up to
:data:`MAX_POINTS` samples (every committed run, the 10 000-step showcase) is drawn as it is.
"""
from __future__ import annotations

import numpy as np

MAX_POINTS = 20_000
COLUMNS = 4096


def _first_per_column(candidates: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The first of ``candidates`` (sorted sample indices) in each column (``starts``: first index of each)."""
    column = np.searchsorted(starts, candidates, side='right') - 1
    return candidates[np.r_[True, column[1:] != column[:-1]]] if candidates.size else candidates


def kept_indices(t: np.ndarray, *ys: np.ndarray, columns: int = COLUMNS) -> np.ndarray:
    """Sorted indices of the samples the envelope of ``ys`` (1-D, over sorted stamps ``t``) keeps."""
    t = np.asarray(t, dtype=float)
    n = t.size
    span = t[-1] - t[0] if n else 0.0
    if not span > 0:
        column = np.zeros(n, dtype=np.int64)
    else:
        column = np.minimum(((t - t[0]) * (columns / span)).astype(np.int64), columns - 1)
    starts = np.flatnonzero(np.r_[True, column[1:] != column[:-1]])
    lengths = np.diff(np.r_[starts, n])
    keep = [starts, starts + lengths - 1]
    for y in ys:
        y = np.asarray(y, dtype=float)
        nan = np.isnan(y)
        for sign in (1.0, -1.0):   # smallest, then largest
            v = np.where(nan, np.inf, sign * y)
            low = np.repeat(np.minimum.reduceat(v, starts), lengths)
            keep.append(_first_per_column(np.flatnonzero(v == low), starts))
        keep.append(_first_per_column(np.flatnonzero(nan), starts))
    return np.unique(np.concatenate(keep))


def reduced(t, *ys, limit: int = MAX_POINTS, columns: int = COLUMNS):
    """``(t, *ys)`` at the envelope's samples when longer than ``limit`` samples, else as given.
    A 2-D ``y`` (N, k) keeps the envelope of each of its columns."""
    t = np.asarray(t)
    if t.size <= limit:
        return (t, *ys)
    flat = [c for y in ys for c in (np.asarray(y).reshape(t.size, -1).T)]
    idx = kept_indices(t, *flat, columns=columns)
    return (t[idx], *(np.asarray(y)[idx] for y in ys))
