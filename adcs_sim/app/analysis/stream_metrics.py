"""A run's metrics computed while its bag is read: :func:`analyse_bag` (issue #18 item 5).

:func:`~adcs_sim.app.analysis.metrics.run_metrics` on :meth:`RunData.from_bag` holds every series of the
run in memory (and the controller status, which no metric uses): its peak grows by ~620 B a step
(+539 MiB over the runner's imports for 24 h at 10 Hz). Here one streaming pass over the bag feeds,
chunk by chunk, what each metric needs:

* settling and first-entry times: per error series and band, the last sample outside the band
  and the one after it, the first inside and the one before it (:class:`BandTrack`);
* peaks (running maxima), final values, counts;
* the metrics defined once (:data:`adcs_sim.app.analysis.metric_defs.DEFINED`: torque integrals and
  peaks, wheel metrics), fed chunk by chunk to their definitions; the torque integrals keep their
  per-sample terms ``‖u_k‖ Δt_k`` and ``u_kᵀu_k Δt_k`` (8 B a step each) and sum them once at the
  end, so that numpy's pairwise summation sees the very array it sees in :func:`run_metrics` (its
  split points depend on the length, unknown until the end: a running sum would differ in the
  last bits); the torque stamps (8 B a step) for the integral after a fault;
* the state stamps (8 B a step): the settling after a fault needs the first sample after the
  fault's time, known only once the ``faults`` topic is read, and the missed-step gaps the median
  step; thruster on-times (one float per thruster and step, thruster runs only).

So the memory kept is 32 B a step (27 MB for 24 h at 10 Hz), and every operation on a sample is
the one :func:`run_metrics` does, in the same order: the metrics are equal bit for bit
(tests/test_stream_metrics.py). That needs each series' stamps in file order, and the scenario
(target attitude, pointing request) before the first state message, as the recorder writes it.
A bag that breaks either (stamps out of order, a scenario written after the data) is analysed by
the in-memory path instead: ``StreamResult.streamed`` says which was used.
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis import run_data as rd
from adcs_sim.app.analysis.metrics import (
    POINTING_BANDS_DEG,
    RunData,
    attitude_errors,
    band_crossing,
    first_fault_time,
    missed_step_gaps,
    pointing_error_deg,
    run_metrics,
)
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.columns import decode_batch, decode_diagnostics

FAULT_BANDS = (0.02, 0.01)   # fault_metrics' default bands
# Storage bytes per batch: RunData's 16 MiB batches cost ~50 MB more peak memory on a 24 h bag
# (the batch and its concatenation) and were not faster here (benchmarks/analysis_speed.py --memory).
STREAM_BATCH_BYTES = 4 << 20


class Unstreamable(Exception):
    """The bag cannot be analysed in one pass with run_metrics' numbers (the reason is the text)."""


@dataclass
class StreamResult:
    """What :func:`analyse_bag` found: the metrics, the recorder's intruder lines, the chosen
    namespace, whether the streamed pass gave them (False: the in-memory path, and why), and the
    recorder's lines about publishers of another type (no intruders: ``unmatchable_lines``)."""

    metrics: dict
    intrusions: list
    namespace: str
    streamed: bool = True
    reason: str | None = None
    unmatchable: list = field(default_factory=list)


class BandTrack:
    """:func:`~adcs_sim.app.analysis.metrics.settling_time` and ``first_entry_time`` of one error series
    at one tolerance, fed in order chunk by chunk; keeps four samples."""

    def __init__(self, tol: float) -> None:
        self.tol = tol
        self.t0 = None                 # the first sample's time
        self.last_out = None           # (t, e) of the last sample outside the band so far
        self.after_out = None          # (t, e) of the sample after it (None: it is the latest)
        self.first_in = None           # (t, e) of the first sample inside
        self.before_in = None          # (t, e) of the sample before that one (None: it was the first)
        self.prev = None               # (t, e) of the latest sample

    def add(self, t: np.ndarray, e: np.ndarray) -> None:
        if not t.size:
            return
        if self.t0 is None:
            self.t0 = t[0]
        if self.last_out is not None and self.after_out is None:
            self.after_out = (t[0], e[0])
        outside = np.flatnonzero(~(e <= self.tol))
        if outside.size:
            i = outside[-1]
            self.last_out = (t[i], e[i])
            self.after_out = (t[i + 1], e[i + 1]) if i + 1 < t.size else None
        if self.first_in is None:
            inside = np.flatnonzero(e <= self.tol)
            if inside.size:
                i = inside[0]
                self.first_in = (t[i], e[i])
                self.before_in = (t[i - 1], e[i - 1]) if i > 0 else self.prev
        self.prev = (t[-1], e[-1])

    def settling(self) -> float:
        if self.t0 is None:
            return math.nan
        if self.last_out is None:
            return float(self.t0)
        if self.after_out is None:
            return math.inf
        return band_crossing(*self.last_out, *self.after_out, self.tol)

    def first_entry(self) -> float:
        if self.first_in is None:
            return math.inf
        if self.before_in is None:
            return float(self.t0)
        return band_crossing(*self.before_in, *self.first_in, self.tol)


class _Ordered:
    """Checks that a topic's stamps never go back (then stamp order is file order, as RunData's
    stable sort by stamp leaves it)."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self.last_ns = None
        self.rows = 0

    def check(self, stamp_ns: np.ndarray) -> None:
        if not stamp_ns.size:
            return
        if np.any(np.diff(stamp_ns) < 0) or (self.last_ns is not None and stamp_ns[0] < self.last_ns):
            raise Unstreamable(f'{self.topic}: stamps out of file order')
        self.last_ns = stamp_ns[-1]
        self.rows += stamp_ns.size


class AttitudeStream(_Ordered):
    """The attitude metrics of one state topic (q_ref, pointing request and bands fixed at the start)."""

    def __init__(self, topic: str, q_ref: np.ndarray, pointing, tol_deg: float, eigen_tol_deg: float) -> None:
        super().__init__(topic)
        self.q_ref, self.pointing = q_ref, pointing
        self.eigen = BandTrack(eigen_tol_deg)
        self.worst = BandTrack(tol_deg)
        self.axes = [BandTrack(tol_deg) for _ in range(3)]
        self.bands = [BandTrack(b) for b in POINTING_BANDS_DEG] if pointing is not None else []
        self.t_parts: list[np.ndarray] = []     # state stamps (s)
        self.q4 = [BandTrack(b) for b in FAULT_BANDS]   # 1 - |q_e,4| (fault metrics)
        self.final_eigen = math.nan
        self.final_pointing = math.nan

    def add(self, t: np.ndarray, stamp_ns: np.ndarray, q: np.ndarray) -> None:
        self.check(stamp_ns)
        if not t.size:
            return
        chunk = SimpleNamespace(q=q, q_ref=self.q_ref, pointing=self.pointing)
        qe, eigen, euler = attitude_errors(chunk)
        euler = np.abs(euler)
        self.eigen.add(t, eigen)
        self.worst.add(t, euler.max(axis=1))
        for i, track in enumerate(self.axes):
            track.add(t, euler[:, i])
        self.final_eigen = float(eigen[-1])
        if self.bands:
            error = pointing_error_deg(chunk)
            for track in self.bands:
                track.add(t, error)
            self.final_pointing = float(error[-1])
        self.t_parts.append(t)
        q4 = 1.0 - np.abs(qe[:, 3])
        for track in self.q4:
            track.add(t, q4)

    def metrics(self, tol_deg: float, eigen_tol_deg: float) -> dict:
        """run_metrics' attitude entries, in its order."""
        return {'duration_s': float(self.t_parts[-1][-1]),
                f'settling_eigenaxis_{eigen_tol_deg:g}deg_s': self.eigen.settling(),
                f'settling_euler213_{tol_deg:g}deg_s': self.worst.settling(),
                'settling_euler213_per_axis_s': [track.settling() for track in self.axes],
                'final_eigenaxis_error_deg': self.final_eigen}

    def pointing_metrics(self) -> dict:
        out = {}
        for b, track in zip(POINTING_BANDS_DEG, self.bands):
            out[f'pointing_first_{b:g}deg_s'] = track.first_entry()
            out[f'pointing_settling_{b:g}deg_s'] = track.settling()
        out['final_pointing_error_deg'] = self.final_pointing
        return out


class TorqueStream(_Ordered):
    """Applied torque: its defined metrics (metric_defs.DEFINED: the integrals keep their terms,
    summed at the end) and its stamps (the integral after a fault)."""

    def __init__(self, topic: str) -> None:
        super().__init__(topic)
        self.t_parts: list[np.ndarray] = []
        self.defined = metric_defs.StreamedValues('torque')

    def add(self, t: np.ndarray, stamp_ns: np.ndarray, u: np.ndarray) -> None:
        self.check(stamp_ns)
        if not t.size:
            return
        self.t_parts.append(t)
        self.defined.add((), np.zeros(0), t, u)

    def norm_terms(self, t_end: float) -> tuple[np.ndarray, np.ndarray]:
        """(stamps, ``‖u‖ Δt`` of every sample, the last held to ``t_end``): the terms of
        :class:`~adcs_sim.app.analysis.metric_defs.IntegratedTorque` (its state, not a copy of its rule)."""
        metric = metric_defs.IntegratedTorque()
        return np.concatenate(self.t_parts), metric.terms(self.defined.state(metric.name, ()), t_end)[0]


class JointStream:
    """A JointState topic: per joint-name list, what the wheel / thruster metrics need of the
    messages with those names (RunData keeps those named as in the topic's last message)."""

    def __init__(self, topic: str, thrusters: bool, limits=None) -> None:
        self.order = _Ordered(topic)
        self.thrusters = thrusters
        self.limits = limits                           # names -> the wheels' speed limits (metric_defs)
        self.defined = metric_defs.StreamedValues()    # the metrics defined once, per names
        self.last_names = None
        self.on_time: dict = defaultdict(list)         # names -> [on-time parts] (thrusters)
        self.impulse: dict = {}                        # names -> latest impulse row (thrusters)

    def add(self, parts: list, row0: int) -> None:
        """``parts``: one batch's decoded Columns (one per layout), its first message the topic's
        ``row0``-th; checked in file order."""
        parts = [c for c in parts if c.rows.size]
        if not parts:
            return
        rows = np.concatenate([c.rows for c in parts])
        stamp_ns = np.concatenate([c.stamp_ns for c in parts])
        self.order.check(stamp_ns[np.argsort(rows, kind='stable')])
        self.last_names = max(parts, key=lambda c: c.rows[-1]).extra
        for c in parts:
            n = len(c.extra)
            if self.thrusters:
                if all(c.fields[k].shape[1] == n for k in ('position', 'velocity', 'effort')):
                    self.on_time[c.extra].append(c.fields['velocity'])
                    last = (row0 + int(c.rows[-1]), c.fields['position'][-1])
                    if c.extra not in self.impulse or last[0] > self.impulse[c.extra][0]:
                        self.impulse[c.extra] = last
        if not self.thrusters:   # the defined metrics in file order (several layouts: interleaved rows)
            for names in dict.fromkeys(c.extra for c in parts):
                same = [c for c in parts if c.extra == names and c.fields['velocity'].shape[1] == len(names)]
                if not same or not names:
                    continue
                t, _, speed = _in_file_order(same, 'velocity')
                self.defined.add(names, self.limits(names), t, speed)

    def defined_values(self) -> dict:
        """The defined metrics (metric_defs.DEFINED) of the wheels named in the last message."""
        return self.defined.values(self.last_names, len(self.last_names or ()))

    def thruster_metrics(self) -> dict:
        parts = self.on_time.get(self.last_names)
        if not parts or not sum(p.size for p in parts):
            return {}
        on_time = np.concatenate(parts)
        impulse = self.impulse[self.last_names][1]
        return {'thruster_impulse_Ns': float(impulse.sum()),
                'thruster_firings': int(np.count_nonzero(on_time > 0.0)),
                'thruster_on_time_s': float(on_time.sum())}


# Topics the streamed pass reads: RunData's, without the controller status (no metric uses it,
# and it was most of RunData's memory).
STREAM_TYPES = {rel: type_name for rel, type_name in rd.READ_TYPES.items() if rel != topics.CONTROLLER_STATUS}


def _in_file_order(parts: list, name: str):
    """(stamps s, stamps ns, field) of a batch's decoded parts, in file order."""
    parts = [c for c in parts if c.rows.size]
    if len(parts) == 1:
        c = parts[0]
        return c.stamp, c.stamp_ns, c.fields[name]
    if not parts:
        return np.zeros(0), np.zeros(0, dtype=np.int64), None
    order = np.argsort(np.concatenate([c.rows for c in parts]), kind='stable')
    return (np.concatenate([c.stamp for c in parts])[order], np.concatenate([c.stamp_ns for c in parts])[order],
            np.concatenate([c.fields[name] for c in parts])[order])


def _scenario_text(metadata: dict) -> str | None:
    return metadata.get('scenario', {}).get('text')


def _target(metadata: dict, bag) -> tuple[np.ndarray, object]:
    """(q_ref, pointing request) of the scenario in ``bag``'s metadata, as RunData sets them."""
    scenario = rd._scenario(_scenario_text(metadata), bag)
    if scenario is None:
        return np.array([0.0, 0.0, 0.0, 1.0]), None
    return rd.target_attitude(scenario), rd.pointing_request(scenario)


def _same_target(a: tuple, b: tuple) -> bool:
    """Whether two (q_ref, pointing request) are the same."""
    if not np.array_equal(a[0], b[0]) or (a[1] is None) != (b[1] is None):
        return False
    return a[1] is None or all(np.array_equal(x, y) for x, y in zip(a[1], b[1]))


class _Pass:
    """One streaming pass: a stream per selected topic, the diagnostics decoded as RunData does."""

    def __init__(self, reader: ColumnReader, tol_deg: float, eigen_tol_deg: float) -> None:
        self.reader, self.tol, self.eigen_tol = reader, tol_deg, eigen_tol_deg
        self.attitude: dict[str, AttitudeStream] = {}
        self.torque: dict[str, TorqueStream] = {}
        self.joints: dict[str, JointStream] = {}
        self.diagnostics: dict[str, list] = defaultdict(list)
        self.seen: dict[str, int] = defaultdict(int)
        self.target = None            # (q_ref, pointing) the attitude streams use
        self.target_text = None       # the scenario text it was read from
        self.limits_text = None       # the scenario text the wheels' speed limits were read from
        self.limits: dict = {}        # wheel names -> their speed limits (metric_defs.wheel_limits)

    def run(self) -> None:
        for batch in self.reader:
            if batch.type_name == rd.DIAGNOSTIC_ARRAY:
                self.diagnostics[batch.topic].append(decode_diagnostics(batch))
            else:
                self._columns(batch.topic, batch.type_name, decode_batch(batch))
            self.seen[batch.topic] += len(batch)

    def _columns(self, topic: str, type_name: str, parts: list) -> None:
        if type_name == rd.JOINT_STATE:
            if topic not in self.joints:
                self.joints[topic] = JointStream(topic, topic.endswith('/' + topics.THRUSTERS_STATE),
                                                 self._wheel_limits)
            self.joints[topic].add(parts, self.seen[topic])
        elif type_name == rd.VECTOR3_STAMPED:
            self.torque.setdefault(topic, TorqueStream(topic)).add(*_in_file_order(parts, 'vector'))
        elif type_name == rd.ODOMETRY:
            if self.target is None:
                self.target_text = _scenario_text(self.reader.metadata)
                self.target = _target(self.reader.metadata, self.reader.bag)
            if topic not in self.attitude:
                self.attitude[topic] = AttitudeStream(topic, *self.target, self.tol, self.eigen_tol)
            self.attitude[topic].add(*_in_file_order(parts, 'orientation'))

    def _wheel_limits(self, names: tuple) -> np.ndarray:
        """The speed limits of wheels ``names`` in the bag's scenario, as RunData reads them."""
        if names not in self.limits:
            if self.limits_text is None:
                self.limits_text = _scenario_text(self.reader.metadata) or ''
            scenario = rd._scenario(self.limits_text, self.reader.bag)
            self.limits[names] = metric_defs.wheel_limits(scenario, names)
        return self.limits[names]

    def metrics(self, path, fixed: str | None) -> tuple[dict, str]:
        """run_metrics' dict (same keys, same order) and the namespace."""
        reader = self.reader
        counts = {name: n for name, n in reader.topic_counts.items() if n}
        ns = fixed if fixed is not None else rd._namespace(counts, reader.topics)
        state = self.attitude.get(ns + topics.STATE)
        if state is None or not state.rows:
            raise rd._no_state(path, reader, ns + topics.STATE)
        # the scenario read again only when its text changed (rcl's reading of it is not free)
        same_text = _scenario_text(reader.metadata) == self.target_text
        target = self.target if same_text else _target(reader.metadata, reader.bag)
        if not _same_target(target, self.target):
            raise Unstreamable('the scenario (target, pointing request) was written after the state')
        truth = self.attitude.get(ns + topics.TRUTH_STATE)
        att = truth if truth is not None and truth.rows else state
        t_end = float(att.t_parts[-1][-1])
        out = att.metrics(self.tol, self.eigen_tol)
        wheels = self.joints.get(ns + topics.WHEELS_STATE)
        if self.limits and (_scenario_text(reader.metadata) or '') != self.limits_text:
            scenario = rd._scenario(_scenario_text(reader.metadata), reader.bag)
            if any(not np.array_equal(metric_defs.wheel_limits(scenario, names), limits)
                   for names, limits in self.limits.items()):
                raise Unstreamable('the scenario (wheel speed limits) was written after the wheel states')
        torque = self.torque.get(ns + topics.APPLIED_TORQUE)
        if torque is not None and not torque.rows:
            torque = None
        # the metrics defined once (metric_defs.DEFINED), in their order
        defined = (torque.defined if torque is not None else metric_defs.StreamedValues('torque')).values((), 0, t_end)
        defined.update(wheels.defined_values() if wheels is not None else
                       metric_defs.StreamedValues().values(None, 0))
        out.update({m.name: defined[m.name] for m in metric_defs.DEFINED})
        dynamics = self.diagnostics.get(ns + topics.DYNAMICS_STATUS, [])
        out['missed_steps'] = rd._missed_steps(dynamics)
        missed_at = rd._missed_at(dynamics)
        if missed_at.size:
            out.update(missed_step_gaps(SimpleNamespace(missed_at=missed_at, t=np.concatenate(att.t_parts))))
        faults = [(stamp, int(s[0]), s[1], s[2]) for stamp, statuses in
                  rd._merged_statuses(self.diagnostics.get(ns + topics.FAULTS, [])) for s in statuses]
        out.update(_fault_metrics(faults, att, torque, t_end))
        thrusters = self.joints.get(ns + topics.THRUSTERS_STATE)
        if thrusters is not None:
            out.update(thrusters.thruster_metrics())
        if target[1] is not None:
            out.update(att.pointing_metrics())
        return out, ns


def _fault_metrics(faults: list, att: AttitudeStream, torque: TorqueStream | None, t_end: float) -> dict:
    """fault_metrics (seed 000 VI.A) from what was kept: the state stamps, the last exit of
    1 - |q_e,4| from each band, the torque stamps and ``‖u‖ Δt`` terms."""
    t0 = first_fault_time(SimpleNamespace(faults=faults))
    if not math.isfinite(t0):
        return {}
    out = {'first_fault_time_s': t0}
    t = np.concatenate(att.t_parts)
    t = t[t >= t0]
    for band, track in zip(FAULT_BANDS, att.q4):
        out[f'settling_q4_{band:g}_after_fault_s'] = _settling_from(track, t, t0) - t0
    if torque is not None:
        t_u, terms = torque.norm_terms(t_end)
        out['integrated_torque_after_fault_Nms'] = float(np.sum(terms[t_u >= t0]))
    return out


def _settling_from(track: BandTrack, t_after: np.ndarray, t0: float) -> float:
    """settling_time of the samples at ``t_after`` (those at or after ``t0``) from ``track``
    (every sample): the last sample outside is among them if it is at or after ``t0``; else none
    of them is outside."""
    if not t_after.size:
        return math.nan
    if track.last_out is None or not track.last_out[0] >= t0:
        return float(t_after[0])
    return track.settling()


def analyse_bag(path, tol_deg: float = 0.5, eigen_tol_deg: float | None = None, namespace: str | None = None,
                batch_bytes: int = STREAM_BATCH_BYTES) -> StreamResult:
    """``run_metrics(RunData.from_bag(path, namespace), tol_deg, eigen_tol_deg)`` and the bag's
    intruder lines, computed in one streaming pass (memory: a few tens of bytes a step), or by
    that in-memory path when the bag does not allow it (module docstring). Raises as
    :meth:`RunData.from_bag` does."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    fixed = rd.namespace_prefix(namespace)
    reader = ColumnReader(path, rd.topic_selector(fixed, STREAM_TYPES), batch_bytes=batch_bytes)
    stream = _Pass(reader, tol_deg, eigen_tol_deg)
    try:
        stream.run()
        metrics, ns = stream.metrics(path, fixed)
    except Unstreamable as exc:
        del stream
        run = RunData.from_bag(path, namespace)
        return StreamResult(run_metrics(run, tol_deg, eigen_tol_deg), run.intrusions, run.namespace,
                            streamed=False, reason=str(exc), unmatchable=run.unmatchable)
    return StreamResult(metrics, rd._recorded_intrusions(stream.diagnostics), ns,
                        unmatchable=rd._recorded_intrusions(stream.diagnostics, rd.unmatchable_lines))
