"""The quantities a report leads with: for each kind of run (:mod:`.kinds`) the metrics its paper
reports, each with its unit, a one-line meaning and, where the run reproduces a published figure,
the paper's value beside ours.

Published values have one home: ``docs/seed00X/paper.yaml`` (``{source: text, runs: {run name:
{metric: value}}}``, the format ``adcs-analyze --compare --reference`` reads). A run's values are
those of its name (the bag folder's run name, e.g. ``uosat12_gsmn`` for ``bags/uosat12_gsmn/bag``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from adcs_core.attitude import eigenaxis_angle, error_quaternion
from adcs_msgs_py.params_file import YamlError, load_yaml
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis.metrics import (
    POINTING_BANDS_DEG,
    fault_metrics,
    first_fault_time,
    integrated_norm,
    pointing_error_deg,
    pointing_metrics,
    run_metrics,
    settling_time,
    settling_times,
    thruster_metrics,
)
from adcs_sim.app.report.kinds import RunKind, param_value, vector
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.app.analysis.status_records import parse_values, status_column

DOCS = Path(__file__).resolve().parents[3] / 'docs'
SPIN_THETA_BAND_RAD = 0.01      # settling band of the spin's attitude error θ (0.57°)
SPIN_RATE_BAND_RAD_S = 1e-3     # settling band of the spin's rate error ‖ω̃‖
TRACKING_BAND_DEG = 1.0         # seed 002's settling band ("settles within approximately 38 s")


# Euler angle index (euler_213 order: about y, x, z) of θ1 (x), θ2 (y), θ3 (z).
_EULER_INDEX = {'theta1_x': 1, 'theta2_y': 0, 'theta3_z': 2}


def comparison_rows(run: RunData, bands=(1.0, 0.5), eigen_tol_deg: float = 0.5) -> dict:
    """The comparison metrics of one run: ``{row key: value}`` (the rows of ``comparison.csv``, :mod:`.comparison`)."""
    rows = {}
    for band, settled in settling_times(run, bands).items():
        for label, i in _EULER_INDEX.items():
            rows[f'settling_euler213_{label}_{band:g}deg_s'] = settled['euler213_per_axis'][i]
        rows[f'settling_euler213_all_{band:g}deg_s'] = settled['euler213']
    m = run_metrics(run, bands[-1], eigen_tol_deg)
    rows[f'settling_eigenaxis_{eigen_tol_deg:g}deg_s'] = m[f'settling_eigenaxis_{eigen_tol_deg:g}deg_s']
    rows['final_eigenaxis_error_deg'] = m['final_eigenaxis_error_deg']
    rows['integrated_torque_Nms'] = m['integrated_torque_Nms']
    rows['control_energy_N2m2s'] = m['control_energy_N2m2s']
    for a, v in zip('xyz', m['peak_torque_Nm']):
        rows[f'peak_torque_{a}_Nm'] = v
    rows['peak_wheel_speed_rad_s'] = m['peak_wheel_speed_rad_s']
    rows['thruster_impulse_Ns'] = m.get('thruster_impulse_Ns')  # n/a without thrusters/state
    rows['missed_steps'] = m['missed_steps']
    rows['duration_s'] = m['duration_s']
    return rows


@dataclass
class Metric:
    key: str
    value: object
    unit: str
    meaning: str
    paper: float | None = None

    @property
    def difference(self) -> float:
        """(ours - paper) / |paper|; NaN without a published value or a number of ours."""
        if self.paper is None or not self.paper or not isinstance(self.value, (int, float)):
            return math.nan
        return (float(self.value) - self.paper) / abs(self.paper)


def paper_values(name: str, docs: Path = DOCS) -> tuple[str, dict]:
    """(source, {metric: published value}) of run ``name`` from the ``docs/*/paper.yaml`` files."""
    for path in sorted(docs.glob('seed*/paper.yaml')):
        try:
            tree = load_yaml(path) or {}
        except YamlError:
            continue
        runs = tree.get('runs') if isinstance(tree, dict) else None
        if isinstance(runs, dict) and isinstance(runs.get(name), dict):
            rel = path.relative_to(docs.parent)
            return f'{tree.get("source", "")} (`{rel}`)', dict(runs[name])
    return '', {}


def lead_metrics(run: RunData, rk: RunKind, q_ref: np.ndarray | None, rows: dict | None = None) -> list[Metric]:
    """The kind's own metrics of ``run`` (no published values yet: :func:`with_paper`). ``rows``:
    the run's :func:`comparison_rows` when computed elsewhere (a streamed long run)."""
    if rk.kind == 'regulation':
        return _regulation(run, rk, q_ref, rows)
    builder = {'tracking': _tracking, 'spin': _spin, 'pointing': _pointing}.get(rk.kind)
    return builder(run, rk, q_ref) if builder else []


def with_paper(metrics: list[Metric], published: dict) -> list[Metric]:
    for m in metrics:
        value = published.get(m.key)
        m.paper = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
    return metrics


def _torque(run: RunData, value: float | None = None) -> list[Metric]:
    """∫‖u‖dt of the run (``value``: already computed, e.g. by run_metrics)."""
    if not run.u.size:
        return [Metric('integrated_torque_Nms', None, 'N·m·s', 'not available: no applied torque recorded')]
    value = integrated_norm(run.t_u, run.u, run.t_end) if value is None else value
    return [Metric('integrated_torque_Nms', value, 'N·m·s',
                   '∫‖u‖dt of the applied body torque over the run (zero-order hold)')]


def actuator_fault(run: RunData, rk: RunKind) -> bool:
    """A fault (level ERROR) on one of the controller's own actuators (its wheels or thrusters): the law
    reconfigures and seed 000's quantities after the fault lead the report. A sensor's outage (a star tracker
    under an estimator) leaves the law's task as it was: the slew's own quantities lead."""
    own = set(param_value(rk.params, 'wheels.names') or []) | set(param_value(rk.params, 'thrusters.names') or [])
    return any(level >= 2 and name in own for _, level, name, _ in run.faults)


def _regulation(run: RunData, rk: RunKind, q_ref, rows: dict | None = None) -> list[Metric]:
    if actuator_fault(run, rk):
        return _after_fault(run, q_ref)
    streamed = rows is not None
    rows = comparison_rows(run) if rows is None else rows
    out = []
    for key, value in rows.items():
        if key.startswith('settling_euler213_theta'):
            axis = key.split('_')[2]
            band = key.rsplit('_', 2)[-2]
            out.append(Metric(key, value, 's', f'time after which the 2-1-3 Euler angle {axis} stays within '
                              f'±{band.replace("deg", "°")} (last exit)'))
    out.append(Metric('settling_euler213_all_0.5deg_s', rows['settling_euler213_all_0.5deg_s'], 's',
                      'time after which all three 2-1-3 Euler angles stay within ±0.5° (seed 004 III.F)'))
    out.append(Metric('final_eigenaxis_error_deg', rows['final_eigenaxis_error_deg'], 'deg',
                      'eigenaxis angle of q_ref* ⊗ q at the end of the run'))
    out += _torque(run, rows['integrated_torque_Nms'] if streamed else None)
    for a in 'xyz':
        out.append(Metric(f'peak_torque_{a}_Nm', rows[f'peak_torque_{a}_Nm'], 'N·m',
                          f'max |u_{a}| of the applied torque (the paper prints it signed)'))
    return out


def _after_fault(run: RunData, q_ref) -> list[Metric]:
    m = fault_metrics(run)
    t0 = m['first_fault_time_s']
    k0 = min(int(np.searchsorted(run.t, t0)), run.t.size - 1)
    qe = error_quaternion(run.q, q_ref[-1] if q_ref is not None else run.q_ref)
    out = [Metric('first_fault_time_s', t0, 's', 'time t0 of the first fault (an ERROR status on `faults`)'),
           Metric('error_at_fault_deg', float(np.degrees(eigenaxis_angle(qe[k0]))), 'deg',
                  'eigenaxis error to the final target at t0 (where the planned slew left the body)')]
    for band in (0.02, 0.01):
        key = f'settling_q4_{band:g}_after_fault_s'
        out.append(Metric(key, m[key], 's', f'time after t0 from which 1 − |q4| stays ≤ {band:g} (eigenaxis error '
                          f'≤ {math.degrees(2 * math.acos(1 - band)):.1f}°; last exit)'))
    out.append(Metric('integrated_torque_after_fault_Nms', m.get('integrated_torque_after_fault_Nms'), 'N·m·s',
                      '∫‖u‖dt of the applied torque over [t0, end]'))
    out.append(Metric('final_one_minus_q4', float(1.0 - abs(qe[-1, 3])), '–', '1 − |q4| of the error at the end'))
    return out


def _tracking(run: RunData, rk: RunKind, q_ref) -> list[Metric]:
    if q_ref is None:
        return []
    err = np.degrees(eigenaxis_angle(error_quaternion(run.q, q_ref)))
    ts = settling_time(run.t, err, TRACKING_BAND_DEG)
    after = err[run.t >= ts] if math.isfinite(ts) else np.zeros(0)
    out = [Metric(f'settling_eigenaxis_{TRACKING_BAND_DEG:g}deg_s', ts, 's',
                  f'time after which the tracking error (eigenaxis angle of q_d(t)* ⊗ q) stays ≤ {TRACKING_BAND_DEG:g}°'),
           Metric('max_error_after_settling_deg', float(after.max()) if after.size else math.nan, 'deg',
                  'largest tracking error from the settling time to the end (the hold)'),
           Metric('final_tracking_error_deg', float(err[-1]), 'deg', 'tracking error at the end of the run')]
    out += _torque(run)
    th = thruster_metrics(run)
    if th:
        out += [Metric('thruster_impulse_Ns', th['thruster_impulse_Ns'], 'N·s', 'total thruster impulse Σ∫F dt'),
                Metric('thruster_firings', th['thruster_firings'], 'count', 'thruster-periods with a firing')]
    return out


def status_array(run: RunData, keys) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, values (N, len(keys))) of numeric controller status values present in every record."""
    found = [status_column(run.controller_status, k) for k in keys]
    if any(not where.size for where, _, _ in found):
        return None
    common = found[0][0]
    for where, _, _ in found[1:]:
        common = np.intersect1d(common, where, assume_unique=True)
    if not common.size:
        return None
    columns = []
    for where, ts, raw in found:
        keep = np.searchsorted(where, common)
        values = parse_values(raw[keep])
        if values.dtype == object:
            return None
        columns.append(values)
    return ts[keep], np.column_stack(columns)


def _spin(run: RunData, rk: RunKind, q_ref) -> list[Metric]:
    w_d = vector(param_value(rk.params, 'target.rate'), 3)
    w_d = np.full(3, math.nan) if w_d is None else w_d
    out = []
    theta = status_array(run, ['theta'])
    w_err = status_array(run, ['w_err_x', 'w_err_y', 'w_err_z'])
    if theta is not None:
        t, th = theta[0], theta[1][:, 0]
        out += [Metric('final_theta_rad', float(th[-1]), 'rad', 'the law\'s attitude error θ to its spinning target '
                       'frame R_d(t) at the end (eigenaxis angle of R_dᵀR; controller/status `theta`)'),
                Metric(f'settling_theta_{SPIN_THETA_BAND_RAD:g}rad_s', settling_time(t, th, SPIN_THETA_BAND_RAD), 's',
                       f'time after which θ stays ≤ {SPIN_THETA_BAND_RAD:g} rad')]
    if w_err is not None:
        t, e = w_err[0], np.linalg.norm(w_err[1], axis=1)
        out += [Metric('final_rate_error_rad_s', float(e[-1]), 'rad/s', 'rate error ‖ω̃‖ = ‖ω − R̃ᵀω_d‖ at the end'),
                Metric(f'settling_rate_error_{SPIN_RATE_BAND_RAD_S:g}rad_s_s',
                       settling_time(t, e, SPIN_RATE_BAND_RAD_S), 's',
                       f'time after which ‖ω̃‖ stays ≤ {SPIN_RATE_BAND_RAD_S:g} rad/s')]
    out.append(Metric('final_spin_rate_rad_s', float(np.linalg.norm(run.w[-1])), 'rad/s',
                      f'‖ω‖ at the end (commanded ‖ω_d‖ = {np.linalg.norm(w_d):.4g} rad/s)'))
    out += _torque(run)
    if run.u.size:
        out += [Metric(f'steady_torque_{a}_Nm', float(run.u[-1, i]), 'N·m',
                       f'applied u_{a} at the end: the torque that holds the spin (ω_d × Jω_d, eq. 59)')
                for i, a in enumerate('xyz')]
        out.append(Metric('peak_torque_inf_Nm', float(np.abs(run.u).max()), 'N·m', 'max ‖u‖∞ of the applied torque'))
    return out


def _pointing(run: RunData, rk: RunKind, q_ref) -> list[Metric]:
    if run.pointing is None:
        return []
    m = pointing_metrics(run.t, pointing_error_deg(run))
    out = [Metric('final_pointing_error_deg', m['final_pointing_error_deg'], 'deg',
                  'angle between the body axis σ̂ and the inertial direction τ̂ at the end')]
    for b in POINTING_BANDS_DEG:
        out += [Metric(f'pointing_first_{b:g}deg_s', m[f'pointing_first_{b:g}deg_s'], 's',
                       f'first time the pointing error reaches {b:g}° (Table 1\'s reading)'),
                Metric(f'pointing_settling_{b:g}deg_s', m[f'pointing_settling_{b:g}deg_s'], 's',
                       f'time after which the pointing error stays ≤ {b:g}° (last exit)')]
    out += _torque(run)
    if run.wheel_speed.size:
        peak = metric_defs.run_values(run, ('peak_wheel_speed_rad_s',))['peak_wheel_speed_rad_s']   # its one definition
        out.append(Metric('peak_wheel_speed_rad_s', peak, 'rad/s', 'max |Ω| over the wheels, relative to the body'))
    return out
