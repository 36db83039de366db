"""Markdown tables of the reports: value formatting, escaping, and the meaning of each metric."""
from __future__ import annotations

import math
import re

import numpy as np

from adcs_sim.app.analysis import metric_defs

METRIC_NOTES = {
    'duration_s': 'simulated time of the last state (s)',
    'settling_eigenaxis': 'time after which the eigenaxis error stays inside the band (s; inf: not settled)',
    'settling_euler213_per_axis_s': 'per 2-1-3 Euler angle, in sequence order (about y, x, z) (s)',
    'settling_euler213': 'all three 2-1-3 Euler angles inside the band (s; inf: not settled)',
    'final_eigenaxis_error_deg': 'eigenaxis error at the end (deg)',
    'missed_steps': 'lockstep steps without the awaited command',
    'thruster_impulse_Ns': 'total thruster impulse Σ∫F dt at the end (N·s)',
    'thruster_firings': 'thruster-periods with a non-zero on-time',
    'thruster_on_time_s': 'total thruster on-time, all thrusters (s)',
    'first_fault_time_s': 'time t0 of the first fault, an ERROR status on `faults` (s)',
    'settling_q4_': 'seed 000: time after t0 from which 1 − |q4| stays inside the band (s; inf: not settled)',
    'integrated_torque_after_fault_Nms': '∫‖u‖dt of the applied torque from t0 to the end (N·m·s)',
    'pointing_first_': 'first time the pointing error ∠(σ̂, τ̂) reaches the band (s; seed 003 Table 1)',
    'pointing_settling_': 'time after which the pointing error ∠(σ̂, τ̂) stays inside the band (s)',
    'final_pointing_error_deg': 'pointing error ∠(σ̂, τ̂) at the end (deg)',
    **metric_defs.notes(),   # the metrics defined once: their notes are in their definitions
}


# The estimation metrics (adcs_sim/app/analysis/estimation.py estimation_metrics), as campaign columns.
ESTIMATION_NOTES = {
    'estimation_attitude_error_rms_deg': 'RMS attitude estimation error (deg)',
    'estimation_attitude_error_max_deg': 'largest attitude estimation error (deg)',
    'estimation_attitude_error_final_deg': 'attitude estimation error at the end (deg)',
    'estimation_rate_error_rms_deg_s': 'RMS rate estimation error (deg/s)',
    'estimation_attitude_inside_3sigma': "fraction of attitude errors inside the filter's ±3σ (fraction of steps)",
    'estimation_bias_error_final_deg_s': 'gyro bias estimation error at the end (deg/s)',
    'nees': 'mean normalised estimation error squared, NEES (χ² degrees of freedom in the name)',
    'nis_': 'normalised innovation squared of a sensor, NIS: its mean, or the fraction inside the 95 % χ² bounds',
}


def metric_note(key: str, notes: dict = METRIC_NOTES) -> str:
    """The explanation of a metric: the first entry of ``notes`` whose key prefixes ``key``."""
    return next((note for prefix, note in notes.items() if key.startswith(prefix)), '')


_COLUMN = re.compile(r'^(?P<key>.+?)(?:\[(?P<index>\d+)\])?$')
_NOTE = re.compile(r'^(?P<name>.*?)\s*\((?P<unit>[^()]*)\)$')
_BAND = re.compile(r'_(?P<band>\d+(?:\.\d+)?)deg_s$')
_PER = {m.name: m.per for m in metric_defs.DEFINED}
_AXES = 'xyz'


def metric_label(column: str, notes: dict = METRIC_NOTES) -> str:
    """A readable name and unit for a metric or a campaign column (``peak_torque_Nm[0]``), from its
    note (:data:`METRIC_NOTES`: the metric declarations' notes and units), e.g. ``settling time, all
    three 2-1-3 Euler angles inside the 0.5° band (s)``; the column itself when it has no note."""
    m = _COLUMN.match(column)
    key, index = m['key'], m['index']
    note = metric_note(key, notes) or metric_note(key, ESTIMATION_NOTES)
    if not note:
        return column
    if key.startswith(('nees', 'nis_')):   # a family: the mean or the fraction inside the χ² bounds
        what = 'fraction of steps inside the 95 % χ² bounds' if key.endswith('_inside_95') else 'mean'
        family = key.rsplit('_inside_95', 1)[0].rsplit('_mean', 1)[0]
        of = (f'NEES ({family[4:]} states)' if family.startswith('nees')
              else f'NIS of the {family[4:].replace("_", " ")}')
        return f'{of}, {what}'
    parts = _NOTE.match(note)
    name, unit = (parts['name'], parts['unit'].split(';', 1)[0].strip()) if parts else (note, '')
    band = _BAND.search(key)
    if band:
        name = name.replace('the band', f'the {band["band"]}° band')
    if key.startswith('settling_') and not name.startswith(('time', 'seed')):
        name = f'settling time, {name}'
    if index is not None:
        per, i = _PER.get(key), int(index)
        if per == 'axis' and i < 3:
            name = f'{name.replace(" per body axis x, y, z", "")} about body axis {_AXES[i]}'
        else:
            name = f'{per or "element"} {i}: {name.replace("per wheel (wheels.names order), ", "")}'
    return f'{name} ({unit})' if unit else name


def fmt(value, digits: int = 6) -> str:
    """A metric value for a table: numbers to ``digits`` significant digits, None/NaN as n/a."""
    if value is None:
        return 'n/a'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(fmt(v, digits) for v in value) + ']'
    if isinstance(value, (float, np.floating)):
        if math.isnan(value):
            return 'n/a'
        return 'inf' if math.isinf(value) else f'{value:.{digits}g}'
    return str(value)


def md_escape(text: str) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')
