"""The comparison of several runs: ``comparison.csv``, ``comparison.md``, overlaid figures and,
with published figures (:func:`load_reference`), a published-vs-ours table
(:func:`write_comparison`)."""
from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import numpy as np

from adcs_msgs_py.params_file import YamlError, load_yaml
from adcs_sim.app.analysis.metrics import attitude_errors
from adcs_sim.app.report.envelope import reduced
from adcs_sim.app.report.figures import add_legend, log_positive, new_figure, save_figure, step_plot
from adcs_sim.app.report.kinds import reference_attitude, run_kind
from adcs_sim.app.report.lead import comparison_rows, lead_metrics  # defined in .lead (no matplotlib there)
from adcs_sim.app.report.loading import Run, fault_events, missing_topics
from adcs_sim.app.report.markdown import METRIC_NOTES, fmt, md_escape, metric_note

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
    return metric_note(key, COMPARISON_NOTES)


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
    try:
        tree = load_yaml(path)
    except YamlError as exc:
        raise ValueError(f'cannot read reference figures: {exc}') from None
    if not isinstance(tree, dict) or not isinstance(tree.get('runs'), dict):
        raise ValueError(f'{path}: expected `source:` and `runs: {{<run name>: {{<metric>: value}}}}`')
    for name, values in tree['runs'].items():
        if not isinstance(values, dict) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values.values()):
            raise ValueError(f'{path}: runs.{name}: expected a mapping of metric names to numbers')
    return tree


def kind_rows(run: Run) -> dict:
    """The metrics the run's report leads with (:func:`.lead.lead_metrics`, by run kind: e.g. seed 000's q4
    settling after the fault, seed 001's steady spin torque, seed 002's tracking settling), ``{key: value}``:
    published figures that are not comparison rows are compared with these."""
    kind = run_kind(run.data.scenario)
    q_ref, _ = reference_attitude(run.data, kind)
    return {m.key: m.value for m in lead_metrics(run.data, kind, q_ref)}


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
        how = 'complete' if r.complete else (f'recovered from a {"damaged" if r.data.damaged else "truncated"} '
                                             f'file ({r.message_count} messages)')
        miss = missing_topics(r.data)
        how += f'; missing topics: {", ".join(miss)}' if miss else ''
        lines.append(f'| {md_escape(name)} | `{r.path}` | {how} |')
    lines += ['', '## Metrics', '', 'Values as in `comparison.csv`; inf: not settled by the end of the run; '
              'n/a: not available in that run.', '',
              '| metric | ' + ' | '.join(md_escape(n) for n in names) + ' | meaning |',
              '| --- | ' + ' | '.join('---' for _ in names) + ' | --- |']
    for k in keys:
        lines.append(f'| `{k}` | ' + ' | '.join(fmt(row[k]) for row in table)
                     + f' | {md_escape(_note_cmp(k))} |')
    if reference is not None:
        rows = [{**row, **kind_rows(r)} if name in reference['runs'] else row
                for name, r, row in zip(names, runs, table)]
        published = reference_rows(names, rows, reference)
        with open(out / 'reference_comparison.csv', 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(['run', 'metric', 'published', 'ours', 'relative_difference'])
            w.writerows([r[:3] + (_csv_value(r[3]), _csv_value(r[4])) for r in published])
        lines += ['', '## Published figures vs ours', '', md_escape(str(reference.get('source', ''))), '',
                  '| run | metric | published | ours | difference |', '| --- | --- | ---: | ---: | ---: |']
        for name, key, pub, ours, diff in published:
            lines.append(f'| {md_escape(name)} | `{key}` | {fmt(pub)} | {fmt(ours)} | '
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

    fig, (ax,) = new_figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        _, eigen, _ = attitude_errors(r.data)
        ax.plot(*reduced(r.data.t, log_positive(eigen)), **style(i), label=name)
        faults(ax, i, name, r)
    ax.set_yscale('log')
    ax.axhline(eigen_tol_deg, color='0.3', linestyle=':', label=f'tolerance {eigen_tol_deg:g}°')
    ax.set_ylabel('eigenaxis error (deg, log scale)')
    ax.set_title('Eigenaxis attitude error')
    add_legend(ax)
    yield 'compare_attitude_error', 'Eigenaxis attitude error', \
        ('Eigenaxis attitude error (deg, log scale), one line per run (an exactly zero error is not drawn on '
         'the log scale); dotted verticals: fault events, in the colour of their run.'), fig

    fig, (ax,) = new_figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        if r.data.u.size:
            step_plot(ax, r.data.t_u, 1e3 * np.linalg.norm(r.data.u, axis=1), r.data.t_end, **style(i), label=name)
        else:
            ax.plot([], [], **style(i), label=f'{name} (no applied torque recorded)')
        faults(ax, i, name, r)
    ax.set_ylabel('‖u‖ (mN·m)')
    ax.set_title('Applied control torque norm')
    add_legend(ax)
    yield 'compare_torque_norm', 'Torque norm', 'Norm of the applied body torque ‖u‖ (mN·m), one line per run.', fig

    fig, (ax,) = new_figure(height=3.6)
    for i, (name, r) in enumerate(zip(names, runs)):
        if r.data.wheel_speed.size:
            ax.plot(*reduced(r.data.t_wheels, np.linalg.norm(r.data.wheel_speed, axis=1)), **style(i), label=name)
        else:
            ax.plot([], [], **style(i), label=f'{name} (no wheel states recorded)')
        faults(ax, i, name, r)
    ax.set_ylabel('‖Ω‖ (rad/s)')
    ax.set_title('Wheel speed norm (all wheels, relative to the body)')
    add_legend(ax)
    yield 'compare_wheel_speed_norm', 'Wheel speed norm', \
        'Euclidean norm of the wheel speeds ‖Ω‖ (rad/s), one line per run.', fig
