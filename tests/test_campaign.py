"""Monte Carlo campaigns (adcs_sim/app/campaign/plan.py, adcs_sim/app/campaign/montecarlo.py).

* reproducible: the same seed gives the same rows bit for bit however the campaign is split, in
  this process or on a Dask LocalCluster (loopback);
* every bad campaign is refused before anything runs, with a message naming the key;
* a diverging run is a failed row with its inputs; the campaign goes on;
* any run can be exported as a scenario file that replays it alone.
"""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from support.paths import CONFIG
from support.scenarios import make_scenario, write_campaign

from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.campaign.plan import Campaign, CampaignError, run_chunk
from adcs_sim.app.campaign.montecarlo import execute, main
from adcs_sim.app.scenario.files import validate_scenario


def rows_of(campaign: Campaign, chunk_size: int) -> list[dict]:
    campaign.chunk_size = chunk_size
    return execute(campaign, scheduler='none', progress=False)


def test_same_seed_same_rows_however_split(tmp_path):
    campaign = Campaign.load(write_campaign(tmp_path))
    whole = rows_of(campaign, 7)
    assert [r['run'] for r in whole] == list(range(7))
    assert rows_of(campaign, 1) == whole
    assert rows_of(campaign, 3) == whole
    # the inputs really are dispersed, and another seed draws others
    attitudes = {tuple(r['inputs']['dynamics.initial.attitude']) for r in whole}
    assert len(attitudes) == 7
    other = Campaign.load(write_campaign(tmp_path, seed=12))
    assert rows_of(other, 7)[0]['inputs'] != whole[0]['inputs']
    # the draws follow the declared distributions
    for r in whole:
        from scipy.spatial.transform import Rotation
        angles = Rotation.from_quat(r['inputs']['dynamics.initial.attitude']).as_euler('YXZ', degrees=True)
        assert np.all(np.abs(angles) <= 30.0 + 1e-9)
        assert abs(r['inputs']['pd_controller.kd'] - 0.05) <= 0.01


@pytest.mark.slow
def test_dask_gives_the_same_rows_locally_and_by_scheduler_address(tmp_path):
    """Chunks of 2 runs on the default LocalCluster (2 workers, 127.0.0.1), and chunks of 3 on a
    separately started cluster reached by its scheduler address (what --scheduler tcp://... does):
    identical to one batch in this process."""
    from dask.distributed import LocalCluster
    campaign = Campaign.load(write_campaign(tmp_path, runs=6))
    here = rows_of(campaign, 6)
    campaign.chunk_size = 2
    assert execute(campaign, scheduler='local', workers=2, progress=False) == here
    campaign.chunk_size = 3
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host='127.0.0.1',
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith('tcp://127.0.0.1:')
        assert execute(campaign, scheduler=cluster.scheduler_address, progress=False) == here


@pytest.mark.graph
def test_an_exported_run_replays_through_the_ros_graph(tmp_path):
    """adcs-run of a run's exported scenario: the graph's recording is that run (batch engine, to
    round-off)."""
    from adcs_sim.app.analysis.metrics import RunData
    from adcs_sim.app.graph.runner import run_scenario
    campaign = Campaign.load(write_campaign(tmp_path, scenario=make_scenario(tmp_path, {
        'dynamics': {'duration': 60.0}})))
    replay = tmp_path / 'run_5.yaml'
    assert main([str(campaign.path), '--export-run', '5', '--out', str(replay)]) == 0
    run_scenario(replay, tmp_path / 'graph', progress=False)
    graph = RunData.from_bag(tmp_path / 'graph' / 'bag')
    campaign.chunk_size = 7
    batch = BatchSimulation.from_runs([campaign.run_sections(5)]).run().run_data(0)
    np.testing.assert_allclose(graph.q, batch.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(graph.u, batch.u, rtol=0, atol=1e-15)


def test_a_run_replays_alone_from_its_exported_scenario(tmp_path):
    campaign = Campaign.load(write_campaign(tmp_path))
    row = rows_of(campaign, 7)[4]
    replay = tmp_path / 'run_4.yaml'
    assert main([str(campaign.path), '--export-run', '4', '--out', str(replay)]) == 0
    alone = BatchSimulation.from_runs([validate_scenario(replay)]).run()  # what adcs-run validates
    from adcs_sim.app.campaign.plan import metric_columns
    assert {m: v for m, v in metric_columns(alone.metrics(0)).items() if m in row['metrics']} == row['metrics']


def test_diverging_runs_are_failed_rows_and_the_campaign_goes_on(tmp_path):
    """Torquers without limit and kd drawn in [0.05, 6]: kd * period > 2 makes the discrete rate
    loop unstable and overflow; those runs fail with their inputs, the others complete."""
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 300.0, 'torquers.enabled': True, 'wheels.names': None, 'wheels.axes': None,
                     'wheels.spin_inertia': None, 'wheels.max_torque': None, 'wheels.max_speed': None},
        'pd_controller': {'actuator': 'torquers', 'wheels.names': None, 'wheels.axes': None,
                          'wheels.max_torque': None}})
    path = write_campaign(tmp_path, scenario, runs=12, chunk_size=5, dispersions={
        'pd_controller.kd': {'distribution': 'uniform', 'low': 0.05, 'high': 6.0}},
        requirements={'settling_euler213_0.5deg_s': {'max': 250.0}})
    out = tmp_path / 'out'
    assert main([str(path), '--scheduler', 'none', '--out', str(out), '--quiet']) == 0
    with open(out / 'results.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 12
    failed = [r for r in rows if r['status'] == 'failed']
    assert failed and all(float(r['pd_controller.kd']) > 2.0 for r in failed)
    assert all('non-finite' in r['reason'] for r in failed)
    completed = [r for r in rows if r['status'] != 'failed']
    assert completed and all(float(r['pd_controller.kd']) < 2.0 for r in completed)
    assert all(math.isfinite(float(r['integrated_torque_Nms'])) for r in completed)
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['counts']['failed'] == len(failed)
    listed = {r['run'] for r in summary['not_ok']}
    assert {int(r['run']) for r in failed} <= listed
    for r in summary['not_ok']:
        assert (out / r['replay']).exists() and r['inputs']['pd_controller.kd'] > 0
    assert (out / 'figures' / 'hist_integrated_torque_Nms.png').exists()
    assert (out / 'campaign.yaml').exists() and (out / 'summary.md').read_text().startswith('# Monte Carlo')


def test_the_reference_campaign_loads_and_runs(tmp_path):
    campaign = Campaign.load(CONFIG / 'campaigns' / 'pd_slew_30deg.yaml', runs=3)
    assert campaign.runs == 3 and campaign.scenario_path.name == 'microsat_pd_slew.yaml'
    rows = run_chunk(campaign, [0, 1, 2])
    for r in rows:
        assert r['status'] == 'ok'
        assert 50.0 < r['metrics']['settling_euler213_0.5deg_s'] < 400.0
        assert r['inputs']['dynamics.wheels.max_torque'] == campaign.run_given(r['run'])['pd_controller'][
            'wheels.max_torque']


@pytest.mark.parametrize('change, message', [
    ({'runs': 0}, 'campaign.runs: must be at least 1'),
    ({'dispersions': {'dynamics.inertai': {'distribution': 'normal', 'std': 1.0}}},
     "unknown parameter 'inertai' of node 'dynamics'"),
    ({'dispersions': {'attitude_node.kp': {'distribution': 'normal', 'std': 1.0}}}, "no section 'attitude_node'"),
    ({'dispersions': {'dynamics.control_period': {'distribution': 'normal', 'std': 0.1}}},
     'dynamics.control_period cannot differ between runs'),
    ({'dispersions': {'dynamics.inertia': {'distribution': 'normal', 'std': -1.0}}}, r'std: must be >= 0'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'uniform', 'low': 0.003, 'high': 0.001}}},
     'low must not exceed high'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'gaussian', 'std': 0.1}}}, "unknown 'gaussian'"),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'normal'}}}, 'std: required by normal'),
    ({'dispersions': {'dynamics.inertia': {'distribution': 'normal', 'std': [1.0, 2.0]}}}, 'do not fit'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'so3_uniform'}}}, 'is not a quaternion'),
    ({'dispersions': {'dynamics.inertia': {'distribution': 'normal', 'std': 8.0}}},
     r"run \d+: drawn parameter 'dynamics.ros__parameters.inertia'"),
    ({'metrics': ['settling_time']}, "unknown metric 'settling_time'"),
    ({'runz': 5}, 'campaign.runz: unknown key'),
    ({'scenario': 'no_such_scenario.yaml'}, 'campaign.scenario'),
])
def test_bad_campaigns_are_refused_before_anything_runs(tmp_path, capsys, change, message):
    path = write_campaign(tmp_path, **change)
    out = tmp_path / 'out'
    assert main([str(path), '--scheduler', 'none', '--out', str(out), '--quiet']) == 2
    err = capsys.readouterr().err
    assert err.startswith('adcs-montecarlo: ') and len(err.strip().splitlines()) == 1
    import re
    assert re.search(message, err), err
    assert not out.exists()


def test_zero_runs_on_the_command_line_is_refused(tmp_path, capsys):
    assert main([str(write_campaign(tmp_path)), '--runs', '0', '--scheduler', 'none']) == 2
    assert '--runs: must be at least 1' in capsys.readouterr().err


def test_negative_inertia_draw_names_run_and_key(tmp_path):
    """A normal draw of the inertia far wide enough to go negative (or break the triangle
    inequality) for some run: refused at load, naming that run and the parameter."""
    path = write_campaign(tmp_path, runs=50, dispersions={
        'dynamics.inertia': {'distribution': 'normal', 'std': [6.0, 7.0, 5.0]}})
    with pytest.raises(CampaignError, match=r"^run \d+: drawn parameter 'dynamics.ros__parameters.inertia'"):
        Campaign.load(path)


def test_summary_statistics_are_those_of_the_rows(tmp_path):
    from adcs_sim.app.campaign.montecarlo import summarize
    campaign = Campaign.load(write_campaign(tmp_path))
    rows = rows_of(campaign, 7)
    summary = summarize(campaign, rows)
    values = np.array([r['metrics']['integrated_torque_Nms'] for r in rows])
    s = summary['metrics']['integrated_torque_Nms']
    assert s['mean'] == pytest.approx(values.mean()) and s['std'] == pytest.approx(values.std(ddof=1))
    assert s['p50'] == pytest.approx(np.median(values)) and s['max'] == values.max()
    assert summary['counts'] == {'ok': 7, 'failed': 0, 'violated': 0}
    assert not math.isnan(s['p95'])
