"""A run's metrics computed while its bag is read: :func:`analyse_bag`.

:func:`~adcs_sim.app.analysis.metrics.run_metrics` on :meth:`RunData.from_bag` holds every series of the
run in memory (and the controller status, which no metric uses): its peak grows by ~620 B a step
(+539 MiB over the runner's imports for 24 h at 10 Hz). Here one streaming pass over the bag feeds
each metric's one definition chunk by chunk (:mod:`~adcs_sim.app.analysis.metric_defs`,
:mod:`~adcs_sim.app.analysis.metric_defs_attitude`, :mod:`~adcs_sim.app.analysis.metric_defs_thrusters`):

* settling and first-entry times: per error series and band, the last sample outside the band
  and the one after it, the first inside and the one before it; final values, peaks, counts;
* the torque integrals keep their per-sample terms ``‖u_k‖ Δt_k`` and ``u_kᵀu_k Δt_k`` (8 B a
  step each) and sum them once at the end, so that numpy's pairwise summation sees the very array
  it sees in :func:`run_metrics` (its split points depend on the length, unknown until the end: a
  running sum would differ in the last bits); the after-fault integral keeps the torque stamps
  (8 B a step) and takes the first integral's terms after the fault (its state, not a copy);
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

from collections import defaultdict
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis import metric_defs_attitude as mda
from adcs_sim.app.analysis.metric_defs_thrusters import THRUSTERS
from adcs_sim.app.analysis import run_data as rd
from adcs_sim.app.analysis.metrics import (
    RunData,
    fault_chunk,
    missed_step_gaps,
    run_metrics,
)
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.columns import decode_batch, decode_diagnostics

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
    at one tolerance, fed in order chunk by chunk: the states of their one definition
    (:class:`~adcs_sim.app.analysis.metric_defs_attitude.SettlingTime`, ``FirstEntryTime``) for one run."""

    def __init__(self, tol: float) -> None:
        self.tol = tol
        self.metrics = (mda.SettlingTime('settling', 'error', tol), mda.FirstEntryTime('first_entry', 'error', tol))
        self.states = [m.init({'runs': 1}) for m in self.metrics]

    def add(self, t: np.ndarray, e: np.ndarray) -> None:
        chunk = {'t_s': t, 'error': e[None]}
        self.states = [m.update(s, chunk) for m, s in zip(self.metrics, self.states)]

    def settling(self) -> float:
        return float(self.metrics[0].finish(self.states[0])[0])

    def first_entry(self) -> float:
        return float(self.metrics[1].finish(self.states[1])[0])


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
    """The attitude metrics of one state topic (q_ref, pointing request and bands fixed at the start):
    their definitions (:mod:`~adcs_sim.app.analysis.metric_defs_attitude`) fed chunk by chunk."""

    def __init__(self, topic: str, q_ref: np.ndarray, pointing, tol_deg: float, eigen_tol_deg: float) -> None:
        super().__init__(topic)
        self.q_ref, self.pointing = q_ref, pointing
        self.head = mda.head_metrics(tol_deg, eigen_tol_deg)
        self.bands = mda.pointing_band_metrics() if pointing is not None else ()
        self.defined = (*self.head, *self.bands)
        self.states = [m.init({'runs': 1}) for m in self.defined]
        self.needs = {n for m in self.defined for n in m.needs} | {'q4_error'}
        self.t_parts: list[np.ndarray] = []     # state stamps (s)
        self.after_fault = [m for m in mda.fault_metrics_defs() if 'q4_error' in m.needs]
        self.fault_states = [m.init({'runs': 1}) for m in self.after_fault]

    def add(self, t: np.ndarray, stamp_ns: np.ndarray, q: np.ndarray) -> None:
        self.check(stamp_ns)
        if not t.size:
            return
        run = SimpleNamespace(q=q, q_ref=self.q_ref, pointing=self.pointing)
        chunk = {'t_s': t, **mda.attitude_series(run, self.needs)}
        self.states = [m.update(s, chunk) for m, s in zip(self.defined, self.states)]
        self.t_parts.append(t)
        self.fault_states = [m.update(s, chunk) for m, s in zip(self.after_fault, self.fault_states)]

    def _values(self, metrics) -> dict:
        return mda.listed({m.name: m.finish(s) for m, s in zip(self.defined, self.states) if m in metrics})

    def metrics(self, tol_deg: float, eigen_tol_deg: float) -> dict:
        """run_metrics' attitude entries, in its order."""
        return self._values(self.head)

    def pointing_metrics(self) -> dict:
        return self._values(self.bands)


class TorqueStream(_Ordered):
    """Applied torque: its defined metrics (metric_defs.DEFINED: the integrals keep their terms,
    summed at the end) and the integral after a fault (its terms and stamps)."""

    def __init__(self, topic: str) -> None:
        super().__init__(topic)
        # the after-fault integral keeps IntegratedTorque's state (its terms) and the stamps: the
        # run's integral is taken from that state, not kept twice (8 B a step)
        self.after_fault = mda.IntegratedTorqueAfterFault()
        self.fault_state = self.after_fault.init({'runs': 1})
        self.defined = metric_defs.StreamedValues('torque', skip=(self.after_fault.inner.name,))

    def add(self, t: np.ndarray, stamp_ns: np.ndarray, u: np.ndarray) -> None:
        self.check(stamp_ns)
        if not t.size:
            return
        self.defined.add((), np.zeros(0), t, u)
        self.fault_state = self.after_fault.update(self.fault_state, {'t_s': t, 'torque': u[None]})

    def defined_values(self, t_end: float) -> dict:
        """The defined metrics (metric_defs.DEFINED) of the applied torque."""
        integral = self.after_fault.inner
        return {**self.defined.values((), 0, t_end),
                integral.name: float(integral.finish(self.fault_state['inner'], t_end)[0])}


class JointStream:
    """A JointState topic: per joint-name list, what the wheel / thruster metrics need of the
    messages with those names (RunData keeps those named as in the topic's last message)."""

    def __init__(self, topic: str, thrusters: bool, limits=None) -> None:
        self.order = _Ordered(topic)
        self.thrusters = thrusters
        self.limits = limits                           # names -> the wheels' speed limits (metric_defs)
        self.defined = metric_defs.StreamedValues()    # the metrics defined once, per names
        self.last_names = None
        self.thruster_states: dict = {}                # names -> [state per THRUSTERS metric]

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
        if self.thrusters:       # the thruster metrics in file order, per names
            for names in dict.fromkeys(c.extra for c in parts):
                same = [c for c in parts if c.extra == names
                        and all(c.fields[k].shape[1] == len(names) for k in ('position', 'velocity', 'effort'))]
                if not same:
                    continue
                t, _, on_time = _in_file_order(same, 'velocity')
                impulse = _in_file_order(same, 'position')[2]
                chunk = {'t_s': t, 'thruster_on_time': on_time[None], 'thruster_impulse': impulse[None]}
                states = self.thruster_states.get(names) or [m.init({'runs': 1}) for m in THRUSTERS]
                self.thruster_states[names] = [m.update(s, chunk) for m, s in zip(THRUSTERS, states)]
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
        """The thruster metrics (metric_defs_thrusters.THRUSTERS) of the thrusters named in the last message."""
        states = self.thruster_states.get(self.last_names)
        if states is None:
            return {}
        return mda.listed({m.name: v for m, s in zip(THRUSTERS, states) if (v := m.finish(s)) is not None})


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
        defined = (torque.defined_values(t_end) if torque is not None else
                   metric_defs.StreamedValues('torque').values((), 0, t_end))
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
    """fault_metrics (seed 000 VI.A): their definitions' states, given the faults read."""
    chunk = fault_chunk(faults)
    metrics = [mda.FirstFaultTime(), *att.after_fault] + ([torque.after_fault] if torque is not None else [])
    states = [metrics[0].init({'runs': 1}), *att.fault_states] + ([torque.fault_state] if torque is not None else [])
    out = {}
    for m, state in zip(metrics, states):
        value = m.finish(m.update(state, chunk), t_end)
        if value is not None:
            out[m.name] = float(value[0])
    return out


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
