"""The time each wheel spends at its speed limit: one definition (adcs_sim/app/analysis/metric_defs.py), the
same value from every metric path.

* closed form: a synthetic wheel history with a known time at the limit (the rule's edge
  ``|Ω| = max_speed (1 - EPS)`` counts, just below does not; a negative speed; an unlimited wheel;
  the last sample counts nothing; uneven steps);
* the reduction is associative: any split into chunks, driven by ``update`` or by ``merge``,
  gives the whole run's integers;
* the in-memory path (run_metrics), the streamed path (analyse_bag, in small batches), the long
  report (load_long) and the campaign (batch_run_metrics, batch_metric_columns, run_chunk) each
  equal the definition run on the whole arrays, on runs that do reach their limit.
"""
from __future__ import annotations

import math

import numpy as np
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_sim.app.analysis import metric_defs
from adcs_sim.app.analysis.metrics import run_metrics
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.analysis.batch_metrics import batch_metric_columns, batch_run_metrics, metric_columns
from adcs_sim.app.campaign.plan import Campaign, run_chunk
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.report import envelope, long_run
from adcs_sim.app.report.markdown import metric_note
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.app.scenario.files import validate_scenario
from adcs_sim.app.analysis.stream_metrics import analyse_bag

NAME = 'wheel_time_at_speed_limit_s'
METRIC = next(m for m in metric_defs.DEFINED if m.name == NAME)
EPS = METRIC.EPS
ESEO = ROOT / 'bags' / 'eseo_backstepping_slew' / 'bag'   # its pitch wheel reaches 527.26 rad/s


def definition(t_s, speed, limits) -> list:
    """The definition on a run's whole arrays: one chunk of one run."""
    m = METRIC
    state = m.update(m.init({'wheel_max_speed': np.asarray(limits, float)[None]}),
                     {'t_s': np.asarray(t_s, float), 'wheel_speed': np.asarray(speed, float)[None]})
    return m.finish(state)[0].tolist()


def synthetic_run(t, speed, limits) -> RunData:
    n = len(t)
    return RunData(t=t, q=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), w=np.zeros((n, 3)), t_wheels=t,
                   wheel_names=[f'w{i}' for i in range(speed.shape[1])], wheel_speed=speed,
                   wheel_max_speed=np.asarray(limits, float))


def test_closed_form_time_at_the_limit():
    limit = 100.0
    edge = limit * (1 - EPS)
    t = np.array([0.0, 0.5, 1.0, 2.0, 2.25, 3.0, 4.0])        # steps 0.5, 0.5, 1, 0.25, 0.75, 1
    speed = np.array([
        [0.0, edge, 150.0, np.nextafter(edge, 0.0), 100.0, 99.0, 100.0],   # at: [0.5, 1) 0.5, [1, 2) 1, [2.25, 3) 0.75
        [-100.0, -100.0, -99.95, 0.0, -120.0, -120.0, -120.0],           # [0, 1) 1, [1, 2) 1 (0.05 % below), [2.25, 4) 1.75
        [1e9, 1e9, 1e9, 1e9, 1e9, 1e9, 1e9],                            # unlimited
    ]).T
    limits = [limit, limit, math.inf]
    expected = [0.5 + 1.0 + 0.75, 1.0 + 1.0 + 1.75, 0.0]
    run = synthetic_run(t, speed, limits)
    assert run_metrics(run)[NAME] == expected
    assert definition(t, speed, limits) == expected
    # the last sample counts nothing: the same history cut before its last sample loses [3, 4)
    assert definition(t[:-1], speed[:-1], limits) == [2.25, 1.0 + 1.0 + 0.75, 0.0]
    # a sample followed by a non-finite one (a batch run's end) counts nothing either
    cut = speed.copy()
    cut[-1] = np.nan
    assert definition(t, cut, limits) == [2.25, 2.75, 0.0]


def test_limits_come_from_the_dynamics_section_by_wheel_name():
    scenario = {'pd_controller': {'ros__parameters': {'wheels': {'names': ['a', 'b'], 'max_speed': [1.0, 1.0]}}},
                '/sat1/dynamics': {'ros__parameters': {'wheels': {'names': ['b', 'a', 'c'],
                                                                 'max_speed': [20.0, 10.0]}}}}
    assert metric_defs.wheel_limits(scenario, ['a', 'b', 'c', 'd']).tolist() == [10.0, 20.0, math.inf, math.inf]
    assert metric_defs.wheel_limits(None, ['a']).tolist() == [math.inf]


@settings(derandomize=True, max_examples=40, deadline=None)
@given(st.lists(st.sampled_from([0.0, 9.0, 9.99, 10.0, -10.5, np.nan]), min_size=2, max_size=40),
       st.lists(st.integers(1, 39), max_size=5), st.integers(2, 3))
def test_any_chunking_or_merge_gives_the_whole_runs_value(values, cuts, runs):
    n = len(values)
    t = np.cumsum(np.r_[0.0, np.arange(1, n) % 3 + 1.0]) * 0.1
    speed = np.stack([np.roll(values, r) for r in range(runs)])[:, :, None] * np.array([1.0, -1.0])   # (runs, n, 2)
    limits = np.full((runs, 2), 10.0)
    m = METRIC
    whole = m.finish(m.update(m.init({'wheel_max_speed': limits}), {'t_s': t, 'wheel_speed': speed}))
    bounds = [0, *sorted({c for c in cuts if c < n}), n]
    chunks = [{'t_s': t[a:b], 'wheel_speed': speed[:, a:b]} for a, b in zip(bounds, bounds[1:])]
    fed = m.init({'wheel_max_speed': limits})
    for c in chunks:
        fed = m.update(fed, c)
    merged = m.init({'wheel_max_speed': limits})
    for c in chunks:
        merged = m.merge(merged, m.update(m.init({'wheel_max_speed': limits}), c))
    assert m.finish(fed).tolist() == whole.tolist() == m.finish(merged).tolist()
    assert whole.tolist() == [definition(t, speed[r], limits[r]) for r in range(runs)]


def test_streamed_and_in_memory_equal_the_definition_on_a_run_at_its_limit():
    run = RunData.from_bag(ESEO)
    expected = definition(run.t_wheels, run.wheel_speed, metric_defs.wheel_limits(run.scenario, run.wheel_names))
    assert expected[0] > 10.0            # the backstepping slew's pitch wheel is pressed at its limit
    assert run_metrics(run)[NAME] == expected
    for batch_bytes in (4 << 10, 64 << 10):   # many chunks
        streamed = analyse_bag(ESEO, batch_bytes=batch_bytes)
        assert streamed.streamed and streamed.metrics[NAME] == expected


def test_the_long_report_equals_the_definition(monkeypatch):
    """The 24 h report's streamed passes (long_run) on a regulation run with wheels."""
    bag = ROOT / 'bags' / 'microsat_gsmn_slew' / 'bag'
    monkeypatch.setattr(envelope, 'MAX_POINTS', 1500)
    run = RunData.from_bag(bag)
    # the definition with a limit the run's wheels do reach (the scenario's own is never reached)
    limits = np.full(3, np.abs(run.wheel_speed).max() * 0.9)
    monkeypatch.setattr(metric_defs, 'wheel_limits', lambda scenario, names: limits)
    expected = definition(run.t_wheels, run.wheel_speed, limits)
    assert max(expected) > 0.0
    _, summary = long_run.load_long(bag, batch_bytes=64 << 10)
    assert summary.metrics[NAME] == expected == run_metrics(run)[NAME]
    assert metric_note(NAME) == METRIC.note


def low_limit_batch(tmp_path, limits_per_run: list) -> BatchSimulation:
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 300.0}})
    nominal = validate_scenario(scenario)
    runs = []
    for limits in limits_per_run:
        given_ = {name: {**params, **({'wheels.max_speed': limits} if name == 'dynamics' else {})}
                  for name, params in nominal.items()}
        runs.append({name: NODES[name].schema.validate(p) for name, p in given_.items()})
    return BatchSimulation.from_runs(runs)


def test_the_campaign_paths_equal_the_definition(tmp_path):
    limits = [[2.0, 2.0, 2.0], [1.0, 3.0, math.inf], [628.3, 628.3, 628.3]]
    result = low_limit_batch(tmp_path, limits).run()
    expected = [definition(result.t, result.wheel_speed[j], limits[j]) for j in range(result.n_runs)]
    assert max(expected[0]) > 0.0 and max(expected[1]) > 0.0 and expected[2] == [0.0] * 3
    rows = batch_run_metrics(result)
    assert [r[NAME] for r in rows] == expected == [result.metrics(j)[NAME] for j in range(result.n_runs)]
    columns = batch_metric_columns(result)
    assert columns == [metric_columns(r) for r in rows]
    assert [[c[f'{NAME}[{i}]'] for i in range(3)] for c in columns] == expected


def test_a_campaign_has_a_column_per_wheel(tmp_path):
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 200.0, 'wheels.max_speed': [2.0, 2.0, 2.0]}})
    campaign_file = tmp_path / 'campaign.yaml'
    campaign_file.write_text(yaml.safe_dump({'campaign': {
        'scenario': str(scenario), 'runs': 3, 'seed': 1, 'chunk_size': 3, 'metrics': [NAME],
        'dispersions': {'dynamics.initial.attitude': {'distribution': 'euler213_uniform', 'max_deg': 30}}}}))
    campaign = Campaign.load(campaign_file)
    assert campaign.metrics == [f'{NAME}[{i}]' for i in range(3)]
    rows = run_chunk(campaign, [0, 1, 2])
    result = BatchSimulation(campaign.batch_sections([0, 1, 2], campaign.draws([0, 1, 2])), 3).run()
    for j, row in enumerate(rows):
        expected = definition(result.t, result.wheel_speed[j], [2.0, 2.0, 2.0])
        assert [row['metrics'][f'{NAME}[{i}]'] for i in range(3)] == expected
    assert any(max(row['metrics'].values()) > 0.0 for row in rows)
