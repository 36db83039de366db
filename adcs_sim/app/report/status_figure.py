"""The controller-status figure: the values a controller publishes on ``controller/status``,
grouped so that the figure stays readable.

* text values (``mode``, ``phase``, ...) share one timeline panel, one lane per value of each
  key, named on the left with its share of the run, the spans where the key holds it coloured (a
  mode held one step in a thousand stays visible); a text key with more than
  :data:`MAX_TIMELINE_LEVELS` values (a message) is left out and named in the caption;
* ``<name>_x``, ``<name>_y``, ``<name>_z`` (and ``J_hat_11`` ... alike: one prefix) share a panel;
* other numeric values with the same unit share a panel, up to three;
* a value that never changes (``rejected_messages`` = 0 all along) is not drawn: the caption
  gives its value; nor the number of a text value (``mode_index`` beside ``mode``: for viewers);
* each panel's label carries the unit (:data:`STATUS_UNITS`; "unit not declared" otherwise).
"""
from __future__ import annotations

import re

import numpy as np
from matplotlib.ticker import MaxNLocator

from adcs_msgs_py import names as topics
from adcs_sim.app.report.figures import LINE, Context, add_legend, mark_faults, new_figure, step_plot
from adcs_sim.app.report.loading import status_series
from adcs_sim.app.analysis.status_records import TORQUE_KEYS

MAX_TIMELINE_LEVELS = 12
MAX_PER_PANEL = 3
# Units of the status values the project's controllers publish (key, or the prefix of a group).
STATUS_UNITS = {
    'demand_max': 'N·m', 'wheel_torque': 'N·m', 'u_cmd': 'N·m', 'd_hat': 'N·m',
    'wd': 'rad/s', 'w_gs': 'rad/s', 'w_des': 'rad/s', 'w_d': 'rad/s', 'w_err': 'rad/s', 'omega_bar': 'rad/s',
    'wd_dot': 'rad/s²', 'h': 'N·m·s', 'J_hat': 'kg·m²',
    'psi': 'rad', 'theta': 'rad', 'phi': 'rad', 'e': 'rad', 'pointing_error': 'rad', 'angle_deg': 'deg',
    'eta_err': 'dimensionless', 'q_vag': 'dimensionless', 'S': 'dimensionless', 'stage': 'index',
    'firing_now': 'count', 'firing_count': 'count', 'rejected_messages': 'count', 'late_faults': 'count',
    'V': 'Lyapunov fn., law units', 'V1': 'Lyapunov fn., law units', 'V2': 'Lyapunov fn., law units',
    'W': 'Lyapunov fn., law units', 'Vdot': 'dV/dt, law units', 'LgV_u': 'dV/dt, law units',
}
_AXIS = re.compile(r'^(?P<base>.+)_(?P<axis>[xyz]|\d\d|\d)$')


def _unit(key: str) -> str:
    name = key.rsplit('/', 1)[-1]
    return STATUS_UNITS.get(name) or STATUS_UNITS.get(name.rsplit('_', 1)[0], 'unit not declared')


def _comparable(a: float, b: float) -> bool:
    """Two scalars' largest magnitudes within a factor 10 (one would be flat next to the other)."""
    return max(a, b) <= 10.0 * min(a, b) if min(a, b) > 0 else a == b


def group_numeric(keys: list[str], scale: dict | None = None) -> list[tuple[str, list[str]]]:
    """(panel label, keys) panels: one per vector prefix (``wd_x/y/z``), then runs of at most
    :data:`MAX_PER_PANEL` scalars with the same unit and comparable magnitudes (``scale``: key ->
    max |value|), in the order the controller publishes them."""
    scale = scale or {}
    prefixes: dict[str, list[str]] = {}
    for k in keys:
        m = _AXIS.match(k)
        if m:
            prefixes.setdefault(m['base'], []).append(k)
    vectors = {base: ks for base, ks in prefixes.items() if len(ks) >= 2}
    in_vector = {k for ks in vectors.values() for k in ks}
    panels: list[tuple[str, list[str]]] = []
    for k in keys:
        base = _AXIS.match(k)['base'] if k in in_vector else None
        if base is not None:
            if vectors[base] and vectors[base][0] == k:
                panels.append((f'{base}_* ({_unit(base)})', vectors[base]))
            continue
        last = panels[-1] if panels else None
        if last and last[0].startswith('\x00') and _unit(last[1][0]) == _unit(k) and len(last[1]) < MAX_PER_PANEL \
                and _unit(k) != 'unit not declared' and _comparable(scale.get(last[1][0], 1.0), scale.get(k, 1.0)):
            last[1].append(k)
        else:
            panels.append(('\x00', [k]))
    return [(label if not label.startswith('\x00') else f'{", ".join(ks)} ({_unit(ks[0])})', ks)
            for label, ks in panels]


def _lanes(series: dict, text: list[str]) -> list[tuple[str, object]]:
    """(key, value) of each lane of the timeline panel, top to bottom: each text key's values in
    the order they first occur."""
    return [(key, value) for key in text for value in dict.fromkeys(series[key][1].tolist())]


def _timelines(ax, series: dict, text: list[str]) -> None:
    """One lane per value of each text key (its name and its share of the run on the left), the
    spans where the key holds that value drawn in the value's colour: a value held for one step
    among thousands of another (a law switching modes at every step) stays visible in its own
    lane instead of being painted over. Keys are separated by a line."""
    lanes = _lanes(series, text)
    row = len(lanes) - 1
    ticks, labels = [], []
    for colour, (key, value) in enumerate(lanes):
        t, v = series[key]
        t_end = float(t[-1])
        change = np.flatnonzero(v[1:] != v[:-1]) + 1
        starts, ends = np.r_[0, change], np.r_[change, len(v) - 1]
        held = [(float(t[a]), float(t[b]) - float(t[a])) for a, b in zip(starts, ends) if v[a] == value]
        span = max(t_end - float(t[0]), 1e-9)
        share = sum(d for _, d in held) / span
        # a span of one step is narrower than a pixel: an edge of the same colour keeps it drawn
        ax.broken_barh([(a, max(d, 1e-9 * max(abs(t_end), 1.0))) for a, d in held], (row - 0.35, 0.7),
                       facecolor=f'C{colour % 10}', edgecolor=f'C{colour % 10}', linewidth=0.6)
        ticks.append(row)
        labels.append(f'{key} = {value}  ({100 * share:.0f} %, {len(held)}×)')
        row -= 1
    first_of_key = [i for i, (key, _) in enumerate(lanes) if i and lanes[i - 1][0] != key]
    for i in first_of_key:
        ax.axhline(len(lanes) - i - 0.5, color='0.4', linewidth=0.8)
    ax.set_yticks(ticks, labels, fontsize='small')
    ax.set_ylim(-0.6, len(lanes) - 0.4)


def fig_controller_status(c: Context):
    series = {k: v for k, v in status_series(c.run).items() if k.rsplit('/', 1)[-1] not in TORQUE_KEYS}
    if not series:
        if c.run.controller_status:
            return 'the controller publishes no status values besides the commanded torque'
        return f'no controller status ({topics.CONTROLLER_STATUS})'
    text = [k for k, (_, v) in series.items() if v.dtype == object]
    chatty = {k: n for k in text if (n := len(set(series[k][1].tolist()))) > MAX_TIMELINE_LEVELS}
    text = [k for k in text if k not in chatty]
    constant_text = {k: series[k][1][0] for k in text if len(set(series[k][1].tolist())) == 1}
    text = [k for k in text if k not in constant_text]
    # ``mode_index`` / ``phase_index``: the number of a text value, for viewers that plot numbers only;
    # the timeline already shows the value by name
    named = {k for k, (_, v) in series.items() if v.dtype == object}
    numeric = [k for k, (_, v) in series.items() if v.dtype != object
               and not (k.endswith('_index') and k[:-len('_index')] in named)]
    constant = {k: series[k][1][0] for k in numeric
                if series[k][1].size and np.all(series[k][1] == series[k][1][0])}
    scale = {k: float(np.nanmax(np.abs(series[k][1]))) if np.isfinite(series[k][1]).any() else 0.0 for k in numeric}
    panels = group_numeric([k for k in numeric if k not in constant], scale)
    if not text and not panels:
        return ('the controller status has no value to plot: '
                + ', '.join([f'{k} constant ({v:g})' for k, v in constant.items()]
                            + [f'{k} constant ({v})' for k, v in constant_text.items()]
                            + [f'{k} ({n} distinct text values)' for k, n in chatty.items()]))
    ratios = ([0.3 + 0.16 * len(_lanes(series, text))] if text else []) + [1.0] * len(panels)
    fig, axes = new_figure(rows=len(ratios), height=1.7, width=10.0, ratios=ratios)
    numeric_axes = axes[len(axes) - len(panels):]
    if text:
        _timelines(axes[0], series, text)
    for ax, (label, keys) in zip(numeric_axes, panels):
        for i, key in enumerate(keys):
            t, v = series[key]
            style = dict(LINE['xyz'[i]]) if i < 3 else {'color': f'C{i}', 'linewidth': 1.4}
            step_plot(ax, t, v, **style, label=key.rsplit('/', 1)[-1] if len(keys) > 1 else None)
        unit = label.rsplit(' (', 1)[1].rstrip(')')
        ax.set_ylabel(unit, fontsize='small')
        ax.set_title(label.rsplit(' (', 1)[0], fontsize='small', loc='left')
        if unit in ('index', 'count'):   # a stage 1 -> 2 has no tick at 1.25
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    # the fault markers' legend on the first numeric panel (the timeline's legend names its values)
    mark_faults(axes[:len(axes) - len(panels)], c.events, legend=not panels)
    mark_faults(numeric_axes, c.events)
    for ax in axes:
        add_legend(ax)
    fig.suptitle(f'Controller status ({topics.CONTROLLER_STATUS}; u_x, u_y, u_z: torque figure)', fontsize='medium')
    notes = []
    if constant or constant_text:
        notes.append('constant over the run (not drawn): ' + ', '.join(
            [f'`{k}` = {v:g}' for k, v in constant.items()] + [f'`{k}` = {v}' for k, v in constant_text.items()]))
    if chatty:
        notes.append(f'not drawn (more than {MAX_TIMELINE_LEVELS} distinct text values): '
                     + ', '.join(f'`{k}` ({n})' for k, n in chatty.items()))
    return fig, (f'Controller status values on `{topics.CONTROLLER_STATUS}`: '
                 + ('timelines of ' + ', '.join(f'`{k}`' for k in text) + ' (top); ' if text else '')
                 + '; '.join(', '.join(f'`{k}`' for k in keys) + f' ({label.rsplit(" (", 1)[1]}'
                             for label, keys in panels)
                 + '. The commanded torque u_x, u_y, u_z is in the torque figure.'
                 + ''.join(f' {n[0].upper()}{n[1:]}.' for n in notes))
