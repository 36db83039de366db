"""The figures of one run's report (:data:`FIGURES`: file name, title, builder) and the drawing
helpers the comparison shares. :class:`matplotlib.figure.Figure` only (no pyplot, no GUI backend);
each figure is saved as PNG and SVG (:func:`save_figure`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis.metrics import RunData
from adcs_sim.app.report.envelope import log_positive, reduced
from adcs_sim.app.report.kinds import UNKNOWN, RunKind
from adcs_sim.app.report.loading import commanded_torque, thruster_topics

DPI = 110
AXES = 'xyz'
COLORS = {'x': 'C0', 'y': 'C1', 'z': 'C2', 'w': 'C3'}
# Line styles per body axis: y wide and translucent, z dashed, so that equal curves (a symmetric
# slew gives identical y and z responses) stay visible on top of each other.
LINE = {'x': {'color': 'C0', 'linewidth': 1.6}, 'y': {'color': 'C1', 'linewidth': 3.2, 'alpha': 0.7},
        'z': {'color': 'C2', 'linewidth': 1.6, 'linestyle': '--'}, 'w': {'color': 'C3', 'linewidth': 1.6}}
FAULT_STYLE = {'color': 'red', 'linestyle': '--', 'linewidth': 1.2}


def _line(i: int) -> dict:
    """Style of the i-th of several series (wheels): the axis styles, then plain colours."""
    return dict(LINE['xyz'[i]]) if i < 3 else {'color': f'C{i}', 'linewidth': 1.6}


# --- figure helpers ---------------------------------------------------------------------------

def new_figure(rows: int = 1, height: float = 2.6, width: float = 10.0, sharex: bool = True, ratios=None):
    total = height * (sum(ratios) if ratios else rows)
    fig = Figure(figsize=(width, 0.9 + total), layout='constrained')
    axes = fig.subplots(rows, 1, sharex=sharex, squeeze=False,
                        gridspec_kw={'height_ratios': ratios} if ratios else None)[:, 0]
    for ax in axes:
        ax.grid(True, alpha=0.35)
    axes[-1].set_xlabel('time t (s)')
    return fig, list(axes)


def mark_faults(axes, events, legend: bool = True) -> None:
    for i, ax in enumerate(axes):
        for t, name, _ in events:
            label = f'fault: {name} (t = {t:g} s)' if legend and i == 0 else None
            ax.axvline(t, **FAULT_STYLE, label=label)


PHASE_COLOURS = ['#dbe9f6', '#fde7cf', '#dff2dc', '#efe0f3', '#f6f3d2']


def shade_phases(axes, phases, legend: bool = True) -> None:
    """Shade each phase (t0, t1, label) of the run on every axis; one legend entry per label."""
    colours: dict[str, str] = {}
    for t0, t1, label in phases:
        new = label not in colours
        colour = colours.setdefault(label, PHASE_COLOURS[len(colours) % len(PHASE_COLOURS)])
        for i, ax in enumerate(axes):
            ax.axvspan(t0, t1, color=colour, alpha=0.9, zorder=0, linewidth=0,
                       label=f'phase: {label}' if legend and new and i == 0 else None)


def add_legend(ax, outside: bool = True, **kw) -> None:
    """The axis' legend, by default outside the plot on the right (never over the data)."""
    if ax.get_legend_handles_labels()[0]:
        if outside and 'loc' not in kw:
            kw.update(loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        ax.legend(fontsize='small', **kw)


def save_figure(fig: Figure, out: Path, name: str) -> list[Path]:
    """Write ``fig`` as ``<name>.png`` and ``<name>.svg`` in ``out``; return the paths.

    The layout (constrained: a text layout of every tick label, twice) is computed once, at the
    PNG's resolution, and both files are drawn with it: ``savefig`` would otherwise draw the figure
    once more before each file just to lay it out (four draws a figure, now two)."""
    paths = [out / f'{name}.png', out / f'{name}.svg']
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)   # one Agg renderer for the layout and the PNG: text measured once
    fix_layout(fig, DPI)
    fig.savefig(paths[0], dpi=DPI)
    with matplotlib.rc_context({'svg.fonttype': 'none'}):  # text stays text: searchable, smaller
        fig.savefig(paths[1], metadata={'Date': None})
    return paths


def fix_layout(fig: Figure, dpi: float) -> None:
    """Run ``fig``'s layout engine once at ``dpi`` and drop the engine: later draws keep that layout
    (what ``savefig`` does before its own draw, without the draw)."""
    engine = fig.get_layout_engine()
    if engine is None:
        return
    old = fig.dpi
    fig.dpi = dpi
    try:
        engine.execute(fig)
    finally:
        fig.dpi = old
    fig.set_layout_engine(None)


def step_plot(ax, t, y, t_end: float | None = None, **kw):
    """Zero-order-held signal: each sample held to the next, the last one to ``t_end``."""
    t, y = reduced(np.asarray(t, dtype=float), np.asarray(y))
    if t_end is not None and t.size and t_end > t[-1]:
        t, y = np.append(t, t_end), np.append(y, y[-1:], axis=0)
    return ax.step(t, y, where='post', **kw)


# --- the figures of one run --------------------------------------------------------------------
# Each builder returns (Figure, caption) or a string: why the figure is skipped.

@dataclass
class Context:
    run: RunData
    events: list
    tol_deg: float
    eigen_tol_deg: float
    metrics: dict          # run_metrics of the run at these tolerances
    errors: tuple          # attitude_errors(run, q_ref): computed once for all the figures
    kind: RunKind = field(default_factory=lambda: RunKind(UNKNOWN, 'not given'))
    q_ref: np.ndarray | None = None   # the reference at each state sample (kinds.reference_attitude)
    reference_text: str = ''
    phases: list = field(default_factory=list)   # (t0, t1, label)
    lead: list = field(default_factory=list)     # lead.Metric of the kind, with the paper's values
    # (series, band) -> settling time of the whole run, computed while it was streamed (a long run:
    # ``run`` holds the samples drawn, long_run); empty: computed from ``run``
    settled: dict = field(default_factory=dict)


def fig_attitude_error(c: Context):
    _, eigen, _ = c.errors
    fig, (ax,) = new_figure(height=3.4)
    ax.plot(*reduced(c.run.t, log_positive(eigen)), color='C0', label='eigenaxis error')
    ax.set_yscale('log')
    ax.axhline(c.eigen_tol_deg, color='0.3', linestyle=':', label=f'tolerance {c.eigen_tol_deg:g}°')
    ts = c.metrics[f'settling_eigenaxis_{c.eigen_tol_deg:g}deg_s']
    if math.isfinite(ts):
        ax.axvline(ts, color='C2', linestyle='-.', linewidth=1, label=f'settled to {c.eigen_tol_deg:g}° at {ts:.1f} s')
    ax.set_ylabel('eigenaxis error (deg, log scale)')
    ax.set_title('Attitude error: eigenaxis rotation angle of $q_e = q_{ref}^* \\otimes q$')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, 'Eigenaxis attitude error (deg, log scale), with the settling tolerance.'


def fig_quaternion(c: Context):
    fig, (ax,) = new_figure(height=3.2)
    shade_phases([ax], c.phases)
    for i, (label, a) in enumerate([('$q_1$ (x)', 'x'), ('$q_2$ (y)', 'y'), ('$q_3$ (z)', 'z'),
                                    ('$q_4$ (scalar)', 'w')]):
        ax.plot(*reduced(c.run.t, c.run.q[:, i]), **LINE[a], label=label)
    if c.q_ref is not None:
        for i, a in enumerate('xyzw'):
            ax.plot(*reduced(c.run.t, c.q_ref[:, i]), color=COLORS[a], linestyle=(0, (1, 1.5)), linewidth=1.2,
                    label='reference $q_{ref}$ (dotted)' if i == 0 else None)
    ax.set_ylabel('quaternion component (–)')
    ax.set_title('Attitude quaternion, body in inertial ($q_1 q_2 q_3$ vector, $q_4$ scalar)')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, ('Attitude quaternion components (dimensionless; vector part first, scalar last)'
                 + ('; dotted, same colours: the reference the controller follows' if c.q_ref is not None else '')
                 + ('; shaded: the run\'s phases.' if c.phases else '.'))


EULER_LABELS = [r'$\theta_2$ about y (1st)', r'$\theta_1$ about x (2nd)', r'$\theta_3$ about z (3rd)']
EULER_AXES = 'yxz'  # body axis of each angle, in sequence order


def fig_euler(c: Context):
    _, _, euler = c.errors
    fig, (ax, ax_log) = new_figure(rows=2, height=2.6)
    for i in range(3):
        ax.plot(*reduced(c.run.t, euler[:, i]), **LINE[EULER_AXES[i]], label=EULER_LABELS[i])
        ax_log.plot(*reduced(c.run.t, log_positive(np.abs(euler[:, i]))), **LINE[EULER_AXES[i]])
    ax.set_ylabel('angle (deg)')
    ax.set_title('2-1-3 Euler angles of the attitude error')
    ax_log.set_yscale('log')
    for tol, style in ((1.0, '--'), (c.tol_deg, ':')):
        ax_log.axhline(tol, color='0.3', linestyle=style, linewidth=1, label=f'±{tol:g}°')
    ax_log.set_ylabel('|angle| (deg, log scale)')
    mark_faults([ax, ax_log], c.events)
    add_legend(ax)
    add_legend(ax_log)
    return fig, ('2-1-3 Euler angles of the attitude error (deg): signed (top) and absolute on a log '
                 'scale with the ±1° and ±0.5° bands (bottom).')


def fig_body_rates(c: Context):
    fig, (ax,) = new_figure(height=3.2)
    for i, a in enumerate(AXES):
        ax.plot(*reduced(c.run.t, c.run.w[:, i]), **LINE[a], label=fr'$\omega_{a}$')
    ax.set_ylabel('body rate (rad/s)')
    ax.set_title('Body angular rate (body axes)')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, 'Body angular rate ω (rad/s, body axes).'


def torque_unit(*values: np.ndarray) -> tuple[float, str]:
    """(scale, unit) for torques: N·m from 1 N·m up (Table I's 140 N·m), mN·m below (wheels of 10-20 mN·m)."""
    peak = max((float(np.nanmax(np.abs(v))) for v in values if np.size(v)), default=0.0)
    return (1.0, 'N·m') if peak >= 1.0 else (1e3, 'mN·m')


def fig_torque(c: Context):
    run = c.run
    cmd = commanded_torque(run)
    if not run.u.size and cmd is None:
        return (f'no applied torque ({topics.APPLIED_TORQUE}) and no commanded torque (u_x, u_y, u_z on '
                f'{topics.CONTROLLER_STATUS})')
    scale, unit = torque_unit(run.u, cmd[1] if cmd is not None else np.empty(0))
    fig, axes = new_figure(rows=3, height=1.9)
    for i, (a, ax) in enumerate(zip(AXES, axes)):
        if run.u.size:
            step_plot(ax, run.t_u, scale * run.u[:, i], run.t_end, color=COLORS[a], linewidth=3.0, alpha=0.7,
                  label='applied')
        if cmd is not None:
            step_plot(ax, cmd[0], scale * cmd[1][:, i], run.t_end, color='k', linestyle='--', linewidth=1,
                  label='commanded')
        ax.set_ylabel(f'$u_{a}$ ({unit})')
    axes[0].set_title('Control torque per body axis: commanded (controller) vs applied (actuators)')
    mark_faults(axes, c.events)
    add_legend(axes[0])
    missing = []
    if not run.u.size:
        missing.append(f'no applied torque recorded ({topics.APPLIED_TORQUE})')
    if cmd is None:
        missing.append(f'no commanded torque recorded (u_x, u_y, u_z on {topics.CONTROLLER_STATUS})')
    return fig, (f'Control torque per body axis ({unit}): commanded by the controller (status values u_x, u_y, '
                 f'u_z on `{topics.CONTROLLER_STATUS}`) and applied to the body (`{topics.APPLIED_TORQUE}`), '
                 'held over each control period.' + (' ' + '; '.join(missing) + '.' if missing else ''))


def fig_wheels(c: Context):
    run = c.run
    if not run.wheel_speed.size:
        return f'no wheel states ({topics.WHEELS_STATE})'
    torque = run.wheel_torque.size > 0   # a batch engine's run has the speeds only
    fig, axes = new_figure(rows=2 if torque else 1, height=2.5)
    scale, unit = torque_unit(run.wheel_torque)
    for j, name in enumerate(run.wheel_names):
        axes[0].plot(*reduced(run.t_wheels, run.wheel_speed[:, j]), **_line(j), label=name)
        if torque:
            step_plot(axes[1], run.t_wheels, scale * run.wheel_torque[:, j], **_line(j), label=name)
    axes[0].set_ylabel('wheel speed (rad/s)')
    axes[0].set_title('Reaction wheels: speed relative to the body'
                      + (' (top), motor torque (bottom)' if torque else ''))
    axes[-1].set_ylabel(f'motor torque ({unit})' if torque else 'wheel speed (rad/s)')
    mark_faults(axes, c.events)
    for ax in axes:
        add_legend(ax)
    return fig, 'Wheel speeds relative to the body (rad/s)' + (f' and wheel motor torques ({unit}).' if torque else '.')


def fig_thrusters(c: Context):
    run = c.run
    if not run.thruster_on_time.size:
        found = thruster_topics(run)
        if found:
            return f'thruster topic(s) {", ".join(found)} recorded, but no {topics.THRUSTERS_STATE} messages'
        return f'no thruster topic recorded ({topics.THRUSTERS_STATE})'
    fig, (ax_f, ax_i, ax_n) = new_figure(rows=3, height=2.4, ratios=[1.4, 1.0, 1.0])
    n = len(run.thruster_names)
    for j, name in enumerate(run.thruster_names):
        # each firing as a bar over [t, t + on-time], one row per thruster
        on = run.thruster_on_time[:, j] > 0.0
        bars = list(zip(run.t_thrusters[on], run.thruster_on_time[on, j]))
        ax_f.broken_barh(bars, (n - 1 - j - 0.4, 0.8), color=_line(j)['color'])
        ax_i.plot(*reduced(run.t_thrusters + _zoh_period(run), run.thruster_impulse[:, j]), **_line(j), label=name)
    ax_f.set_yticks(range(n), list(reversed(run.thruster_names)))
    ax_f.set_ylim(-0.6, n - 0.4)
    ax_f.set_ylabel('firing')
    ax_f.set_title('Thrusters: firings (top), cumulated impulse (middle), firings so far (bottom)')
    ax_i.set_ylabel('impulse (N·s)')
    add_legend(ax_i)
    count = np.cumsum(np.count_nonzero(run.thruster_on_time > 0.0, axis=1))
    step_plot(ax_n, run.t_thrusters, count, color='C4')
    ax_n.set_ylabel('firings (thruster-periods)')
    ax_n.yaxis.set_major_locator(MaxNLocator(integer=True))
    mark_faults((ax_f, ax_i, ax_n), c.events)
    m = c.metrics
    return fig, (f'Thruster firings (bars: on-time from each period\'s start), cumulated impulse per thruster (N·s) '
                 f'and the number of firings so far: {m.get("thruster_firings", 0)} firings, '
                 f'{m.get("thruster_impulse_Ns", float("nan")):.4g} N·s in all ({topics.THRUSTERS_STATE}).')


def _zoh_period(run) -> float:
    """The step length of the thruster series (impulses are at the step ends)."""
    t = run.t_thrusters
    return float(np.median(np.diff(t))) if t.size > 1 else 0.0


def reference_jumps(q_ref, threshold_deg: float = 1.0) -> np.ndarray:
    """Indices k where the reference steps by more than ``threshold_deg`` from sample k-1 to k."""
    if q_ref is None or len(q_ref) < 2:
        return np.zeros(0, dtype=int)
    step = np.abs(np.sum(q_ref[1:] * q_ref[:-1], axis=1)).clip(0.0, 1.0)
    return np.flatnonzero(np.degrees(2 * np.arccos(step)) > threshold_deg) + 1


def fig_phase(c: Context):
    qe, _, _ = c.errors
    qe = qe * np.where(qe[:, 3:4] < 0, -1.0, 1.0)  # the shortest-path sign (q4 >= 0)
    jumps = reference_jumps(c.q_ref)
    fig = Figure(figsize=(10.0, 4.6), layout='constrained')
    ax = fig.subplots()
    ax.grid(True, alpha=0.35)
    for i, a in enumerate(AXES):
        # the curve is broken where the reference steps (seed 000's slew target -> identity)
        t, x, y = reduced(c.run.t, qe[:, i], c.run.w[:, i])
        cut = np.searchsorted(t, c.run.t[jumps]) if t.size < c.run.t.size else jumps
        ax.plot(np.insert(x, cut, np.nan), np.insert(y, cut, np.nan), **LINE[a],
                label=fr'$q_{i + 1}$ vs $\omega_{a}$')
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
    add_legend(ax)
    return fig, ('Phase portraits: error quaternion component q_i (to the reference) vs body rate ω_i (rad/s), '
                 'i = 1..3' + (f'; the curves break where the reference steps ({len(jumps)}×).' if jumps.size else '.'))


# (file name, title, builder) of the generic figures (the controller status: .status_figure)
FIGURES = [
    ('attitude_error', 'Eigenaxis attitude error', fig_attitude_error),
    ('quaternion', 'Quaternion components', fig_quaternion),
    ('euler_213', '2-1-3 Euler angles', fig_euler),
    ('body_rates', 'Body rates', fig_body_rates),
    ('torque', 'Commanded vs applied torque', fig_torque),
    ('wheels', 'Wheel speeds and motor torques', fig_wheels),
    ('thrusters', 'Thruster firing', fig_thrusters),
    ('phase_portrait', 'Phase portraits', fig_phase),
]
