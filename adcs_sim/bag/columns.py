"""Decoding the CDR bytes of a :class:`~adcs_sim.bag.batches.TopicBatch` into numpy columns.

The CDR layout of a message type is fixed up to its string and sequence lengths, so it is
computed once per distinct layout and the fields of all messages sharing it are gathered with
numpy, without deserialising message by message: :func:`decode_batch` (Odometry,
Vector3Stamped, JointState) and :func:`decode_diagnostics` (DiagnosticArray).
"""
from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from adcs_sim.bag.batches import TopicBatch


class _Cursor:
    """Walks one CDR message (XCDR1, as ROS 2 writes) and records what pins its layout."""

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise ValueError('unsupported CDR encapsulation')
        self.data = data
        self.little = data[1] == 1
        self.pos = 4
        self.checks: list[tuple[int, bytes]] = [(0, bytes(data[:2]))]
        self.u32 = struct.Struct('<I' if self.little else '>I')

    def _need(self, n: int) -> None:
        if self.pos + n > len(self.data):
            raise ValueError('CDR message shorter than its layout')

    def align(self, n: int) -> None:
        self.pos += -(self.pos - 4) % n

    def skip(self, n: int, align: int) -> None:
        self.align(align)
        self._need(n)
        self.pos += n

    def uint32(self) -> int:
        """A length or count: pinned (messages with another value have another layout)."""
        self.align(4)
        self._need(4)
        self.checks.append((self.pos, bytes(self.data[self.pos:self.pos + 4])))
        value = self.u32.unpack_from(self.data, self.pos)[0]
        self.pos += 4
        return value

    def string(self, pin_text: bool = False) -> str:
        n = self.uint32()
        self._need(n)
        text = bytes(self.data[self.pos:self.pos + n])
        if pin_text:
            self.checks.append((self.pos, text))
        self.pos += n
        return text.rstrip(b'\x00').decode('utf-8', 'replace')

    def float64(self, count: int) -> int:
        """Offset of ``count`` doubles (an empty array is not aligned, as CDR writers do)."""
        if count:
            self.align(8)
        self._need(8 * count)
        pos = self.pos
        self.pos += 8 * count
        return pos


@dataclass
class _Layout:
    little: bool
    end: int
    checks: list[tuple[int, bytes]]
    fields: dict[str, tuple[int, int]]   # name -> (offset, number of float64)
    extra: Any = None

    @property
    def key(self):
        return tuple(self.checks)


def _header(c: _Cursor) -> None:
    c.skip(8, 4)          # builtin_interfaces/Time: int32 sec, uint32 nanosec
    c.string()            # frame_id


def _odometry(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    c.string()                                   # child_frame_id
    fields = {'position': (c.float64(3), 3), 'orientation': (c.float64(4), 4)}
    c.float64(36)
    fields['linear'] = (c.float64(3), 3)
    fields['angular'] = (c.float64(3), 3)
    c.float64(36)
    return fields, None


def _vector3_stamped(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    return {'vector': (c.float64(3), 3)}, None


def _joint_state(c: _Cursor) -> tuple[dict, Any]:
    _header(c)
    names = tuple(c.string(pin_text=True) for _ in range(c.uint32()))
    fields = {}
    for name in ('position', 'velocity', 'effort'):
        n = c.uint32()
        fields[name] = (c.float64(n), n)
    return fields, names


LAYOUTS: dict[str, Callable[[_Cursor], tuple[dict, Any]]] = {
    'nav_msgs/msg/Odometry': _odometry,
    'geometry_msgs/msg/Vector3Stamped': _vector3_stamped,
    'sensor_msgs/msg/JointState': _joint_state,
}
MAX_TEMPLATES = 16


class _TemplateBudget:
    """When to stop vectorising a batch by layout templates and parse the rest one by one.

    A template that matched only its own message (a one-off layout) cost a pass over the batch
    for nothing: after ``MAX_TEMPLATES`` of those, or ``4 * MAX_TEMPLATES`` passes in all, the
    remaining messages are parsed individually (so many distinct layouts stay linear in time).
    """

    def __init__(self) -> None:
        self.passes = self.misses = 0

    def left(self) -> bool:
        return self.misses < MAX_TEMPLATES and self.passes < 4 * MAX_TEMPLATES

    def used(self, matched: int) -> None:
        self.passes += 1
        self.misses += matched <= 1


def _layout(type_name: str, data: bytes) -> _Layout | None:
    try:
        c = _Cursor(data)
        fields, extra = LAYOUTS[type_name](c)
    except (ValueError, struct.error, UnicodeDecodeError):
        return None
    return _Layout(c.little, c.pos, c.checks, fields, extra)


@dataclass
class Columns:
    """Decoded messages of one layout: ``rows`` index the batch's messages (ascending)."""

    rows: np.ndarray
    sec: np.ndarray                 # int64 stamp seconds
    nanosec: np.ndarray             # int64 stamp nanoseconds
    fields: dict[str, np.ndarray]   # float64 (n, k) per field
    extra: Any = None               # JointState: the joint names

    @property
    def stamp(self) -> np.ndarray:
        """Stamps in seconds (``sec + nanosec * 1e-9``)."""
        return self.sec + self.nanosec * 1e-9

    @property
    def stamp_ns(self) -> np.ndarray:
        return self.sec * 1_000_000_000 + self.nanosec


def _gather(buf: np.ndarray, starts: np.ndarray, nbytes: int) -> np.ndarray:
    return buf[starts[:, None] + np.arange(nbytes)]


def header_time(buf: np.ndarray, starts: np.ndarray, e: str) -> tuple[np.ndarray, np.ndarray]:
    """int64 ``(sec, nanosec)`` of the ``builtin_interfaces/Time`` that follows the 4-byte
    encapsulation of each message starting at ``starts`` in ``buf`` (byte order ``e``: '<' or '>'),
    the stamp of every header-first message."""
    stamp = _gather(buf, starts + 4, 8)
    sec = stamp[:, :4].copy().view(e + 'i4')[:, 0].astype(np.int64)
    nsec = stamp[:, 4:].copy().view(e + 'u4')[:, 0].astype(np.int64)
    return sec, nsec


def _columns(batch: TopicBatch, rows: np.ndarray, layout: _Layout) -> Columns:
    starts = batch.starts[rows]
    e = '<' if layout.little else '>'
    sec, nsec = header_time(batch.buf, starts, e)
    fields = {}
    for name, (off, n) in layout.fields.items():
        if n:
            fields[name] = _gather(batch.buf, starts + off, 8 * n).view(e + 'f8').astype(np.float64)
        else:
            fields[name] = np.zeros((rows.size, 0))
    return Columns(rows, sec, nsec, fields, layout.extra)


def _matching(batch: TopicBatch, rows: np.ndarray, layout: _Layout) -> np.ndarray:
    """Boolean mask over ``rows``: messages with exactly ``layout``."""
    mask = batch.sizes[rows] >= layout.end
    for off, expected in layout.checks:
        sub = rows[mask]
        if not sub.size:
            break
        got = _gather(batch.buf, batch.starts[sub] + off, len(expected))
        ok = np.all(got == np.frombuffer(expected, np.uint8), axis=1)
        mask[np.flatnonzero(mask)[~ok]] = False
    return mask


def decode_batch(batch: TopicBatch) -> list[Columns]:
    """The stamps and float fields of every message of ``batch``, one :class:`Columns` per layout.

    Types: ``nav_msgs/Odometry`` (fields ``position``, ``orientation``, ``linear``, ``angular``),
    ``geometry_msgs/Vector3Stamped`` (``vector``) and ``sensor_msgs/JointState`` (``position``,
    ``velocity``, ``effort``; ``extra`` = names). Each distinct layout (string and sequence
    lengths, byte order, joint names) is parsed once in Python from its first message; the fields
    of all messages sharing it are gathered with numpy. Messages that do not parse are skipped.
    """
    if batch.type_name not in LAYOUTS:
        raise ValueError(f'no column decoder for {batch.type_name}')
    out = []
    rows = np.arange(len(batch))
    budget = _TemplateBudget()
    while rows.size and budget.left():
        layout = _layout(batch.type_name, batch.message(rows[0]))
        if layout is None:
            budget.used(0)
            rows = rows[1:]
            continue
        mask = _matching(batch, rows, layout)
        out.append(_columns(batch, rows[mask], layout))
        budget.used(int(mask.sum()))
        rows = rows[~mask]
    if rows.size:  # many distinct layouts: parse each message, gather per layout
        groups: dict[Any, tuple[_Layout, list[int]]] = {}
        for r in rows.tolist():
            layout = _layout(batch.type_name, batch.message(r))
            if layout is not None:
                groups.setdefault(layout.key, (layout, []))[1].append(r)
        out.extend(_columns(batch, np.array(r, dtype=np.int64), lay) for lay, r in groups.values())
    return out


def decode_diagnostics(batch: TopicBatch) -> tuple[np.ndarray, list[list[tuple]]]:
    """``diagnostic_msgs/DiagnosticArray`` messages: (stamps in s, statuses per message).

    Each status is a tuple ``(level, name, message, hardware_id, {key: value})``; names and keys
    are shared string objects across messages. No rosbags deserialisation: the first message of
    a structure (number of statuses, their names, their keys) is parsed in Python, then every
    message with the same structure is walked with numpy (only the value strings' lengths
    differ from message to message) and its strings cut from one decoded blob. Messages that do
    not parse are skipped (their stamp is not returned either).
    """
    n = len(batch)
    stamps = np.zeros(n)
    out: list = [None] * n
    names: dict[bytes, str] = {}
    rows = np.arange(n)
    budget = _TemplateBudget()
    while rows.size and budget.left():
        try:
            template = _diagnostic_array(batch.message(rows[0]), names)
        except (ValueError, struct.error, IndexError, UnicodeDecodeError):
            budget.used(0)
            rows = rows[1:]
            continue
        done = _diagnostics_like(batch, rows, batch.message(rows[0])[:2], template[1], stamps, out)
        if not done[0]:  # (cannot happen: a message has its own structure) parse it on its own
            stamps[rows[0]], out[rows[0]] = template
            done[0] = True
        budget.used(int(done.sum()))
        rows = rows[~done]
    for r in rows.tolist():
        try:
            stamps[r], out[r] = _diagnostic_array(batch.message(r), names)
        except (ValueError, struct.error, IndexError, UnicodeDecodeError):
            pass
    keep = [i for i, x in enumerate(out) if x is not None]
    if len(keep) == n:
        return stamps, out
    return stamps[keep], [out[i] for i in keep]


class _VecWalk:
    """CDR walk of many messages at once; messages that leave the expected structure drop out."""

    def __init__(self, batch: TopicBatch, rows: np.ndarray, little: bool) -> None:
        self.buf = batch.buf
        self.sel = np.arange(rows.size)             # indices into rows still matching
        self.start = batch.starts[rows]
        self.size = batch.sizes[rows]
        self.r = np.full(rows.size, 4, dtype=np.int64)
        self.e = '<' if little else '>'
        self.cols: list[np.ndarray] = []            # recorded per-message arrays, aligned with sel

    def keep(self, ok: np.ndarray) -> None:
        if not ok.all():
            self.sel, self.r = self.sel[ok], self.r[ok]
            self.cols = [c[ok] for c in self.cols]

    def need(self, width) -> None:
        self.keep(self.r + width <= self.size[self.sel])

    def at(self) -> np.ndarray:
        return self.start[self.sel] + self.r

    def octet(self) -> int:
        self.need(1)
        self.cols.append(self.buf[self.at()].astype(np.int64))
        self.r = self.r + 1
        return len(self.cols) - 1

    def uint32(self) -> np.ndarray:
        self.r = (self.r + 3) & ~3
        self.need(4)
        value = _gather(self.buf, self.at(), 4).view(self.e + 'u4')[:, 0].astype(np.int64)
        self.r = self.r + 4
        return value

    def count(self, expected: int) -> None:
        self.keep(self.uint32() == expected)

    def const_string(self, text: bytes) -> None:
        self.keep(self.uint32() == len(text))
        self.need(len(text))
        if text:
            got = _gather(self.buf, self.at(), len(text))
            self.keep(np.all(got == np.frombuffer(text, np.uint8), axis=1))
        self.r = self.r + len(text)

    def string(self) -> int:
        """Record (start, length without the NUL) of a string; returns the column index."""
        n = self.uint32()
        ok = self.r + n <= self.size[self.sel]
        if not ok.all():
            self.sel, self.r, n = self.sel[ok], self.r[ok], n[ok]
            self.cols = [c[ok] for c in self.cols]
        self.cols.append(self.at())
        self.cols.append(np.maximum(n - 1, 0))
        self.r = self.r + n
        return len(self.cols) - 2


def _cdr_text(value: str) -> bytes:
    return value.encode() + b'\x00'


def _strings(buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> list[str]:
    """Decode many strings at once: gather their bytes into one blob, decode once, cut."""
    total = int(lengths.sum())
    if total == 0:
        return [''] * int(lengths.size)
    ends = np.cumsum(lengths)
    blob = buf[np.repeat(starts - (ends - lengths), lengths) + np.arange(total)].tobytes()
    bounds = ends.tolist()
    lo = [0] + bounds[:-1]
    if blob.isascii():
        text = blob.decode('ascii')
        return [text[a:b] for a, b in zip(lo, bounds)]
    return [blob[a:b].decode() for a, b in zip(lo, bounds)]


def _diagnostics_like(batch: TopicBatch, rows: np.ndarray, encapsulation: bytes, template: list,
                      stamps: np.ndarray, out: list) -> np.ndarray:
    """Decode the messages of ``rows`` with the structure of ``template``; the mask of those done."""
    walk = _VecWalk(batch, rows, encapsulation[1:2] == b'\x01')
    enc = _gather(batch.buf, walk.start, 2)
    walk.keep(np.all(enc == np.frombuffer(encapsulation, np.uint8), axis=1))
    walk.need(12)
    walk.r = walk.r + 8                                  # the stamp
    walk.string()                                        # header.frame_id
    walk.count(len(template))
    layout = []
    for level, name, _, _, values in template:
        lv = walk.octet()
        walk.const_string(_cdr_text(name))
        msg, hw = walk.string(), walk.string()
        walk.count(len(values))
        cols = []
        for key in values:
            walk.const_string(_cdr_text(key))
            cols.append(walk.string())
        layout.append((lv, name, msg, hw, list(values), cols))
    done = np.zeros(rows.size, dtype=bool)
    if not walk.sel.size:
        return done
    try:
        def text(col):
            return _strings(batch.buf, walk.cols[col], walk.cols[col + 1])
        per_status = []
        for lv, name, msg, hw, keys, cols in layout:
            levels = walk.cols[lv].tolist()
            values = [text(c) for c in cols]
            per_status.append([(level, name, m, h, dict(zip(keys, vs)))
                               for level, m, h, *vs in zip(levels, text(msg), text(hw), *values)])
    except UnicodeDecodeError:
        return done
    picked = rows[walk.sel]
    sec, nsec = header_time(batch.buf, walk.start[walk.sel], walk.e)
    stamps[picked] = sec + nsec * 1e-9
    if not per_status:
        lists = [[] for _ in range(picked.size)]
    elif len(per_status) == 1:
        lists = [[s] for s in per_status[0]]
    else:
        lists = [list(x) for x in zip(*per_status)]
    for i, statuses in zip(picked.tolist(), lists):
        out[i] = statuses
    done[walk.sel] = True
    return done


_LE_U32, _BE_U32 = struct.Struct('<I').unpack_from, struct.Struct('>I').unpack_from


def _diagnostic_array(data: bytes, names: dict[bytes, str]) -> tuple[float, list[tuple]]:
    """One DiagnosticArray. Positions are absolute: with the 4-byte encapsulation header in front,
    CDR's 4-byte alignment is ``(pos + 3) & ~3``; a string is followed by unaligned data.
    ``names`` caches the decoded repeating strings (bytes -> str)."""
    if len(data) < 16 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError('unsupported CDR encapsulation')
    little = data[1] == 1
    u32 = _LE_U32 if little else _BE_U32
    sec, nsec = struct.unpack_from('<iI' if little else '>iI', data, 4)
    pos = (19 + u32(data, 12)[0]) & ~3               # past header.frame_id, aligned
    count = u32(data, pos)[0]
    pos += 4
    statuses = []
    for _ in range(count):
        level = data[pos]
        pos = (pos + 4) & ~3                            # the level octet, then align
        strs = []
        for _ in range(3):                              # name, message, hardware_id
            n = u32(data, pos)[0]
            raw = data[pos + 4:pos + 3 + n]
            text = names.get(raw)
            if text is None:
                text = names[raw] = raw.decode()
            strs.append(text)
            pos = (pos + 7 + n) & ~3
        nv = u32(data, pos)[0]
        pos += 4
        values = {}
        for _ in range(nv):
            pos = (pos + 3) & ~3
            n = u32(data, pos)[0]
            raw = data[pos + 4:pos + 3 + n]
            key = names.get(raw)
            if key is None:
                key = names[raw] = raw.decode()
            pos = (pos + 7 + n) & ~3
            n = u32(data, pos)[0]
            values[key] = data[pos + 4:pos + 3 + n].decode()
            pos += 4 + n                                # unaligned: a level octet may follow
        statuses.append((level, strs[0], strs[1], strs[2], values))
    if pos > len(data):
        raise ValueError('DiagnosticArray past the end of its message')
    return sec + nsec * 1e-9, statuses
