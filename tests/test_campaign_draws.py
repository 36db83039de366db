"""Campaign.draws (all of a chunk's runs at once) gives exactly Campaign.draw run by run, for every
distribution (the 2-1-3 Euler draws are converted to quaternions in one call)."""
from __future__ import annotations

from test_campaign import write_campaign

from adcs_sim.app.campaign import Campaign

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
