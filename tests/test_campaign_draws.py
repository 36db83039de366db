"""Campaign.draws (all of a chunk's runs at once) gives exactly Campaign.draw run by run, for every
distribution (the 2-1-3 Euler draws are converted to quaternions in one call)."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from support.scenarios import write_campaign

from adcs_sim.app.campaign.plan import Campaign, run_chunk

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


def numpy_draw(campaign: Campaign, index: int) -> dict:
    """Run ``index``'s draws with numpy's and scipy's own samplers (``rng.uniform(low, high)``,
    ``rng.normal(mean, std)``, ``Rotation.random``, ``from_euler`` of one run): what the campaign
    drew before it drew the raw deviates and scaled all the runs at once."""
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(index,)))
    out = {}
    for d in campaign.dispersions:
        a, base = d.args, np.asarray(campaign.defaults[d.section][d.key], dtype=float)
        full = lambda v: np.array(np.broadcast_to(np.asarray(v, dtype=float), base.shape))  # noqa: E731
        if d.distribution == 'so3_uniform':
            value = Rotation.random(random_state=rng).as_quat().tolist()
        elif d.distribution == 'euler213_uniform':
            m = np.broadcast_to(np.asarray(a['max_deg'], dtype=float), (3,))
            value = Rotation.from_euler('YXZ', rng.uniform(-m, m), degrees=True).as_quat().tolist()
        elif d.distribution == 'run_index':
            value = int(a.get('offset', 0)) + index
        elif d.distribution == 'normal':
            value = rng.normal(full(a.get('mean', base)), full(a['std']))
        elif 'plus_minus' in a:
            value = rng.uniform(base - full(a['plus_minus']), base + full(a['plus_minus']))
        else:
            value = rng.uniform(full(a['low']), full(a['high']))
        out[d.target] = value.tolist() if isinstance(value, np.ndarray) and value.ndim else (
            float(value) if isinstance(value, (float, np.ndarray)) else value)
    return out


def test_draws_equal_numpys_samplers_run_by_run(tmp_path):
    """The raw deviates scaled over all the runs give the bits of numpy's uniform / normal calls of
    each run (scalar and per-element arguments, plus_minus, a drawn mean, several max_deg) and of
    scipy's Rotation.random (normals, then normalised)."""
    dispersions = {**DISPERSIONS, 'dynamics.inertia': {'distribution': 'normal', 'std': 0.4, 'mean': [11, 12, 9.5]},
                   'dynamics.wheels.max_torque': {'distribution': 'uniform', 'plus_minus': [0.001, 0.002, 0.0005]},
                   'pd_controller.kp': {'distribution': 'normal', 'std': 0.0001}}
    so3 = {**DISPERSIONS, 'dynamics.initial.attitude': {'distribution': 'so3_uniform'}}
    for disp in (DISPERSIONS, dispersions, so3):
        campaign = Campaign.load(write_campaign(tmp_path, runs=40, dispersions=disp))
        assert repr(campaign.draws(list(range(40)))) == repr([numpy_draw(campaign, i) for i in range(40)])


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


def test_draws_reuse_the_loads_draws_and_only_for_the_same_seed_and_dispersions(tmp_path):
    """Campaign.load draws every run once (check_runs); draws() takes a chunk's rows from those, the
    same values as drawing the chunk's runs again, and draws afresh once the seed, the run count or
    a dispersion changed (or for an index beyond the runs)."""
    campaign = Campaign.load(write_campaign(tmp_path, runs=9, dispersions=DISPERSIONS))
    assert campaign._drawn is not None
    fresh = lambda c, idx: [dict(zip([d.target for d in c.dispersions], row))  # noqa: E731
                            for row in zip(*[col.tolist() for col in c.draw_columns(idx)])]
    for indices in ([0, 1, 2], [8, 3, 4], [], [5]):
        assert repr(campaign.draws(indices)) == repr(fresh(campaign, indices)) == repr(
            [campaign.draw(i) for i in indices])
    assert repr(campaign.draws([9, 10])) == repr([campaign.draw(i) for i in (9, 10)])
    cached = repr(campaign.draws([2]))
    campaign.seed += 1
    assert repr(campaign.draws([2])) == repr([campaign.draw(2)]) != cached
    campaign.seed -= 1
    campaign.dispersions[2].args['plus_minus'] = np.asarray(0.02)
    assert repr(campaign.draws([2])) == repr([campaign.draw(2)]) != cached
