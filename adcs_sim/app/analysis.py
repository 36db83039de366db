"""Run metrics: numpy in, numbers out, and the extraction of a run's time series from a bag.

Definitions (every metric printed by ``adcs-run`` and ``adcs-analyze``):

* **Attitude error** is the true attitude relative to the controller's target (identity unless
  the bag's scenario gives ``target.attitude``): ``q_e = q_ref* ⊗ q``. The *eigenaxis error* is
  its rotation angle ``2 atan2(|q_e,v|, |q_e,4|)``; the *2-1-3 Euler errors* are the three angles
  of ``q_e`` in the 2-1-3 sequence (scipy ``'YXZ'``), as seed 004 measures its settling time.
* **Settling time** to a tolerance: the time after which the error stays inside the band
  (``error <= tol``) to the end of the record (*last exit*, not first entry), linearly
  interpolated between the last sample outside and the first inside; the first sample time
  ``t0`` (0 for a run starting at 0) if always inside; ``inf`` if the run ends outside. A NaN
  sample counts as outside. For Euler angles the band must hold on all three axes at once (the
  max of the absolute angles); per axis, each angle on its own. ``first_entry_time`` is the other
  reading (first time the error reaches the band, interpolated the same way); the two differ
  when the error overshoots out of the band again. Sampling: for a smooth error crossing the
  band at ``t*`` with slope ``e'``, the interpolated time is within ``max|e''| Δt² / (8 |e'|)``
  of ``t*`` (tested); an excursion out of the band between two samples is not seen.
* **Integrated torque** ``∫‖u‖ dt`` and **control energy** ``∫uᵀu dt`` of the applied body
  torque ``u`` (``actuators/torque``): the torque is held over each control period (zero-order
  hold), so the integrals are exact sums ``Σ ‖u_k‖ Δt_k`` with ``Δt_k`` the time to the next
  sample (the last one up to the end of the run). ``‖·‖`` is the Euclidean norm.
* **After a fault** (runs with a level-ERROR status on ``faults``; seed 000 VI.A): from the first
  fault's time ``t0``, the *q4 settling time* in a band ``δ`` (the time after ``t0`` from which the
  error quaternion's scalar part stays within ``1 ± δ``, i.e. an eigenaxis error within
  ``2 acos(1 - δ)``: 23.0° for 0.02, 16.2° for 0.01; last exit as above) and ``∫‖u‖ dt`` over
  ``[t0, end]``.
* **Pointing** (seed 003; runs whose controller section has ``sigma`` and ``tau``): the pointing
  error is the angle between the body axis ``σ̂`` and the inertial direction ``τ̂``
  (:func:`adcs_core.attitude.pointing_error`, true attitude); at 1°, 0.1° and
  0.01° (Table 1) the *first entry* and the *settling* (staying below to the end) times, as above,
  and the final pointing error.
* **Peak torque** per body axis ``max |u_i|`` over the applied-torque samples; **peak wheel
  speed** ``max |Ω|`` over all wheels and samples (rad/s, relative to the body); **missed
  steps** from the last ``dynamics/status`` that reports them.

:func:`run_metrics` gives these at one tolerance; :func:`settling_times` the settling times at
several (e.g. 0.5° and 1° for a comparison table). :func:`k0_metric` is seed 001's settling index
(eq. 29) of a sampled error series.
"""
from __future__ import annotations

import gc
import math
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np
import yaml

from adcs_core.attitude import eigenaxis_angle, error_quaternion, euler_213, pointing_error
from adcs_msgs_py import names as topics
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.columns import decode_batch, decode_diagnostics
from adcs_sim.bag.reader import read_raw
from adcs_sim.bag.storage import typestore

NS = 1e-9


# --- metrics on arrays ------------------------------------------------------------------------

def settling_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """Time after which ``error`` stays ``<= tol`` to the end (last exit, interpolated).

    ``t[0]`` if every sample is inside, ``inf`` if the last one is outside, NaN if there are no
    samples. ``t`` ascending; a NaN error counts as outside.
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(error, dtype=float)
    outside = np.flatnonzero(~(e <= tol))
    if outside.size == 0:
        return float(t[0]) if t.size else math.nan
    i = outside[-1]
    if i == e.size - 1:
        return math.inf
    e0, e1 = e[i], e[i + 1]
    if not math.isfinite(e0):
        return float(t[i + 1])
    return float(t[i] + (e0 - tol) / (e0 - e1) * (t[i + 1] - t[i]))


def first_entry_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """First time ``error`` reaches ``tol`` (interpolated): ``t[0]`` if it starts inside, ``inf`` if
    never. Unlike :func:`settling_time`, later exits from the band do not count."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(error, dtype=float)
    inside = np.flatnonzero(e <= tol)
    if inside.size == 0:
        return math.inf
    i = inside[0]
    if i == 0:
        return float(t[0])
    e0, e1 = e[i - 1], e[i]
    if not math.isfinite(e0):
        return float(t[i])
    return float(t[i - 1] + (e0 - tol) / (e0 - e1) * (t[i] - t[i - 1]))


def zoh_durations(t: np.ndarray, t_end: float) -> np.ndarray:
    """Hold durations of samples at ``t`` (to the next sample, the last to ``t_end``)."""
    t = np.asarray(t, dtype=float)
    return np.diff(np.append(t, max(t_end, t[-1]))) if t.size else t


def integrated_norm(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫‖u‖ dt`` of a zero-order-held signal ``u`` (N, k) sampled at ``t``."""
    return float(np.sum(np.linalg.norm(u, axis=-1) * zoh_durations(t, t_end)))


def integrated_square(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫uᵀu dt`` of a zero-order-held signal ``u`` (N, k) sampled at ``t``."""
    return float(np.sum(np.sum(np.asarray(u) ** 2, axis=-1) * zoh_durations(t, t_end)))


def k0_metric(e: np.ndarray, window: int = 200, threshold: float = 0.03, reduce: str = 'max'):
    """Settling index of seed 001 eq. (29): the first step k > window such that the last ``window``
    errors ``e(k-1) .. e(k-window)`` are below ``threshold`` (``reduce='max'``, as printed) or
    average below it (``reduce='mean'``, the text's wording). ``e`` (..., n) sampled errors; -1 if
    never."""
    e = np.asarray(e, dtype=float)
    n = e.shape[-1]
    c = np.concatenate([np.zeros(e.shape[:-1] + (1,)), np.cumsum(e, axis=-1)], axis=-1)
    if reduce == 'mean':
        ok = (c[..., window:] - c[..., :-window]) / window < threshold
    elif reduce == 'max':
        bad = np.concatenate([np.zeros(e.shape[:-1] + (1,)), np.cumsum(e >= threshold, axis=-1)], -1)
        ok = (bad[..., window:] - bad[..., :-window]) == 0
    else:
        raise ValueError(f"reduce must be 'max' or 'mean', got {reduce!r}")
    ok = ok[..., 1:]  # k = window + 1 .. n: window e(k-1) .. e(k-window)
    k = np.where(ok.any(axis=-1), np.argmax(ok, axis=-1) + window + 1, -1)
    return k if n > window else np.full(e.shape[:-1], -1)


# --- a run's time series -------------------------------------------------------------------

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
    t_thrusters: np.ndarray = field(default_factory=lambda: np.zeros(0))  # step starts
    thruster_names: list = field(default_factory=list)
    thruster_impulse: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # at step ends, N s
    thruster_on_time: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # per step, s
    thruster_force: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))    # at step starts, N
    missed_steps: int | None = None
    missed_at: np.ndarray = field(default_factory=lambda: np.empty(0))   # stamps (s) of missed steps
    q_ref: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    scenario: dict | None = None
    controller_status: list = field(default_factory=list)  # (t, name, {key: value text}) per status
    faults: list = field(default_factory=list)  # (t, level, name, message) per status on faults
    intrusions: list = field(default_factory=list)  # the recorder's intruder lines (intrusion_lines)
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
    def from_bag(cls, path, namespace: str | None = None) -> 'RunData':
        """Read a bag of the graph into arrays: ours or any rosbag2 bag with the graph's topics.

        MCAP (complete or truncated: everything up to the last whole chunk) or sqlite3 storage.
        Topics may be namespaced (``/sat1/state``): ``namespace`` picks one; by default it is the
        prefix of a ``state`` topic with the most of the graph's topics beside it. Only ``state``
        (``nav_msgs/Odometry``) is required; other topics are read when present and their absence
        listed in ``missing_topics``. One streaming pass; fixed-layout messages are decoded with
        numpy from their CDR bytes (:func:`adcs_sim.bag.columns.decode_batch`).

        Raises ValueError (not a bag, no ``state`` messages) or OSError (no such path), each with
        a one-line message.
        """
        # The status records are millions of small acyclic objects on a long run: the cyclic
        # garbage collector, triggered again and again by their allocation, doubled the time.
        gc_enabled = gc.isenabled()
        gc.disable()
        try:
            return cls._from_bag(path, namespace)
        finally:
            if gc_enabled:
                gc.enable()

    @classmethod
    def _from_bag(cls, path, namespace: str | None = None) -> 'RunData':
        fixed = None if namespace is None else ('/' + namespace.strip('/') + '/').replace('//', '/')

        def select(topic: str, type_name: str) -> bool:
            if type_name == DIAGNOSTIC_ARRAY and _is_intrusions(topic):
                return True
            if fixed is not None:
                return topic.startswith(fixed) and READ_TYPES.get(topic[len(fixed):]) == type_name
            return any(READ_TYPES[rel] == type_name and (topic == '/' + rel or topic.endswith('/' + rel))
                       for rel in READ_TYPES)

        reader = ColumnReader(path, select)
        columns: dict[str, list] = defaultdict(list)     # topic -> [(first row number, Columns)]
        diagnostics: dict[str, list] = defaultdict(list)  # topic -> [(stamps, statuses)]
        seen: dict[str, int] = defaultdict(int)
        for batch in reader:
            if batch.type_name == DIAGNOSTIC_ARRAY:
                diagnostics[batch.topic].append(decode_diagnostics(batch))
            else:
                columns[batch.topic].extend((seen[batch.topic], c) for c in decode_batch(batch))
            seen[batch.topic] += len(batch)
        counts = {name: n for name, n in reader.topic_counts.items() if n}
        ns = fixed if fixed is not None else _namespace(counts, reader.topics)
        state_topic = ns + topics.STATE
        if not any(c.rows.size for _, c in columns.get(state_topic, [])):
            raise _no_state(path, reader, state_topic)
        truth = _merged(columns.get(ns + topics.TRUTH_STATE, []))
        t, cols = truth if truth[0].size else _merged(columns[state_topic])
        run = cls(t=t, q=cols['orientation'], w=cols['angular'])
        t_u, cols = _merged(columns.get(ns + topics.APPLIED_TORQUE, []))
        if t_u.size:
            run.t_u, run.u = t_u, cols['vector']
        _set_wheels(run, columns.get(ns + topics.WHEELS_STATE, []))
        _set_thrusters(run, columns.get(ns + topics.THRUSTERS_STATE, []))
        for stamp, statuses in _merged_statuses(diagnostics.get(ns + topics.DYNAMICS_STATUS, [])):
            for status in statuses:
                if 'missed_steps' in status[4]:
                    try:
                        run.missed_steps = int(float(status[4]['missed_steps']))
                    except ValueError:
                        pass
        run.controller_status = [(stamp, s[1], s[4]) for stamp, statuses in
                                 _merged_statuses(diagnostics.get(ns + topics.CONTROLLER_STATUS, []))
                                 for s in statuses]
        run.missed_at = _missed_at(diagnostics.get(ns + topics.DYNAMICS_STATUS, []))
        run.faults = [(stamp, int(s[0]), s[1], s[2]) for stamp, statuses in
                      _merged_statuses(diagnostics.get(ns + topics.FAULTS, [])) for s in statuses]
        run.intrusions = _recorded_intrusions(diagnostics)
        run.topic_counts = {_relative(name, ns): n for name, n in counts.items()}
        run.truncated = reader.truncated
        run.problem, run.damaged = reader.problem, reader.damaged
        run.message_count = reader.message_count
        run.missing_topics = [rel for rel in REPORTED_TOPICS if not counts.get(ns + rel)]
        run.namespace = ns
        scenario_text = reader.metadata.get('scenario', {}).get('text')
        if scenario_text:
            run.scenario = yaml.safe_load(scenario_text)
            run.q_ref = target_attitude(run.scenario)
            run.pointing = pointing_request(run.scenario)
        return run


def _no_state(path, reader: ColumnReader, state_topic: str) -> ValueError:
    """The one-line error for a bag without a state message (saying so when it is damaged)."""
    what = f'{state_topic} ({ODOMETRY})'
    if state_topic in reader.topics and reader.topics[state_topic] != ODOMETRY:
        what = f'{state_topic} of type {ODOMETRY} (it is {reader.topics[state_topic]})'
    if reader.problem is not None:
        return ValueError(f'{path}: {reader.problem}: no {what} message before it '
                          f'({reader.message_count} messages salvaged): nothing to analyse')
    return ValueError(f'{path}: no {what} messages: not a run of the graph')


def _relative(topic: str, ns: str) -> str:
    return topic[len(ns):] if topic.startswith(ns) else topic.lstrip('/')


def _namespace(counts: dict[str, int], types: dict[str, str]) -> str:
    """The prefix of the ``state`` topic with the most of the graph's topics beside it ('/' first)."""
    best = None
    for name, n in counts.items():
        if not name.endswith('/' + topics.STATE) or types.get(name) != ODOMETRY:
            continue
        prefix = name[:-len(topics.STATE)]
        score = sum(1 for rel in set(READ_TYPES) | set(REPORTED_TOPICS) if counts.get(prefix + rel))
        key = (-score, len(prefix), prefix)
        best = key if best is None or key < best else best
    return best[2] if best else '/'


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


def thruster_metrics(run: RunData) -> dict:
    """Total thruster impulse at the end (N s), firings (thruster-periods with a non-zero
    on-time) and total on-time (s); empty without ``thrusters/state``."""
    if not run.thruster_on_time.size:
        return {}
    return {'thruster_impulse_Ns': float(run.thruster_impulse[-1].sum()),
            'thruster_firings': int(np.count_nonzero(run.thruster_on_time > 0.0)),
            'thruster_on_time_s': float(run.thruster_on_time.sum())}


def _merged_statuses(parts: list) -> list[tuple[float, list]]:
    """(stamp, statuses) of DiagnosticArray messages in stamp order (file order on ties)."""
    merged = [(stamp, statuses) for stamps, batch in parts for stamp, statuses in zip(stamps.tolist(), batch)]
    merged.sort(key=lambda r: r[0])
    return merged


def target_attitude(scenario: dict) -> np.ndarray:
    """The regulation target of a scenario: a controller section's ``target.attitude``, or identity."""
    for name, section in (scenario or {}).items():
        params = (section or {}).get('ros__parameters') or {}
        target = (params.get('target') or {}).get('attitude') if isinstance(params, dict) else None
        if target is not None and str(name).lstrip('/') != 'dynamics':
            q = np.asarray(target, dtype=float)
            return q / np.linalg.norm(q)
    return np.array([0.0, 0.0, 0.0, 1.0])


def pointing_request(scenario: dict) -> tuple | None:
    """(σ̂, τ̂) of a scenario whose controller section points a body axis (``sigma``, ``tau``)."""
    for name, section in (scenario or {}).items():
        params = (section or {}).get('ros__parameters') or {}
        if isinstance(params, dict) and 'sigma' in params and 'tau' in params:
            return np.asarray(params['sigma'], dtype=float), np.asarray(params['tau'], dtype=float)
    return None


POINTING_BANDS_DEG = (1.0, 0.1, 0.01)   # seed 003 Table 1


def pointing_error_deg(run: RunData) -> np.ndarray:
    """Angle (deg) between σ̂ and τ̂ at each state sample of a pointing run."""
    sigma, tau = run.pointing
    return np.degrees(pointing_error(run.q, sigma, tau))


def pointing_metrics(t: np.ndarray, error_deg: np.ndarray, bands=POINTING_BANDS_DEG) -> dict:
    """First-entry and settling (staying below) times of the pointing error at each band (deg),
    and the final error: ``pointing_first_<b>deg_s``, ``pointing_settling_<b>deg_s``,
    ``final_pointing_error_deg``."""
    out = {}
    for b in bands:
        out[f'pointing_first_{b:g}deg_s'] = first_entry_time(t, error_deg, b)
        out[f'pointing_settling_{b:g}deg_s'] = settling_time(t, error_deg, b)
    out['final_pointing_error_deg'] = float(error_deg[-1]) if len(error_deg) else math.nan
    return out


def attitude_errors(run: RunData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(error quaternion (N, 4), eigenaxis error (N,) deg, signed 2-1-3 Euler errors (N, 3) deg in
    sequence order y, x, z)."""
    qe = error_quaternion(run.q, run.q_ref)
    return qe, np.degrees(eigenaxis_angle(qe)), np.degrees(euler_213(qe))


def attitude_errors_deg(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """(eigenaxis error (N,), absolute 2-1-3 Euler errors (N, 3) in sequence order y, x, z), degrees."""
    _, eigen, euler = attitude_errors(run)
    return eigen, np.abs(euler)


def settling_times(run: RunData, tols_deg=(0.5, 1.0)) -> dict[float, dict]:
    """Settling times at several tolerances: ``{tol: {'eigenaxis': s, 'euler213': s,
    'euler213_per_axis': [s_y, s_x, s_z]}}`` (definitions in the module docstring)."""
    eigen, euler = attitude_errors_deg(run)
    worst = euler.max(axis=1)
    return {tol: {'eigenaxis': settling_time(run.t, eigen, tol),
                  'euler213': settling_time(run.t, worst, tol),
                  'euler213_per_axis': [settling_time(run.t, euler[:, i], tol) for i in range(3)]}
            for tol in tols_deg}


def first_fault_time(run: RunData) -> float:
    """Stamp of the first fault (a ``faults`` status of level ERROR), NaN if the run had none."""
    times = [t for t, level, _, _ in run.faults if level >= 2]
    return float(min(times)) if times else math.nan


def q4_settling_after(run: RunData, band: float, t0: float) -> float:
    """Seed 000's settling time: the time after ``t0`` from which the scalar part of the error
    quaternion stays within ``1 ± band`` (``1 - |q4| <= band``; last exit, interpolated); counted
    from ``t0`` (0 if already inside at ``t0``)."""
    qe = error_quaternion(run.q, run.q_ref)
    after = run.t >= t0
    return settling_time(run.t[after], 1.0 - np.abs(qe[after, 3]), band) - t0


def fault_metrics(run: RunData, bands=(0.02, 0.01)) -> dict:
    """Recovery after the first fault ``t0`` (seed 000 VI.A): q4 settling times in each band and
    ``∫‖u‖dt`` over ``[t0, end]``; empty if the run had no fault."""
    t0 = first_fault_time(run)
    if not math.isfinite(t0):
        return {}
    out = {'first_fault_time_s': t0}
    for band in bands:
        out[f'settling_q4_{band:g}_after_fault_s'] = q4_settling_after(run, band, t0)
    if run.u.size:
        after = run.t_u >= t0
        out['integrated_torque_after_fault_Nms'] = integrated_norm(run.t_u[after], run.u[after], run.t_end)
    return out


def run_metrics(run: RunData, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
    """The run's metrics (see the module docstring for each definition)."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    eigen, euler = attitude_errors_deg(run)
    out = {
        'duration_s': run.t_end,
        f'settling_eigenaxis_{eigen_tol_deg:g}deg_s': settling_time(run.t, eigen, eigen_tol_deg),
        f'settling_euler213_{tol_deg:g}deg_s': settling_time(run.t, euler.max(axis=1), tol_deg),
        'settling_euler213_per_axis_s': [settling_time(run.t, euler[:, i], tol_deg) for i in range(3)],
        'final_eigenaxis_error_deg': float(eigen[-1]),
        'integrated_torque_Nms': math.nan, 'control_energy_N2m2s': math.nan,
        'peak_torque_Nm': [math.nan] * 3, 'peak_wheel_speed_rad_s': math.nan,
        'missed_steps': run.missed_steps,
    }
    if run.u.size:
        out['integrated_torque_Nms'] = integrated_norm(run.t_u, run.u, run.t_end)
        out['control_energy_N2m2s'] = integrated_square(run.t_u, run.u, run.t_end)
        out['peak_torque_Nm'] = np.abs(run.u).max(axis=0).tolist()
    if run.wheel_speed.size:
        out['peak_wheel_speed_rad_s'] = float(np.abs(run.wheel_speed).max())
    out.update(missed_step_gaps(run))
    out.update(fault_metrics(run))
    out.update(thruster_metrics(run))
    if run.pointing is not None:
        out.update(pointing_metrics(run.t, pointing_error_deg(run)))
    return out


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


def missed_step_gaps(run: RunData) -> dict:
    """Where the lockstep loop ran without commands: ``missed_step_gaps`` (runs of consecutive
    missed steps) and ``longest_missed_gap_s`` ([first, last] stamp of the longest run), e.g. a
    controller that crashed and was restarted. Empty when no step was missed."""
    t = run.missed_at
    if not t.size:
        return {}
    period = float(np.median(np.diff(run.t))) if run.t.size > 1 else 0.0
    breaks = np.flatnonzero(np.diff(t) > 1.5 * period)
    starts = np.r_[0, breaks + 1]
    ends = np.r_[breaks, t.size - 1]
    longest = int(np.argmax(t[ends] - t[starts]))
    return {'missed_step_gaps': int(starts.size),
            'longest_missed_gap_s': [float(t[starts[longest]]), float(t[ends[longest]])]}


def jsonable_metrics(metrics: dict) -> dict:
    """Metrics as JSON-safe values: inf / nan (also inside lists) as the strings 'inf' / 'nan'.

    The form of ``metrics.json`` and of ``adcs-analyze --json`` (strict JSON has no Infinity).
    """
    def conv(v):
        if isinstance(v, float) and not math.isfinite(v):
            return str(v)
        if isinstance(v, list):
            return [conv(x) for x in v]
        return v
    return {k: conv(v) for k, v in metrics.items()}


def format_metrics(metrics: dict) -> str:
    """Human-readable table of :func:`run_metrics`."""
    def fmt(v):
        if isinstance(v, list):
            return '[' + ', '.join(fmt(x) for x in v) + ']'
        if isinstance(v, float):
            return f'{v:.6g}'
        return str(v)
    width = max(len(k) for k in metrics)
    return '\n'.join(f'  {k:<{width}}  {fmt(v)}' for k, v in metrics.items())


def intrusion_lines(values) -> list[str]:
    """One line per intruder (node, topic, GID, who was allowed), each once, from the ``{key:
    value}`` of the statuses the recorder wrote on ``intrusions`` (adcs_msgs_py.guard)."""
    return list(dict.fromkeys(
        f'intruder node {kv.get("node", "?")} published on {kv.get("topic", "?")} '
        f'(GID {kv.get("gid", "?")}; allowed: {kv.get("allowed", "?")})' for kv in values))


def _is_intrusions(topic: str) -> bool:
    return topic.rsplit('/', 1)[-1] == topics.INTRUSIONS


def _recorded_intrusions(diagnostics: dict) -> list[str]:
    """:func:`intrusion_lines` of the decoded ``intrusions`` topics ({topic: [(stamps, statuses)]})."""
    return intrusion_lines(s[4] for name, parts in diagnostics.items() if _is_intrusions(name)
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
