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

import math

import numpy as np

from adcs_core.attitude import euler_213, pointing_error
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis import metrics_kernel as mk
from adcs_sim.app.analysis.metrics import POINTING_BANDS_DEG, run_metrics, zoh_durations
from adcs_sim.app.analysis.estimation import estimation_metrics, series_from_batch
from adcs_sim.app.analysis.metrics_kernel import error_quaternions
from adcs_sim.truth.kernel import kernel_rows


def settling_times(t: np.ndarray, error: np.ndarray, tol: float) -> np.ndarray:
    """:func:`adcs_sim.app.analysis.metrics.settling_time` of each row of ``error`` (runs, samples) on the
    common times ``t`` (samples,): the last exit from ``<= tol``, interpolated; ``t[0]`` if never
    outside, ``inf`` if the last sample is outside, the next sample's time after a non-finite one."""
    n = error.shape[-1]
    outside = ~(error <= tol)
    last = n - 1 - np.argmax(outside[:, ::-1], axis=1)
    rows = np.arange(error.shape[0])
    nxt = np.minimum(last + 1, n - 1)
    e0, e1 = error[rows, last], error[rows, nxt]
    with np.errstate(all='ignore'):
        crossing = t[last] + (e0 - tol) / (e0 - e1) * (t[nxt] - t[last])
    out = np.where(np.isfinite(e0), crossing, t[nxt])
    out = np.where(last == n - 1, math.inf, out)
    return np.where(outside.any(axis=1), out, t[0])


def first_entry_times(t: np.ndarray, error: np.ndarray, tol: float) -> np.ndarray:
    """:func:`adcs_sim.app.analysis.metrics.first_entry_time` of each row of ``error`` (runs, samples)."""
    inside = error <= tol
    first = np.argmax(inside, axis=1)
    rows = np.arange(error.shape[0])
    prev = np.maximum(first - 1, 0)
    e0, e1 = error[rows, prev], error[rows, first]
    with np.errstate(all='ignore'):
        crossing = t[prev] + (e0 - tol) / (e0 - e1) * (t[first] - t[prev])
    out = np.where(np.isfinite(e0), crossing, t[first])
    out = np.where(first == 0, t[0], out)
    return np.where(inside.any(axis=1), out, math.inf)


def _pointing_columns(t: np.ndarray, error_deg: np.ndarray, bands) -> dict[str, np.ndarray]:
    """:func:`adcs_sim.app.analysis.metrics.pointing_metrics` over the batch axis (one array per metric)."""
    out = {}
    for b in bands:
        out[f'pointing_first_{b:g}deg_s'] = first_entry_times(t, error_deg, b)
        out[f'pointing_settling_{b:g}deg_s'] = settling_times(t, error_deg, b)
    out['final_pointing_error_deg'] = error_deg[:, -1]
    return out


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
        out.update(_fault_columns(result, t, qe, (u[..., 0], u[..., 1], u[..., 2]), t_end))
    if result.pointing is not None:
        sigma, tau = result.pointing
        out.update(_pointing_columns(t, np.degrees(pointing_error(q, sigma, tau)), POINTING_BANDS_DEG))
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
    u0, u1, u2 = u[..., 0], u[..., 1], u[..., 2]
    # The reductions over the 3 components written out: numpy reduces a length-3 axis in sequence
    # ((a0 + a1) + a2; max is exact) but 20-50x slower than these element-wise passes.
    out = {
        'duration_s': np.full(rows.size, t_end),
        f'settling_eigenaxis_{tol_deg:g}deg_s': settling_times(t, eigen, tol_deg),
        f'settling_euler213_{tol_deg:g}deg_s': settling_times(
            t, np.maximum(np.maximum(euler[..., 0], euler[..., 1]), euler[..., 2]), tol_deg),   # euler.max(axis=2)
        'settling_euler213_per_axis_s': np.stack([settling_times(t, euler[:, :, i], tol_deg)
                                                  for i in range(3)], axis=1),
        'final_eigenaxis_error_deg': eigen[:, -1],
        **metric_defs.batch_values(result, rows),   # the metrics defined once (metric_defs.DEFINED)
    }
    out.update(_fault_columns(result, t, qe, (u0, u1, u2), t_end))
    if result.pointing is not None:
        sigma, tau = result.pointing
        out.update(_pointing_columns(t, np.degrees(pointing_error(q, sigma, tau)), POINTING_BANDS_DEG))
    return out



def _fault_columns(result, t: np.ndarray, qe: np.ndarray, u: tuple, t_end: float) -> dict[str, np.ndarray]:
    """:func:`adcs_sim.app.analysis.metrics.fault_metrics` of full runs (the batch's fault schedule is every
    run's): q4 settling after the first fault in each band and the torque integral after it."""
    K = t.size - 1
    times = [f[0] for f in result.faults if f[0] <= t[K] and f[1] >= 2]   # run_data's faults, level ERROR
    if not times:
        return {}
    t0 = float(min(times))
    after = t >= t0
    out = {'first_fault_time_s': np.full(qe.shape[0], t0)}
    for band in (0.02, 0.01):
        out[f'settling_q4_{band:g}_after_fault_s'] = settling_times(t[after], 1.0 - np.abs(qe[:, after, 3]), band) - t0
    t_u = t[:K]
    late = t_u >= t0
    u0, u1, u2 = u
    norm = np.sqrt((u0 * u0 + u1 * u1) + u2 * u2)
    # C order: each row summed as one run's 1-D array (pairwise); a masked column selection's
    # product may come out in another order, which numpy would sum column by column
    held = np.ascontiguousarray(norm[:, late] * zoh_durations(t_u[late], t_end))
    out['integrated_torque_after_fault_Nms'] = np.sum(held, axis=-1)
    return out


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
