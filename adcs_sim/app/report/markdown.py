"""Markdown tables of the reports: value formatting, escaping, and the meaning of each metric."""
from __future__ import annotations

import math

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


def metric_note(key: str, notes: dict = METRIC_NOTES) -> str:
    """The explanation of a metric: the first entry of ``notes`` whose key prefixes ``key``."""
    return next((note for prefix, note in notes.items() if key.startswith(prefix)), '')


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
