"""A run's time series read from a bag: :class:`RunData` (one streaming pass over an MCAP or
sqlite3 rosbag2 bag), what the scenario embedded in the bag asks for (its regulation target, its
pointing request) and what the recorder wrote about intruders.

Split out of :mod:`adcs_sim.app.analysis.metrics` (which defines the metrics and re-exports these names):
this module reads, that one computes.
"""
from __future__ import annotations

import gc
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from adcs_msgs_py import names as topics
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import load_params_text
from adcs_sim.app.analysis.status_records import StatusRecords
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.columns import decode_batch, decode_diagnostics
from adcs_sim.bag.reader import read_raw
from adcs_sim.bag.storage import typestore

ODOMETRY = 'nav_msgs/msg/Odometry'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
# Topics RunData reads (names relative to the run's namespace) and the type each must have.
READ_TYPES = {
    topics.STATE: ODOMETRY, topics.TRUTH_STATE: ODOMETRY, topics.APPLIED_TORQUE: VECTOR3_STAMPED,
    topics.WHEELS_STATE: JOINT_STATE, topics.DYNAMICS_STATUS: DIAGNOSTIC_ARRAY,
    topics.CONTROLLER_STATUS: DIAGNOSTIC_ARRAY, topics.FAULTS: DIAGNOSTIC_ARRAY,
    topics.THRUSTERS_STATE: JOINT_STATE,
}
# Topics whose absence RunData reports in ``missing_topics`` (only ``state`` is required).
REPORTED_TOPICS = (topics.STATE, topics.APPLIED_TORQUE, topics.WHEELS_STATE, topics.DYNAMICS_STATUS,
                   topics.CONTROLLER_STATUS)


@dataclass
class RunData:
    """Time series of one run, as recorded (seconds, SI units).

    Rows of each series are in stamp order (file order among equal stamps). ``q``/``w`` come from
    ``truth/state`` when the bag has it (measurement noise configured), else from ``state``.
    """

    t: np.ndarray                      # state stamps
    q: np.ndarray                      # (N, 4) true attitude
    w: np.ndarray                      # (N, 3) true body rate
    t_u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    t_wheels: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wheel_names: list = field(default_factory=list)
    wheel_speed: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    wheel_torque: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    wheel_max_speed: np.ndarray | None = None   # (n,) rad/s; None: the scenario's (metric_defs.wheel_limits)
    t_thrusters: np.ndarray = field(default_factory=lambda: np.zeros(0))  # step starts
    thruster_names: list = field(default_factory=list)
    thruster_impulse: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # at step ends, N s
    thruster_on_time: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # per step, s
    thruster_force: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))    # at step starts, N
    missed_steps: int | None = None
    missed_at: np.ndarray = field(default_factory=lambda: np.empty(0))   # stamps (s) of missed steps
    q_ref: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    scenario: dict | None = None
    controller_status: Sequence = field(default_factory=list)  # (t, name, {key: value text}) per status (StatusRecords)
    faults: list = field(default_factory=list)  # (t, level, name, message) per status on faults
    intrusions: list = field(default_factory=list)  # the recorder's intruder lines (intrusion_lines)
    unmatchable: list = field(default_factory=list)  # publishers of another type it saw (unmatchable_lines)
    topic_counts: dict = field(default_factory=dict)  # messages per topic (relative to the namespace)
    # How the bag was read:
    truncated: bool = False            # no MCAP summary/footer (writer killed): data up to the last whole chunk
    problem: str | None = None         # one line: damage (byte offset, reason), truncation or damaged summary
    damaged: bool = False              # a fault was found: the data is every record before it
    message_count: int = 0             # messages read from the bag, all topics
    missing_topics: list = field(default_factory=list)  # of REPORTED_TOPICS, those with no message
    pointing: tuple | None = None      # (σ̂ body axis, τ̂ inertial direction) of a pointing run (seed 003)
    namespace: str = '/'               # the run's topic prefix ('/' or e.g. '/sat1/')

    @property
    def t_end(self) -> float:
        return float(self.t[-1]) if self.t.size else 0.0

    @classmethod
    def from_bag(cls, path, namespace: str | None = None, max_samples: int | None = None) -> 'RunData':
        """Read a bag of the graph into arrays: ours or any rosbag2 bag with the graph's topics.

        MCAP (complete or truncated: everything up to the last whole chunk) or sqlite3 storage.
        Topics may be namespaced (``/sat1/state``): ``namespace`` picks one; by default it is the
        prefix of a ``state`` topic with the most of the graph's topics beside it. Only ``state``
        (``nav_msgs/Odometry``) is required; other topics are read when present and their absence
        listed in ``missing_topics``. One streaming pass; fixed-layout messages are decoded with
        numpy from their CDR bytes (:func:`adcs_sim.bag.columns.decode_batch`).

        Raises ValueError (not a bag, no ``state`` messages) or OSError (no such path), each with
        a one-line message; :class:`TooLong` as soon as a ``state`` topic has more than
        ``max_samples`` messages (None: no limit; a long run's report streams instead).
        """
        # The status records are millions of small acyclic objects on a long run: the cyclic
        # garbage collector, triggered again and again by their allocation, doubled the time.
        gc_enabled = gc.isenabled()
        gc.disable()
        try:
            return cls._from_bag(path, namespace, max_samples)
        finally:
            if gc_enabled:
                gc.enable()

    @classmethod
    def _from_bag(cls, path, namespace: str | None = None, max_samples: int | None = None) -> 'RunData':
        fixed = namespace_prefix(namespace)
        reader = ColumnReader(path, topic_selector(fixed, READ_TYPES))
        columns, diagnostics, status_records = _read(reader, max_samples)
        counts = {name: n for name, n in reader.topic_counts.items() if n}
        ns = fixed if fixed is not None else _namespace(counts, reader.topics)
        state_topic = ns + topics.STATE
        if not any(c.rows.size for _, c in columns.get(state_topic, [])):
            raise _no_state(path, reader, state_topic)
        # Each topic's decoded parts are let go as soon as they are merged (pop): the reading's peak
        # memory is the run's arrays plus one topic's parts, not plus every topic's.
        truth = _merged(columns.pop(ns + topics.TRUTH_STATE, []))
        t, cols = truth if truth[0].size else _merged(columns.pop(state_topic))
        del truth
        run = cls(t=t, q=cols['orientation'], w=cols['angular'])
        columns.pop(state_topic, None)
        t_u, cols = _merged(columns.pop(ns + topics.APPLIED_TORQUE, []))
        if t_u.size:
            run.t_u, run.u = t_u, cols['vector']
        _set_wheels(run, columns.pop(ns + topics.WHEELS_STATE, []))
        _set_thrusters(run, columns.pop(ns + topics.THRUSTERS_STATE, []))
        columns.clear()
        if ns + topics.CONTROLLER_STATUS in status_records:
            run.controller_status = status_records[ns + topics.CONTROLLER_STATUS].freeze()
        set_recording(run, reader, diagnostics, ns)
        return run


class TooLong(Exception):
    """A ``state`` topic has more messages than :meth:`RunData.from_bag` was allowed to hold."""


def set_recording(run: RunData, reader: ColumnReader, diagnostics: dict, ns: str) -> None:
    """The fields of ``run`` that are not time series, from a finished pass of ``reader`` over the
    bag and its decoded diagnostics (``{topic: [(stamps, statuses)]}``) under namespace ``ns``:
    missed steps, faults, intruders, counts, how the bag was read, the scenario and its target."""
    counts = {name: n for name, n in reader.topic_counts.items() if n}
    run.missed_steps = _missed_steps(diagnostics.get(ns + topics.DYNAMICS_STATUS, []))
    run.missed_at = _missed_at(diagnostics.get(ns + topics.DYNAMICS_STATUS, []))
    run.faults = [(stamp, int(s[0]), s[1], s[2]) for stamp, statuses in
                  _merged_statuses(diagnostics.get(ns + topics.FAULTS, [])) for s in statuses]
    run.intrusions = _recorded_intrusions(diagnostics)
    run.unmatchable = _recorded_intrusions(diagnostics, unmatchable_lines)
    run.topic_counts = {_relative(name, ns): n for name, n in counts.items()}
    run.truncated = reader.truncated
    run.problem, run.damaged = reader.problem, reader.damaged
    run.message_count = reader.message_count
    run.missing_topics = [rel for rel in REPORTED_TOPICS if not counts.get(ns + rel)]
    run.namespace = ns
    run.scenario = _scenario(reader.metadata.get('scenario', {}).get('text'), reader.bag)
    if run.scenario is not None:
        run.q_ref = target_attitude(run.scenario)
        run.pointing = pointing_request(run.scenario)


def namespace_prefix(namespace: str | None) -> str | None:
    """'/sat1/' of a namespace given as 'sat1', '/sat1' ... ; None: not given."""
    return None if namespace is None else ('/' + namespace.strip('/') + '/').replace('//', '/')


def topic_selector(fixed: str | None, read_types: dict):
    """The ColumnReader selection of the topics of ``read_types`` ({relative name: type}) under
    the prefix ``fixed`` (None: under any prefix), and of every ``intrusions`` topic."""
    def select(topic: str, type_name: str) -> bool:
        if type_name == DIAGNOSTIC_ARRAY and _is_intrusions(topic):
            return True
        if fixed is not None:
            return topic.startswith(fixed) and read_types.get(topic[len(fixed):]) == type_name
        return any(read_types[rel] == type_name and (topic == '/' + rel or topic.endswith('/' + rel))
                   for rel in read_types)
    return select


def _read(reader: ColumnReader, max_samples: int | None = None) -> tuple[dict, dict, dict]:
    """Every batch of ``reader``, decoded: ``(columns, diagnostics, status records)`` by topic;
    columns as ``[(first row number, Columns)]``, diagnostics as ``[(stamps, statuses)]``, the
    controller status compact (:class:`StatusRecords`, not yet frozen). :class:`TooLong` when an
    Odometry topic passes ``max_samples`` messages."""
    columns: dict[str, list] = defaultdict(list)
    diagnostics: dict[str, list] = defaultdict(list)
    status_records: dict[str, StatusRecords] = defaultdict(StatusRecords)
    seen: dict[str, int] = defaultdict(int)
    for batch in reader:
        if batch.type_name == DIAGNOSTIC_ARRAY and batch.topic.endswith('/' + topics.CONTROLLER_STATUS):
            status_records[batch.topic].add(*decode_diagnostics(batch))
        elif batch.type_name == DIAGNOSTIC_ARRAY:
            diagnostics[batch.topic].append(decode_diagnostics(batch))
        else:
            columns[batch.topic].extend((seen[batch.topic], _kept(c, batch.type_name)) for c in decode_batch(batch))
        seen[batch.topic] += len(batch)
        if max_samples is not None and batch.type_name == ODOMETRY and seen[batch.topic] > max_samples:
            raise TooLong(f'{batch.topic}: more than {max_samples} messages')
    return columns, diagnostics, status_records


def _missed_steps(parts: list) -> int | None:
    """The last ``missed_steps`` the dynamics node's status gave (None: none readable)."""
    missed = None
    for _, statuses in _merged_statuses(parts):
        for status in statuses:
            if 'missed_steps' in status[4]:
                try:
                    missed = int(float(status[4]['missed_steps']))
                except ValueError:
                    pass
    return missed


def _scenario(text: str | None, bag) -> dict | None:
    """The scenario embedded in ``bag`` as the nodes got it (rcl's reading, merged sections and all:
    :func:`load_params_text`, which warns about a section or key written twice), as a tree
    ``{section: {'ros__parameters': {nested keys}}}``; None without one, or when the nodes could not
    have run it (not a params file: a bag from elsewhere, the report then says it has no usable scenario)."""
    if not text:
        return None
    try:
        sections = load_params_text(text, f'{bag} (embedded scenario)')
    except ParameterError:
        return None
    return {name: {'ros__parameters': _nested(params)} for name, params in sections.items()}


def _nested(flat: dict) -> dict:
    """``{'a.b': v}`` -> ``{'a': {'b': v}}``; a name that is both a value and a prefix of others
    (``a`` and ``a.b``: rcl allows both) stays dotted beside them."""
    out: dict = {}
    for key in sorted(flat, key=lambda k: k.count('.')):   # shorter names first: a value is never replaced
        node = out
        *parents, leaf = key.split('.')
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                break
        if isinstance(node, dict) and leaf not in node:
            node[leaf] = flat[key]
        else:
            out[key] = flat[key]
    return out


def _no_state(path, reader: ColumnReader, state_topic: str) -> ValueError:
    """The one-line error for a bag without a state message of the run (saying so when it is
    damaged, and when the run was compromised: its states may all be under quarantine)."""
    what = f'{state_topic} ({ODOMETRY})'
    if state_topic in reader.topics and reader.topics[state_topic] != ODOMETRY:
        what = f'{state_topic} of type {ODOMETRY} (it is {reader.topics[state_topic]})'
    if reader.problem is not None:
        return ValueError(f'{path}: {reader.problem}: no {what} message before it '
                          f'({reader.message_count} messages salvaged): nothing to analyse')
    intrusions = bag_intrusions(path)
    if intrusions:   # e.g. a compromised run whose recorder took every state after the detection
        kept = topics.quarantine_topic(state_topic, state_topic[:-len(topics.STATE)])
        where = f' (those recorded are under {kept}, not analysed)' if kept in reader.topics else ''
        return ValueError(f'{path}: no {what} messages of the run{where}: nothing to analyse; run compromised: '
                          + '; '.join(intrusions))
    return ValueError(f'{path}: no {what} messages: not a run of the graph')


def _relative(topic: str, ns: str) -> str:
    return topic[len(ns):] if topic.startswith(ns) else topic.lstrip('/')


def _namespace(counts: dict[str, int], types: dict[str, str]) -> str:
    """The prefix of the ``state`` topic with the most of the graph's topics beside it ('/' first);
    never a quarantine (``<ns>/quarantine/state``: a compromised run's states, maybe an intruder's,
    are not the run's even when every state of it went there)."""
    best = None
    for name, n in counts.items():
        if not name.endswith('/' + topics.STATE) or types.get(name) != ODOMETRY or topics.quarantined(name):
            continue
        prefix = name[:-len(topics.STATE)]
        score = sum(1 for rel in set(READ_TYPES) | set(REPORTED_TOPICS) if counts.get(prefix + rel))
        key = (-score, len(prefix), prefix)
        best = key if best is None or key < best else best
    return best[2] if best else '/'


# The fields RunData keeps of each type (decode_batch gives more: Odometry's position and linear
# velocity are 48 of its 104 bytes a message, and a long run holds every message until the merge).
KEPT_FIELDS = {ODOMETRY: ('orientation', 'angular')}


def _kept(columns, type_name: str):
    """``columns`` without the fields RunData does not keep (KEPT_FIELDS)."""
    names = KEPT_FIELDS.get(type_name)
    if names is not None:
        # (a copy when a field is a view: the decoded block it views would otherwise stay alive)
        columns.fields = {name: (columns.fields[name] if columns.fields[name].base is None
                                 else columns.fields[name].copy()) for name in names}
    return columns


def _merged(parts: list, names=None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Concatenate decoded columns ([(first row, Columns)]) in stamp order (file order on ties).

    ``names``: the fields to merge (default all)."""
    parts = [(row0, c) for row0, c in parts if c.rows.size]
    if not parts:
        return np.zeros(0), {}
    seq = np.concatenate([row0 + c.rows for row0, c in parts])
    stamp_ns = np.concatenate([c.stamp_ns for _, c in parts])
    order = np.lexsort((seq, stamp_ns))
    t = np.concatenate([c.stamp for _, c in parts])[order]
    fields = {name: np.concatenate([c.fields[name] for _, c in parts])[order]
              for name in (names or parts[0][1].fields)}
    return t, fields


def _set_wheels(run: RunData, parts: list) -> None:
    """Wheel series from JointState columns: the joints named in the last message (others dropped)."""
    parts = [(row0, c) for row0, c in parts if c.rows.size]
    if not parts:
        return
    names = max(parts, key=lambda p: p[0] + p[1].rows[-1])[1].extra
    n = len(names)
    keep = []
    for row0, c in parts:
        if c.extra != names or c.fields['velocity'].shape[1] != n:
            continue
        if c.fields['effort'].shape[1] != n:
            c.fields['effort'] = np.full((c.rows.size, n), math.nan)
        keep.append((row0, c))
    t, fields = _merged(keep, ('velocity', 'effort'))
    run.t_wheels, run.wheel_names = t, list(names)
    run.wheel_speed, run.wheel_torque = fields['velocity'], fields['effort']


def _set_thrusters(run: RunData, parts: list) -> None:
    """Thruster series from ``thrusters/state`` (JointState: impulse in ``position``, on-time in
    ``velocity``, thrust in ``effort``), the thrusters named in the last message."""
    parts = [(row0, c) for row0, c in parts if c.rows.size]
    if not parts:
        return
    names = max(parts, key=lambda p: p[0] + p[1].rows[-1])[1].extra
    n = len(names)
    keep = [(row0, c) for row0, c in parts if c.extra == names
            and all(c.fields[k].shape[1] == n for k in ('position', 'velocity', 'effort'))]
    t, fields = _merged(keep, ('position', 'velocity', 'effort'))
    run.t_thrusters, run.thruster_names = t, list(names)
    run.thruster_impulse, run.thruster_on_time = fields['position'], fields['velocity']
    run.thruster_force = fields['effort']


def _merged_statuses(parts: list) -> list[tuple[float, list]]:
    """(stamp, statuses) of DiagnosticArray messages in stamp order (file order on ties)."""
    merged = [(stamp, statuses) for stamps, batch in parts for stamp, statuses in zip(stamps.tolist(), batch)]
    merged.sort(key=lambda r: r[0])
    return merged


def _sections(scenario) -> list[tuple[str, dict]]:
    """(section name, its ``ros__parameters`` mapping) of a scenario; malformed sections skipped."""
    out = []
    for name, section in (scenario.items() if isinstance(scenario, dict) else ()):
        params = section.get('ros__parameters') if isinstance(section, dict) else None
        if isinstance(params, dict):
            out.append((str(name), params))
    return out


def _finite(value, n: int) -> np.ndarray | None:
    try:
        v = np.asarray(value, dtype=float).reshape(n)
    except (TypeError, ValueError):
        return None
    return v if np.all(np.isfinite(v)) and np.any(v) else None


def target_attitude(scenario: dict) -> np.ndarray:
    """The regulation target of a scenario: a controller section's ``target.attitude``, or identity
    (also when the one given is not a non-zero 4-vector: a scenario not validated by the graph)."""
    for name, params in _sections(scenario):
        target = params.get('target').get('attitude') if isinstance(params.get('target'), dict) else None
        if target is not None and name.lstrip('/') != 'dynamics':
            q = _finite(target, 4)
            if q is not None:
                return q / np.linalg.norm(q)
    return np.array([0.0, 0.0, 0.0, 1.0])


def pointing_request(scenario: dict) -> tuple | None:
    """(σ̂, τ̂) of a scenario whose controller section points a body axis (``sigma``, ``tau``)."""
    for _, params in _sections(scenario):
        if 'sigma' in params and 'tau' in params:
            sigma, tau = _finite(params['sigma'], 3), _finite(params['tau'], 3)
            if sigma is not None and tau is not None:
                return sigma, tau
    return None


def _missed_at(parts: list) -> np.ndarray:
    """Stamps (s) at which the dynamics node's ``missed_steps`` count went up: it publishes its
    status at each missed step, stamped with that step."""
    out, count = [], 0
    for stamp, statuses in _merged_statuses(parts):
        for status in statuses:
            try:
                n = int(float(status[4].get('missed_steps', count)))
            except ValueError:
                continue
            if n > count:
                out.append(stamp)
            count = max(count, n)
    return np.asarray(out, dtype=float)


def intrusion_lines(values) -> list[str]:
    """One line per intruder (node, topic, GID, who was allowed; a second node of an allowed name
    said so), each once, from the ``{key: value}`` of the statuses the recorder wrote on
    ``intrusions`` (adcs_msgs_py.guard); a publisher of another type there is no intruder
    (:func:`unmatchable_lines`)."""
    def line(kv) -> str:
        node = kv.get('node', '?') + (' (a second node of that name)' if kv.get('duplicate') == 'true' else '')
        if kv.get('topic') == '':   # found in the graph's node names
            return f'intruder node {node} in the graph'
        return (f'intruder node {node} published on {kv.get("topic", "?")} '
                f'(GID {kv.get("gid", "?")}; allowed: {kv.get("allowed", "?")})')
    return list(dict.fromkeys(line(kv) for kv in values if kv.get('unmatchable') != 'true'))


def unmatchable_lines(values) -> list[str]:
    """One line per publisher of another type on a run topic (node, type, topic, GID), each once,
    from the statuses on ``intrusions``: it could never deliver, the run is not compromised."""
    return list(dict.fromkeys(
        f'node {kv.get("node", "?")} published {kv.get("type", "?")} on {kv.get("topic", "?")}, which '
        f'carries {kv.get("expected", "?")} (GID {kv.get("gid", "?")}): it could never deliver; ignored'
        for kv in values if kv.get('unmatchable') == 'true'))


def _is_intrusions(topic: str) -> bool:
    return topic.rsplit('/', 1)[-1] == topics.INTRUSIONS


def _recorded_intrusions(diagnostics: dict, lines=intrusion_lines) -> list[str]:
    """:func:`intrusion_lines` (or ``lines``) of the decoded ``intrusions`` topics ({topic: [(stamps, statuses)]})."""
    return lines(s[4] for name, parts in diagnostics.items() if _is_intrusions(name)
                 for _, statuses in _merged_statuses(parts) for s in statuses)


def bag_intrusions(bag) -> list[str]:
    """What the recorder wrote on ``intrusions`` (publishers the run did not allow: the run is
    compromised): :func:`intrusion_lines` of a bag read for that alone (e.g. one a run left
    behind when it failed). A bag read into :class:`RunData` has them in ``intrusions``."""
    values = []
    try:
        for topic, type_name, _, data in read_raw(bag):
            if _is_intrusions(topic):
                values += [{v.key: v.value for v in status.values}
                           for status in typestore().deserialize_cdr(data, type_name).status]
    except (OSError, ValueError):
        pass
    return intrusion_lines(values)
