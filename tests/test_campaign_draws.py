"""Campaign.draws (all of a chunk's runs at once) gives exactly Campaign.draw run by run, for every
distribution (the 2-1-3 Euler draws are converted to quaternions in one call)."""
from __future__ import annotations

from test_campaign import write_campaign

from adcs_sim.app.campaign import Campaign, run_chunk

DISPERSIONS = {
    'dynamics.initial.attitude': {'distribution': 'euler213_uniform', 'max_deg': [30, 10, 60]},
    'dynamics.inertia': {'distribution': 'normal', 'std': [0.6, 0.7, 0.5]},
    'pd_controller.kd': {'distribution': 'uniform', 'plus_minus': 0.01},
    'pd_controller.kp': {'distribution': 'uniform', 'low': 0.0015, 'high': 0.0025},
    'dynamics.noise.seed': {'distribution': 'run_index', 'offset': 40},
}


def test_draws_equal_draw_run_by_run(tmp_path):
    campaign = Campaign.load(write_campaign(tmp_path, runs=9, dispersions=DISPERSIONS))
    indices = [0, 3, 4, 8]
    assert repr(campaign.draws(indices)) == repr([campaign.draw(i) for i in indices])
    so3 = Campaign.load(write_campaign(tmp_path, runs=5, dispersions={
        'dynamics.initial.attitude': {'distribution': 'so3_uniform'}, **{k: v for k, v in DISPERSIONS.items()
                                                                        if k != 'dynamics.initial.attitude'}}))
    assert repr(so3.draws(list(range(5)))) == repr([so3.draw(i) for i in range(5)])


def _same_sections(a: dict, b: dict) -> None:
    assert list(a) == list(b)
    for section in a:
        assert list(a[section]) == list(b[section]), section
        for key, value in a[section].items():
            other = b[section][key]
            assert type(value) is type(other), (section, key)
            assert repr(value) == repr(other), (section, key)


def test_a_checked_campaigns_batch_sections_are_its_validated_runs_stacked(tmp_path):
    """A campaign checked at load assembles a chunk's sections from its draws without validating
    each run again: the same sections (keys, order, types, values) as validating every run and
    stacking them (BatchSimulation.from_runs), links and an integer dispersion included; the same rows."""
    links = {**DISPERSIONS, 'dynamics.wheels.max_torque': {'distribution': 'uniform', 'low': 0.009, 'high': 0.011,
                                                           'link': ['pd_controller.wheels.max_torque']}}
    for dispersions in (DISPERSIONS, links):
        campaign = Campaign.load(write_campaign(tmp_path, runs=9, dispersions=dispersions))
        assert campaign.checked
        indices = [1, 2, 5, 8]
        inputs = campaign.draws(indices)
        fast, fast_rows = campaign.batch_sections(indices, inputs), run_chunk(campaign, indices)
        campaign.checked = False
        _same_sections(fast, campaign.batch_sections(indices, inputs))
        assert repr(fast_rows) == repr(run_chunk(campaign, indices))
        alone = campaign.batch_sections([5], [inputs[2]])   # one run: nothing stacked
        campaign.checked = True
        _same_sections(alone, campaign.batch_sections([5], [inputs[2]]))
