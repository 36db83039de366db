"""The attitude metrics defined once, on the protocol of :mod:`adcs_sim.app.analysis.metric_defs`.

Each reads an error series of the state topic (``state`` or ``truth/state``), given in a chunk with
the state stamps ``t_s`` (samples,) shared by the runs, each series (runs, samples[, 3]):

* ``'eigen_error_deg'``: the eigenaxis error ``2 atan2(|q_e,v|, |q_e,4|)``, ``q_e = q_ref* ⊗ q``;
* ``'euler_error_deg'``: the absolute 2-1-3 Euler errors (y, x, z), (runs, samples, 3);
* ``'euler_worst_deg'``: their largest (a NaN one wins);
* ``'pointing_error_deg'``: the angle between the body axis σ̂ and the inertial direction τ̂;
* ``'q4_error'``: ``1 - |q_e,4|`` (seed 000's band on the error quaternion's scalar part).

:func:`attitude_series` derives them from the attitude (what the in-memory and streamed paths give);
the campaign's numpy path derives the same bits over its batch axis (its compiled kernel equals it,
docs/architecture.md §3).

* :class:`SettlingTime` (``tol``): the time after which the error stays ``<= tol`` to the end (the
  *last exit*), linearly interpolated between the last sample outside and the next; the first
  stamp if always inside, ``inf`` if the run ends outside, NaN without samples; a NaN sample is
  outside, and the crossing after a non-finite one is the next sample's time (:func:`crossing`).
* :class:`FirstEntryTime` (``tol``): the first time the error is ``<= tol``, interpolated the same
  way; the first stamp if it starts inside, ``inf`` if never.
* :class:`FinalValue`: the last sample (NaN without one); :class:`Duration`: the last stamp.

Each keeps a few samples a run (the last exit and the sample after it; the first entry and the one
before it), and only copies samples: the crossing is computed once in ``finish``, so any chunking
gives the same bits. The names carry the band (``settling_eigenaxis_0.5deg_s``): the metrics of a
run at tolerance ``tol_deg`` are :func:`head_metrics` and :func:`pointing_band_metrics`.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from adcs_core.attitude import eigenaxis_angle, error_quaternion, euler_213, pointing_error
from adcs_sim.app.analysis.metric_defs import IntegratedTorque, Metric, sampled_side

POINTING_BANDS_DEG = (1.0, 0.1, 0.01)   # seed 003 Table 1


def crossing(t0, e0, t1, e1, tol):
    """When the error crosses ``tol`` between the samples ``(t0, e0)`` and ``(t1, e1)``, linearly
    interpolated; ``t1`` where ``e0`` is not finite (element-wise, arrays or numbers)."""
    with np.errstate(all='ignore'):
        return np.where(np.isfinite(e0), t0 + (e0 - tol) / (e0 - e1) * (t1 - t0), t1)


def _rows(chunk: dict, series: str) -> np.ndarray:
    """The series as rows of samples: (runs, samples), or (runs·3, samples) for one per axis."""
    e = np.asarray(chunk[series], dtype=float)
    return e if e.ndim == 2 else np.moveaxis(e, 1, -1).reshape(-1, e.shape[1])


def _shaped(values: np.ndarray, per: str | None) -> np.ndarray:
    return values.reshape(-1, 3) if per else values


class SettlingTime(Metric):
    """The last exit from the band ``<= tol`` (module docstring). State per row (run, or run and
    axis): whether a sample was outside, whether the latest was, and ``(t, e)`` of the last one
    outside and of the sample after it."""

    def __init__(self, name: str, series: str, tol: float, per: str | None = None) -> None:
        self.name, self.needs, self.tol, self.per = name, (series,), float(tol), per
        self.unit = 's'

    def init(self, context: dict):
        rows = context['runs'] * (3 if self.per else 1)
        return {'t0': None, 'first': None, 'seen': np.zeros(rows, bool), 'pending': np.zeros(rows, bool),
                'exit': np.full((4, rows), math.nan)}   # out_t, out_e, next_t, next_e

    def update(self, state, chunk: dict):
        t = np.asarray(chunk['t_s'], dtype=float)
        if not t.size:
            return state
        e = _rows(chunk, self.needs[0])
        if state['t0'] is None:
            state['t0'], state['first'] = t[0], (t[0], e[:, 0].copy())
        pending, ex = state['pending'], state['exit']
        if pending.any():                      # the sample after the previous chunk's last exit
            ex[2, pending], ex[3, pending] = t[0], e[pending, 0]
            state['pending'] = pending = np.zeros(pending.shape, bool)
        outside = ~(e <= self.tol)
        now = outside.any(axis=1)
        if now.any():
            m = t.size
            rows = np.flatnonzero(now)
            sub = outside if rows.size == now.size else outside[rows]   # every row: no copy
            last = m - 1 - np.argmax(sub[:, ::-1], axis=1)
            after = np.minimum(last + 1, m - 1)
            ex[:, rows] = (t[last], e[rows, last], t[after], e[rows, after])
            pending[rows] = last == m - 1
            state['seen'] = state['seen'] | now
        return state

    def merge(self, a, b):
        if (side := sampled_side(a, b, 't0')) is not None:
            return side
        ex = np.where(b['seen'], b['exit'], a['exit'])
        fill = a['pending'] & ~b['seen']        # a's last exit, then b's first sample after it
        ex[2, fill], ex[3, fill] = b['first'][0], b['first'][1][fill]
        return {'t0': a['t0'], 'first': a['first'], 'seen': a['seen'] | b['seen'], 'pending': b['pending'],
                'exit': ex}

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        if state['t0'] is None:
            return _shaped(np.full(state['seen'].shape, math.nan), self.per)
        value = crossing(*state['exit'], self.tol)
        value[state['pending']] = math.inf
        value[~state['seen']] = state['t0']
        return _shaped(value, self.per)


class FirstEntryTime(Metric):
    """The first sample ``<= tol``, the crossing interpolated from the one before (module docstring).
    State per row: whether found, whether at the first sample, ``(t, e)`` of the sample before and
    of the first inside, and the latest sample (the one before the next chunk's first)."""

    def __init__(self, name: str, series: str, tol: float, per: str | None = None) -> None:
        self.name, self.needs, self.tol, self.per = name, (series,), float(tol), per
        self.unit = 's'

    def init(self, context: dict):
        rows = context['runs'] * (3 if self.per else 1)
        return {'t0': None, 'found': np.zeros(rows, bool), 'at_start': np.zeros(rows, bool),
                'entry': np.full((4, rows), math.nan), 'last_t': math.nan, 'last_e': None}   # before t, e; in t, e

    def update(self, state, chunk: dict):
        t = np.asarray(chunk['t_s'], dtype=float)
        if not t.size:
            return state
        e = _rows(chunk, self.needs[0])
        started = state['t0'] is not None
        if not started:
            state['t0'] = t[0]
        found = state['found']
        if not found.all():
            inside = e <= self.tol
            new = inside.any(axis=1) & ~found
            if new.any():
                rows = np.flatnonzero(new)
                first = np.argmax(inside if rows.size == new.size else inside[rows], axis=1)   # every row: no copy
                before = np.maximum(first - 1, 0)
                entry = np.array((t[before], e[rows, before], t[first], e[rows, first]))
                start = first == 0               # the sample before is the previous chunk's last
                if start.any():
                    entry[0, start] = state['last_t']
                    entry[1, start] = state['last_e'][rows[start]] if started else math.nan
                state['entry'][:, rows] = entry
                state['at_start'][rows] = start & (not started)
                state['found'] = found | new
        state['last_t'], state['last_e'] = t[-1], e[:, -1].copy()
        return state

    def merge(self, a, b):
        if (side := sampled_side(a, b, 't0')) is not None:
            return side
        take = b['found'] & ~a['found']
        entry = np.where(take, b['entry'], a['entry'])
        start = take & b['at_start']            # b's first sample: the one before it is a's last
        entry[0, start], entry[1, start] = a['last_t'], a['last_e'][start]
        return {'t0': a['t0'], 'found': a['found'] | b['found'], 'at_start': np.where(take, False, a['at_start']),
                'entry': entry, 'last_t': b['last_t'], 'last_e': b['last_e']}

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        if state['t0'] is None:
            return _shaped(np.full(state['found'].shape, math.inf), self.per)
        value = crossing(*state['entry'], self.tol)
        value[state['at_start']] = state['t0']
        value[~state['found']] = math.inf
        return _shaped(value, self.per)


class FinalValue(Metric):
    """The series' last sample (NaN without samples)."""

    def __init__(self, name: str, series: str, unit: str = 'deg') -> None:
        self.name, self.needs, self.unit = name, (series,), unit

    def init(self, context: dict):
        return {'runs': context['runs'], 'last': None}

    def update(self, state, chunk: dict):
        e = np.asarray(chunk[self.needs[0]], dtype=float)
        if e.shape[1]:
            state['last'] = e[:, -1].copy()
        return state

    def merge(self, a, b):
        return a if b['last'] is None else b

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        return state['last'] if state['last'] is not None else np.full(state['runs'], math.nan)


class Duration(Metric):
    """The last state stamp (s): the simulated time of the run (NaN without a state)."""

    name, unit, needs = 'duration_s', 's', ('eigen_error_deg',)   # (only the stamps of the state's chunks)

    def init(self, context: dict):
        return {'runs': context['runs'], 'last': math.nan}

    def update(self, state, chunk: dict):
        if len(chunk['t_s']):
            state['last'] = chunk['t_s'][-1]
        return state

    def merge(self, a, b):
        return a if math.isnan(b['last']) else b

    def finish(self, state, t_end_s: float | None = None) -> np.ndarray:
        return np.full(state['runs'], state['last'])


def head_metrics(tol_deg: float, eigen_tol_deg: float | None = None) -> tuple[Metric, ...]:
    """The attitude metrics at the head of a run's metrics, in their order (run_metrics')."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    return (Duration(),
            SettlingTime(f'settling_eigenaxis_{eigen_tol_deg:g}deg_s', 'eigen_error_deg', eigen_tol_deg),
            SettlingTime(f'settling_euler213_{tol_deg:g}deg_s', 'euler_worst_deg', tol_deg),
            SettlingTime('settling_euler213_per_axis_s', 'euler_error_deg', tol_deg, per='axis'),
            FinalValue('final_eigenaxis_error_deg', 'eigen_error_deg'))


def pointing_band_metrics(bands=POINTING_BANDS_DEG) -> tuple[Metric, ...]:
    """A pointing run's metrics (seed 003): first entry and settling at each band (deg), the final error."""
    out: list[Metric] = []
    for b in bands:
        out += [FirstEntryTime(f'pointing_first_{b:g}deg_s', 'pointing_error_deg', b),
                SettlingTime(f'pointing_settling_{b:g}deg_s', 'pointing_error_deg', b)]
    return (*out, FinalValue('final_pointing_error_deg', 'pointing_error_deg'))


# --- the series, from the attitude ---------------------------------------------------------------

def attitude_errors(run, q_ref: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(error quaternion (N, 4), eigenaxis error (N,) deg, signed 2-1-3 Euler errors (N, 3) deg in
    sequence order y, x, z) to ``q_ref`` ((4,) or (N, 4) at the state samples; default the run's
    target ``run.q_ref``). At gimbal lock (θ1 = ±90°) the 2-1-3 angles are not unique: scipy sets
    the third to zero (its warning is not repeated here: the angles are what the docstring says)."""
    qe = error_quaternion(run.q, run.q_ref if q_ref is None else q_ref)
    with warnings.catch_warnings():
        warnings.filterwarnings('ignore', message='Gimbal lock detected', category=UserWarning)
        euler = euler_213(qe)
    return qe, np.degrees(eigenaxis_angle(qe)), np.degrees(euler)


def attitude_series(run, needs=('eigen_error_deg', 'euler_error_deg', 'euler_worst_deg')) -> dict:
    """The error series of one run's attitude ``run.q`` (N, 4) to ``run.q_ref`` (and ``run.pointing``
    for ``'pointing_error_deg'``), each with a leading run axis of 1: those of ``needs``."""
    out: dict = {}
    if {'eigen_error_deg', 'euler_error_deg', 'euler_worst_deg', 'q4_error'} & set(needs):
        qe, eigen, euler = attitude_errors(run)
        euler = np.abs(euler)
        out = {'eigen_error_deg': eigen[None], 'euler_error_deg': euler[None],
               'euler_worst_deg': euler.max(axis=1)[None]}
        if 'q4_error' in needs:
            out['q4_error'] = (1.0 - np.abs(qe[:, 3]))[None]
    if 'pointing_error_deg' in needs:
        sigma, tau = run.pointing
        out['pointing_error_deg'] = np.degrees(pointing_error(run.q, sigma, tau))[None]
    return out


def values_of(metrics, context: dict, chunks, t_end_s: float | None = None) -> dict:
    """``{name: value (runs, ...)}`` of ``metrics`` on runs whose samples are all in ``chunks`` (a chunk,
    or several: each metric is fed, in order, those holding a series it needs); a metric without a
    value for the runs (None) is left out."""
    chunks = [chunks] if isinstance(chunks, dict) else chunks
    out = {}
    for m in metrics:
        state = m.init(context)
        for chunk in chunks:
            if any(n in chunk for n in m.needs):
                state = m.update(state, chunk)
        value = m.finish(state, t_end_s)
        if value is not None:
            out[m.name] = value
    return out


def listed(values: dict, row: int = 0) -> dict:
    """One run's values as run_metrics shows them: a list per axis or wheel, else a float (an int
    for a count)."""
    return {k: v[row].tolist() for k, v in values.items()}


# --- after the first fault (seed 000 VI.A) -------------------------------------------------------

FAULT_BANDS = (0.02, 0.01)   # fault_metrics' bands on 1 - |q_e,4|


def first_fault(chunk: dict) -> float:
    """The first fault's stamp in a ``'faults'`` chunk (rows (stamp s, level)): the earliest status
    of level ERROR (2) or worse; NaN without one."""
    faults = np.asarray(chunk['faults'], dtype=float).reshape(-1, 2)
    times = faults[faults[:, 1] >= 2, 0]
    return float(times.min()) if times.size else math.nan


class _AfterFault(Metric):
    """A metric from the first fault's time ``t0`` on, fed the ``'faults'`` chunk (its rows (stamp,
    level), before or after the samples: a stream reads the faults when it reads them) and the
    samples; it keeps what it needs of every sample and takes ``t0`` in :meth:`finish`. No value
    (None: left out of the run's metrics) without a fault."""

    def _fault(self, state, chunk: dict) -> bool:
        if 'faults' not in chunk:
            return False
        t0 = first_fault(chunk)
        if not math.isnan(t0):
            state['t0'] = t0 if math.isnan(state['t0']) else min(state['t0'], t0)
        return True


class _OverSamplesAfterFault(_AfterFault):
    """An ``inner`` metric of every sample, with the stamps kept: :meth:`finish` keeps what is at or
    after ``t0`` (the state: ``t0``, the stamps ``t`` and the inner metric's state ``inner``)."""

    inner: Metric

    def init(self, context: dict):
        return {'t0': math.nan, 't': [], 'inner': self.inner.init(context)}

    def update(self, state, chunk: dict):
        if not self._fault(state, chunk) and len(chunk['t_s']):
            state['t'].append(np.asarray(chunk['t_s'], dtype=float))
            state['inner'] = self.inner.update(state['inner'], chunk)
        return state

    def merge(self, a, b):
        return {'t0': float(np.fmin(a['t0'], b['t0'])), 't': [*a['t'], *b['t']],
                'inner': self.inner.merge(a['inner'], b['inner'])}


class FirstFaultTime(_AfterFault):
    """The first fault's stamp ``t0`` (s)."""

    name, unit, needs = 'first_fault_time_s', 's', ('faults',)

    def init(self, context: dict):
        return {'runs': context['runs'], 't0': math.nan}

    def update(self, state, chunk: dict):
        self._fault(state, chunk)
        return state

    def merge(self, a, b):
        return {'runs': a['runs'], 't0': float(np.fmin(a['t0'], b['t0']))}

    def finish(self, state, t_end_s: float | None = None):
        return None if math.isnan(state['t0']) else np.full(state['runs'], state['t0'])


class Q4SettlingAfterFault(_OverSamplesAfterFault):
    """Seed 000's settling time: the time after ``t0`` from which ``1 - |q_e,4|`` stays ``<= band``
    (the last exit of the samples at or after ``t0``, interpolated), counted from ``t0``; NaN without
    samples after ``t0``. Kept: the last exit over every sample (:class:`SettlingTime`) and the
    stamps; the last exit is among the samples after ``t0`` if it is at or after ``t0``, else none of
    them is outside and the value is their first stamp."""

    unit = 's'

    def __init__(self, band: float) -> None:
        self.band = band
        self.name, self.needs = f'settling_q4_{band:g}_after_fault_s', ('q4_error', 'faults')
        self.inner = SettlingTime('q4', 'q4_error', band)   # the last exit

    def finish(self, state, t_end_s: float | None = None):
        t0, ex = state['t0'], state['inner']
        if math.isnan(t0):
            return None
        t = np.concatenate(state['t']) if state['t'] else np.zeros(0)
        after = t[t >= t0]
        if not after.size:
            return np.full(ex['seen'].shape, math.nan)
        inside = ~(ex['seen'] & (ex['exit'][0] >= t0))   # no sample after t0 outside
        return np.where(inside, after[0], self.inner.finish(ex)) - t0


class IntegratedTorqueAfterFault(_OverSamplesAfterFault):
    """``∫‖u‖ dt`` over ``[t0, end]``: the terms of :class:`~adcs_sim.app.analysis.metric_defs.IntegratedTorque`
    of the torque samples at or after ``t0`` (each held to the next sample, the last to the run's
    end), summed once (numpy's pairwise sum of the row). No value without torque samples."""

    name, unit, needs = 'integrated_torque_after_fault_Nms', 'N·m·s', ('torque', 'faults')

    def __init__(self) -> None:
        self.inner = IntegratedTorque()

    def finish(self, state, t_end_s: float | None = None):
        if math.isnan(state['t0']) or not state['t']:
            return None
        terms = self.inner.terms(state['inner'], t_end_s)
        late = np.concatenate(state['t']) >= state['t0']
        return np.sum(np.ascontiguousarray(terms[:, late]), axis=-1)   # each run's row: its pairwise sum


def fault_metrics_defs(bands=FAULT_BANDS) -> tuple[Metric, ...]:
    """The metrics after the first fault, in run_metrics' order."""
    return (FirstFaultTime(), *(Q4SettlingAfterFault(b) for b in bands), IntegratedTorqueAfterFault())
