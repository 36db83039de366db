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
* **Peak torque** per body axis ``max |u_i|`` over the applied-torque samples; **missed
  steps** from the last ``dynamics/status`` that reports them.
* The metrics of :data:`adcs_sim.app.analysis.metric_defs.DEFINED`, each defined there once and computed
  by every path from that definition (the **torque integrals** and **peak torque** above, the
  **peak wheel speed**, the **time each wheel spends at its speed limit**), between the final
  eigenaxis error and the missed steps.

The time series come from :class:`~adcs_sim.app.analysis.run_data.RunData` (a bag read in one pass).
:func:`run_metrics` gives these at one tolerance; :func:`settling_times` the settling times at
several (e.g. 0.5° and 1° for a comparison table). :func:`k0_metric` is seed 001's settling index
(eq. 29) of a sampled error series.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_core.attitude import error_quaternion, pointing_error
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis import metric_defs_attitude as mda
from adcs_sim.app.analysis.metric_defs_attitude import POINTING_BANDS_DEG, attitude_errors  # noqa: F401
from adcs_sim.app.analysis.metric_defs_thrusters import THRUSTERS

# The run's time series and what its scenario asks for (re-exported: this module's historical API).
from adcs_sim.app.analysis.run_data import (  # noqa: F401
    DIAGNOSTIC_ARRAY,
    JOINT_STATE,
    ODOMETRY,
    READ_TYPES,
    REPORTED_TOPICS,
    VECTOR3_STAMPED,
    RunData,
    bag_intrusions,
    intrusion_lines,
    pointing_request,
    target_attitude,
)

NS = 1e-9


# --- metrics on arrays ------------------------------------------------------------------------

def _band_time(metric, t: np.ndarray, error: np.ndarray) -> float:
    """``metric`` (a band time of :mod:`~adcs_sim.app.analysis.metric_defs_attitude`) of one series."""
    chunk = {'t_s': np.asarray(t, dtype=float), metric.needs[0]: np.asarray(error, dtype=float)[None]}
    return float(metric.finish(metric.update(metric.init({'runs': 1}), chunk))[0])


def settling_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """Time after which ``error`` stays ``<= tol`` to the end (last exit, interpolated): its one
    definition, :class:`~adcs_sim.app.analysis.metric_defs_attitude.SettlingTime`.

    ``t[0]`` if every sample is inside, ``inf`` if the last one is outside, NaN if there are no
    samples. ``t`` ascending; a NaN error counts as outside.
    """
    return _band_time(mda.SettlingTime('settling', 'error', tol), t, error)


def first_entry_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """First time ``error`` reaches ``tol`` (interpolated): ``t[0]`` if it starts inside, ``inf`` if
    never. Unlike :func:`settling_time`, later exits from the band do not count. Its one
    definition: :class:`~adcs_sim.app.analysis.metric_defs_attitude.FirstEntryTime`."""
    return _band_time(mda.FirstEntryTime('first_entry', 'error', tol), t, error)


def band_crossing(t0, e0, t1, e1, tol: float) -> float:
    """When the error crosses ``tol`` between the samples ``(t0, e0)`` and ``(t1, e1)``, linearly
    interpolated; ``t1`` when ``e0`` is not finite (:func:`~adcs_sim.app.analysis.metric_defs_attitude.crossing`)."""
    return float(mda.crossing(t0, e0, t1, e1, tol))


def zoh_durations(t: np.ndarray, t_end: float) -> np.ndarray:
    """Hold durations of samples at ``t`` (to the next sample, the last to ``t_end``)."""
    t = np.asarray(t, dtype=float)
    return np.diff(np.append(t, max(t_end, t[-1]))) if t.size else t


def _held(metric, t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``metric`` (a :class:`~adcs_sim.app.analysis.metric_defs.HeldIntegral`) of one run's samples; 0 (the
    empty sum) without samples."""
    t = np.asarray(t, dtype=float)
    if not t.size:
        return 0.0
    chunk = {'t_s': t, 'torque': np.asarray(u, dtype=float).reshape(1, -1, 3)}
    return float(metric.finish(metric.update(metric.init({'runs': 1}), chunk), t_end)[0])


def integrated_norm(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫‖u‖ dt`` of a zero-order-held torque ``u`` (N, 3) sampled at ``t``: its one definition,
    :class:`~adcs_sim.app.analysis.metric_defs.IntegratedTorque`."""
    return _held(metric_defs.IntegratedTorque(), t, u, t_end)


def integrated_square(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫uᵀu dt`` of a zero-order-held torque ``u`` (N, 3) sampled at ``t``: its one definition,
    :class:`~adcs_sim.app.analysis.metric_defs.ControlEnergy`."""
    return _held(metric_defs.ControlEnergy(), t, u, t_end)


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


def thruster_metrics(run: RunData) -> dict:
    """Total thruster impulse at the end (N s), firings (thruster-periods with a non-zero
    on-time) and total on-time (s); empty without ``thrusters/state``: their one definition,
    :data:`adcs_sim.app.analysis.metric_defs_thrusters.THRUSTERS`."""
    chunk = {'t_s': run.t_thrusters, 'thruster_on_time': np.asarray(run.thruster_on_time)[None],
             'thruster_impulse': np.asarray(run.thruster_impulse)[None]}
    return mda.listed(mda.values_of(THRUSTERS, {'runs': 1}, chunk))


def pointing_error_deg(run: RunData) -> np.ndarray:
    """Angle (deg) between σ̂ and τ̂ at each state sample of a pointing run."""
    sigma, tau = run.pointing
    return np.degrees(pointing_error(run.q, sigma, tau))


def pointing_metrics(t: np.ndarray, error_deg: np.ndarray, bands=POINTING_BANDS_DEG) -> dict:
    """First-entry and settling (staying below) times of the pointing error at each band (deg),
    and the final error: ``pointing_first_<b>deg_s``, ``pointing_settling_<b>deg_s``,
    ``final_pointing_error_deg`` (their definitions:
    :func:`~adcs_sim.app.analysis.metric_defs_attitude.pointing_band_metrics`)."""
    chunk = {'t_s': np.asarray(t, dtype=float), 'pointing_error_deg': np.asarray(error_deg, dtype=float)[None]}
    return mda.listed(mda.values_of(mda.pointing_band_metrics(bands), {'runs': 1}, chunk))


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


def fault_chunk(faults) -> dict:
    """A run's ``faults`` statuses ``(stamp, level, ...)`` as the chunk the fault metrics read."""
    return {'faults': np.array([(t, level) for t, level, *_ in faults], dtype=float).reshape(-1, 2)}


def first_fault_time(run: RunData) -> float:
    """Stamp of the first fault (a ``faults`` status of level ERROR), NaN if the run had none
    (:func:`~adcs_sim.app.analysis.metric_defs_attitude.first_fault`)."""
    return mda.first_fault(fault_chunk(run.faults))


def q4_settling_after(run: RunData, band: float, t0: float) -> float:
    """Seed 000's settling time: the time after ``t0`` from which the scalar part of the error
    quaternion stays within ``1 ± band`` (``1 - |q4| <= band``; last exit, interpolated); counted
    from ``t0`` (0 if already inside at ``t0``): its one definition,
    :class:`~adcs_sim.app.analysis.metric_defs_attitude.Q4SettlingAfterFault`."""
    qe = error_quaternion(run.q, run.q_ref)
    chunks = [{'faults': np.array([[t0, 2.0]])}, {'t_s': run.t, 'q4_error': (1.0 - np.abs(qe[:, 3]))[None]}]
    metric = mda.Q4SettlingAfterFault(band)
    return float(mda.values_of([metric], {'runs': 1}, chunks)[metric.name][0])


def fault_metrics(run: RunData, bands=mda.FAULT_BANDS) -> dict:
    """Recovery after the first fault ``t0`` (seed 000 VI.A): q4 settling times in each band and
    ``∫‖u‖dt`` over ``[t0, end]`` (:func:`~adcs_sim.app.analysis.metric_defs_attitude.fault_metrics_defs`);
    empty if the run had no fault."""
    chunks = [fault_chunk(run.faults)]
    if not chunks[0]['faults'].size:
        return {}
    qe = error_quaternion(run.q, run.q_ref)
    chunks.append({'t_s': run.t, 'q4_error': (1.0 - np.abs(qe[:, 3]))[None]})
    if run.u.size:
        chunks.append({'t_s': run.t_u, 'torque': np.asarray(run.u).reshape(1, -1, 3)})
    return mda.listed(mda.values_of(mda.fault_metrics_defs(bands), {'runs': 1}, chunks, run.t_end))


def run_metrics(run: RunData, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
    """The run's metrics (see the module docstring for each definition)."""
    head = mda.head_metrics(tol_deg, eigen_tol_deg)   # duration, settling times, final error
    pointing = mda.pointing_band_metrics() if run.pointing is not None else ()
    series = mda.attitude_series(run, {n for m in (*head, *pointing) for n in m.needs})
    chunk = {'t_s': np.asarray(run.t, dtype=float), **series}
    out = {
        **mda.listed(mda.values_of(head, {'runs': 1}, chunk, run.t_end)),
        **metric_defs.run_values(run),   # the metrics defined once (metric_defs.DEFINED)
        'missed_steps': run.missed_steps,
    }
    out.update(missed_step_gaps(run))
    out.update(fault_metrics(run))
    out.update(thruster_metrics(run))
    if pointing:
        out.update(mda.listed(mda.values_of(pointing, {'runs': 1}, chunk, run.t_end)))
    return out


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
