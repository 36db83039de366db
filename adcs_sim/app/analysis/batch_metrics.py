"""The metrics of every run of a batch at once: :func:`adcs_sim.app.analysis.metrics.run_metrics` over the batch axis.

A campaign (:func:`adcs_sim.app.campaign.plan.run_chunk`) needs the metrics of each of its runs;
computing them run by run costs about a millisecond each in numpy call overhead, more than the
runs' simulation. :func:`batch_run_metrics` computes them for all the runs of a
:class:`~adcs_sim.app.batch.engine.BatchResult` with one call per operation on ``(runs, samples, ...)``
arrays, with the same element-wise operations in the same order as :func:`run_metrics` on
:meth:`BatchResult.run_data` (the error quaternion, eigenaxis and 2-1-3 Euler errors, settling by
the last exit interpolated, the zero-order-hold integrals summed along each run's own row, peaks),
so each run gets the same numbers bit for bit (``tests/test_batch_metrics.py`` compares them).

Runs it does not vectorise go through :func:`run_metrics` one by one: a run that ended early or
failed (its series is shorter than the grid). A fault schedule is every run's (the batch engine
applies it to all), so the fault metrics of the full runs are vectorised too.
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import euler_213, pointing_error
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis import metric_defs_attitude as mda
from adcs_sim.app.analysis import metrics_kernel as mk
from adcs_sim.app.analysis.metrics import run_metrics, zoh_durations
from adcs_sim.app.analysis.estimation import estimation_metrics, series_from_batch
from adcs_sim.app.analysis.metrics_kernel import error_quaternions
from adcs_sim.truth.kernel import kernel_rows


def _band_times(metric, t: np.ndarray, error: np.ndarray) -> np.ndarray:
    chunk = {'t_s': t, metric.needs[0]: error}
    return metric.finish(metric.update(metric.init({'runs': error.shape[0]}), chunk))


def settling_times(t: np.ndarray, error: np.ndarray, tol: float) -> np.ndarray:
    """:func:`adcs_sim.app.analysis.metrics.settling_time` of each row of ``error`` (runs, samples) on the
    common times ``t`` (samples,): the last exit from ``<= tol``, interpolated; ``t[0]`` if never
    outside, ``inf`` if the last sample is outside, the next sample's time after a non-finite one
    (its one definition, :class:`~adcs_sim.app.analysis.metric_defs_attitude.SettlingTime`)."""
    return _band_times(mda.SettlingTime('settling', 'error', tol), t, error)


def first_entry_times(t: np.ndarray, error: np.ndarray, tol: float) -> np.ndarray:
    """:func:`adcs_sim.app.analysis.metrics.first_entry_time` of each row of ``error`` (runs, samples)
    (:class:`~adcs_sim.app.analysis.metric_defs_attitude.FirstEntryTime`)."""
    return _band_times(mda.FirstEntryTime('first_entry', 'error', tol), t, error)


def _pointing_columns(t: np.ndarray, error_deg: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`adcs_sim.app.analysis.metrics.pointing_metrics` over the batch axis (one array per metric)."""
    return mda.values_of(mda.pointing_band_metrics(), {'runs': error_deg.shape[0]},
                         {'t_s': t, 'pointing_error_deg': error_deg})


def _full_run_columns(result, rows: np.ndarray, tol_deg: float) -> dict[str, np.ndarray]:
    """The metrics of runs ``rows`` (each simulated over the whole grid), one array per metric
    (a list-valued metric: an array (runs, n)), in :func:`run_metrics`' order: the compiled passes of
    :mod:`adcs_sim.app.analysis.metrics_kernel` (:func:`full_run_columns_numpy`'s numbers bit for bit)."""
    K = result.t.size - 1
    t, t_end = result.t, float(result.t[K])
    take = slice(None) if rows.size == result.n_runs else rows   # every run: views, not copies
    q = kernel_rows(result.q[take])
    q_ref = result.q_ref[take] if result.q_ref.ndim == 2 else np.broadcast_to(result.q_ref, (rows.size, 4))
    u = np.ascontiguousarray(result.u[take])
    speed = (np.ascontiguousarray(result.wheel_speed[take]) if result.wheel_names and result.wheel_speed.shape[-1]
             else np.zeros((rows.size, K + 1, 0)))
    q_ref = kernel_rows(q_ref)
    eigen, gv, ga = np.empty((rows.size, 2), np.int64), np.empty((rows.size, 3)), np.empty((rows.size, 3))
    cols = np.empty((rows.size, mk.N_COLUMNS))
    mk.first_pass(q, q_ref, u, speed, t, zoh_durations(t[:K], t_end), float(tol_deg),
                  mk.euler_bands(float(tol_deg)), eigen, gv, ga, cols)
    # the eigenaxis angle: numpy's arctan2 (as eigenaxis_angle), at the samples the settling time and
    # final value need; of every sample for a run with one too close to the band to tell
    mk.eigen_columns(np.arctan2(gv, ga), eigen, t, float(tol_deg), cols)
    every = np.flatnonzero(eigen[:, 1])
    if every.size:
        qe, vn, sub = np.empty((every.size,) + q.shape[1:]), np.empty((every.size, K + 1)), cols[every]
        error_quaternions(np.ascontiguousarray(q[every]), np.ascontiguousarray(q_ref[every]), qe, vn)
        mk.second_pass(np.arctan2(vn, np.abs(qe[..., 3])), t, float(tol_deg), sub)
        cols[every] = sub
    out = {
        'duration_s': cols[:, mk.DURATION],
        f'settling_eigenaxis_{tol_deg:g}deg_s': cols[:, mk.SETTLE_EIGEN],
        f'settling_euler213_{tol_deg:g}deg_s': cols[:, mk.SETTLE_EULER],
        'settling_euler213_per_axis_s': cols[:, mk.SETTLE_AXIS:mk.SETTLE_AXIS + 3],
        'final_eigenaxis_error_deg': cols[:, mk.FINAL_EIGEN],
        # the metrics defined once; the torque integrals and peaks and the peak wheel speed from
        # the compiled pass, their twins (tests/test_metrics_kernel.py)
        **metric_defs.batch_values(result, rows, {
            'integrated_torque_Nms': cols[:, mk.TORQUE], 'control_energy_N2m2s': cols[:, mk.ENERGY],
            'peak_torque_Nm': cols[:, mk.PEAK_TORQUE:mk.PEAK_TORQUE + 3],
            'peak_wheel_speed_rad_s': cols[:, mk.PEAK_SPEED]}),
    }
    if result.faults:
        qe = np.empty(q.shape)
        error_quaternions(q, q_ref, qe, np.empty(q.shape[:2]))
        out.update(_fault_columns(result, t, qe, u, t_end))
    if result.pointing is not None:
        sigma, tau = result.pointing
        out.update(_pointing_columns(t, np.degrees(pointing_error(q, sigma, tau))))
    return out


def full_run_columns_numpy(result, rows: np.ndarray, tol_deg: float) -> dict[str, np.ndarray]:
    """:func:`_full_run_columns` in numpy over the batch axis (the reference of the compiled passes)."""
    K = result.t.size - 1
    t, t_end = result.t, float(result.t[K])
    take = slice(None) if rows.size == result.n_runs else rows   # every run: views, not copies
    q = result.q[take]
    q_ref = result.q_ref[take] if result.q_ref.ndim == 2 else np.broadcast_to(result.q_ref, (rows.size, 4))
    qe, vnorm = np.empty(q.shape), np.empty(q.shape[:2])
    error_quaternions(kernel_rows(q), kernel_rows(q_ref), qe, vnorm)
    eigen = np.degrees(2.0 * np.arctan2(vnorm, np.abs(qe[..., 3])))   # eigenaxis_angle(qe)
    euler = np.abs(np.degrees(euler_213(qe)))
    u = result.u[take]
    # the attitude metrics' series over the batch axis, fed to their definitions (metric_defs_attitude);
    # the largest Euler error written out: numpy reduces a length-3 axis in sequence (max is exact)
    # but 20-50x slower than these element-wise passes
    series = {'t_s': t, 'eigen_error_deg': eigen, 'euler_error_deg': euler,
              'euler_worst_deg': np.maximum(np.maximum(euler[..., 0], euler[..., 1]), euler[..., 2])}  # max(axis=2)
    out = {
        **mda.values_of(mda.head_metrics(tol_deg), {'runs': rows.size}, series, t_end),
        **metric_defs.batch_values(result, rows),   # the metrics defined once (metric_defs.DEFINED)
    }
    out.update(_fault_columns(result, t, qe, u, t_end))
    if result.pointing is not None:
        sigma, tau = result.pointing
        out.update(_pointing_columns(t, np.degrees(pointing_error(q, sigma, tau))))
    return out


def _fault_columns(result, t: np.ndarray, qe: np.ndarray, u: np.ndarray, t_end: float) -> dict[str, np.ndarray]:
    """:func:`adcs_sim.app.analysis.metrics.fault_metrics` of full runs (the batch's fault schedule is every
    run's, those up to the end as a bag records them): their definitions over the batch axis
    (:func:`~adcs_sim.app.analysis.metric_defs_attitude.fault_metrics_defs`)."""
    K = t.size - 1
    faults = np.array([(f[0], f[1]) for f in result.faults if f[0] <= t[K]], dtype=float).reshape(-1, 2)
    chunks = [{'faults': faults}, {'t_s': t, 'q4_error': 1.0 - np.abs(qe[..., 3])}, {'t_s': t[:K], 'torque': u}]
    return mda.values_of(mda.fault_metrics_defs(), {'runs': qe.shape[0]}, chunks, t_end)


def batch_run_metrics(result, tol_deg: float = 0.5) -> list[dict]:
    """``[result.metrics(j, tol_deg) for j in range(result.n_runs)]``, the same dicts (keys, order,
    values bit for bit), computed over the batch axis where it can (module docstring)."""
    K = result.t.size - 1
    full = (result.n_steps == K) & np.array([f is None for f in result.failure], dtype=bool)
    if K < 1:
        full[:] = False
    rows = np.flatnonzero(full)
    metrics: list[dict | None] = [None] * result.n_runs
    if rows.size:
        with np.errstate(all='ignore'):
            columns = _full_run_columns(result, rows, tol_deg)
        # each column as Python floats (a row of a 2-D one: a list) in one call, not one per run
        lists = [(key, values.tolist() if values.ndim == 2 else np.asarray(values, dtype=float).tolist())
                 for key, values in columns.items()]
        for r, j in enumerate(rows.tolist()):
            m = {}
            for key, values in lists:
                m[key] = values[r]
                if key == metric_defs.DEFINED[-1].name:   # run_metrics' order: missed_steps after them
                    m['missed_steps'] = 0  # BatchResult.run_data's: the batch engine misses none
            metrics[j] = m
    for j in range(result.n_runs):
        if metrics[j] is None:
            metrics[j] = run_metrics(result.run_data(j), tol_deg)
        if result.estimate is not None:   # as BatchResult.metrics: the estimation metrics too
            metrics[j].update(estimation_metrics(series_from_batch(result, j)))
    return metrics


def metric_columns(metrics: dict) -> dict[str, float]:
    """A run's metrics as scalar columns: lists become ``name[0]``, ``name[1]``, ...; ``missed_steps``
    (a graph-only quantity) is left out."""
    out: dict[str, float] = {}
    for key, value in metrics.items():
        if key == 'missed_steps':
            continue
        if isinstance(value, list):
            out.update({f'{key}[{j}]': float(v) for j, v in enumerate(value)})
        else:
            out[key] = float(value)
    return out


def batch_metric_columns(result, tol_deg: float = 0.5) -> list[dict[str, float]]:
    """``[metric_columns(m) for m in batch_run_metrics(result, tol_deg)]`` (a campaign's rows), the full
    runs' columns taken from the batch arrays directly instead of through a dict of lists per run."""
    K = result.t.size - 1
    full = (result.n_steps == K) & np.array([f is None for f in result.failure], dtype=bool)
    rows = np.flatnonzero(full)
    if K < 1 or result.estimate is not None or not rows.size:
        return [metric_columns(m) for m in batch_run_metrics(result, tol_deg)]
    with np.errstate(all='ignore'):
        columns = _full_run_columns(result, rows, tol_deg)
    flat = []
    for key, values in columns.items():
        if values.ndim == 2:
            flat += [(f'{key}[{i}]', values[:, i].tolist()) for i in range(values.shape[1])]
        else:
            flat.append((key, np.asarray(values, dtype=float).tolist()))
    out: list = [None] * result.n_runs
    for r, j in enumerate(rows.tolist()):
        out[j] = {name: values[r] for name, values in flat}
    for j in np.flatnonzero(~full).tolist():
        out[j] = metric_columns(run_metrics(result.run_data(j), tol_deg))
    return out
