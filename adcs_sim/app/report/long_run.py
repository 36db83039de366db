"""A long run's report without holding the run (issue #18: a day at 10 Hz in <= 300 MB): :func:`load_long`.

:meth:`~adcs_sim.app.analysis.run_data.RunData.from_bag` holds every series of a run, ~620 B a step. A
report draws a series of more than :data:`~.envelope.MAX_POINTS` samples from its envelope
(:func:`~.envelope.reduced`), and the envelope of any superset of an envelope's samples is that
envelope (the same columns: the first and last samples are in it; the same first smallest, largest
and NaN sample of each column). So a long run is read in two streaming passes into a
:class:`RunData` that holds, of each series, only the samples the report can draw:

1. the metrics as :mod:`adcs_sim.app.analysis.stream_metrics` computes them (run_metrics' bit for bit), the
   recording's other fields (:func:`~adcs_sim.app.analysis.run_data.set_recording`) and the first and last
   stamps and the length of each series: where its envelope's columns are cut;
2. every series the report draws — the derived ones (errors to the reference, 2-1-3 angles, their
   log-axis masks, torques in N·m and in mN·m) computed per chunk with the code the figures run on
   the whole arrays — into :class:`~.envelope.EnvelopeStream`; the samples kept are those of the
   envelopes, the columns' first and last, the samples on both sides of each change of a status
   text, at each fault, and every k-th sample so that the kept series stays longer than
   MAX_POINTS (the figures then reduce it: to the whole series' envelope). Whole-run numbers a
   figure or table prints besides the metrics (settling times of the lead figures and rows) are
   band tracks of the same chunks.

What this does not cover is read in memory as before (:class:`Unstreamable`, the reason in its
text): kinds other than ``unknown`` and ``regulation``, a fault on the controller's actuators,
the three-wheel slew, thrusters, a phase that changes, joint names that change, a controller
status with several statuses or layouts, stamps out of file order, a status text that changes
more than :data:`MAX_TEXT_CHANGES` times.
"""
from __future__ import annotations

import ctypes
import math
from collections import defaultdict
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis import run_data as rd
from adcs_sim.app.analysis import stream_metrics as sm
from adcs_sim.app.analysis.metrics import attitude_errors
from adcs_sim.app.report import envelope
from adcs_sim.app.report.envelope import log_positive
from adcs_sim.app.report.kinds import PHASE_KEYS, _unit, param_value, run_kind
from adcs_sim.app.report.lead import actuator_fault
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.app.analysis.status_records import TORQUE_KEYS, StatusRecords
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.columns import decode_batch, decode_diagnostics, header_time

Unstreamable = sm.Unstreamable
STREAM_KINDS = ('unknown', 'regulation')
MAX_TEXT_CHANGES = 20_000     # changes of a status text kept (each keeps two status records)
SCALES = (1.0, 1e3)           # torque_unit's scales: N·m, mN·m
BANDS = (1.0, 0.5)            # comparison_rows' bands (the regulation lead)
BATCH_BYTES = sm.STREAM_BATCH_BYTES   # storage bytes a batch of the passes
PRUNE_ROWS = 20_000           # rows a series stores beyond twice the kept ones before it prunes


@dataclass
class LongSummary:
    """What the report needs of the whole run besides the kept samples."""

    tol: tuple                 # (tol_deg, eigen_tol_deg) of the metrics
    metrics: dict              # run_metrics of the whole run at ``tol``
    samples: int               # state samples of the whole run
    settled: dict = field(default_factory=dict)   # (series, band) -> settling time (s), kind_figures
    rows: dict | None = None   # comparison_rows of the whole run (regulation lead)


def load_long(path, tol_deg: float = 0.5, eigen_tol_deg: float | None = None,
              batch_bytes: int | None = None) -> tuple[RunData, LongSummary]:
    """The kept samples of a long run (module docstring) and its whole-run numbers. Raises
    :class:`Unstreamable` (read it in memory) or as :meth:`RunData.from_bag` does."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    batch_bytes = BATCH_BYTES if batch_bytes is None else batch_bytes
    reader = ColumnReader(path, rd.topic_selector(None, rd.READ_TYPES), batch_bytes=batch_bytes)
    first = _FirstPass(reader)
    first.run()
    counts = {name: n for name, n in reader.topic_counts.items() if n}
    ns = rd._namespace(counts, reader.topics)
    run = RunData(t=np.zeros(0), q=np.zeros((0, 4)), w=np.zeros((0, 3)))
    rd.set_recording(run, reader, first.diagnostics, ns)
    spans = first.spans(path, ns)
    kind = run_kind(run.scenario)
    target = _target(run, kind)
    second = _SecondPass(path, ns, spans, run, target, (tol_deg, eigen_tol_deg), batch_bytes)
    second.run()
    metrics, _ = second.metrics_pass.metrics(path, ns)
    second.finish(run, kind)
    summary = LongSummary((tol_deg, eigen_tol_deg), metrics, spans['state'][1][2], second.settled())
    if kind.kind == 'regulation':
        summary.rows = second.comparison_rows(metrics, eigen_tol_deg)
    return run, summary


def release_memory() -> None:
    """Give the memory the passes freed back to the system (glibc's ``malloc_trim``; elsewhere
    nothing): their many small arrays leave the heap in holes that the figures' allocations (in
    other arenas) do not reuse, ~50 MiB on a day at 10 Hz."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _target(run: RunData, kind) -> np.ndarray:
    """The constant reference of a run the streamed report covers (kinds.reference_attitude's
    without a slew); a regulation run's must be the scenario's target (its comparison rows, from
    the same band tracks, measure against that)."""
    if kind.kind not in STREAM_KINDS:
        raise Unstreamable(f'a {kind.kind} run')
    if actuator_fault(run, kind):
        raise Unstreamable('a fault on the controller\'s actuators')
    if param_value(kind.params, 'three_wheel.enabled'):
        raise Unstreamable('the three-wheel slew')
    if run.topic_counts.get(topics.THRUSTERS_STATE):
        raise Unstreamable('thrusters')
    target = _unit(param_value(kind.params, 'target.attitude', [0.0, 0.0, 0.0, 1.0]))
    target = run.q_ref if target is None else target
    if kind.kind == 'regulation' and not np.array_equal(target, run.q_ref):
        raise Unstreamable('the controller\'s target is not the scenario\'s')
    return target


def header_stamps(batch) -> np.ndarray:
    """The header stamps (s) of a batch of stamped messages (header first: Odometry, JointState,
    Vector3Stamped, DiagnosticArray), as adcs_sim.bag.columns computes them (the second pass checks
    that it decodes every message, to the same stamps)."""
    if np.any(batch.sizes < 12):
        raise Unstreamable(f'{batch.topic}: a message shorter than its header')
    order = batch.buf[batch.starts + 1]   # the encapsulation's byte-order flag
    if np.all(order == 1):
        e = '<'
    elif np.all(order == 0):
        e = '>'
    else:
        raise Unstreamable(f'{batch.topic}: mixed byte orders')
    sec, nsec = header_time(batch.buf, batch.starts, e)
    return sec + nsec * 1e-9


def _span(spans: dict, topic: str, t: np.ndarray) -> None:
    """Note the stamps ``t`` (the next ones, in file order) in ``spans[topic]`` = [first, last, count]."""
    if t.size:
        span = spans.setdefault(topic, [t[0], t[-1], 0])
        span[1], span[2] = t[-1], span[2] + t.size


class _FirstPass:
    """Pass 1: the span of every stamped series (header stamps only, nothing decoded) and the other
    diagnostics (small: faults, the dynamics node's status, intruders), decoded."""

    def __init__(self, reader: ColumnReader) -> None:
        self.reader = reader
        self.found: dict[str, list] = {}   # topic -> [first stamp, last stamp, count]
        self.diagnostics: dict[str, list] = defaultdict(list)

    def run(self) -> None:
        for batch in self.reader:
            if batch.type_name == rd.DIAGNOSTIC_ARRAY and not batch.topic.endswith('/' + topics.CONTROLLER_STATUS):
                self.diagnostics[batch.topic].append(decode_diagnostics(batch))
            elif len(batch):
                _span(self.found, batch.topic, header_stamps(batch))

    def spans(self, path, ns: str) -> dict:
        """{series: (topic, [first stamp, last stamp, count])} of the state (truth when recorded),
        the applied torque, the wheels and the controller status (those with messages)."""
        found = self.found
        state = ns + (topics.TRUTH_STATE if ns + topics.TRUTH_STATE in found else topics.STATE)
        if state not in found:
            raise rd._no_state(path, self.reader, ns + topics.STATE)
        out = {'state': (state, found[state])}
        for key, rel in (('torque', topics.APPLIED_TORQUE), ('wheels', topics.WHEELS_STATE),
                         ('status', topics.CONTROLLER_STATUS)):
            if ns + rel in found:
                out[key] = (ns + rel, found[ns + rel])
        return out


class _Series:
    """One series of the second pass (its first and last stamps and length known): the envelopes of
    what is drawn of it, and the rows (stamp and fields) of the samples it may keep, chunk by chunk.
    Kept whatever the values: each column's first and last samples, every k-th sample (more than
    MAX_POINTS in all), the first at or after each of ``times``, and the extra ones :meth:`add` names."""

    def __init__(self, span, times=()) -> None:
        self.first, self.last, self.n = span
        self.long = self.n > envelope.MAX_POINTS
        self.env = envelope.EnvelopeStream(self.first, self.last - self.first)
        self.stride = max(1, self.n // (envelope.MAX_POINTS + 1))
        self.times = sorted(times)     # the first sample at or after each (fault events)
        self.i0 = 0
        self.prev = None               # the latest stamp read
        self.blocks: list = []         # (indices, rows) of the samples stored
        self.stored = self.pruned = 0  # rows stored, and after the last pruning
        self.extra: list = []          # more samples to keep, found while reading

    def add(self, t: np.ndarray, rows: np.ndarray, ys: dict, more=()) -> None:
        """The next samples (stamps ``t``, their ``rows``), the drawn series ``ys`` ({name: values})
        and other samples to keep (``more``: indices in the series, up to the last one read; each
        chunk's last sample is stored, so ``more`` may name the previous chunk's)."""
        i0, i1 = self.i0, self.i0 + t.size
        if not t.size:
            return
        self._check(t)
        while self.times and t[-1] >= self.times[0]:
            more = [*more, i0 + int(np.searchsorted(t, self.times.pop(0)))]
        self.extra += list(more)
        if self.long:
            column = self.env.column(t)
            new = [self.env.ends(column, i0)]
            if ys:
                new.append(self.env.add_many(list(ys), column, i0, np.column_stack(list(ys.values()))))
            more = np.asarray(more, dtype=np.int64)
            pinned = np.arange(i0 + (-i0) % self.stride, i1, self.stride)
            idx = np.unique(np.concatenate([pinned, more[more >= i0], [i1 - 1], *new]))
        else:
            idx = np.arange(i0, i1)
        self.blocks.append((idx, rows[idx - i0]))
        self.stored += idx.size
        self.i0 = i1
        if self.long and self.stored > 2 * self.pruned + PRUNE_ROWS:
            self._prune()

    def _prune(self) -> None:
        """Drop the stored rows no longer kept (a column's smallest superseded by a later sample):
        the rows held stay within about twice the kept ones."""
        idx, rows = self._stored()
        keep = np.isin(idx, self._final()) | (idx == self.i0 - 1)
        self.blocks = [(idx[keep], rows[keep])]
        self.stored = self.pruned = int(keep.sum())

    def _stored(self) -> tuple[np.ndarray, np.ndarray]:
        idx = np.concatenate([b[0] for b in self.blocks])
        rows = np.concatenate([b[1] for b in self.blocks])
        idx, first = np.unique(idx, return_index=True)
        return idx, rows[first]

    def _final(self) -> np.ndarray:
        """The samples kept of those read so far."""
        pinned = np.arange(0, self.i0, self.stride)
        return np.unique(np.concatenate([pinned, self.env.indices(), np.asarray(self.extra, dtype=np.int64)]))

    def _check(self, t: np.ndarray) -> None:
        """The second pass reads the first pass's stamps, in order (else the bag is not as read)."""
        ordered = not np.any(np.diff(t) < 0) and (self.prev is None or t[0] >= self.prev)
        if not ordered or self.i0 + t.size > self.n or (self.i0 == 0 and t[0] != self.first):
            raise Unstreamable('the second pass did not read the first pass\'s stamps')
        self.prev = t[-1]

    def kept(self) -> tuple[np.ndarray, np.ndarray]:
        """(indices, rows) of the kept samples: the pinned ones, the envelopes' and the extra ones."""
        if self.i0 != self.n or self.prev != self.last:
            raise Unstreamable('the second pass did not read the first pass\'s stamps')
        idx, rows = self._stored()
        if not self.long:
            return idx, rows
        final = self._final()
        keep = np.isin(idx, final)
        if int(keep.sum()) != final.size:
            raise Unstreamable('a kept sample was not read')  # (cannot happen: every candidate is stored)
        return idx[keep], rows[keep]


class _Status:
    """The controller status of the second pass: one status per message, one (name, keys)
    layout; per key, the envelope of its numbers or the changes of its text."""

    def __init__(self, span) -> None:
        self.series = _Series(span)
        self.layout = None              # (name, keys)
        self.numeric: dict = {}         # key -> True while every value parsed
        self.changes: dict = defaultdict(list)   # key -> indices where its text changes
        self.last: dict = {}            # key -> the latest value text
        self.finite: dict = {}          # key -> first sample with a finite value

    def add(self, batch) -> None:
        stamps, messages = decode_diagnostics(batch)
        i0 = self.series.i0
        if len(messages) != len(batch):
            raise Unstreamable(f'{batch.topic}: a message that does not decode')
        if not messages:
            return
        if self.layout is None:
            self.layout = (messages[0][0][1], tuple(messages[0][0][4]))
        name, keys = self.layout
        # one status a message, of one name and one set of keys (their order does not matter to
        # the report: the keys are listed in the order they first appear)
        statuses = [m[0] for m in messages if len(m) == 1 and m[0][1] == name]
        values = [s[4] for s in statuses if len(s[4]) == len(keys)]
        if len(values) != len(messages):
            raise Unstreamable(f'{batch.topic}: the status layout changes')
        try:
            texts = {k: np.array([v[k] for v in values], dtype=object) for k in keys}
        except KeyError:
            raise Unstreamable(f'{batch.topic}: the status layout changes') from None
        ys, more = {}, []
        for k, raw in texts.items():
            ys.update(self._key(k, raw, i0, more))
        rows = np.empty((len(messages), 1 + len(keys)), dtype=object)
        rows[:, 0] = stamps.tolist()
        for j, k in enumerate(keys):
            rows[:, 1 + j] = texts[k]
        self.series.add(stamps, rows, ys, more)

    def _key(self, key: str, raw: np.ndarray, i0: int, more: list) -> dict:
        """The drawn series of one key's values ``raw`` (samples ``i0 ..``), the text changes noted in ``more``."""
        prev = self.last.get(key)
        if raw.size:
            self.last[key] = raw[-1]
        values = None
        if self.numeric.get(key, True):
            try:
                values = np.array(raw.tolist(), dtype=float)
            except ValueError:
                pass
        if values is None:
            if self.numeric.get(key) and i0 > 0:
                raise Unstreamable(f'status value {key}: numbers, then text')
            self.numeric[key] = False
            change = np.flatnonzero(raw[1:] != raw[:-1]) + 1
            if prev is not None and raw.size and raw[0] != prev:
                change = np.r_[0, change]
            self.changes[key].extend((i0 + change).tolist())
            if len(self.changes[key]) > MAX_TEXT_CHANGES:
                raise Unstreamable(f'status value {key}: more than {MAX_TEXT_CHANGES} changes')
            more += [i for c in change.tolist() for i in (i0 + c - 1, i0 + c) if i >= 0]
            return {}
        self.numeric[key] = True
        finite = np.flatnonzero(np.isfinite(values))
        if key not in self.finite and finite.size:
            self.finite[key] = i0 + int(finite[0])
            more.append(self.finite[key])
        ys = {key: values}
        if key in TORQUE_KEYS:
            ys[f'{key}*1e3'] = SCALES[1] * values
        return ys

    def records(self) -> StatusRecords:
        """The kept status records (frozen)."""
        _, rows = self.series.kept()
        name, keys = self.layout
        out = StatusRecords()
        out.add(np.asarray(rows[:, 0], dtype=float), [[(0, name, '', '', dict(zip(keys, r[1:])))] for r in rows])
        return out.freeze()


class _SecondPass:
    """Pass 2 (module docstring) over the series of the first pass's ``stamps``."""

    def __init__(self, path, ns: str, spans: dict, run: RunData, target: np.ndarray, tol: tuple,
                 batch_bytes: int) -> None:
        self.topics = {topic: key for key, (topic, _) in spans.items()}
        self.reader = ColumnReader(path, rd.topic_selector(ns, rd.READ_TYPES), batch_bytes=batch_bytes)
        self.metrics_pass = sm._Pass(self.reader, *tol)   # run_metrics, streamed (stream_metrics)
        self.target = target
        self.series = {'state': _Series(spans['state'][1], [t for t, _, _, _ in run.faults])}
        for key in ('torque', 'wheels'):
            if key in spans:
                self.series[key] = _Series(spans[key][1])
        self.status = _Status(spans['status'][1]) if 'status' in spans else None
        self.tracks = {(name, band): sm.BandTrack(band) for name, bands in
                       (('eigen', {tol[1], 0.5}), ('euler_all', BANDS), ('euler_0', BANDS), ('euler_1', BANDS),
                        ('euler_2', BANDS)) for band in bands}
        self.wheel_names = None

    def run(self) -> None:
        for batch in self.reader:
            self._batch(batch)
            self.metrics_pass.seen[batch.topic] += len(batch)

    def _batch(self, batch) -> None:
        key = self.topics.get(batch.topic)
        if key == 'status':
            self.status.add(batch)
        elif batch.type_name == rd.DIAGNOSTIC_ARRAY:
            self.metrics_pass.diagnostics[batch.topic].append(decode_diagnostics(batch))
        else:
            parts = decode_batch(batch)
            self.metrics_pass._columns(batch.topic, batch.type_name, parts)   # (before _wheels fills an effort)
            if key == 'state':
                self._state(parts)
            elif key == 'torque':
                t, _, u = sm._in_file_order(parts, 'vector')
                ys = {f'u{i}*{s:g}': s * u[:, i] for i in range(3) for s in SCALES}
                self.series['torque'].add(t, np.column_stack([t, u]), ys)
            elif key == 'wheels':
                self._wheels(parts)

    def _state(self, parts: list) -> None:
        t, _, q = sm._in_file_order(parts, 'orientation')
        w = sm._in_file_order(parts, 'angular')[2]
        q_ref = np.broadcast_to(self.target, (t.size, 4)).copy()
        qe, eigen, euler = attitude_errors(SimpleNamespace(q=q), q_ref)
        ys = {'eigen': log_positive(eigen)}
        for i in range(4):   # (q_ref is constant: each column's first sample is its envelope)
            ys[f'q{i}'] = q[:, i]
        phase = qe * np.where(qe[:, 3:4] < 0, -1.0, 1.0)
        for i in range(3):
            ys[f'euler{i}'], ys[f'log_euler{i}'] = euler[:, i], log_positive(np.abs(euler[:, i]))
            ys[f'w{i}'], ys[f'phase{i}'] = w[:, i], phase[:, i]
        self.series['state'].add(t, np.column_stack([t, q, w]), ys)
        absolute = np.abs(euler)
        errors = {'eigen': eigen, 'euler_all': absolute.max(axis=1),
                  **{f'euler_{i}': absolute[:, i] for i in range(3)}}
        for (name, _), track in self.tracks.items():
            track.add(t, errors[name])

    def _wheels(self, parts: list) -> None:
        parts = [c for c in parts if c.rows.size]
        if not parts:
            return
        self.wheel_names = self.wheel_names or parts[0].extra
        n = len(self.wheel_names)
        for c in parts:
            if c.extra != self.wheel_names or c.fields['velocity'].shape[1] != n:
                raise Unstreamable('the wheels\' joints change during the run')
            if c.fields['effort'].shape[1] != n:
                c.fields['effort'] = np.full((c.rows.size, n), math.nan)
        t, _, speed = sm._in_file_order(parts, 'velocity')
        torque = sm._in_file_order(parts, 'effort')[2]
        ys = {f'speed{j}': speed[:, j] for j in range(n)}
        ys.update({f'torque{j}*{s:g}': s * torque[:, j] for j in range(n) for s in SCALES})
        self.series['wheels'].add(t, np.column_stack([t, speed, torque]), ys)

    def finish(self, run: RunData, kind) -> None:
        """The kept samples into ``run`` (its series, its controller status)."""
        _, rows = self.series['state'].kept()
        run.t, run.q, run.w = rows[:, 0].copy(), rows[:, 1:5].copy(), rows[:, 5:8].copy()
        if 'torque' in self.series:
            _, rows = self.series['torque'].kept()
            run.t_u, run.u = rows[:, 0].copy(), rows[:, 1:4].copy()
        if 'wheels' in self.series and self.wheel_names is not None:
            _, rows = self.series['wheels'].kept()
            n = len(self.wheel_names)
            run.t_wheels, run.wheel_names = rows[:, 0].copy(), list(self.wheel_names)
            run.wheel_speed, run.wheel_torque = rows[:, 1:1 + n].copy(), rows[:, 1 + n:].copy()
        if self.status is not None and self.status.layout is not None:
            phase = PHASE_KEYS.get(kind.kind)
            if phase in self.status.changes and len(self.status.changes[phase]) > 0:
                raise Unstreamable(f'the run\'s {phase} changes')
            run.controller_status = self.status.records()

    def settled(self) -> dict:
        """{(series, band): settling time} of the lead figures (kind_figures)."""
        return {key: track.settling() for key, track in self.tracks.items()}

    def comparison_rows(self, metrics: dict, eigen_tol_deg: float) -> dict:
        """lead.comparison_rows of the whole run (bands 1 and 0.5, eigenaxis at 0.5), from the
        tracks and the tolerance-free metrics."""
        rows = {}
        for band in BANDS:
            for label, i in (('theta1_x', 1), ('theta2_y', 0), ('theta3_z', 2)):
                rows[f'settling_euler213_{label}_{band:g}deg_s'] = self.tracks[f'euler_{i}', band].settling()
            rows[f'settling_euler213_all_{band:g}deg_s'] = self.tracks['euler_all', band].settling()
        rows['settling_eigenaxis_0.5deg_s'] = self.tracks['eigen', 0.5].settling()
        for key in ('final_eigenaxis_error_deg', 'integrated_torque_Nms', 'control_energy_N2m2s'):
            rows[key] = metrics[key]
        for a, v in zip('xyz', metrics['peak_torque_Nm']):
            rows[f'peak_torque_{a}_Nm'] = v
        rows['peak_wheel_speed_rad_s'] = metrics['peak_wheel_speed_rad_s']
        rows['thruster_impulse_Ns'] = metrics.get('thruster_impulse_Ns')
        rows['missed_steps'] = metrics['missed_steps']
        rows['duration_s'] = metrics['duration_s']
        return rows
