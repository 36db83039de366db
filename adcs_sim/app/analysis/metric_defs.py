"""Metrics defined once: a declaration and an exact chunk reduction that every metric path drives.

A :class:`Metric` declares its ``name``, ``unit`` and ``note`` (the reports' explanation, the
campaign's columns), the series it reads (``needs``) and the run constants it takes, and reduces
a run's samples chunk by chunk:

* ``state = init(context)``: ``context`` the run constants, each with a leading run axis;
* ``state = update(state, chunk)`` for each chunk in time order: ``chunk['t_s']`` (samples,)
  stamps (s) shared by the runs (:func:`stamps_ns` gives their exact integer nanoseconds), each
  series of ``needs`` (runs, samples, ...);
* ``merge(a, b)``: the state of span ``a`` followed by span ``b`` (each from ``init``);
* ``finish(state)``: the value of each run, an array (runs, ...).

The paths are only drivers of these four calls: the in-memory path
(:func:`adcs_sim.app.analysis.metrics.run_metrics`, ``adcs-analyze``) gives the whole run as one chunk of
one run (:func:`run_values`); the streamed path (:mod:`adcs_sim.app.analysis.stream_metrics`: ``adcs-run``
and the long report, :mod:`adcs_sim.app.report.long_run`) the bag's batches as they are read
(:class:`StreamedValues`); the campaign (:mod:`adcs_sim.app.analysis.batch_metrics`) the whole grid of every
run of a batch at once (:func:`batch_values`). A reduction made of integer sums, maxima and counts is
exact, so the paths give the same bits by construction (no summation order to keep).

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

    def finish(self, state) -> np.ndarray:
        raise NotImplementedError


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

    def finish(self, state) -> np.ndarray:
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
        if a['last_t'] is None:
            return b
        if b['last_t'] is None:
            return a
        a['total'] = a['total'] + b['total'] + (a['last_at'] & b['first_finite']) * (b['first_t'] - a['last_t'])
        a['last_t'], a['last_at'] = b['last_t'], b['last_at']
        return a

    def finish(self, state) -> np.ndarray:
        return state['total'] / NS_PER_S   # the double nearest the exact seconds


# In run_metrics' order, between ``peak_torque_Nm`` and ``missed_steps``.
DEFINED: tuple[Metric, ...] = (PeakWheelSpeed(), TimeAtWheelSpeedLimit())


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
    return {'wheel_max_speed': np.asarray(limits, dtype=float).reshape(1, len(run.wheel_names))}


def _listed(metric: Metric, values: np.ndarray):
    """A run's value (``values`` (...)) as run_metrics shows it: a list per wheel, or a float."""
    return values.tolist() if metric.per else float(values)


# --- drivers -------------------------------------------------------------------------------------

def run_values(run) -> dict:
    """The defined metrics of one run in memory: one chunk (the in-memory path)."""
    context = run_context(run)
    chunk = {'t_s': run.t_wheels, 'wheel_speed': run.wheel_speed[None]}
    out = {}
    for m in DEFINED:
        out[m.name] = _listed(m, m.finish(m.update(m.init(context), chunk))[0])
    return out


def batch_values(result, rows: np.ndarray, twins: dict | None = None) -> dict[str, np.ndarray]:
    """The defined metrics of runs ``rows`` of a :class:`~adcs_sim.app.batch.engine.BatchResult` over its
    whole grid (the campaign path): ``{name: (runs, ...)}``. ``twins``: ``{name: values}`` computed by
    a fast path that equals the definition (docs/architecture.md §3), used instead."""
    twins = twins or {}
    take = slice(None) if rows.size == result.n_runs else rows
    n = len(result.wheel_names) if result.wheel_names and result.wheel_speed.shape[-1] else 0
    speed = result.wheel_speed[take] if n else np.zeros((rows.size, result.t.size, 0))
    limits = result.wheel_limits()[take] if n else np.zeros((rows.size, 0))
    context = {'wheel_max_speed': limits}
    chunk = {'t_s': result.t, 'wheel_speed': speed}
    if n and twins.get('peak_wheel_speed_rad_s') is not None:   # the whole run's max |Ω|, known
        chunk['wheel_peak'] = twins['peak_wheel_speed_rad_s']
    return {m.name: twins[m.name] if m.name in twins else m.finish(m.update(m.init(context), chunk))
            for m in DEFINED}


class StreamedValues:
    """The defined metrics of one run fed chunk by chunk (the streamed path), per joint-name list
    (:class:`~adcs_sim.app.analysis.stream_metrics.JointStream` keeps those named in the last message)."""

    def __init__(self) -> None:
        self.states: dict = {}      # names -> [state per metric]
        self.limits: dict = {}      # names -> the limits used

    def add(self, names: tuple, limits: np.ndarray, t_s: np.ndarray, speed: np.ndarray) -> None:
        if names not in self.states:
            context = {'wheel_max_speed': np.asarray(limits, dtype=float).reshape(1, len(names))}
            self.states[names] = [m.init(context) for m in DEFINED]
            self.limits[names] = limits
        chunk = {'t_s': t_s, 'wheel_speed': speed[None]}
        self.states[names] = [m.update(s, chunk) for m, s in zip(DEFINED, self.states[names])]

    def values(self, names, n_wheels: int) -> dict:
        """The values for the wheels ``names`` (those RunData keeps); no samples: as a run with none."""
        if names not in self.states:
            context = {'wheel_max_speed': np.zeros((1, n_wheels))}
            return {m.name: _listed(m, m.finish(m.init(context))[0]) for m in DEFINED}
        return {m.name: _listed(m, m.finish(s)[0]) for m, s in zip(DEFINED, self.states[names])}
