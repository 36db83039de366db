"""A run's controller status records, stored compactly: :class:`StatusRecords`.

The controller publishes one ``DiagnosticArray`` per step; :class:`~adcs_sim.app.run_data.RunData`
keeps each status as ``(t, name, {key: value text})``. Held as Python tuples and dicts that is
about 1.5 kB a step (a 24 h run at 10 Hz: 1.3 GB, almost all of ``adcs-run``'s end-of-run
memory, issue #18). Here the records of one layout (status name and keys) are a stamp array and
one fixed-width byte-string array per key, about 130 B a step; a record is rebuilt as the same
tuple when it is read. The sequence compares equal to the list of those tuples.

A value that a fixed-width byte string cannot hold exactly (over :data:`WIDE` bytes, or ending in
NUL, which numpy's ``S`` type strips) keeps its text in an object array: a hostile bag with one
huge value costs that value, not its width times every step.
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

WIDE = 64   # bytes: a longer value goes to an object column


class _Layout:
    """Records with one (name, keys): stamps, reading order, values per key (being read: lists)."""

    def __init__(self, name: str, keys: tuple) -> None:
        self.name, self.keys = name, keys
        self.stamps: list = []
        self.order: list = []
        self.values: list[list] = [[] for _ in keys]
        self.done: list[tuple] = []   # (stamps, order, [column per key]) per finished batch

    def flush(self) -> None:
        if self.stamps:
            self.done.append((np.array(self.stamps, dtype=float), np.array(self.order, dtype=np.int64),
                              [_column(v) for v in self.values]))
            self.stamps, self.order, self.values = [], [], [[] for _ in self.keys]

    def freeze(self) -> tuple[np.ndarray, np.ndarray, list]:
        self.flush()
        parts = self.done
        stamps = np.concatenate([p[0] for p in parts])
        order = np.concatenate([p[1] for p in parts])
        columns = [_concatenate([p[2][k] for p in parts]) for k in range(len(self.keys))]
        self.done = []
        return stamps, order, columns


def _column(texts: list) -> np.ndarray:
    """Fixed-width UTF-8 bytes when every text fits exactly, else an object array of the texts."""
    raw = [t.encode('utf-8', 'surrogatepass') for t in texts]
    if any(len(b) > WIDE or b.endswith(b'\0') for b in raw):
        out = np.empty(len(texts), dtype=object)
        out[:] = texts
        return out
    return np.array(raw, dtype=bytes) if raw else np.zeros(0, dtype='S1')


def _concatenate(columns: list) -> np.ndarray:
    if any(c.dtype == object for c in columns):
        return np.concatenate([c.astype(object) if c.dtype != object else c for c in columns])
    return np.concatenate(columns)


def _text(value) -> str:
    return value.decode('utf-8', 'surrogatepass') if isinstance(value, bytes) else value


class StatusRecords(Sequence):
    """``(t, name, {key: value})`` per status, in stamp order (reading order on ties).

    Build it with :meth:`add` for each DiagnosticArray batch as it is read (``(stamps, statuses per
    message)``, :func:`adcs_sim.bag.columns.decode_diagnostics`), then :meth:`freeze`."""

    def __init__(self) -> None:
        self._layouts: dict[tuple, _Layout] = {}
        self._count = 0
        self._frozen: list[tuple] = []                 # (name, keys, stamps, columns) per layout
        self._where = np.zeros((0, 2), dtype=np.int32)  # record i -> (layout, row)

    def add(self, stamps: np.ndarray, messages: list) -> None:
        """One batch of messages: each status kept as (its message's stamp, name, values)."""
        for stamp, statuses in zip(stamps.tolist(), messages):
            for status in statuses:
                values = status[4]
                key = (status[1], tuple(values))
                layout = self._layouts.get(key)
                if layout is None:
                    layout = self._layouts[key] = _Layout(status[1], key[1])
                layout.stamps.append(stamp)
                layout.order.append(self._count)
                for column, value in zip(layout.values, values.values()):
                    column.append(value)
                self._count += 1
        for layout in self._layouts.values():
            layout.flush()

    def freeze(self) -> StatusRecords:
        """Finish reading: sort every record by stamp (reading order on ties). Returns self."""
        stamps, order, where = [], [], []
        for i, layout in enumerate(self._layouts.values()):
            s, o, columns = layout.freeze()
            self._frozen.append((layout.name, layout.keys, s, columns))
            stamps.append(s)
            order.append(o)
            where.append(np.stack([np.full(s.size, i, dtype=np.int32), np.arange(s.size, dtype=np.int32)], axis=1))
        self._layouts = {}
        if stamps:
            stamps, order, where = np.concatenate(stamps), np.concatenate(order), np.concatenate(where)
            self._where = where[np.lexsort((order, stamps))]
        return self

    def __len__(self) -> int:
        return len(self._where)

    def _record(self, i: int) -> tuple[float, str, dict]:
        layout, row = self._where[i]
        name, keys, stamps, columns = self._frozen[layout]
        return float(stamps[row]), name, {k: _text(c[row]) for k, c in zip(keys, columns)}

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self._record(j) for j in range(*i.indices(len(self)))]
        n = len(self)
        if not -n <= i < n:
            raise IndexError('status record index out of range')
        return self._record(i % n)

    def __iter__(self) -> Iterator[tuple[float, str, dict]]:
        for i in range(len(self)):
            yield self._record(i)

    def __eq__(self, other) -> bool:
        if isinstance(other, (StatusRecords, list, tuple)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    def __repr__(self) -> str:
        return f'StatusRecords({len(self)} records)'
