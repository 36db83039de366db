"""Campaigns at their edges (issue #31, class "Campaigns"; the batch half of item 5).

* every parameter a schema declares dispersible (``Param(batch=True)``, the set
  :meth:`Campaign._target` accepts) is dispersed in a tiny campaign: the campaign runs as one batch,
  each run gets its own draw, and each run's results are those of the run alone with its draw
  (and differ from run to run where the scenario uses the parameter);
* one run whose model fails (an SGP4 failure, a law that raises) is a ``failed`` row with its reason:
  the other runs of its batch get the rows they get without it, and the campaign goes on;
* a non-finite requirement, and counts a campaign file or the command line gives beyond what the
  seeding or this machine can take (runs, chunk size, offsets, seed), are refused at load in one line
  naming the key, before any run.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from support.paths import CONFIG
from support.scenarios import make_scenario

import adcs_sim.app.campaign.plan as campaign_module
import adcs_sim.app.campaign.montecarlo as montecarlo
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.campaign.plan import Campaign, CampaignError
from adcs_sim.app.scenario.registry import NODES

STEPS = 5   # control steps of every tiny campaign's runs

# --- every dispersible parameter ---------------------------------------------------------------

DISPERSIBLE = [(section, p.name) for section, info in NODES.items() for p in info.schema.params if p.batch]

# Sensors and an estimator flying the controller: the gyro, the star tracker and both vector sensors
# in use, with constant references (their references.* are then the filter's).
LEO = 'leo_tle_sun_magnetometer_mekf.yaml'
ALL_SENSORS = {'dynamics': {'sensors.star_tracker.enabled': True, 'sensors.star_tracker.cross_std': 2.4e-5,
                            'sensors.star_tracker.about_std': 1.9e-4},
               'mekf_estimator': {'sensors': ['gyro', 'star_tracker', 'sun', 'magnetometer'],
                                  'references.model': 'constant', 'environment': None,
                                  'references.sun': [0.6, 0.8, 0.0], 'references.magnetometer': [0.0, 2e-5, 2e-5]}}
# The fine sun sensor on the Sun (near inertial +x at the LEO scenario's epoch, the body at the identity).
FINE_SUN = {'dynamics': {'sensors.fine_sun_sensor.enabled': True, 'sensors.fine_sun_sensor.std': 2e-4,
                         'sensors.fine_sun_sensor.boresight': [1.0, 0.0, 0.0]},
            'mekf_estimator': {'sensors': ['gyro', 'fine_sun_sensor', 'magnetometer']}}
QUEST = {'quest_estimator': {'sensors': ['gyro', 'sun', 'magnetometer'], 'references.sun': [0.6, 0.8, 0.0],
                             'references.magnetometer': [0.0, 2e-5, 2e-5], 'initial.attitude_sigma': [0.1, 0.1, 0.1]}}
# Seed 000's two-wheel laws from the first step (no three-wheel phase, no fault), away from the target.
TWO_WHEELS = {'dynamics': {'initial.attitude': [0.1, 0.2, 0.1, math.sqrt(0.94)], 'initial.rate': [0.001, 0.002, 0.0]}}
# Ideal torquers instead of the wheels, with a finite limit that binds at the start of the slew.
TORQUERS = {'dynamics': {'torquers.enabled': True, 'torquers.max_torque': [0.003, 0.003, 0.003], 'wheels': None},
            '*': {'actuator': 'torquers', 'wheels': None, 'torquers.max_torque': 0.003}}
# Wheel limits below the slew's first torques (about 0.007 N m), so that they bind.
BINDING_WHEEL_TORQUE = {'spec': {'distribution': 'uniform', 'low': 0.002, 'high': 0.004}}
ESEO = ('eseo_backstepping_slew.yaml', {}, ())
# Seed 001's laws: B set (its smallest singular value keeps eq. 20, (alpha + beta) / smin(B) <= u_max = 1)
SEED001 = {'*': {'B': [1.2, 1.3, 1.4]}}

# The scenario each section is dispersed in: (config file, overrides, sections dropped); a section not
# listed is dispersed in the first scenario of config/ that has it.
BASES: dict[str, tuple[str, dict, tuple]] = {
    'dynamics': ('microsat_pd_slew.yaml', {}, ()),
    'pd_controller': ('microsat_pd_slew.yaml', {}, ()),
    'mekf_estimator': (LEO, ALL_SENSORS, ()),
    'quest_estimator': (LEO, QUEST, ('mekf_estimator',)),
    'zero_momentum_controller': ('uosat12_zero_momentum.yaml', {**TWO_WHEELS, '*': {'three_wheel': None}},
                                 ('fault_injector',)),
    'snlc_controller': ('uosat12_snlc.yaml', {**TWO_WHEELS, '*': {'three_wheel': None}}, ('fault_injector',)),
    'snlc_gsmn_controller': ('uosat12_gsmn.yaml', {**TWO_WHEELS, '*': {'three_wheel': None}}, ('fault_injector',)),
    'm2r_controller': ('m2r_umax1.yaml', SEED001, ()),
    'm2s_controller': ('m2s_nonprincipal_vagc_0p02.yaml', {'*': {'B': [1.2, 1.3, 1.4], 'torquers.max_torque': 1.0}},
                       ()),
    'snlc_minnorm_controller': ('uosat12_snlc.yaml', {**TWO_WHEELS, 'snlc_minnorm_controller': {
        'inertia': [40.45, 42.09, 42.36], 'k': 0.02, 'g': 0.08, 'K': 10.0, 'gamma': 0.01, 'sigma': 0.04,
        'a1': 0.025, 'a2': 0.025, 'wheels.names': ['rw_x', 'rw_y', 'rw_z'],
        'wheels.axes': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], 'wheels.max_torque': [0.02, 0.02, 0.02]}},
        ('fault_injector', 'snlc_controller')),
}

# Parameters that need more than their section's base to be in use, or another draw than the default
# (ten per cent around a non-zero nominal value, [0, 1e-3] around zero): why, and what.
SETUPS: dict[tuple[str, str], dict] = {
    # the scenario's limit (628 rad/s) is not reached in a few steps; these are, in about a second
    ('dynamics', 'wheels.max_speed'): {'spec': {'distribution': 'uniform', 'low': 0.5, 'high': 2.0}},
    ('dynamics', 'wheels.max_torque'): BINDING_WHEEL_TORQUE,
    ('pd_controller', 'wheels.max_torque'): BINDING_WHEEL_TORQUE,
    # the scenario leaves them unset (none: no value to draw around)
    **{('dynamics', f'wheels.{key}'): {'overrides': {'dynamics': {f'wheels.{key}': [0.0, 0.0, 0.0]}}}
       for key in ('viscous_friction', 'coulomb_friction', 'initial_speed')},
    # the speed loop acts only on speed commands: a law that commands the wheels' momentum
    ('dynamics', 'wheels.speed_loop_gain'): {'base': ('ukdmc_two_wheels.yaml', {
        'dynamics': {'wheels.speed_loop_gain': [1.0, 1.0]}}, ())},
    ('dynamics', 'torquers.max_torque'): {'overrides': TORQUERS},
    ('dynamics', 'thrusters.positions'): {'base': ESEO},
    ('dynamics', 'thrusters.directions'): {'base': ESEO},
    ('dynamics', 'thrusters.max_force'): {'base': ESEO},
    # seed 001: the alpha + beta of eq. (20) kept within u_max; u_max itself above alpha + beta
    ('m2r_controller', 'alpha'): {'spec': {'distribution': 'uniform', 'low': 0.4, 'high': 0.5}},
    ('m2r_controller', 'beta'): {'spec': {'distribution': 'uniform', 'low': 0.4, 'high': 0.5}},
    ('m2r_controller', 'torquers.max_torque'): {'spec': {'distribution': 'uniform', 'low': 1.0, 'high': 1.2}},
    ('m2s_controller', 'torquers.max_torque'): {'spec': {'distribution': 'uniform', 'low': 1.0, 'high': 1.2}},
    # its principal moments are within 3 % of the triangle inequality
    ('m2s_controller', 'inertia'): {'spec': {'distribution': 'uniform', 'plus_minus': 0.01}},
    # the thrusters fire above on_level and stop below off_level <= on_level
    ('backstepping_controller', 'firing.on_level'): {'spec': {'distribution': 'uniform', 'low': 0.013, 'high': 0.015}},
    ('backstepping_controller', 'firing.off_level'): {'spec': {'distribution': 'uniform', 'low': 0.010, 'high': 0.013}},
    # a periodic disturbance with an amplitude, a frequency and a phase that all matter
    **{('dynamics', f'disturbance.{name}'): {'overrides': {'dynamics': {
        'disturbance.amplitude': [1e-3, 1e-3, 1e-3], 'disturbance.frequency': [0.1, 0.1, 0.1],
        'disturbance.phase': [0.3, 0.3, 0.3]}}} for name in ('amplitude', 'frequency', 'phase')},
    # run lengths of 2 to 8 steps
    ('dynamics', 'duration'): {'spec': {'distribution': 'uniform', 'low': 2.0, 'high': 8.0}},
    ('dynamics', 'noise.seed'): {'overrides': {'dynamics': {'noise.attitude_std': 1e-3}}},
    ('mekf_estimator', 'fine_sun_sensor.sigma'): {'base': (LEO, FINE_SUN, ())},
    # the sensors' noise and errors reach the trajectory through the estimator the controller flies on
    **{('dynamics', key): {'base': (LEO, ALL_SENSORS, ())}
       for key in ('sensors.seed', 'sensors.gyro.bias', 'sensors.gyro.scale_factor', 'sensors.magnetometer.bias')},
    ('dynamics', 'sensors.magnetometer.bias'): {'base': (LEO, ALL_SENSORS, ()),
                                                'spec': {'distribution': 'uniform', 'low': 0.0, 'high': 1e-6}},
}
# A controller's torquer limit, in the torquer variant of its base.
TORQUER_LIMIT = {'overrides': TORQUERS}
# Parameters no scenario of their section uses, so their draws reach the runs but change nothing:
# {(section, key): why}.
UNUSED: dict[tuple[str, str], str] = {
    **{(s, 'torquers.max_torque'): "the law commands wheels only (its section's check refuses torquers)"
       for s in ('zero_momentum_controller', 'pointing_a_controller', 'pointing_b_controller')},
    ('backstepping_controller', 'torquers.max_torque'): 'the law commands thrusters and a wheel',
}
# Parameters whose draws reach the runs (each run as alone) but change nothing in a few steps of their
# base scenario, nor in the law's status: {(section, key): why}.
HIGH_GAIN = 'a gain of the high-gain mode, entered once the torque has fallen below epsilon: later in the slew'
SINGULAR = 'with a1, a2 set the singular term of eq. (8) is saturated at the start of the slew'
NOT_SHOWN: dict[tuple[str, str], str] = {
    **{('gsmn_controller', k): HIGH_GAIN for k in ('kp2', 'kd2', 'epsilon')},
    **{('snlc_gsmn_controller', k): HIGH_GAIN for k in ('k2', 'g2', 'K2', 'epsilon')},
    **{(s, 'eps_den'): SINGULAR for s in ('zero_momentum_controller', 'snlc_controller', 'snlc_minnorm_controller',
                                          'snlc_gsmn_controller')},
    **{(s, 'wheels.max_torque'): 'the first torques are well below the limit'
       for s in ('gsmn_controller', 'kt_controller', 'zero_momentum_controller')},
    ('m2r_controller', 'torquers.max_torque'): 'the first torques are below u_max',
    **{(s, 'inertia'): 'the first stage of the pointing laws does not use the inertia model'
       for s in ('pointing_a_controller', 'pointing_b_controller')},
    **{('backstepping_controller', k): 'the thrusters fire bang-bang at full force in the first steps, as in every run'
       for k in ('target.rate', 'thrusters.positions', 'thrusters.directions', 'thrusters.max_force',
                 'wheels.max_torque', 'firing.on_level')},
    ('backstepping_controller', 'firing.off_level'): "a firing thruster's demand is over 15 times on_level in the "
                                                     'first steps of the slew: it never falls to the off level '
                                                     '(per-run hysteresis: tests/test_laws_backstepping.py)',
    ('quest_estimator', 'initial.attitude_sigma'): "the first fix of both vectors replaces the initial estimate's "
                                                   'covariance',
}
# Parameters no scenario of their section can disperse, refused at load naming the key: {(section, key): why}.
REFUSED: dict[tuple[str, str], str] = {
    **{(s, 'wheels.max_torque'): "the law commands torquers only (its section's check refuses wheels): no "
                                 'wheel limit to draw around' for s in ('m2r_controller', 'm2s_controller')},
    ('m2r_controller', 'target.rate'): 'M2R brings the body to rest: its check refuses any rate but zero',
}


def _tiny_scenario(tmp_path: Path, section: str, key: str) -> Path:
    """A scenario using ``section.key``, its runs ``STEPS`` control steps long."""
    torquers = key == 'torquers.max_torque' and NODES[section].role == 'controller' \
        and (section, key) not in UNUSED and 'spec' not in SETUPS.get((section, key), {})
    setup = SETUPS.get((section, key), TORQUER_LIMIT if torquers else {})
    if 'base' in setup:
        base, overrides, drop = setup['base']
    elif section in BASES:
        base, overrides, drop = BASES[section]
    else:
        found = [p.name for p in sorted(CONFIG.glob('*.yaml')) if section in yaml.safe_load(p.read_text())]
        assert found, f'no scenario in config/ has a {section} section: give it a base in BASES'
        base, overrides, drop = found[0], {}, ()
    overrides = {s: dict(v) for s, v in overrides.items()}
    for s, v in setup.get('overrides', {}).items():
        overrides.setdefault(s, {}).update(v)
    tree = yaml.safe_load((CONFIG / base).read_text())
    sections = [s for s in tree if s not in drop] + [s for s in overrides if s not in tree and s != '*']
    for s in sections:   # '*': every controller section
        if s in NODES and NODES[s].role == 'controller' and '*' in overrides:
            overrides[s] = {**overrides['*'], **overrides.get(s, {})}
    overrides.pop('*', None)
    period = tree['dynamics']['ros__parameters']['control_period']
    overrides.setdefault('dynamics', {})['duration'] = STEPS * period
    return make_scenario(tmp_path, overrides, base=base, drop=drop)


def _spec(section: str, key: str, nominal) -> dict:
    """How ``section.key`` is drawn (see SETUPS for the exceptions)."""
    if 'spec' in SETUPS.get((section, key), {}):
        return SETUPS[(section, key)]['spec']
    param = NODES[section].schema.by_name[key]
    if param.kind == 'int':
        return {'distribution': 'run_index', 'offset': 1}
    if param.kind == 'bool':
        return {'distribution': 'bernoulli', 'p': 0.5}
    if param.kind == 'double_array' and param.length == 4:
        return {'distribution': 'euler213_uniform', 'max_deg': 10.0}
    values = np.asarray(nominal, dtype=float)
    if (section, key) in REFUSED or (section, key) in UNUSED and not np.all(np.isfinite(values)):
        return {'distribution': 'uniform', 'low': 1e-3, 'high': 2e-3}
    assert values.size and np.all(np.isfinite(values)), f'{section}.{key} = {nominal}: give it a SETUPS entry'
    if not np.any(values):
        return {'distribution': 'uniform', 'low': 0.0, 'high': 1e-3}
    spread = np.abs(0.1 * values)
    if values.size == 9:   # a matrix (an inertia): 1 % of its diagonal, keeping it symmetric and a body's
        spread = 0.1 * spread * np.eye(3).ravel()
    return {'distribution': 'uniform', 'plus_minus': spread.tolist()}


class _Recorded(BatchSimulation):
    """The batch engine, keeping the sections and the result of every batch it runs."""

    batches: list = []

    def run(self, *args, **kwargs):
        result = super().run(*args, **kwargs)
        _Recorded.batches.append(result)
        return result


def _series(result, i: int) -> list[np.ndarray]:
    """Everything run ``i`` of a batch result recorded, to its own last step."""
    k = int(result.n_steps[i])
    out = [result.q[i, :k + 1], result.w[i, :k + 1], result.u[i, :k], result.wheel_speed[i, :k + 1],
           result.thruster_on_time[i, :k], result.thruster_impulse[i, :k + 1], np.array([k])]
    if result.estimate is not None:
        for name, values in sorted(result.estimate.items()):
            out += [values[i, :k]] if name != 'status' else [v[i, :k] for _, v in sorted(values.items())]
    return out


def _status(statuses: dict[int, dict], i: int) -> list[np.ndarray]:
    """Run ``i``'s row of every step's law status (values without a batch axis are every run's)."""
    out = []
    for k in sorted(statuses):
        for name, value in sorted(statuses[k].items()):
            value = np.asarray(value)
            out.append(value[i] if value.ndim and value.shape[0] == 3 and value.dtype != object else value)
    return out


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    def equal(x, y):
        return np.array_equal(x, y, equal_nan=x.dtype.kind in 'fc' and y.dtype.kind in 'fc')
    return len(a) == len(b) and all(x.shape == y.shape and equal(x, y) for x, y in zip(a, b))


def _campaign_file(tmp_path: Path, scenario: Path, **body) -> Path:
    content = {'scenario': str(scenario), 'runs': 3, 'seed': 5, 'chunk_size': 3, **body}
    path = tmp_path / f'campaign_{len(list(tmp_path.glob("campaign_*.yaml")))}.yaml'
    path.write_text(yaml.safe_dump({'campaign': content}, sort_keys=False))
    return path


@pytest.mark.slow
@pytest.mark.parametrize('section, key', [pytest.param(s, k, id=f'{s}.{k}') for s, k in DISPERSIBLE])
def test_every_dispersible_parameter_reaches_the_runs(tmp_path, monkeypatch, section, key):
    """Dispersing ``section.key`` in 3 runs of a few steps: one batch, each run its own draw, each
    run's results equal to those of the run alone, and different from run to run where it is used."""
    scenario = _tiny_scenario(tmp_path, section, key)
    nominal = Campaign.load(_campaign_file(tmp_path, scenario)).defaults[section][key]
    path = _campaign_file(tmp_path, scenario, dispersions={f'{section}.{key}': _spec(section, key, nominal)})
    if (section, key) in REFUSED:
        with pytest.raises(CampaignError, match=re.escape(f'{section}.{key}')):
            Campaign.load(path)
        return
    campaign = Campaign.load(path)
    monkeypatch.setattr(campaign_module, 'BatchSimulation', _Recorded)
    monkeypatch.setattr(_Recorded, 'batches', [])
    rows = montecarlo.execute(campaign, scheduler='none', progress=False)
    assert [r['status'] for r in rows] == ['ok'] * 3, [r['reason'] for r in rows]
    assert len(_Recorded.batches) == 1   # the runs ran together, as one batch
    drawn = [r['inputs'][f'{section}.{key}'] for r in rows]
    pairs = [(i, j) for i in range(3) for j in range(i) if drawn[i] != drawn[j]]
    assert pairs, drawn   # (a boolean draws two values: some runs share theirs)
    result = _Recorded.batches[0]
    for i in range(3):
        alone = BatchSimulation.from_runs([campaign.run_sections(i)]).run()
        assert _same(_series(result, i), _series(alone, 0)), f'run {i} differs from the run alone'
    # what each run did, and what its law computed each step (its status: torques before saturation,
    # modes, Lyapunov values: a parameter may change them before it changes the trajectory)
    statuses: dict[int, dict] = {}
    BatchSimulation(campaign.batch_sections([0, 1, 2], [r['inputs'] for r in rows]), 3).run(
        observe=lambda k, t, status: statuses.__setitem__(k, status))
    seen = [_series(result, i) + _status(statuses, i) for i in range(3)]
    differ = [not _same(seen[i], seen[j]) for i, j in pairs]
    if (section, key) in UNUSED:
        assert not any(differ), f'{section}.{key} is used now: remove it from UNUSED ({UNUSED[section, key]})'
    elif (section, key) not in NOT_SHOWN:
        assert all(differ), f'{section}.{key}: runs with different draws have the same results'


# --- one run's model fails: a failed row, the others unchanged -------------------------------------

def _rows_alone(campaign: Campaign) -> list[dict]:
    """The campaign's rows, each run simulated alone (chunks of one run)."""
    campaign.chunk_size = 1
    return montecarlo.execute(campaign, scheduler='none', progress=False)


def _equal_rows(a: list[dict], b: list[dict]) -> bool:
    """Rows equal, NaN metrics (a failed run's) included."""
    def key(r):
        return {**r, 'metrics': {m: ('nan' if math.isnan(v) else v) for m, v in r['metrics'].items()}}
    return [key(r) for r in a] == [key(r) for r in b]


# The TLE of leo_tle_sun_magnetometer_mekf.yaml lowered (16.1 rev/day) with a drag term of 1 (B* 99999+0):
# SGP4's mean eccentricity leaves [0, 1) 87 s after the epoch.
DECAYING_TLE = {'line1': '1 90001U          26079.50000000  .00000000  00000-0  99999+0 0    06',
                'line2': '2 90001  97.4000  10.0000 0005000  90.0000   0.0000 16.10000000    05'}


def test_a_run_whose_sgp4_fails_is_a_failed_row_and_the_others_are_unchanged(tmp_path):
    """Durations of 30 to 150 s over a TLE that SGP4 cannot propagate past 87 s (the nominal 30 s run
    is valid): the longer runs are failed rows naming SGP4, the shorter ones the rows they have alone."""
    tle = {'environment.tle.line1': DECAYING_TLE['line1'], 'environment.tle.line2': DECAYING_TLE['line2']}
    scenario = make_scenario(tmp_path, {'dynamics': {**tle, 'duration': 30.0, 'control_period': 5.0,
                                                     'integrator.max_step': 5.0},
                                        'mekf_estimator': tle}, base=LEO)
    path = _campaign_file(tmp_path, scenario, runs=6, chunk_size=6, dispersions={
        'dynamics.duration': {'distribution': 'uniform', 'low': 30.0, 'high': 150.0}})
    rows = montecarlo.execute(Campaign.load(path), scheduler='none', progress=False)
    failed = [r for r in rows if r['status'] == 'failed']
    assert failed and all(r['inputs']['dynamics.duration'] > 87.0 and 'SGP4' in r['reason'] for r in failed)
    assert len(failed) < len(rows) and all(r['inputs']['dynamics.duration'] < 90.0 for r in rows if r not in failed)
    assert _equal_rows(rows, _rows_alone(Campaign.load(path)))


def test_a_law_that_raises_in_one_run_fails_that_run_only(tmp_path, monkeypatch):
    """A law whose arithmetic raises for some runs' gains (the batched call raises for the whole
    batch): those runs are failed rows with the error, every other run's row is its row alone."""
    from adcs_controllers.laws.inverse_optimal import MinNormLaw
    control = MinNormLaw.control

    def fragile(self, t, q, w, *args):
        if np.any(np.asarray(self.kp) > 0.0021):
            raise FloatingPointError('kp beyond what this law can take')
        return control(self, t, q, w, *args)
    monkeypatch.setattr(MinNormLaw, 'control', fragile)
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 1.0}}, base='microsat_minnorm_slew.yaml')
    path = _campaign_file(tmp_path, scenario, runs=6, chunk_size=6, dispersions={
        'minnorm_controller.kp': {'distribution': 'uniform', 'low': 0.0019, 'high': 0.0022}})
    rows = montecarlo.execute(Campaign.load(path), scheduler='none', progress=False)
    bad = [r['run'] for r in rows if r['inputs']['minnorm_controller.kp'] > 0.0021]
    assert bad and len(bad) < len(rows)
    assert [r['run'] for r in rows if r['status'] == 'failed'] == bad
    assert all('kp beyond what this law can take' in r['reason'] and all(math.isnan(v) for v in r['metrics'].values())
               for r in rows if r['run'] in bad)
    assert _equal_rows(rows, _rows_alone(Campaign.load(path)))


def test_failed_rows_are_written_with_the_others(tmp_path, monkeypatch):
    """A campaign with a run that raised writes its tables, summary and replay like a diverged run's."""
    import json

    from adcs_controllers.laws.inverse_optimal import MinNormLaw
    control = MinNormLaw.control
    monkeypatch.setattr(MinNormLaw, 'control', lambda self, t, q, w, *a: (_ for _ in ()).throw(
        ValueError('cannot answer')) if np.any(np.asarray(self.kp) > 0.0021) else control(self, t, q, w, *a))
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 1.0}}, base='microsat_minnorm_slew.yaml')
    path = _campaign_file(tmp_path, scenario, runs=4, chunk_size=4, series_every=2, dispersions={
        'minnorm_controller.kp': {'distribution': 'uniform', 'low': 0.0019, 'high': 0.0022}})
    out = tmp_path / 'out'
    assert montecarlo.main([str(path), '--scheduler', 'none', '--out', str(out), '--quiet', '--no-figures']) == 0
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['counts']['failed'] >= 1 and summary['counts']['ok'] >= 1
    assert all('cannot answer' in r['reason'] and (out / r['replay']).exists() for r in summary['not_ok'])
    assert montecarlo.read_results(out).num_rows == 4 and (out / 'series.npz').exists()


# --- refused at load, in one line naming the key, before any run ---------------------------------

def _refused(tmp_path, monkeypatch, capsys, argv_extra=(), **body) -> str:
    """adcs-montecarlo on a campaign of ``body``: exit 2, one line, no run started; the line."""
    started = []
    monkeypatch.setattr(montecarlo, 'execute', lambda *a, **k: started.append(a))
    monkeypatch.setattr(campaign_module, 'run_chunk', lambda *a, **k: started.append(a))
    path = _campaign_file(tmp_path, CONFIG / 'microsat_pd_slew.yaml', **body)
    out = tmp_path / 'out'
    assert montecarlo.main([str(path), '--scheduler', 'none', '--out', str(out), '--quiet', *argv_extra]) == 2
    err = capsys.readouterr().err
    assert not started and not out.exists()
    assert err.startswith('adcs-montecarlo: ') and len(err.strip().splitlines()) == 1, err
    return err


SEED = {'dynamics.noise.seed': {'distribution': 'run_index'}}
TORQUE = 'integrated_torque_Nms'


@pytest.mark.parametrize('body, message', [
    ({'requirements': {TORQUE: {'max': math.nan}}}, r'requirements\.integrated_torque_Nms\.max: must be finite'),
    ({'requirements': {TORQUE: {'min': -math.inf}}}, r'requirements\.integrated_torque_Nms\.min: must be finite'),
    ({'requirements': {TORQUE: {'max': 10**400}}}, r'requirements\.integrated_torque_Nms\.max: must be finite'),
    ({'requirements': {TORQUE: {'min': 2.0, 'max': 1.0}}}, r'integrated_torque_Nms: min 2 exceeds max 1'),
    ({'requirements': ['integrated_torque_Nms']}, r'campaign\.requirements: must be a mapping'),
    ({'runs': 10**9}, r'campaign\.runs: 1000000000 runs need .* GiB .*more than 50% of this machine'),
    ({'runs': 10**40}, r'campaign\.runs: at most 4294967296 runs'),
    ({'seed': 10**40}, r'campaign\.seed: at most 2\^128 - 1'),
    ({'dispersions': {'dynamics.noise.seed': {'distribution': 'run_index', 'offset': 1.5}}},
     r'noise\.seed\.offset: expected 64-bit integers'),
    ({'dispersions': {'dynamics.noise.seed': {'distribution': 'run_index', 'offset': 10**30}}},
     r'noise\.seed\.offset: expected 64-bit integers'),
    ({'dispersions': {'dynamics.noise.seed': {'distribution': 'run_index', 'offset': 2**63 - 2}}},
     r'noise\.seed\.offset: offset \+ run index must fit a 64-bit integer'),
    ({'dispersions': {'pd_controller.torquers.max_torque': {'distribution': 'uniform', 'plus_minus': 1.0}}},
     r'pd_controller\.torquers\.max_torque: the scenario\'s value inf is not finite'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'uniform', 'low': -1e308, 'high': 1e308}}},
     r'pd_controller\.kp: the range overflows'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'normal', 'std': 1e308}}},
     r"run \d+: drawn parameter 'pd_controller.ros__parameters.kp'"),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'normal', 'std': 1e-4, 'link': 'pd_controller.kd'}}},
     r'pd_controller\.kp\.link: expected a list'),
    ({'dispersions': {'dynamics.thrusters.max_force': {'distribution': 'uniform', 'low': 1.0, 'high': 2.0}}},
     r'dynamics\.thrusters\.max_force: the scenario sets no value'),
    ({'dispersions': {'pd_controller.kp': {'distribution': 'bernoulli', 'p': 0.5}}},
     r'pd_controller\.kp: bernoulli draws booleans'),
])
def test_bad_numbers_are_refused_at_load_naming_the_key(tmp_path, monkeypatch, capsys, body, message):
    err = _refused(tmp_path, monkeypatch, capsys, **body)
    assert re.search(message, err), err


def test_runs_on_the_command_line_are_bounded_as_the_files(tmp_path, monkeypatch, capsys):
    err = _refused(tmp_path, monkeypatch, capsys, ('--runs', str(10**9)))
    assert re.search(r'^adcs-montecarlo: --runs: 1000000000 runs need', err), err


def test_a_chunk_that_does_not_fit_in_memory_is_refused(tmp_path, monkeypatch, capsys):
    """1000 runs of 600 steps a batch (~120 MB) on a machine of 128 MiB: refused naming chunk_size and
    the most runs a chunk can take; the same campaign in chunks of 100 loads."""
    monkeypatch.setattr('adcs_sim.app.campaign.checks.physical_memory_bytes', lambda: 128 * 2**20)
    err = _refused(tmp_path, monkeypatch, capsys, runs=1000, chunk_size=1000, dispersions=SEED)
    assert re.search(r'campaign\.chunk_size: 1000 runs a batch need .* GiB .*at most \d+ runs a chunk', err), err
    assert Campaign.load(_campaign_file(tmp_path, CONFIG / 'microsat_pd_slew.yaml', runs=1000, chunk_size=100,
                                        dispersions=SEED)).chunk_size == 100


@settings(derandomize=True, max_examples=60, deadline=None)
@given(st.dictionaries(st.sampled_from(['runs', 'seed', 'chunk_size', 'series_every', 'tolerance_deg', 'offset',
                                        'max']),
                       st.one_of(st.integers(-3, 12), st.integers(), st.floats(allow_nan=True), st.none(),
                                 st.booleans(), st.text(max_size=3), st.lists(st.integers(0, 3), max_size=2)),
                       max_size=4))
def test_hostile_numbers_load_or_are_refused(tmp_path_factory, numbers):
    """Any value of the campaign's numbers: a campaign (of at most 12 runs here), or CampaignError."""
    body = {k: v for k, v in numbers.items() if k not in ('offset', 'max')}
    if isinstance(body.get('runs'), int) and not isinstance(body['runs'], bool) and body['runs'] > 12:
        body['runs'] = 10**12 + body['runs']   # a valid count this large would be drawn at load: refused
    if 'offset' in numbers:
        body['dispersions'] = {'dynamics.noise.seed': {'distribution': 'run_index', 'offset': numbers['offset']}}
    if 'max' in numbers:
        body['requirements'] = {TORQUE: {'max': numbers['max']}}
    path = _campaign_file(tmp_path_factory.mktemp('c'), CONFIG / 'microsat_pd_slew.yaml', **body)
    try:
        campaign = Campaign.load(path)
    except CampaignError as exc:
        assert len(str(exc).splitlines()) == 1
        return
    assert 1 <= campaign.runs <= 12 and campaign.chunk_size >= 1
    assert all(math.isfinite(v) for b in campaign.requirements.values() for v in b.values())
