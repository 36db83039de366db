"""A run's controller status records, stored compactly: :class:`StatusRecords`.

The controller publishes one ``DiagnosticArray`` per step; :class:`~adcs_sim.app.analysis.run_data.RunData`
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
# Status keys of the commanded torque (a report plots them in the torque figure, not with the other values).
TORQUE_KEYS = ('u_x', 'u_y', 'u_z')


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


def _texts(column: np.ndarray) -> list[str]:
    """The value texts of a column (fixed-width UTF-8 bytes or an object array of texts)."""
    if column.dtype == object:
        return [_text(v) for v in column.tolist()]
    try:
        return column.astype(str).tolist()   # ASCII (every number a controller publishes): one cast
    except UnicodeDecodeError:
        return [_text(v) for v in column.tolist()]


CHUNK = 65536   # values parsed at a time: the texts of one chunk exist at once, not a run's


def status_keys(records) -> list[tuple[str, str]]:
    """(status name, key) of every value in status records (a :class:`StatusRecords` or any sequence
    of ``(t, name, {key: value})``), in the order they first appear (a record's keys in its order)."""
    if isinstance(records, StatusRecords):
        return records.keys()
    return list(dict.fromkeys((name, key) for _, name, values in records for key in values))


def status_names(records) -> set[str]:
    """The status names of the records (those with no value included)."""
    if isinstance(records, StatusRecords):
        return {name for name, _, stamps, _ in records._frozen if stamps.size}
    return {name for _, name, _ in records}


def status_column(records, key: str, name: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, stamps, raw values) of the records holding ``key`` (those of status ``name``; None:
    any name), in record order. Raw values: fixed-width UTF-8 bytes, or an object array of texts
    (:func:`parse_values`, :func:`texts`)."""
    if isinstance(records, StatusRecords):
        return records.column(key, name)
    rows = [(i, t, values[key]) for i, (t, n, values) in enumerate(records)
            if key in values and (name is None or n == name)]
    raw = np.empty(len(rows), dtype=object)
    raw[:] = [v for _, _, v in rows]
    return (np.array([i for i, _, _ in rows], dtype=np.int64), np.array([t for _, t, _ in rows], dtype=float), raw)


def status_values(records, key: str, name: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, :func:`parse_values`) of :func:`status_column`; a :class:`StatusRecords` parses each
    key once (the torque and the status figures both read the status values: 864 000 texts a key
    for a day at 10 Hz)."""
    if isinstance(records, StatusRecords):
        return records.values(key, name)
    _, stamps, raw = status_column(records, key, name)
    return stamps, parse_values(raw)


def parse_values(raw: np.ndarray) -> np.ndarray:
    """Raw status values as floats where every one parses (as ``np.array(texts, dtype=float)``
    would: chunk by chunk, so a day's texts never exist at once), else as :func:`texts`."""
    out = np.empty(raw.size, dtype=float)
    for i in range(0, raw.size, CHUNK):
        try:
            out[i:i + CHUNK] = np.array(_texts(raw[i:i + CHUNK]), dtype=float)
        except ValueError:
            return texts(raw)
    return out


def texts(raw: np.ndarray) -> np.ndarray:
    """Raw status values as an object array of texts, each distinct text one object."""
    if raw.dtype == object:
        out = np.empty(raw.size, dtype=object)
        out[:] = [str(v) for v in _texts(raw)]
        return out
    distinct, inverse = np.unique(raw, return_inverse=True)
    decoded = np.empty(distinct.size, dtype=object)
    decoded[:] = _texts(distinct)
    return decoded[inverse.reshape(-1)]


class StatusRecords(Sequence):
    """``(t, name, {key: value})`` per status, in stamp order (reading order on ties).

    Build it with :meth:`add` for each DiagnosticArray batch as it is read (``(stamps, statuses per
    message)``, :func:`adcs_sim.bag.columns.decode_diagnostics`), then :meth:`freeze`."""

    def __init__(self) -> None:
        self._layouts: dict[tuple, _Layout] = {}
        self._count = 0
        self._frozen: list[tuple] = []                 # (name, keys, stamps, columns) per layout
        self._where = np.zeros((0, 2), dtype=np.int32)  # record i -> (layout, row)
        self._positions = None   # per layout, its records' positions (_layout_positions)
        self._values: dict = {}  # (key, name) -> values(): parsed once

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

    def keys(self) -> list[tuple[str, str]]:
        """:func:`status_keys` of the records, from the layouts."""
        first = {}   # (name, key) -> (record where it first appears, place in that record)
        for i, (name, keys, _, _) in enumerate(self._frozen):
            where = self._layout_positions(i)
            for j, key in enumerate(keys):
                if where.size and ((name, key) not in first or first[name, key] > (int(where[0]), j)):
                    first[name, key] = (int(where[0]), j)
        return sorted(first, key=first.get)

    def _layout_positions(self, i: int) -> np.ndarray:
        """Positions (record order) of layout ``i``'s records; computed once per layout."""
        if self._positions is None:
            order = np.argsort(self._where[:, 0], kind='stable')
            bounds = np.searchsorted(self._where[order, 0], np.arange(len(self._frozen) + 1))
            self._positions = [order[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        return self._positions[i]

    def values(self, key: str, name: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:func:`status_values` of the records, parsed once per (key, name)."""
        if (key, name) not in self._values:
            _, stamps, raw = self.column(key, name)
            self._values[key, name] = (stamps, parse_values(raw))
        return self._values[key, name]

    def column(self, key: str, name: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`status_column` of the records, from the layouts' columns (no record rebuilt)."""
        parts = []
        for i, (layout_name, keys, stamps, columns) in enumerate(self._frozen):
            if key in keys and (name is None or layout_name == name):
                where = self._layout_positions(i)
                rows = self._where[where, 1]
                parts.append((where, stamps[rows], columns[keys.index(key)][rows]))
        if not parts:
            return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=object)
        if len(parts) == 1:
            return parts[0]
        where = np.concatenate([p[0] for p in parts])
        order = np.argsort(where, kind='stable')
        return where[order], np.concatenate([p[1] for p in parts])[order], _concatenate([p[2] for p in parts])[order]
