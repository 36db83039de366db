"""adcs-montecarlo's default scheduler (adcs_sim/app/campaign/scheduling.py, montecarlo.execute 'auto'):
in this process unless a LocalCluster is expected to finish the chunks left sooner, its start-up
included; the choice's arithmetic, and what ``execute`` runs where (no timing is asserted: the
measured cost of a run is replaced by the choice under test)."""
from __future__ import annotations

import pytest
from support.scenarios import write_campaign

from adcs_sim.app.campaign import montecarlo, scheduling
from adcs_sim.app.campaign.montecarlo import _parser, execute
from adcs_sim.app.campaign.plan import Campaign


def test_a_pd_campaign_of_a_millisecond_a_run_stays_in_the_process():
    # the default PD campaign: 1000 runs in chunks of 500, ~1.5 ms a run: 0.75 s left against the
    # start-up + 0.375 s
    assert scheduling.choose(1.5e-3, [500], workers=2) == 'none'
    # with a 3 s start-up on 2 workers the cluster wins past 4000 runs left (1.5 ms x r / 2 > 3 s)
    assert scheduling.choose(1.5e-3, [500] * 7, workers=2, start_s=3.0) == 'none'    # 5.25 s against 3 + 2.625 s
    assert scheduling.choose(1.5e-3, [500] * 9, workers=2, start_s=3.0) == 'local'   # 6.75 s against 3 + 3.375 s


def test_long_runs_go_to_the_cluster_and_one_chunk_or_one_worker_never_does():
    assert scheduling.choose(1.0, [100, 100, 100], workers=2) == 'local'
    assert scheduling.choose(1.0, [100], workers=8) == 'none'         # one chunk: nothing to share
    assert scheduling.choose(1.0, [100] * 10, workers=1) == 'none'    # one worker: only the start-up added
    assert scheduling.choose(1.0, [], workers=2) == 'none'            # nothing left


def test_the_threshold_is_where_the_start_up_equals_what_the_workers_save():
    # here p r, there S + p r / w: the cluster wins iff p r (1 - 1 / w) > S; with S = 3, w = 2, r = 600:
    # p = 0.01 exactly breaks even (6 s here, 3 + 3 s there) and stays here
    assert scheduling.choose(0.01, [300, 300], workers=2, start_s=3.0) == 'none'
    assert scheduling.choose(0.0101, [300, 300], workers=2, start_s=3.0) == 'local'
    assert scheduling.choose(0.0099, [300, 300], workers=2, start_s=3.0) == 'none'
    # more workers than chunks: only as many as the chunks work
    assert scheduling.choose(0.0101, [300, 300], workers=16, start_s=3.0) == 'local'
    assert scheduling.choose(0.0099, [300, 300], workers=16, start_s=3.0) == 'none'


@pytest.mark.parametrize('args', [(-1.0, [1], 2), (1.0, [1], 0), (1.0, [1], 2, -0.5)])
def test_negative_costs_and_no_worker_are_refused(args):
    with pytest.raises(ValueError, match='choose: '):
        scheduling.choose(*args)


@pytest.fixture
def dask_calls(monkeypatch):
    """The chunks execute hands to Dask (recorded; run here instead, without starting a cluster)."""
    calls = []

    def on_dask(campaign, chunks, scheduler, workers, bar):
        calls.append((scheduler, [list(c) for c in chunks]))
        return [row for chunk in chunks for row in montecarlo.run_chunk(campaign, chunk)]
    monkeypatch.setattr(montecarlo, '_on_dask', on_dask)
    return calls


@pytest.mark.parametrize('choice', ['none', 'local'])
def test_auto_runs_the_first_chunk_here_and_the_rest_where_the_choice_says(tmp_path, monkeypatch, dask_calls, choice):
    campaign = Campaign.load(write_campaign(tmp_path))
    campaign.chunk_size = 3
    seen = []

    def choose(per_run_s, chunk_sizes, workers):
        seen.append((per_run_s > 0, chunk_sizes, workers))
        return choice
    monkeypatch.setattr(scheduling, 'choose', choose)
    rows = execute(campaign, scheduler='auto', workers=2, progress=False)
    assert seen == [(True, [3, 1], 2)]   # 7 runs: the first chunk of 3 timed, then [3, 1] left
    assert dask_calls == ([] if choice == 'none' else [('local', [[3, 4, 5], [6]])])
    assert rows == execute(campaign, scheduler='none', progress=False)


def test_forced_schedulers_skip_the_choice(tmp_path, monkeypatch, dask_calls):
    campaign = Campaign.load(write_campaign(tmp_path))
    monkeypatch.setattr(scheduling, 'choose', lambda *a: pytest.fail('auto chose although a scheduler was given'))
    execute(campaign, scheduler='none', progress=False)
    assert dask_calls == []
    execute(campaign, scheduler='local', workers=2, progress=False)
    assert [scheduler for scheduler, _ in dask_calls] == ['local']


def test_auto_is_the_default():
    assert _parser().parse_args(['c.yaml']).scheduler == 'auto'
