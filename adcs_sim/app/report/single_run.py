"""The report of one run: ``report.md`` and its figures (:func:`write_report`).

Drawing the figures is most of a report's time (matplotlib's layout and rasterising, about a
second per figure and format). ``jobs > 1`` draws them in that many forked processes (each draws
whole figures of :data:`FIGURES` and writes their files; the report is the same): what
``adcs-run --report`` does, as a process with no ROS context left open by then. A library caller
keeps the default, one process (forking a process whose other threads hold locks is not safe).
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis import attitude_errors, run_metrics
from adcs_sim.app.report.figures import FIGURES, Context, save_figure
from adcs_sim.app.report.loading import Run, fault_events, missing_topics
from adcs_sim.app.report.markdown import fmt, md_escape, metric_note
from adcs_sim.bag.reader import read_metadata


def write_report(run: Run, out, tol_deg: float = 0.5, eigen_tol_deg: float | None = None, jobs: int = 1) -> Path:
    """Write ``report.md`` and the figures of one run into ``out``; return the report's path.
    ``jobs``: processes drawing the figures (module docstring)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = run.data
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    events = fault_events(data)
    metrics = run_metrics(data, tol_deg, eigen_tol_deg)
    ctx = Context(data, events, tol_deg, eigen_tol_deg, metrics, attitude_errors(data))
    lines = (_recording_lines(run) + _topic_lines(run) + _fault_lines(events) + _scenario_lines(run)
             + _metric_lines(metrics) + _figure_lines(ctx, out, jobs))
    path = out / 'report.md'
    path.write_text('\n'.join(lines))
    return path


def _recording_lines(run: Run) -> list[str]:
    """The title and how the bag was read: complete, truncated or damaged (and where)."""
    data = run.data
    lines = [f'# Run report: {run.name}', '', '| | |', '| --- | --- |',
             f'| bag | `{run.path}` |']
    if run.complete:
        lines.append(f'| recording | complete ({run.message_count} messages) |')
    elif data.damaged:
        lines.append(f'| recording | **damaged file**: {md_escape(data.problem)}; {run.message_count} intact '
                     'messages before the damage read |')
    else:
        lines.append(f'| recording | **recovered from a truncated file** (no MCAP summary: the recorder did '
                     f'not close the bag); {run.message_count} messages recovered |')
    lines += [f'| simulated time | {data.t[0]:g} s to {data.t_end:g} s ({data.t.size} state samples) |',
              f'| attitude | {"true state (truth/state)" if data.topic_counts.get(topics.TRUTH_STATE) else "state"} |',
              '']
    if not run.complete:
        what = 'the intact part of a damaged file' if data.damaged else 'a truncated file'
        lines += [f'> Recovered from {what}: {run.message_count} messages recovered, '
                  f'up to t = {data.t_end:g} s ({md_escape(data.problem or "")}). Metrics and figures cover '
                  'the recovered part only (`missed_steps`: the last count published before the cut).', '']
    return lines


def _topic_lines(run: Run) -> list[str]:
    """The topics in the bag with their message counts, and the graph's topics it lacks."""
    lines = ['## Topics', '', '| topic | messages |', '| --- | --- |']
    lines += [f'| `{t}` | {n} |' for t, n in sorted(run.data.topic_counts.items())]
    lines.append('')
    missing = missing_topics(run.data)
    if missing:
        lines += ['**Missing topics** (no messages in the bag): '
                  + ', '.join(f'`{t}`' for t in missing)
                  + '. Figures and metrics that need them are skipped or n/a.', '']
    else:
        lines += ['Missing topics: none.', '']
    return lines


def _fault_lines(events: list) -> list[str]:
    lines = ['## Faults', '']
    if events:
        lines += [f'- fault at t = {t:g} s: `{name}`' + (f': {md_escape(msg)}' if msg else '')
                  for t, name, msg in events]
        lines += ['', 'Each fault is marked by a red dashed line on the time plots.', '']
    else:
        lines += [f'No fault events (no ERROR status on `{topics.FAULTS}`).', '']
    return lines


def _scenario_lines(run: Run) -> list[str]:
    """The scenario as embedded in the bag (MCAP metadata), in a YAML code block."""
    lines = ['## Scenario', '']
    scenario_text = read_metadata(run.path).get('scenario') if run.data.scenario is not None else None
    if scenario_text:
        fence = '~~~~' if '```' in scenario_text else '```'
        lines += ['As embedded in the bag (MCAP metadata `scenario`):', '', fence + 'yaml', scenario_text.rstrip('\n'),
                  fence, '']
    else:
        lines += ['The bag carries no scenario (no MCAP metadata record `scenario`).', '']
    return lines


def _metric_lines(metrics: dict) -> list[str]:
    lines = ['## Metrics', '', 'Definitions: `adcs_sim/app/analysis.py`.', '',
             '| metric | value | meaning |', '| --- | --- | --- |']
    lines += [f'| `{k}` | {fmt(v)} | {md_escape(metric_note(k))} |' for k, v in metrics.items()]
    lines.append('')
    return lines


_FORKED: tuple | None = None  # (Context, out): what the forked drawing processes inherit


def _draw(index: int, ctx: Context | None = None, out: Path | None = None) -> tuple[bool, str]:
    """Draw and save figure ``index`` of :data:`FIGURES`: (True, its caption), or (False, why it
    is skipped). In a forked process the context is the inherited :data:`_FORKED`."""
    if ctx is None:
        ctx, out = _FORKED
    name, _, builder = FIGURES[index]
    result = builder(ctx)
    if isinstance(result, str):
        return False, result
    fig, caption = result
    save_figure(fig, out, name)
    return True, caption


def _figure_lines(ctx: Context, out: Path, jobs: int = 1) -> list[str]:
    """Draw and save each figure of :data:`FIGURES` the run has data for (in ``jobs`` forked
    processes if > 1); the section that shows them (or says why one is skipped)."""
    global _FORKED
    if jobs > 1:
        _FORKED = (ctx, out)
        try:
            with ProcessPoolExecutor(min(jobs, len(FIGURES)), mp_context=multiprocessing.get_context('fork')) as pool:
                results = list(pool.map(_draw, range(len(FIGURES))))
        finally:
            _FORKED = None
    else:
        results = [_draw(i, ctx, out) for i in range(len(FIGURES))]
    lines = ['## Figures', '']
    for (name, title, _), (drawn, text) in zip(FIGURES, results):
        lines += [f'### {title}', '']
        if not drawn:
            lines += [f'Skipped: {text}.', '']
            continue
        lines += [f'![{title}]({name}.png)', '', f'{text} ([SVG]({name}.svg))', '']
    return lines
