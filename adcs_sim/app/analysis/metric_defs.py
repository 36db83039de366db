"""Metrics defined once: a declaration and an exact chunk reduction that every metric path drives.

A :class:`Metric` declares its ``name``, ``unit`` and ``note`` (the reports' explanation, the
campaign's columns), the series it reads (``needs``) and the run constants it takes, and reduces
a run's samples chunk by chunk:

* ``state = init(context)``: ``context`` the run constants, each with a leading run axis;
* ``state = update(state, chunk)`` for each chunk in time order: ``chunk['t_s']`` (samples,)
  stamps (s) shared by the runs (:func:`stamps_ns` gives their exact integer nanoseconds) of the
  one topic the series of ``needs`` come from, each series (runs, samples, ...): ``'wheel_speed'``
  (``wheels/state``, rad/s) or ``'torque'`` (``actuators/torque``, the applied body torque, N·m);
* ``merge(a, b)``: the state of span ``a`` followed by span ``b`` (each from ``init``);
* ``finish(state, t_end_s)``: the value of each run, an array (runs, ...); ``t_end_s`` the run's
  end (its last state stamp), to which a zero-order-held last sample counts.

The paths are only drivers of these four calls: the in-memory path
(:func:`adcs_sim.app.analysis.metrics.run_metrics`, ``adcs-analyze``) gives the whole run as one chunk of
one run (:func:`run_values`); the streamed path (:mod:`adcs_sim.app.analysis.stream_metrics`: ``adcs-run``
and the long report, :mod:`adcs_sim.app.report.long_run`) the bag's batches as they are read
(:class:`StreamedValues`); the campaign (:mod:`adcs_sim.app.analysis.batch_metrics`) the whole grid of every
run of a batch at once (:func:`batch_values`). A reduction made of integer sums, maxima and counts is
exact, so the paths give the same bits by construction (no summation order to keep). A float
sum (the torque integrals) keeps its terms and sums them once in :func:`finish` with numpy's
pairwise summation of the whole row: the order :func:`adcs_sim.app.analysis.metrics.run_metrics` always
had, whatever the chunking (merging is concatenating), at 8 B a sample.

To add a metric: a subclass here, an instance in :data:`DEFINED`, its test. Nothing else.
"""
from __future__ import annotations

import math

import numpy as np

NS_PER_S = 1_000_000_000


def stamps_ns(t_s) -> np.ndarray:
    """Stamps in seconds as int64 nanoseconds: the bag's own stamps again (exact below ~2^51 ns,
    i.e. any run shorter than ~26 days), and the same integers from the batch engine's grid."""
    return np.rint(np.asarray(t_s, dtype=float) * NS_PER_S).astype(np.int64)


def sampled_side(a, b, key: str):
    """For a ``merge``: the other state when one of ``a``, ``b`` covers no sample (its ``key`` is
    None), else None (both hold samples: the metric merges them)."""
    if a[key] is None:
        return b
    return a if b[key] is None else None


class Metric:
    """The protocol (module docstring). ``per``: ``'wheel'`` for a value per wheel (a list in
    wheel order in a run's metrics, columns ``name[i]`` in a campaign), ``None`` for a number."""

    name: str = ''
    unit: str = ''
    note: str = ''
    needs: tuple = ()
    per: str | None = None

    def init(self, context: dict):
        raise NotImplementedError

    def update(self, state, chunk: dict):
        raise NotImplementedError

    def merge(self, a, b):
        raise NotImplementedError

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        raise NotImplementedError


class HeldIntegral(Metric):
    """``∫ f(u) dt`` of the applied body torque ``u``, held over each control period (zero-order
    hold): ``Σ f(u_k) Δt_k``, ``Δt_k`` the time to the next sample, the last one's to the run's end
    (``max(t_end, t_last) - t_last``); NaN without torque samples. The terms are kept and summed
    once in :meth:`finish` (numpy's pairwise summation of the run's whole row: module docstring)."""

    needs = ('torque',)

    @staticmethod
    def term(u0, u1, u2):
        raise NotImplementedError

    def init(self, context: dict):
        return {'runs': context['runs'], 'parts': [], 'first_t': None, 'last_t': None, 'last_v': None}

    def update(self, state, chunk: dict):
        t = np.asarray(chunk['t_s'], dtype=float)
        if not t.size:
            return state
        u = np.asarray(chunk['torque'], dtype=float)                # (runs, m, 3)
        v = self.term(u[..., 0], u[..., 1], u[..., 2])              # (runs, m)
        if state['last_t'] is None:
            state['first_t'] = t[0]
        else:                                                       # the previous sample's hold
            state['parts'].append((state['last_v'] * (t[0] - state['last_t']))[:, None])
        if t.size > 1:
            state['parts'].append(v[:, :-1] * np.diff(t))
        state['last_t'], state['last_v'] = t[-1], v[:, -1]
        return state

    def merge(self, a, b):
        if (side := sampled_side(a, b, 'last_t')) is not None:
            return side
        hold = (a['last_v'] * (b['first_t'] - a['last_t']))[:, None]
        return {'runs': a['runs'], 'parts': [*a['parts'], hold, *b['parts']], 'first_t': a['first_t'],
                'last_t': b['last_t'], 'last_v': b['last_v']}

    def terms(self, state, t_end_s: float) -> np.ndarray:
        """``f(u_k) Δt_k`` of every sample (runs, samples), the last held to ``t_end_s``."""
        if state['last_t'] is None:
            return np.zeros((state['runs'], 0))
        last = state['last_v'] * (max(t_end_s, state['last_t']) - state['last_t'])   # zoh_durations
        return np.concatenate([*state['parts'], last[:, None]], axis=1)

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        if state['last_t'] is None:
            return np.full(state['runs'], math.nan)
        return np.sum(self.terms(state, t_end_s), axis=-1)   # each C-order row: its 1-D pairwise sum


class IntegratedTorque(HeldIntegral):
    """``∫‖u‖ dt`` (N·m·s), ``‖u‖`` the Euclidean norm ``sqrt((u0² + u1²) + u2²)`` (numpy's
    ``norm(u, axis=-1)``, the same operations in the same order)."""

    name = 'integrated_torque_Nms'
    unit = 'N·m·s'
    note = '∫‖u‖dt of the applied torque (N·m·s)'

    @staticmethod
    def term(u0, u1, u2):
        return np.sqrt((u0 * u0 + u1 * u1) + u2 * u2)


class ControlEnergy(HeldIntegral):
    """``∫uᵀu dt`` (N²·m²·s), ``uᵀu = (u0² + u1²) + u2²`` (numpy's ``sum(u ** 2, axis=-1)``)."""

    name = 'control_energy_N2m2s'
    unit = 'N²·m²·s'
    note = '∫uᵀu dt of the applied torque (N²·m²·s)'

    @staticmethod
    def term(u0, u1, u2):
        return (u0 ** 2 + u1 ** 2) + u2 ** 2


class PeakTorque(Metric):
    """``max |u_i|`` per body axis x, y, z over the applied-torque samples (N·m); NaN without
    samples; a NaN sample makes its axis NaN (numpy's maximum)."""

    name = 'peak_torque_Nm'
    unit = 'N·m'
    note = 'max |u_i| per body axis x, y, z (N·m)'
    needs = ('torque',)
    per = 'axis'

    def init(self, context: dict):
        return {'runs': context['runs'], 'peak': None}

    def update(self, state, chunk: dict):
        u = np.asarray(chunk['torque'], dtype=float)               # (runs, m, 3)
        if not u.shape[1]:
            return state
        # per component: numpy reduces a middle axis of length-3 rows ~20-50x slower (max is exact)
        peak = np.stack([np.abs(u[..., i]).max(axis=1) for i in range(3)], axis=1)
        state['peak'] = peak if state['peak'] is None else np.maximum(state['peak'], peak)
        return state

    def merge(self, a, b):
        if a['peak'] is None or b['peak'] is None:
            return b if a['peak'] is None else a
        return {'runs': a['runs'], 'peak': np.maximum(a['peak'], b['peak'])}

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        return state['peak'] if state['peak'] is not None else np.full((state['runs'], 3), math.nan)


class PeakWheelSpeed(Metric):
    """``max |Ω|`` over all wheels and samples (rad/s, relative to the body); NaN without wheel
    samples. A NaN sample makes it NaN (numpy's maximum), as the whole-array ``max`` would."""

    name = 'peak_wheel_speed_rad_s'
    unit = 'rad/s'
    note = 'max |Ω| over all wheels (rad/s)'
    needs = ('wheel_speed',)

    def init(self, context: dict):
        return {'peak': np.full(len(context['wheel_max_speed']), -np.inf), 'seen': False}

    def update(self, state, chunk: dict):
        speed = np.asarray(chunk['wheel_speed'], dtype=float)   # (runs, m, n)
        if speed.shape[1] and speed.shape[2]:
            state['peak'] = np.maximum(state['peak'], np.abs(speed).max(axis=(1, 2)))
            state['seen'] = True
        return state

    def merge(self, a, b):
        return {'peak': np.maximum(a['peak'], b['peak']), 'seen': a['seen'] or b['seen']}

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        return state['peak'] if state['seen'] else np.full(state['peak'].shape, math.nan)


class TimeAtWheelSpeedLimit(Metric):
    """Time each wheel spends at its speed limit.

    Rule: wheel ``i``'s speed sample ``Ω_i(t_k)`` (relative to the body, ``wheels/state``) is *at
    the limit* when ``|Ω_i(t_k)| >= max_speed_i (1 - EPS)``, ``max_speed_i`` the truth model's
    ``wheels.max_speed`` (:class:`adcs_sim.truth.plant.ReactionWheels`: there the motor torque
    that would spin the wheel faster is cut, so a wheel pressed against its limit hovers just
    below it); the sample then counts for ``t_{k+1} - t_k``, to the next sample, if that one
    exists and is finite (the last sample counts nothing). Stamps in integer nanoseconds, so the
    sum is exact. An unlimited wheel (``inf``, the schema's default) is never at its limit: 0 s.
    """

    name = 'wheel_time_at_speed_limit_s'
    unit = 's'
    EPS = 1e-3
    note = (f'per wheel (wheels.names order), time with |Ω| >= wheels.max_speed·(1 − {EPS:g}), '
            'each sample held to the next (s)')
    needs = ('wheel_speed',)
    per = 'wheel'

    def init(self, context: dict):
        limit = np.asarray(context['wheel_max_speed'], dtype=float)        # (runs, n)
        runs, n = limit.shape
        return {'threshold': limit * (1.0 - self.EPS), 'total': np.zeros((runs, n), np.int64),
                'first_t': None, 'first_finite': None, 'last_t': None, 'last_at': None}

    def update(self, state, chunk: dict):
        t_s, speed = chunk['t_s'], np.asarray(chunk['wheel_speed'], dtype=float)   # (m,), (runs, m, n)
        if not len(t_s):
            return state
        first, last = stamps_ns([t_s[0], t_s[-1]])
        limited = np.isfinite(state['threshold'])
        if not limited.any():   # no limit (the schema's default): never at it, nothing to compute
            state['first_t'] = first if state['last_t'] is None else state['first_t']
            state['first_finite'] = state['first_finite'] if state['first_finite'] is not None else limited
            state['last_t'], state['last_at'] = last, limited
            return state
        if state['last_t'] is None:
            state['first_t'], state['first_finite'] = first, np.isfinite(speed[:, 0])
        elif state['last_at'].any():
            state['total'] += (state['last_at'] & np.isfinite(speed[:, 0])) * (first - state['last_t'])
        # Only the runs with a sample at a limit (or NaN) need the per-sample pass: most runs never
        # reach one, and two reductions tell which (exact: max and min only compare). Over each
        # run's samples flattened: numpy reduces a middle axis of length-3 rows ~50x slower.
        # ``chunk['wheel_peak']``: that max |Ω| of each run if a path has it already (the campaign's
        # compiled pass, the twin of PeakWheelSpeed: equal to it, tests/test_metrics_kernel.py).
        peak = chunk.get('wheel_peak')
        if peak is None:
            flat = speed.reshape(speed.shape[0], -1)
            peak = np.maximum(flat.max(axis=1), -flat.min(axis=1))
        lowest = np.where(limited, state['threshold'], math.inf).min(axis=1)   # the run's lowest limit
        with np.errstate(invalid='ignore'):
            near = ~(peak < lowest)
        last_at = np.zeros(state['total'].shape, dtype=bool)
        rows = np.flatnonzero(near)
        if rows.size:
            v = speed[rows]
            with np.errstate(invalid='ignore'):
                at = (np.abs(v) >= state['threshold'][rows, None, :]) & limited[rows, None, :]
            held = (at[:, :-1] & np.isfinite(v[:, 1:])) * np.diff(stamps_ns(t_s))[None, :, None]
            state['total'][rows] += held.sum(axis=1, dtype=np.int64)
            last_at[rows] = at[:, -1]
        state['last_t'], state['last_at'] = last, last_at
        return state

    def merge(self, a, b):
        if (side := sampled_side(a, b, 'last_t')) is not None:
            return side
        a['total'] = a['total'] + b['total'] + (a['last_at'] & b['first_finite']) * (b['first_t'] - a['last_t'])
        a['last_t'], a['last_at'] = b['last_t'], b['last_at']
        return a

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        return state['total'] / NS_PER_S   # the double nearest the exact seconds


# In run_metrics' order, between ``final_eigenaxis_error_deg`` and ``missed_steps``.
DEFINED: tuple[Metric, ...] = (IntegratedTorque(), ControlEnergy(), PeakTorque(),
                               PeakWheelSpeed(), TimeAtWheelSpeedLimit())


def notes() -> dict[str, str]:
    """``{name: note (unit)}`` of the defined metrics (the reports' METRIC_NOTES)."""
    return {m.name: m.note for m in DEFINED}


# --- the run constants each path knows ----------------------------------------------------------

def wheel_limits(scenario: dict | None, names) -> np.ndarray:
    """``wheels.max_speed`` of the wheels ``names`` (rad/s, ``inf`` where not limited) from a bag's
    scenario tree (``{section: {'ros__parameters': {...}}}``, :attr:`RunData.scenario`): the
    dynamics section's (the truth model's), by wheel name; all ``inf`` without one."""
    out = np.full(len(names), math.inf)
    for section, body in (scenario.items() if isinstance(scenario, dict) else ()):
        params = body.get('ros__parameters') if isinstance(body, dict) else None
        wheels = params.get('wheels') if isinstance(params, dict) else None
        if str(section).rstrip('/').rsplit('/', 1)[-1] != 'dynamics' or not isinstance(wheels, dict):
            continue
        have, limits = list(wheels.get('names') or []), list(wheels.get('max_speed') or [])
        for i, name in enumerate(names):
            if name in have and have.index(name) < len(limits):
                out[i] = float(limits[have.index(name)])
        break
    return out


def run_context(run) -> dict:
    """The constants of a :class:`~adcs_sim.app.analysis.run_data.RunData` (one run: leading axis 1)."""
    limits = run.wheel_max_speed
    if limits is None:
        limits = wheel_limits(run.scenario, run.wheel_names)
    return {'runs': 1, 'wheel_max_speed': np.asarray(limits, dtype=float).reshape(1, len(run.wheel_names))}


def _listed(metric: Metric, values: np.ndarray):
    """A run's value (``values`` (...)) as run_metrics shows it: a list per wheel or axis, or a float."""
    return values.tolist() if metric.per else float(values)


def _value(metric: Metric, context: dict, chunk: dict, t_end_s: float) -> np.ndarray:
    """``metric`` of the runs whose samples are all in ``chunk``."""
    return metric.finish(metric.update(metric.init(context), chunk), t_end_s)


# --- drivers -------------------------------------------------------------------------------------

def run_values(run, names=None) -> dict:
    """The defined metrics of one run in memory (``names``: only those), one chunk a topic (the
    in-memory path)."""
    context = run_context(run)
    chunks = {'wheel_speed': {'t_s': run.t_wheels, 'wheel_speed': run.wheel_speed[None]},
              'torque': {'t_s': run.t_u, 'torque': np.asarray(run.u).reshape(1, -1, 3)}}
    return {m.name: _listed(m, _value(m, context, chunks[m.needs[0]], run.t_end)[0])
            for m in DEFINED if names is None or m.name in names}


def batch_values(result, rows: np.ndarray, twins: dict | None = None) -> dict[str, np.ndarray]:
    """The defined metrics of runs ``rows`` of a :class:`~adcs_sim.app.batch.engine.BatchResult` over its
    whole grid (the campaign path): ``{name: (runs, ...)}``. ``twins``: ``{name: values}`` computed by
    a fast path that equals the definition (docs/architecture.md §3), used instead."""
    twins = twins or {}
    K = result.t.size - 1
    take = slice(None) if rows.size == result.n_runs else rows
    n = len(result.wheel_names) if result.wheel_names and result.wheel_speed.shape[-1] else 0
    limits = result.wheel_limits()[take] if n else np.zeros((rows.size, 0))
    context = {'runs': rows.size, 'wheel_max_speed': limits}

    def chunk(series: str) -> dict:   # only for a metric without a twin (a row selection copies)
        if series == 'torque':
            return {'t_s': result.t[:K], 'torque': result.u[take]}   # each held over its step
        out = {'t_s': result.t, 'wheel_speed': result.wheel_speed[take] if n else np.zeros((rows.size, K + 1, 0))}
        if n and twins.get('peak_wheel_speed_rad_s') is not None:   # the whole run's max |Ω|, known
            out['wheel_peak'] = twins['peak_wheel_speed_rad_s']
        return out

    chunks: dict = {}
    out = {}
    for m in DEFINED:
        if m.name in twins:
            out[m.name] = twins[m.name]
            continue
        if m.needs[0] not in chunks:
            chunks[m.needs[0]] = chunk(m.needs[0])
        out[m.name] = _value(m, context, chunks[m.needs[0]], float(result.t[K]))
    return out


class StreamedValues:
    """The defined metrics that read ``series`` of one run, fed chunk by chunk (the streamed path),
    per joint-name list (:class:`~adcs_sim.app.analysis.stream_metrics.JointStream` keeps those named in the
    last message; ``()`` for a topic without names, the applied torque). ``skip``: names of metrics a
    driver takes from another state (the torque integral, from the after-fault integral's)."""

    def __init__(self, series: str = 'wheel_speed', skip: tuple = ()) -> None:
        self.series = series
        self.metrics = [m for m in DEFINED if m.needs == (series,) and m.name not in skip]
        self.states: dict = {}      # names -> [state per metric]
        self.limits: dict = {}      # names -> the limits used

    def add(self, names: tuple, limits: np.ndarray, t_s: np.ndarray, values: np.ndarray) -> None:
        if names not in self.states:
            context = {'runs': 1, 'wheel_max_speed': np.asarray(limits, dtype=float).reshape(1, len(limits))}
            self.states[names] = [m.init(context) for m in self.metrics]
            self.limits[names] = limits
        chunk = {'t_s': t_s, self.series: values[None]}
        self.states[names] = [m.update(s, chunk) for m, s in zip(self.metrics, self.states[names])]

    def state(self, name: str, names: tuple):
        """The state of metric ``name`` for ``names`` (fed at least once)."""
        return self.states[names][[m.name for m in self.metrics].index(name)]

    def values(self, names, n_wheels: int, t_end_s: float | None = None) -> dict:
        """The values for the wheels ``names`` (those RunData keeps); no samples: as a run with none."""
        if names not in self.states:
            context = {'runs': 1, 'wheel_max_speed': np.zeros((1, n_wheels))}
            return {m.name: _listed(m, m.finish(m.init(context), t_end_s)[0]) for m in self.metrics}
        return {m.name: _listed(m, m.finish(s, t_end_s)[0]) for m, s in zip(self.metrics, self.states[names])}
