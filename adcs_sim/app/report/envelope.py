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


def log_positive(y: np.ndarray) -> np.ndarray:
    """Values for a log axis: non-positive ones masked (NaN)."""
    y = np.asarray(y, dtype=float).copy()
    y[~(y > 0)] = np.nan
    return y


def _first_per_column(candidates: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The first of ``candidates`` (sorted sample indices) in each column (``starts``: first index of each)."""
    column = np.searchsorted(starts, candidates, side='right') - 1
    return candidates[np.r_[True, column[1:] != column[:-1]]] if candidates.size else candidates


def kept_indices(t: np.ndarray, *ys: np.ndarray, columns: int | None = None) -> np.ndarray:
    """Sorted indices of the samples the envelope of ``ys`` (1-D, over sorted stamps ``t``) keeps
    (``columns``: default :data:`COLUMNS`)."""
    columns = COLUMNS if columns is None else columns
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


def reduced(t, *ys, limit: int | None = None, columns: int | None = None):
    """``(t, *ys)`` at the envelope's samples when longer than ``limit`` (default
    :data:`MAX_POINTS`) samples, else as given. A 2-D ``y`` (N, k) keeps the envelope of each of
    its columns."""
    t = np.asarray(t)
    if t.size <= (MAX_POINTS if limit is None else limit):
        return (t, *ys)
    flat = [c for y in ys for c in (np.asarray(y).reshape(t.size, -1).T)]
    idx = kept_indices(t, *flat, columns=columns)
    return (t[idx], *(np.asarray(y)[idx] for y in ys))


class EnvelopeStream:
    """:func:`kept_indices` of series over the stamps ``t`` fed chunk by chunk, in order (a long
    run's report, never holding the whole series): per column and series, the smallest and the
    largest value with their first sample and the first NaN; the columns' first and last samples
    come from the stamps (:func:`kept_indices` of ``t`` alone). ``t0`` and ``span`` are the whole
    series' (``t[0]``, ``t[-1] - t[0]``): the columns are those :func:`kept_indices` cuts."""

    def __init__(self, t0: float, span: float, columns: int | None = None) -> None:
        columns = COLUMNS if columns is None else columns
        self.t0, self.columns = t0, columns
        self.scale = columns / span if span > 0 else None
        self.slots: dict = {}     # (series, slot) -> [best value (columns,), first sample index (columns,)]

    def column(self, t: np.ndarray) -> np.ndarray:
        """The column of each stamp (the expression :func:`kept_indices` evaluates)."""
        if self.scale is None:
            return np.zeros(t.size, dtype=np.int64)
        return np.minimum(((t - self.t0) * self.scale).astype(np.int64), self.columns - 1)

    def ends(self, column: np.ndarray, i0: int) -> np.ndarray:
        """Samples ``i0 ..`` (their columns ``column``): each column's first and last sample so far;
        returns the indices that became one."""
        if not column.size:
            return np.zeros(0, dtype=np.int64)
        starts = np.flatnonzero(np.r_[True, column[1:] != column[:-1]])
        cols, last = column[starts], np.r_[starts[1:], column.size] - 1 + i0
        first = self._update((None, 'first'), cols, np.zeros(starts.size), starts + i0, strict=False)
        self._update((None, 'last'), cols, np.zeros(starts.size), last, strict=False)
        self.slots[None, 'last'][1][cols] = last
        return np.concatenate([first, last])

    def add(self, name, column: np.ndarray, i0: int, y: np.ndarray) -> np.ndarray:
        """Samples ``i0 ..`` (their columns ``column``) of series ``name``; returns the indices
        that became a column's smallest, largest or first NaN."""
        return self.add_many([name], column, i0, np.asarray(y, dtype=float).reshape(-1, 1))

    def add_many(self, names: list, column: np.ndarray, i0: int, ys: np.ndarray) -> np.ndarray:
        """:meth:`add` of several series at once: ``ys`` (n, len(names)), one series a column."""
        n = column.size
        if not n:
            return np.zeros(0, dtype=np.int64)
        starts = np.flatnonzero(np.r_[True, column[1:] != column[:-1]])
        lengths = np.diff(np.r_[starts, n])
        cols = column[starts]
        nan = np.isnan(ys)
        at = np.arange(n)[:, None]
        new = []
        for slot, sign in (('min', 1.0), ('max', -1.0)):
            v = np.where(nan, np.inf, sign * ys)
            low = np.minimum.reduceat(v, starts, axis=0)
            # the first sample of each column at its smallest value (every column has one)
            first = np.minimum.reduceat(np.where(v == np.repeat(low, lengths, axis=0), at, n), starts, axis=0)
            for j, name in enumerate(names):
                new.append(self._update((name, slot), cols, low[:, j], first[:, j] + i0, strict=True))
        if nan.any():
            first = np.minimum.reduceat(np.where(nan, at, n), starts, axis=0)
            for j, name in enumerate(names):
                has = first[:, j] < n
                if has.any():
                    new.append(self._update((name, 'nan'), cols[has], np.zeros(int(has.sum())),
                                            first[has, j] + i0, strict=False))
        return np.concatenate(new)

    def _update(self, key, cols, values, index, strict: bool) -> np.ndarray:
        best = self.slots.get(key)
        if best is None:
            best = self.slots[key] = [np.full(self.columns, np.inf), np.full(self.columns, -1, dtype=np.int64)]
        empty = best[1][cols] < 0
        take = empty | (values < best[0][cols]) if strict else empty
        best[0][cols[take]] = values[take]
        best[1][cols[take]] = index[take]
        return index[take]

    def indices(self) -> np.ndarray:
        """The kept samples: every series' and, once :meth:`ends` was given the stamps, the columns'
        first and last (:func:`kept_indices` of the stamps and the series)."""
        parts = [best[1][best[1] >= 0] for best in self.slots.values()]
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
