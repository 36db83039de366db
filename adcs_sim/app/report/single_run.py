"""The report of one run: ``report.md`` and its figures (:func:`write_report`).

The layout is :data:`SECTIONS`, in order: how the bag was read; what kind of run it is and the
quantities, metrics and figures its paper shows (:mod:`.kinds`, :mod:`.lead`,
:mod:`.kind_figures`), with the paper's values beside ours; the sections other modules add
(:data:`EXTRA_SECTIONS`, :func:`register_section`: e.g. estimation errors); the topics, faults,
every metric, the other figures and the scenario.
"""
from __future__ import annotations

import gc
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis.metrics import attitude_errors, run_metrics
from adcs_sim.app.report.estimation import estimation_lines
from adcs_sim.app.report.figures import FIGURES, Context, save_figure
from adcs_sim.app.report.kind_figures import LEAD_FIGURES
from adcs_sim.app.report.kinds import UNKNOWN, phases, reference_attitude, run_kind
from adcs_sim.app.report.lead import actuator_fault, lead_metrics, paper_values, with_paper
from adcs_sim.app.report.loading import Run, fault_events, has_wheels, missing_topics
from adcs_sim.app.report.markdown import fmt, md_escape, metric_note
from adcs_sim.app.report.status_figure import fig_controller_status
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.bag.reader import read_metadata

# Rest-to-rest metrics: not shown for a spin or a pointing run (the attitude is not regulated to a
# fixed quaternion there: their "error" grows by design).
REST_TO_REST = ('settling_eigenaxis', 'settling_euler213', 'final_eigenaxis_error_deg')
# Generic figures that mean nothing for a kind, with the reason.
NOT_FOR_KIND = {
    'spin': ({'attitude_error', 'euler_213', 'phase_portrait'},
             'a spin run is not brought to a fixed attitude: its attitude error is in the spin figure above'),
    'pointing': ({'attitude_error', 'euler_213', 'phase_portrait'},
                 'a pointing run leaves the rotation about σ̂ free: its error is the pointing error above'),
}
# The generic figures shown above, in the lead section, for a kind.
IN_LEAD = {'regulation': {'attitude_error'}, 'tracking': {'attitude_error'}}


@dataclass
class Report:
    """What the sections of one report share."""

    run: Run
    out: Path
    ctx: Context
    source: str          # where the paper's values come from ('' without any)


# A section: (name, builder(Report) -> Markdown lines). A builder draws its figures with
# draw_figures(report, [(file name, title, builder(Context) -> (Figure, caption) or why-skipped str)]).
Section = tuple[str, Callable[[Report], list]]
# Sections added by other modules (shown after the kind's lead section), in registration order:
# e.g. the estimation errors (adcs_sim/app/report/estimation.py, a builder of its own added here
# or with register_section at its import).
EXTRA_SECTIONS: list[Section] = []


def register_section(name: str, builder: Callable[[Report], list]) -> None:
    """Add a section to every report (after the lead section); a name registered again replaces."""
    EXTRA_SECTIONS[:] = [s for s in EXTRA_SECTIONS if s[0] != name] + [(name, builder)]


def build_context(data: RunData, name: str, tol_deg: float, eigen_tol_deg: float,
                  long=None) -> tuple[Context, str]:
    """What the figures and sections of run ``name`` need (its kind, reference, phases, lead metrics
    with the paper's values) and where the paper's values come from ('' without any). ``long``: the
    whole-run numbers of a streamed long run (``data`` then holds the samples drawn: long_run)."""
    kind = run_kind(data.scenario)
    q_ref, ref_text = reference_attitude(data, kind)
    source, published = paper_values(name)
    lead = with_paper(lead_metrics(data, kind, q_ref, long.rows if long is not None else None), published)
    metrics = long.metrics if long is not None else run_metrics(data, tol_deg, eigen_tol_deg)
    ctx = Context(data, fault_events(data), tol_deg, eigen_tol_deg, metrics,
                  attitude_errors(data, q_ref), kind, q_ref, ref_text, phases(data, kind), lead,
                  long.settled if long is not None else {})
    return ctx, source


def write_report(run: Run, out, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> Path:
    """Write ``report.md`` and the figures of one run into ``out``; return the report's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    if run.long is not None:
        run.metrics(tol_deg, eigen_tol_deg)   # (a long run streamed at other tolerances: again at these)
    ctx, source = build_context(run.data, run.name, tol_deg, eigen_tol_deg, run.long)
    report = Report(run, out, ctx, source)
    lines = []
    for _, builder in SECTIONS[:2] + EXTRA_SECTIONS + SECTIONS[2:]:
        lines += builder(report)
    path = out / 'report.md'
    path.write_text('\n'.join(lines))
    return path


def _recording_lines(report: Report) -> list[str]:
    """The title and how the bag was read: complete, truncated or damaged (and where)."""
    run = report.run
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
    lines += [f'| simulated time | {data.t[0]:g} s to {data.t_end:g} s ({run.samples} state samples) |',
              f'| attitude | {"true state (truth/state)" if data.topic_counts.get(topics.TRUTH_STATE) else "state"} |',
              '']
    if not run.complete:
        what = 'the intact part of a damaged file' if data.damaged else 'a truncated file'
        lines += [f'> Recovered from {what}: {run.message_count} messages recovered, '
                  f'up to t = {data.t_end:g} s ({md_escape(data.problem or "")}). Metrics and figures cover '
                  'the recovered part only (`missed_steps`: the last count published before the cut).', '']
    return lines


def _topic_lines(report: Report) -> list[str]:
    """The topics in the bag with their message counts, and the graph's topics it lacks."""
    run = report.run
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


def _fault_lines(report: Report) -> list[str]:
    events = report.ctx.events
    lines = ['## Faults', '']
    if events:
        lines += [f'- fault at t = {t:g} s: `{name}`' + (f': {md_escape(msg)}' if msg else '')
                  for t, name, msg in events]
        lines += ['', 'Each fault is marked by a red dashed line on the time plots.', '']
    else:
        lines += [f'No fault events (no ERROR status on `{topics.FAULTS}`).', '']
    return lines


def _scenario_lines(report: Report) -> list[str]:
    """The scenario as embedded in the bag (MCAP metadata), in a YAML code block."""
    run = report.run
    lines = ['## Scenario', '']
    scenario_text = read_metadata(run.path).get('scenario') if run.data.scenario is not None else None
    if scenario_text:
        fence = '~~~~' if '```' in scenario_text else '```'
        lines += ['As embedded in the bag (MCAP metadata `scenario`):', '', fence + 'yaml', scenario_text.rstrip('\n'),
                  fence, '']
    else:
        lines += ['The bag carries no scenario (no MCAP metadata record `scenario`).', '']
    return lines


def _lead_lines(report: Report) -> list[str]:
    """What kind of run this is, its reference and phases, its own metrics (the paper's beside
    ours) and its figures: the section the report leads with."""
    ctx = report.ctx
    kind = ctx.kind
    lines = [f'## What this run is: {kind.kind}', '', '| | |', '| --- | --- |',
             f'| kind | **{kind.kind}**: {md_escape(kind.description)} |',
             f'| determined from | {md_escape(kind.why)} |']
    if kind.kind != UNKNOWN:
        lines.append(f'| reference | {md_escape(ctx.reference_text)} |')
    if ctx.phases:
        lines.append('| phases | ' + '; '.join(f'{t0:g}–{t1:g} s: {md_escape(label)}' for t0, t1, label in ctx.phases)
                     + ' |')
    if ctx.events:
        lines.append('| faults | ' + '; '.join(f'`{name}` at t = {t:g} s' for t, name, _ in ctx.events) + ' |')
    lines.append('')
    lines += findings(ctx)
    if kind.kind == UNKNOWN:
        return lines + ['The report cannot tell what this run is meant to do, so it leads with nothing: the '
                        'generic metrics and figures below measure the attitude against the scenario\'s '
                        '`target.attitude` (or the identity) as a rest-to-rest run would. Read them with care.', '']
    lines += ['### Its quantities', '']
    if report.source:
        lines += [f'Paper: {md_escape(report.source)}. Difference: (ours − paper) / |paper|.', '']
    elif kind.kind == 'pointing':
        lines += ['The paper gives no number for this single run (Fig. 4-8); Table 1 is over 1000 random '
                  'initial conditions (docs/seed003.md).', '']
    else:
        lines += ['No published value for this run (no `docs/seed*/paper.yaml` entry for '
                  f'`{md_escape(report.run.name)}`).', '']
    lines += ['| metric | ours | paper | difference | unit | meaning |', '| --- | ---: | ---: | ---: | --- | --- |']
    for m in ctx.lead:
        diff = m.difference
        lines.append(f'| `{m.key}` | {fmt(m.value)} | {fmt(m.paper) if m.paper is not None else "–"} | '
                     + ('–' if math.isnan(diff) else f'{100 * diff:+.1f} %') + f' | {m.unit} | {md_escape(m.meaning)} |')
    return lines + [''] + ['### Its figures', ''] + draw_figures(report, lead_figures(ctx), level='####')


def findings(ctx: Context) -> list[str]:
    """What a reader must not miss, whatever the kind of run, said before its quantities: each
    wheel that spent time at its speed limit (``wheel_time_at_speed_limit_s`` > 0: there its motor
    torque is cut, so the applied torque is not the commanded one)."""
    at_limit = ctx.metrics.get(AT_SPEED_LIMIT) or []
    names = ctx.run.wheel_names
    limits = metric_defs.run_context(ctx.run)['wheel_max_speed'][0] if names else []
    found = [f'**wheel `{name}` at its speed limit** ({limit:g} rad/s, `wheels.max_speed`) for {fmt(s, 4)} s '
             f'of the run: its motor torque is cut there, so the applied torque is not the commanded one '
             f'(`{AT_SPEED_LIMIT}`)'
             for name, limit, s in zip(names, limits, at_limit) if isinstance(s, (int, float)) and s > 0]
    return ['> Findings: ' + '; '.join(found) + '.', ''] if found else []


def lead_figures(ctx: Context) -> list:
    """(file name, title, builder) of the figures the kind of run leads with."""
    kind = ctx.kind.kind
    after_fault = kind == 'regulation' and actuator_fault(ctx.run, ctx.kind)
    return LEAD_FIGURES.get('regulation_after_fault' if after_fault else kind, [])


def other_figures(ctx: Context) -> list:
    """(file name, title, builder) of the generic figures that mean something for the kind of run
    and are not in its lead section."""
    skip = NOT_FOR_KIND.get(ctx.kind.kind, (set(), ''))[0] | IN_LEAD.get(ctx.kind.kind, set())
    return [f for f in FIGURES + [('controller_status', 'Controller status', fig_controller_status)]
            if f[0] not in skip]


def run_figures(data: RunData, name: str = '', tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
    """``{file name: Figure}`` of every figure a report of the run draws (those it has data for)."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    ctx, _ = build_context(data, name, tol_deg, eigen_tol_deg)
    drawn = {fname: builder(ctx) for fname, _, builder in lead_figures(ctx) + other_figures(ctx)}
    return {fname: d[0] for fname, d in drawn.items() if not isinstance(d, str)}


WHEEL_METRICS = {m.name for m in metric_defs.DEFINED if 'wheel_speed' in m.needs}
AT_SPEED_LIMIT = metric_defs.TimeAtWheelSpeedLimit.name


def _metric_lines(report: Report) -> list[str]:
    """Every metric of :func:`run_metrics` that means something for the run, with its meaning."""
    metrics, kind = report.ctx.metrics, report.ctx.kind.kind
    shown, left = {}, []
    for k, v in metrics.items():
        if kind in ('spin', 'pointing') and k.startswith(REST_TO_REST):
            left.append(f'`{k}` (rest to rest: not meaningful for a {kind} run)')
        elif k.startswith('settling_q4_') and kind != 'regulation':
            left.append(f'`{k}` (seed 000\'s 1 − |q4| to a fixed target: not meaningful for a {kind} run)')
        elif k.startswith('settling_q4_') and not actuator_fault(report.run.data, report.ctx.kind):
            left.append(f'`{k}` (seed 000\'s settling after a wheel fault: the fault here is not on an actuator)')
        elif k in WHEEL_METRICS and not has_wheels(report.run.data.scenario):
            left.append(f'`{k}` (the spacecraft has no reaction wheels)')
        else:
            shown[k] = v
    lines = ['## All metrics', '', 'Definitions: `adcs_sim/app/analysis/metrics.py`; the same numbers as '
             '`adcs-analyze` prints (the attitude error against the scenario\'s `target.attitude`).', '',
             '| metric | value | meaning |', '| --- | --- | --- |']
    lines += [f'| `{k}` | {fmt(v)} | {md_escape(metric_note(k))} |' for k, v in shown.items()]
    lines.append('')
    if left:
        lines += ['Not shown: ' + '; '.join(left) + '.', '']
    return lines


def draw_figures(report: Report, figures, level: str = '###') -> list[str]:
    """Draw and save each figure (file name, title, builder); its Markdown, or why it is skipped."""
    lines = []
    for name, title, builder in figures:
        result = builder(report.ctx)
        lines += [f'{level} {title}', '']
        if isinstance(result, str):
            lines += [f'Skipped: {result}.', '']
            continue
        fig, caption = result
        save_figure(fig, report.out, name)
        lines += [f'![{title}]({name}.png)', '', f'{caption} ([SVG]({name}.svg))', '']
        del fig, result
        if report.run.long is not None:   # a long run's report, within its memory bound: a figure (and
            gc.collect()                  # its renderer) is a cycle, freed now rather than beside the next
    return lines


def _figure_lines(report: Report) -> list[str]:
    """The generic figures the run has data for (those that mean nothing for its kind left out, said so)."""
    skip, why = NOT_FOR_KIND.get(report.ctx.kind.kind, (set(), ''))
    lines = ['## Other figures', '']
    if skip:
        lines += [f'Not drawn: {", ".join(f"`{n}`" for n in sorted(skip))} ({why}).', '']
    return lines + draw_figures(report, other_figures(report.ctx))


# The layout of a report, in order; EXTRA_SECTIONS go after the first two (recording, lead).
SECTIONS: list[Section] = [('recording', _recording_lines), ('lead', _lead_lines), ('topics', _topic_lines),
                           ('faults', _fault_lines), ('metrics', _metric_lines), ('figures', _figure_lines),
                           ('scenario', _scenario_lines)]

# The estimation section (a run with an estimator): after the lead.
register_section('estimation', estimation_lines)
