"""Reports of recorded runs: one run -> ``report.md`` with figures; several runs -> a comparison.

Pure module (no rclpy): the time series come from :meth:`adcs_sim.app.analysis.RunData.from_bag` (one
streaming pass over the bag) and the numbers from :mod:`adcs_sim.app.analysis`. Figures are drawn with
:class:`matplotlib.figure.Figure` (no pyplot, no GUI backend) and saved as PNG and SVG.

One run (:func:`write_report`) writes into ``out``:

* ``report.md``: how the bag was read (complete, or recovered from a truncated file and how many
  messages), the topics it holds and the ones missing, fault events, the scenario (YAML, as
  embedded in the bag), the metrics and the figures;
* one ``<figure>.png`` and ``<figure>.svg`` per figure of :data:`FIGURES` the bag has data for.

Several runs (:func:`write_comparison`) write ``comparison.csv`` and ``comparison.md`` (one column
per run, rows of :func:`comparison_rows`) and overlaid figures, one line per run.

Every time axis carries a red dashed marker at each fault event: a status of level ERROR on the
``faults`` topic (``diagnostic_msgs/DiagnosticArray``) whose previous status of the same name was
not ERROR.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from adcs_msgs_py import names as topics
from adcs_sim import bag as bagio
from adcs_sim.app.analysis import RunData, attitude_errors, run_metrics, settling_times

ERROR_LEVEL = 2  # diagnostic_msgs/DiagnosticStatus.ERROR
DPI = 110
AXES = 'xyz'
COLORS = {'x': 'C0', 'y': 'C1', 'z': 'C2', 'w': 'C3'}
# Line styles per body axis: y wide and translucent, z dashed, so that equal curves (a symmetric
# slew gives identical y and z responses) stay visible on top of each other.
LINE = {'x': {'color': 'C0', 'linewidth': 1.6}, 'y': {'color': 'C1', 'linewidth': 3.2, 'alpha': 0.7},
        'z': {'color': 'C2', 'linewidth': 1.6, 'linestyle': '--'}, 'w': {'color': 'C3', 'linewidth': 1.6}}
FAULT_STYLE = {'color': 'red', 'linestyle': '--', 'linewidth': 1.2}
# Status keys plotted elsewhere (the commanded torque, in the torque figure).
TORQUE_KEYS = ('u_x', 'u_y', 'u_z')
MAX_TIMELINE_LEVELS = 12  # distinct values of a text status key drawn as a timeline


def _line(i: int) -> dict:
    """Style of the i-th of several series (wheels): the axis styles, then plain colours."""
    return dict(LINE['xyz'[i]]) if i < 3 else {'color': f'C{i}', 'linewidth': 1.6}


# --- reading ----------------------------------------------------------------------------------

def _bag_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that mean "this input is not a readable bag" (reported in one line, no traceback)."""
    import struct

    from mcap.exceptions import McapError
    errors = [OSError, ValueError, EOFError, struct.error, McapError]
    try:
        from rosbags.highlevel import AnyReaderError
        from rosbags.rosbag2 import ReaderError
        from rosbags.serde import SerdeError
        errors += [AnyReaderError, ReaderError, SerdeError]
    except ImportError:  # pragma: no cover - other rosbags versions
        pass
    return tuple(errors)


def bag_folder(path) -> Path | None:
    """The bag folder of ``path`` (the folder itself, or the folder of a ``<folder>_0.mcap`` file)."""
    path = Path(os.path.abspath(path))
    if path.is_dir():
        return path
    parent = path.parent
    if (parent / 'metadata.yaml').exists() or path.stem.startswith(parent.name + '_'):
        return parent
    return None


def run_name(path) -> str:
    """A run's name: the run folder holding ``bag/`` (``runs/<name>/bag``), else the bag's name."""
    folder = bag_folder(path)
    if folder is None:
        return Path(path).stem
    return folder.parent.name if folder.name == 'bag' and folder.parent.name else folder.name


def default_report_dir(path) -> Path:
    """``<bag>/../report``: a ``report`` folder beside the bag folder."""
    folder = bag_folder(path)
    if folder is None:
        p = Path(os.path.abspath(path))
        return p.parent / f'{p.stem}-report'
    return folder.parent / 'report'


@dataclass
class Run:
    """A loaded run: the bag, its name and its time series."""

    path: Path
    name: str
    data: RunData

    @property
    def complete(self) -> bool:
        """False when the bag was recovered from a truncated file (writer killed, no summary)."""
        return not self.data.truncated

    @property
    def message_count(self) -> int:
        """Messages read from the bag (all topics)."""
        return int(self.data.message_count)


class BagError(Exception):
    """An input that is not a readable bag of the graph (the message is one line)."""


def load_run(path, name: str | None = None) -> Run:
    """Check and read a bag; raises :class:`BagError` (one-line message) if it cannot be used."""
    try:
        data = RunData.from_bag(path)
    except _bag_errors() as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        reason = reason[len(str(path)) + 2:] if reason.startswith(f'{path}: ') else reason
        raise BagError(reason) from None
    return Run(Path(path), name or run_name(path), data)


# --- derived series -------------------------------------------------------------------------

def status_series(run: RunData) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Controller status values per key: ``{key: (t, values)}``, values float where all parse, else str.

    Keys are prefixed ``<status name>/`` when several controllers publish.
    """
    records = run.controller_status
    several = len({name for _, name, _ in records}) > 1
    raw: dict[str, tuple[list, list]] = {}
    for t, name, values in records:
        for key, value in values.items():
            ts, vs = raw.setdefault(f'{name}/{key}' if several else key, ([], []))
            ts.append(t)
            vs.append(value)
    out = {}
    for key, (ts, vs) in raw.items():
        try:
            arr = np.array(vs, dtype=float)
        except ValueError:
            arr = np.array(vs, dtype=object)
        out[key] = (np.array(ts, dtype=float), arr)
    return out


def commanded_torque(run: RunData) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, u (N, 3)) from the controller's status values ``u_x, u_y, u_z``, or None."""
    series = status_series(run)
    for prefix in [''] + sorted({k.rsplit('/', 1)[0] + '/' for k in series if '/' in k}):
        keys = [prefix + k for k in TORQUE_KEYS]
        if all(k in series and series[k][1].dtype != object for k in keys):
            t = series[keys[0]][0]
            if all(series[k][0].shape == t.shape for k in keys):
                return t, np.column_stack([series[k][1] for k in keys])
    return None


def fault_events(run: RunData) -> list[tuple[float, str, str]]:
    """(t, name, message) of every fault onset: an ERROR status whose previous same-name status was not."""
    last: dict[str, int] = {}
    events = []
    for t, level, name, message in sorted(run.faults, key=lambda r: r[0]):
        if level == ERROR_LEVEL and last.get(name) != ERROR_LEVEL:
            events.append((float(t), name, message))
        last[name] = level
    return events


def has_wheels(scenario: dict | None) -> bool:
    """Whether the scenario's spacecraft has reaction wheels (True when there is no scenario)."""
    if scenario is None:
        return True
    dyn = (scenario.get('dynamics') or {}).get('ros__parameters') or {}
    return bool(isinstance(dyn, dict) and (dyn.get('wheels') or {}).get('names'))


def missing_topics(run: RunData) -> list[str]:
    """Topics of the graph with no message in the bag (``RunData.missing_topics``); ``wheels/state``
    only when the spacecraft has wheels."""
    wheels = has_wheels(run.scenario)
    return [t for t in run.missing_topics if wheels or t != topics.WHEELS_STATE]


def thruster_topics(run: RunData) -> list[str]:
    return sorted(t for t in run.topic_counts if 'thruster' in t)


# --- figure helpers ---------------------------------------------------------------------------

def _figure(rows: int = 1, height: float = 2.6, width: float = 8.0, sharex: bool = True, ratios=None):
    total = height * (sum(ratios) if ratios else rows)
    fig = Figure(figsize=(width, 0.9 + total), layout='constrained')
    axes = fig.subplots(rows, 1, sharex=sharex, squeeze=False,
                        gridspec_kw={'height_ratios': ratios} if ratios else None)[:, 0]
    for ax in axes:
        ax.grid(True, alpha=0.35)
    axes[-1].set_xlabel('time t (s)')
    return fig, list(axes)


def _mark_faults(axes, events, legend: bool = True) -> None:
    for i, ax in enumerate(axes):
        for t, name, _ in events:
            label = f'fault: {name} (t = {t:g} s)' if legend and i == 0 else None
            ax.axvline(t, **FAULT_STYLE, label=label)


def _legend(ax, **kw) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize='small', **kw)


def save_figure(fig: Figure, out: Path, name: str) -> list[Path]:
    """Write ``fig`` as ``<name>.png`` and ``<name>.svg`` in ``out``; return the paths."""
    paths = [out / f'{name}.png', out / f'{name}.svg']
    fig.savefig(paths[0], dpi=DPI)
    fig.set_layout_engine('none')  # keep the layout just computed: the SVG need not redo it
    with matplotlib.rc_context({'svg.fonttype': 'none'}):  # text stays text: searchable, smaller
        fig.savefig(paths[1], metadata={'Date': None})
    return paths


def _step(ax, t, y, t_end: float | None = None, **kw):
    """Zero-order-held signal: each sample held to the next, the last one to ``t_end``."""
    t, y = np.asarray(t, dtype=float), np.asarray(y)
    if t_end is not None and t.size and t_end > t[-1]:
        t, y = np.append(t, t_end), np.append(y, y[-1:], axis=0)
    return ax.step(t, y, where='post', **kw)


def _positive(y: np.ndarray) -> np.ndarray:
    """Values for a log axis: non-positive ones masked (NaN)."""
    y = np.asarray(y, dtype=float).copy()
    y[~(y > 0)] = np.nan
    return y


# --- the figures of one run --------------------------------------------------------------------
# Each builder returns (Figure, caption) or a string: why the figure is skipped.

@dataclass
class Context:
    run: RunData
    events: list
    tol_deg: float
    eigen_tol_deg: float
    metrics: dict          # run_metrics of the run at these tolerances
    errors: tuple          # attitude_errors(run): computed once for all the figures


def fig_attitude_error(c: Context):
    _, eigen, _ = c.errors
    fig, (ax,) = _figure(height=3.4)
    ax.plot(c.run.t, _positive(eigen), color='C0', label='eigenaxis error')
    ax.set_yscale('log')
    ax.axhline(c.eigen_tol_deg, color='0.3', linestyle=':', label=f'tolerance {c.eigen_tol_deg:g}°')
    ts = c.metrics[f'settling_eigenaxis_{c.eigen_tol_deg:g}deg_s']
    if math.isfinite(ts):
        ax.axvline(ts, color='C2', linestyle='-.', linewidth=1, label=f'settled to {c.eigen_tol_deg:g}° at {ts:.1f} s')
    ax.set_ylabel('eigenaxis error (deg, log scale)')
    ax.set_title('Attitude error: eigenaxis rotation angle of $q_e = q_{ref}^* \\otimes q$')
    _mark_faults([ax], c.events)
    _legend(ax, loc='upper right')
    return fig, 'Eigenaxis attitude error (deg, log scale), with the settling tolerance.'


def fig_quaternion(c: Context):
    fig, (ax,) = _figure(height=3.2)
    for i, (label, a) in enumerate([('$q_1$ (x)', 'x'), ('$q_2$ (y)', 'y'), ('$q_3$ (z)', 'z'),
                                    ('$q_4$ (scalar)', 'w')]):
        ax.plot(c.run.t, c.run.q[:, i], **LINE[a], label=label)
    ax.set_ylabel('quaternion component (–)')
    ax.set_title('Attitude quaternion, body in inertial ($q_1 q_2 q_3$ vector, $q_4$ scalar)')
    _mark_faults([ax], c.events)
    _legend(ax, loc='best', ncol=2)
    return fig, 'Attitude quaternion components (dimensionless; vector part first, scalar last).'


EULER_LABELS = [r'$\theta_2$ about y (1st)', r'$\theta_1$ about x (2nd)', r'$\theta_3$ about z (3rd)']
EULER_AXES = 'yxz'  # body axis of each angle, in sequence order


def fig_euler(c: Context):
    _, _, euler = c.errors
    fig, (ax, ax_log) = _figure(rows=2, height=2.6)
    for i in range(3):
        ax.plot(c.run.t, euler[:, i], **LINE[EULER_AXES[i]], label=EULER_LABELS[i])
        ax_log.plot(c.run.t, _positive(np.abs(euler[:, i])), **LINE[EULER_AXES[i]])
    ax.set_ylabel('angle (deg)')
    ax.set_title('2-1-3 Euler angles of the attitude error')
    ax_log.set_yscale('log')
    for tol, style in ((1.0, '--'), (c.tol_deg, ':')):
        ax_log.axhline(tol, color='0.3', linestyle=style, linewidth=1, label=f'±{tol:g}°')
    ax_log.set_ylabel('|angle| (deg, log scale)')
    _mark_faults([ax, ax_log], c.events)
    _legend(ax, loc='upper right')
    _legend(ax_log, loc='upper right')
    return fig, ('2-1-3 Euler angles of the attitude error (deg): signed (top) and absolute on a log '
                 'scale with the ±1° and ±0.5° bands (bottom).')


def fig_body_rates(c: Context):
    fig, (ax,) = _figure(height=3.2)
    for i, a in enumerate(AXES):
        ax.plot(c.run.t, c.run.w[:, i], **LINE[a], label=fr'$\omega_{a}$')
    ax.set_ylabel('body rate (rad/s)')
    ax.set_title('Body angular rate (body axes)')
    _mark_faults([ax], c.events)
    _legend(ax, loc='best')
    return fig, 'Body angular rate ω (rad/s, body axes).'


def fig_torque(c: Context):
    run = c.run
    cmd = commanded_torque(run)
    if not run.u.size and cmd is None:
        return f'no applied torque ({topics.APPLIED_TORQUE}) and no commanded torque (u_x, u_y, u_z on {topics.CONTROLLER_STATUS})'
    fig, axes = _figure(rows=3, height=1.9)
    for i, (a, ax) in enumerate(zip(AXES, axes)):
        if run.u.size:
            _step(ax, run.t_u, 1e3 * run.u[:, i], run.t_end, color=COLORS[a], linewidth=3.0, alpha=0.7,
                  label='applied')
        if cmd is not None:
            _step(ax, cmd[0], 1e3 * cmd[1][:, i], run.t_end, color='k', linestyle='--', linewidth=1,
                  label='commanded')
        ax.set_ylabel(f'$u_{a}$ (mN·m)')
    axes[0].set_title('Control torque per body axis: commanded (controller) vs applied (actuators)')
    _mark_faults(axes, c.events)
    _legend(axes[0], loc='upper right', ncol=3)
    missing = []
    if not run.u.size:
        missing.append(f'no applied torque recorded ({topics.APPLIED_TORQUE})')
    if cmd is None:
        missing.append(f'no commanded torque recorded (u_x, u_y, u_z on {topics.CONTROLLER_STATUS})')
    return fig, ('Control torque per body axis (mN·m): commanded by the controller (status values u_x, u_y, '
                 f'u_z on `{topics.CONTROLLER_STATUS}`) and applied to the body (`{topics.APPLIED_TORQUE}`), '
                 'held over each control period.' + (' ' + '; '.join(missing) + '.' if missing else ''))


def fig_wheels(c: Context):
    run = c.run
    if not run.wheel_speed.size:
        return f'no wheel states ({topics.WHEELS_STATE})'
    fig, (ax_s, ax_t) = _figure(rows=2, height=2.5)
    for j, name in enumerate(run.wheel_names):
        ax_s.plot(run.t_wheels, run.wheel_speed[:, j], **_line(j), label=name)
        _step(ax_t, run.t_wheels, 1e3 * run.wheel_torque[:, j], **_line(j), label=name)
    ax_s.set_ylabel('wheel speed (rad/s)')
    ax_s.set_title('Reaction wheels: speed relative to the body (top), motor torque (bottom)')
    ax_t.set_ylabel('motor torque (mN·m)')
    _mark_faults([ax_s, ax_t], c.events)
    _legend(ax_s, loc='best')
    _legend(ax_t, loc='best')
    return fig, 'Wheel speeds relative to the body (rad/s) and wheel motor torques (mN·m).'


def fig_thrusters(c: Context):
    run = c.run
    if not run.thruster_on_time.size:
        found = thruster_topics(run)
        if found:
            return f'thruster topic(s) {", ".join(found)} recorded, but no {topics.THRUSTERS_STATE} messages'
        return f'no thruster topic recorded ({topics.THRUSTERS_STATE})'
    fig, (ax_f, ax_i, ax_n) = _figure(rows=3, height=2.4, ratios=[1.4, 1.0, 1.0])
    n = len(run.thruster_names)
    for j, name in enumerate(run.thruster_names):
        # each firing as a bar over [t, t + on-time], one row per thruster
        on = run.thruster_on_time[:, j] > 0.0
        bars = list(zip(run.t_thrusters[on], run.thruster_on_time[on, j]))
        ax_f.broken_barh(bars, (n - 1 - j - 0.4, 0.8), color=_line(j)['color'])
        ax_i.plot(run.t_thrusters + _zoh_period(run), run.thruster_impulse[:, j], **_line(j), label=name)
    ax_f.set_yticks(range(n), list(reversed(run.thruster_names)))
    ax_f.set_ylim(-0.6, n - 0.4)
    ax_f.set_ylabel('firing')
    ax_f.set_title('Thrusters: firings (top), cumulated impulse (middle), firings so far (bottom)')
    ax_i.set_ylabel('impulse (N·s)')
    _legend(ax_i, loc='upper left')
    count = np.cumsum(np.count_nonzero(run.thruster_on_time > 0.0, axis=1))
    _step(ax_n, run.t_thrusters, count, color='C4')
    ax_n.set_ylabel('firings (thruster-periods)')
    ax_n.yaxis.set_major_locator(MaxNLocator(integer=True))
    _mark_faults((ax_f, ax_i, ax_n), c.events)
    m = c.metrics
    return fig, (f'Thruster firings (bars: on-time from each period\'s start), cumulated impulse per thruster (N·s) '
                 f'and the number of firings so far: {m.get("thruster_firings", 0)} firings, '
                 f'{m.get("thruster_impulse_Ns", float("nan")):.4g} N·s in all ({topics.THRUSTERS_STATE}).')


def _zoh_period(run) -> float:
    """The step length of the thruster series (impulses are at the step ends)."""
    t = run.t_thrusters
    return float(np.median(np.diff(t))) if t.size > 1 else 0.0


def fig_phase(c: Context):
    qe, _, _ = c.errors
    qe = qe * np.where(qe[:, 3:4] < 0, -1.0, 1.0)  # the shortest-path sign (q4 >= 0)
    fig = Figure(figsize=(8.0, 4.6), layout='constrained')
    ax = fig.subplots()
    ax.grid(True, alpha=0.35)
    for i, a in enumerate(AXES):
        ax.plot(qe[:, i], c.run.w[:, i], **LINE[a], label=fr'$q_{i + 1}$ vs $\omega_{a}$')
        ax.plot(qe[0, i], c.run.w[0, i], 'o', color=COLORS[a], markersize=6)
        ax.plot(qe[-1, i], c.run.w[-1, i], 'x', color=COLORS[a], markersize=8)
    for t, name, _ in c.events:
        k = min(np.searchsorted(c.run.t, t), len(c.run.t) - 1)
        ax.plot(qe[k, :3], c.run.w[k], '*', color='red', markersize=11,
                label=f'fault: {name} (t = {t:g} s)')
    ax.plot([], [], 'o', color='0.4', label='start')
    ax.plot([], [], 'x', color='0.4', label='end')
    ax.axhline(0, color='0.5', linewidth=0.8)
    ax.axvline(0, color='0.5', linewidth=0.8)
    ax.set_xlabel('error quaternion component $q_i$ (–)')
    ax.set_ylabel(r'body rate $\omega_i$ (rad/s)')
    ax.set_title(r'Phase portrait: $q_i$ vs $\omega_i$, i = 1, 2, 3')
    _legend(ax, loc='best')
    return fig, 'Phase portraits: error quaternion component q_i vs body rate ω_i (rad/s), i = 1..3.'


def fig_controller_status(c: Context):
    series = {k: v for k, v in status_series(c.run).items() if k.rsplit('/', 1)[-1] not in TORQUE_KEYS}
    if not series:
        if c.run.controller_status:
            return 'the controller publishes no status values besides the commanded torque'
        return f'no controller status ({topics.CONTROLLER_STATUS})'
    text = [k for k, (_, v) in series.items() if v.dtype == object]
    # A text value that changes all the time (a message) is no timeline: left out, and said so.
    chatty = {k: len(set(series[k][1].tolist())) for k in text}
    chatty = {k: n for k, n in chatty.items() if n > MAX_TIMELINE_LEVELS}
    text = [k for k in text if k not in chatty]
    numeric = [k for k, (_, v) in series.items() if v.dtype != object]
    keys = text + numeric
    if not keys:
        return ('the controller status has only text values with too many distinct values for a timeline: '
                + ', '.join(f'{k} ({n})' for k, n in chatty.items()))
    fig, axes = _figure(rows=len(keys), height=1.6, ratios=[0.6] * len(text) + [1.0] * len(numeric))
    for ax, key in zip(axes, keys):
        t, v = series[key]
        if v.dtype == object:
            levels = list(dict.fromkeys(v.tolist()))
            idx = np.array([levels.index(x) for x in v])
            _step(ax, t, idx, color='C4', linewidth=2)
            ax.set_yticks(range(len(levels)), levels)
            ax.set_ylim(-0.5, len(levels) - 0.5)
            ax.set_ylabel(f'{key} (timeline)')
        else:
            _step(ax, t, v, color='C0')
            finite = v[np.isfinite(v)]
            if finite.size and np.all(finite == np.round(finite)):  # counts: integer ticks
                lo, hi = int(finite.min()), int(finite.max())
                if hi - lo < 4:  # a few values: every integer, a count from 0 without negatives
                    ticks = np.arange(max(lo - 1, 0) if lo >= 0 else lo - 1, hi + 2)
                    ax.set_yticks(ticks)
                    ax.set_ylim(ticks[0] - 0.25, ticks[-1] + 0.25)
                else:
                    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_ylabel(f'{key}\n(as published)')
    axes[0].set_title(f'Controller status values ({topics.CONTROLLER_STATUS}; u_x, u_y, u_z are in the torque figure)')
    _mark_faults(axes, c.events)
    _legend(axes[0], loc='upper right')
    return fig, (f'Controller status values on `{topics.CONTROLLER_STATUS}`: '
                 + ', '.join(f'`{k}`' + (' (timeline)' if k in text else '') for k in keys)
                 + '. The commanded torque u_x, u_y, u_z is in the torque figure.'
                 + (' Not plotted (more than {} distinct text values): {}.'.format(
                     MAX_TIMELINE_LEVELS, ', '.join(f'`{k}` ({n})' for k, n in chatty.items())) if chatty else ''))


# (file name, title, builder)
FIGURES = [
    ('attitude_error', 'Eigenaxis attitude error', fig_attitude_error),
    ('quaternion', 'Quaternion components', fig_quaternion),
    ('euler_213', '2-1-3 Euler angles', fig_euler),
    ('body_rates', 'Body rates', fig_body_rates),
    ('torque', 'Commanded vs applied torque', fig_torque),
    ('wheels', 'Wheel speeds and motor torques', fig_wheels),
    ('thrusters', 'Thruster firing', fig_thrusters),
    ('phase_portrait', 'Phase portraits', fig_phase),
    ('controller_status', 'Controller status', fig_controller_status),
]


# --- the report of one run ---------------------------------------------------------------------

METRIC_NOTES = {
    'duration_s': 'simulated time of the last state (s)',
    'settling_eigenaxis': 'time after which the eigenaxis error stays inside the band (s; inf: not settled)',
    'settling_euler213_per_axis_s': 'per 2-1-3 Euler angle, in sequence order (about y, x, z) (s)',
    'settling_euler213': 'all three 2-1-3 Euler angles inside the band (s; inf: not settled)',
    'final_eigenaxis_error_deg': 'eigenaxis error at the end (deg)',
    'integrated_torque_Nms': '∫‖u‖dt of the applied torque (N·m·s)',
    'control_energy_N2m2s': '∫uᵀu dt of the applied torque (N²·m²·s)',
    'peak_torque_Nm': 'max |u_i| per body axis x, y, z (N·m)',
    'peak_wheel_speed_rad_s': 'max |Ω| over all wheels (rad/s)',
    'missed_steps': 'lockstep steps without the awaited command',
    'thruster_impulse_Ns': 'total thruster impulse Σ∫F dt at the end (N·s)',
    'thruster_firings': 'thruster-periods with a non-zero on-time',
    'thruster_on_time_s': 'total thruster on-time, all thrusters (s)',
}


def _note(key: str, notes: dict = METRIC_NOTES) -> str:
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


def _md_escape(text: str) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def write_report(run: Run, out, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> Path:
    """Write ``report.md`` and the figures of one run into ``out``; return the report's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = run.data
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    events = fault_events(data)
    metrics = run_metrics(data, tol_deg, eigen_tol_deg)
    ctx = Context(data, events, tol_deg, eigen_tol_deg, metrics, attitude_errors(data))
    missing = missing_topics(data)

    lines = [f'# Run report: {run.name}', '', '| | |', '| --- | --- |',
             f'| bag | `{run.path}` |']
    if run.complete:
        lines.append(f'| recording | complete ({run.message_count} messages) |')
    else:
        lines.append(f'| recording | **recovered from a truncated file** (no MCAP summary: the recorder did '
                     f'not close the bag); {run.message_count} messages recovered |')
    lines += [f'| simulated time | {data.t[0]:g} s to {data.t_end:g} s ({data.t.size} state samples) |',
              f'| attitude | {"true state (truth/state)" if data.topic_counts.get(topics.TRUTH_STATE) else "state"} |',
              '']
    if not run.complete:
        lines += [f'> Recovered from a truncated file: {run.message_count} messages recovered, '
                  f'up to t = {data.t_end:g} s. Metrics and figures cover the recovered part only '
                  '(`missed_steps`: the last count published before the cut).', '']

    lines += ['## Topics', '', '| topic | messages |', '| --- | --- |']
    lines += [f'| `{t}` | {n} |' for t, n in sorted(data.topic_counts.items())]
    lines.append('')
    if missing:
        lines += ['**Missing topics** (no messages in the bag): '
                  + ', '.join(f'`{t}`' for t in missing)
                  + '. Figures and metrics that need them are skipped or n/a.', '']
    else:
        lines += ['Missing topics: none.', '']

    lines += ['## Faults', '']
    if events:
        lines += [f'- fault at t = {t:g} s: `{name}`' + (f': {_md_escape(msg)}' if msg else '')
                  for t, name, msg in events]
        lines += ['', 'Each fault is marked by a red dashed line on the time plots.', '']
    else:
        lines += [f'No fault events (no ERROR status on `{topics.FAULTS}`).', '']

    lines += ['## Scenario', '']
    scenario_text = bagio.read_metadata(run.path).get('scenario') if data.scenario is not None else None
    if scenario_text:
        fence = '~~~~' if '```' in scenario_text else '```'
        lines += ['As embedded in the bag (MCAP metadata `scenario`):', '', fence + 'yaml', scenario_text.rstrip('\n'),
                  fence, '']
    else:
        lines += ['The bag carries no scenario (no MCAP metadata record `scenario`).', '']

    lines += ['## Metrics', '', 'Definitions: `adcs_sim/app/analysis.py`.', '',
              '| metric | value | meaning |', '| --- | --- | --- |']
    lines += [f'| `{k}` | {fmt(v)} | {_md_escape(_note(k))} |' for k, v in metrics.items()]
    lines.append('')

    lines += ['## Figures', '']
    for name, title, builder in FIGURES:
        result = builder(ctx)
        lines += [f'### {title}', '']
        if isinstance(result, str):
            lines += [f'Skipped: {result}.', '']
            continue
        fig, caption = result
        save_figure(fig, out, name)
        lines += [f'![{title}]({name}.png)', '', f'{caption} ([SVG]({name}.svg))', '']
    path = out / 'report.md'
    path.write_text('\n'.join(lines))
    return path


# --- comparison of several runs ----------------------------------------------------------------

# Euler angle index (euler_213 order: about y, x, z) of θ1 (x), θ2 (y), θ3 (z).
_EULER_INDEX = {'theta1_x': 1, 'theta2_y': 0, 'theta3_z': 2}


def comparison_rows(run: RunData, bands=(1.0, 0.5), eigen_tol_deg: float = 0.5) -> dict:
    """The comparison metrics of one run: ``{row key: value}`` (see :data:`COMPARISON_ROWS`)."""
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
    for a, v in zip(AXES, m['peak_torque_Nm']):
        rows[f'peak_torque_{a}_Nm'] = v
    rows['peak_wheel_speed_rad_s'] = m['peak_wheel_speed_rad_s']
    rows['thruster_impulse_Ns'] = m.get('thruster_impulse_Ns')  # n/a without thrusters/state
    rows['missed_steps'] = m['missed_steps']
    rows['duration_s'] = m['duration_s']
    return rows


COMPARISON_NOTES = {
    'settling_euler213_theta1_x': 'settling of θ1 (about x) of the 2-1-3 Euler error (s)',
    'settling_euler213_theta2_y': 'settling of θ2 (about y) of the 2-1-3 Euler error (s)',
    'settling_euler213_theta3_z': 'settling of θ3 (about z) of the 2-1-3 Euler error (s)',
    'settling_euler213_all': 'settling of all three 2-1-3 Euler angles (s)',
    'thruster_impulse_Ns': 'total thruster impulse (N·s; n/a: no thrusters modelled yet)',
    'peak_torque_': 'max |u_i| of the applied torque on this axis (N·m)',
    **{k: v for k, v in METRIC_NOTES.items() if k not in ('peak_torque_Nm',)},
}


def _note_cmp(key: str) -> str:
    return _note(key, COMPARISON_NOTES)


def _csv_value(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 'n/a'
    if isinstance(value, float):
        return 'inf' if math.isinf(value) else repr(value)
    return str(value)


def unique_names(runs: list[Run]) -> list[str]:
    """Run names, made unique with the bag path where two runs share one."""
    names = [r.name for r in runs]
    if len(set(names)) == len(names):
        return names
    common = os.path.commonpath([os.path.abspath(r.path) for r in runs])
    return [os.path.relpath(os.path.abspath(r.path), common) if names.count(r.name) > 1 else r.name
            for r in runs]


def load_reference(path) -> dict:
    """Published figures to compare runs with: a YAML file ``{source: text, runs: {run name:
    {comparison row: value}}}`` (rows as in ``comparison.csv``, e.g. ``integrated_torque_Nms``,
    ``peak_torque_x_Nm``, ``settling_euler213_theta1_x_0.5deg_s``). Raises ValueError."""
    import yaml
    try:
        tree = yaml.safe_load(Path(path).read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f'{path}: cannot read reference figures: {exc}') from None
    if not isinstance(tree, dict) or not isinstance(tree.get('runs'), dict):
        raise ValueError(f'{path}: expected `source:` and `runs: {{<run name>: {{<metric>: value}}}}`')
    for name, values in tree['runs'].items():
        if not isinstance(values, dict) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values.values()):
            raise ValueError(f'{path}: runs.{name}: expected a mapping of metric names to numbers')
    return tree


def reference_rows(names: list[str], table: list[dict], reference: dict) -> list[tuple]:
    """(run, metric, published, ours, relative difference) for every published figure of a run
    being compared. ValueError for a metric name that is not a comparison row."""
    out = []
    for name, row in zip(names, table):
        for key, published in (reference['runs'].get(name) or {}).items():
            if key not in row:
                raise ValueError(f'reference figure {name}.{key}: not a comparison metric; known: {list(row)}')
            ours = row[key]
            diff = (ours - published) / abs(published) if ours is not None and published else math.nan
            out.append((name, key, float(published), ours, diff))
    return out


def write_comparison(runs: list[Run], out, tol_deg: float = 0.5,
                     eigen_tol_deg: float | None = None, reference: dict | None = None) -> tuple[Path, Path]:
    """Write ``comparison.csv``, ``comparison.md`` and overlaid figures; return (csv, md) paths.

    ``reference`` (:func:`load_reference`): published figures; adds a "published vs ours" table
    with the relative differences (also ``reference_comparison.csv``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    bands = tuple(sorted({1.0, 0.5, float(tol_deg)}, reverse=True))
    names = unique_names(runs)
    table = [comparison_rows(r.data, bands, eigen_tol_deg) for r in runs]
    keys = list(table[0])

    csv_path = out / 'comparison.csv'
    with open(csv_path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['metric', *names])
        for k in keys:
            w.writerow([k, *(_csv_value(row[k]) for row in table)])

    lines = [f'# Comparison of {len(runs)} runs', '', '| run | bag | recording |', '| --- | --- | --- |']
    for name, r in zip(names, runs):
        how = 'complete' if r.complete else f'recovered from a truncated file ({r.message_count} messages)'
        miss = missing_topics(r.data)
        how += f'; missing topics: {", ".join(miss)}' if miss else ''
        lines.append(f'| {_md_escape(name)} | `{r.path}` | {how} |')
    lines += ['', '## Metrics', '', 'Values as in `comparison.csv`; inf: not settled by the end of the run; '
              'n/a: not available in that run.', '',
              '| metric | ' + ' | '.join(_md_escape(n) for n in names) + ' | meaning |',
              '| --- | ' + ' | '.join('---' for _ in names) + ' | --- |']
    for k in keys:
        lines.append(f'| `{k}` | ' + ' | '.join(fmt(row[k]) for row in table)
                     + f' | {_md_escape(_note_cmp(k))} |')
    if reference is not None:
        published = reference_rows(names, table, reference)
        with open(out / 'reference_comparison.csv', 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(['run', 'metric', 'published', 'ours', 'relative_difference'])
            w.writerows([r[:3] + (_csv_value(r[3]), _csv_value(r[4])) for r in published])
        lines += ['', '## Published figures vs ours', '', _md_escape(str(reference.get('source', ''))), '',
                  '| run | metric | published | ours | difference |', '| --- | --- | ---: | ---: | ---: |']
        for name, key, pub, ours, diff in published:
            lines.append(f'| {_md_escape(name)} | `{key}` | {fmt(pub)} | {fmt(ours)} | '
                         + ('n/a' if math.isnan(diff) else f'{100 * diff:+.1f} %') + ' |')
    lines += ['', '## Figures', '']
    for name, title, caption, fig in _comparison_figures(runs, names, eigen_tol_deg):
        save_figure(fig, out, name)
        lines += [f'### {title}', '', f'![{title}]({name}.png)', '', f'{caption} ([SVG]({name}.svg))', '']
    md_path = out / 'comparison.md'
    md_path.write_text('\n'.join(lines))
    return csv_path, md_path


def _comparison_figures(runs: list[Run], names: list[str], eigen_tol_deg: float):
    def faults(ax, i, name, r):
        for k, (t, fname, _) in enumerate(fault_events(r.data)):
            ax.axvline(t, color=f'C{i}', linestyle=(0, (2, 2)), linewidth=1.2, alpha=0.9,
                       label=f'fault in {name}' if k == 0 else None)

    def style(i):  # colour and dash per run: runs with equal curves stay distinguishable
        return {'color': f'C{i}', 'linestyle': ['-', '--', '-.', ':'][i % 4], 'linewidth': 1.6}

    fig, (ax,) = _figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        _, eigen, _ = attitude_errors(r.data)
        ax.plot(r.data.t, _positive(eigen), **style(i), label=name)
        faults(ax, i, name, r)
    ax.set_yscale('log')
    ax.axhline(eigen_tol_deg, color='0.3', linestyle=':', label=f'tolerance {eigen_tol_deg:g}°')
    ax.set_ylabel('eigenaxis error (deg, log scale)')
    ax.set_title('Eigenaxis attitude error')
    _legend(ax, loc='upper right')
    yield 'compare_attitude_error', 'Eigenaxis attitude error', \
        ('Eigenaxis attitude error (deg, log scale), one line per run (an exactly zero error is not drawn on '
         'the log scale); dotted verticals: fault events, in the colour of their run.'), fig

    fig, (ax,) = _figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        if r.data.u.size:
            _step(ax, r.data.t_u, 1e3 * np.linalg.norm(r.data.u, axis=1), r.data.t_end, **style(i), label=name)
        else:
            ax.plot([], [], **style(i), label=f'{name} (no applied torque recorded)')
        faults(ax, i, name, r)
    ax.set_ylabel('‖u‖ (mN·m)')
    ax.set_title('Applied control torque norm')
    _legend(ax, loc='upper right')
    yield 'compare_torque_norm', 'Torque norm', 'Norm of the applied body torque ‖u‖ (mN·m), one line per run.', fig

    fig, (ax,) = _figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        if r.data.wheel_speed.size:
            ax.plot(r.data.t_wheels, np.linalg.norm(r.data.wheel_speed, axis=1), **style(i), label=name)
        else:
            ax.plot([], [], **style(i), label=f'{name} (no wheel states recorded)')
        faults(ax, i, name, r)
    ax.set_ylabel('‖Ω‖ (rad/s)')
    ax.set_title('Wheel speed norm (all wheels, relative to the body)')
    _legend(ax, loc='upper right')
    yield 'compare_wheel_speed_norm', 'Wheel speed norm', \
        'Euclidean norm of the wheel speeds ‖Ω‖ (rad/s), one line per run.', fig
