"""Validated, then failing mid-run (issue #31, class "Validated, then failing mid-run").

Validation looked at the run's first instant: a TLE that decays inside the run, a span that leaves
the field model's years, negative seeds, a control period below a nanosecond, thousands of wheels
and a bag larger than the disk all passed, then failed mid-run (or took seconds per step). Now the
whole run is checked before anything starts (adcs_sim/app/scenario/checks.py): ``adcs-run`` exits 2
with one line naming the section and key (or the resource), no domain leased, no output folder.
The estimator's parameters are bounded to what its filter's arithmetic can take: fuzzed, each
draw is either refused at validation or the batch engine runs it finite.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.paths import CONFIG
from support.scenarios import make_scenario

from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.graph import runner
from adcs_sim.app.scenario import checks as scenario_checks
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario, validate_sections

LEO = 'leo_tle_sun_magnetometer_mekf.yaml'
# A 200 km TLE with a large drag term (B* = 0.05): SGP4 reports it decayed 240 min after its epoch.
DECAYING = ('1 90002U          26079.50000000  .00000000  00000-0  50000-1 0    09',
            '2 90002  97.4000  10.0000 0005000  90.0000   0.0000 16.30000000    08')


def refused_before_anything(path, section: str, key: str, capsys, monkeypatch, *words: str) -> str:
    """``adcs-run`` refuses ``path`` in one line naming ``section.key`` (and ``words``), exit 2,
    before a domain is leased or the output folder made."""
    leased = []
    monkeypatch.setattr(runner, 'lease_domain', lambda *a: leased.append(a))
    out = path.parent / 'run'
    assert runner.main([str(path), '--out', str(out), '--no-progress']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"'{section}.ros__parameters.{key}'" in err, err
    for word in words:
        assert word in err, err
    assert not leased and not out.exists()
    return err


def test_a_tle_that_decays_inside_the_run_is_refused(tmp_path, capsys, monkeypatch):
    """Accepted at its epoch, SGP4 fails 240 min in: a 6 h run is refused, a 3 h one is not."""
    tle = {'environment.tle.line1': DECAYING[0], 'environment.tle.line2': DECAYING[1]}
    fine = make_scenario(tmp_path, {'dynamics': {**tle, 'duration': 3 * 3600.0},
                                    'mekf_estimator': tle}, base=LEO)
    validate_scenario(fine)
    path = make_scenario(tmp_path, {'dynamics': {**tle, 'duration': 6 * 3600.0}}, base=LEO)
    refused_before_anything(path, 'dynamics', 'environment.tle.line1', capsys, monkeypatch, 'decayed', '240.0 min')


def test_the_estimators_own_tle_is_propagated_over_the_run_too(tmp_path, capsys, monkeypatch):
    tle = {'environment.tle.line1': DECAYING[0], 'environment.tle.line2': DECAYING[1]}
    path = make_scenario(tmp_path, {'dynamics': {'duration': 6 * 3600.0}, 'mekf_estimator': tle}, base=LEO)
    refused_before_anything(path, 'mekf_estimator', 'environment.tle.line1', capsys, monkeypatch, 'decayed')


def test_a_run_that_leaves_the_field_models_years_is_refused(tmp_path, capsys, monkeypatch):
    """The epoch is inside IGRF-14's 1900-2030, the run's end is not."""
    late = {'environment.epoch': '2029-12-31T23:30:00Z', 'environment.orbit': 'circular'}
    path = make_scenario(tmp_path, {'dynamics': {**late, 'duration': 3600.0}, 'mekf_estimator': late}, base=LEO)
    refused_before_anything(path, 'dynamics', 'duration', capsys, monkeypatch, 'IGRF', '2030.00')
    path = make_scenario(tmp_path, {'dynamics': {'duration': 3600.0}, 'mekf_estimator': late}, base=LEO)
    refused_before_anything(path, 'mekf_estimator', 'environment.epoch', capsys, monkeypatch, 'IGRF')


@pytest.mark.parametrize('key', ['noise.seed', 'link_faults.seed'])
def test_negative_seeds_are_refused(tmp_path, capsys, monkeypatch, key):
    """numpy refuses a negative seed when the node or the batch engine draws (mid-start)."""
    path = make_scenario(tmp_path, {'dynamics': {key: -1, 'noise.rate_std': 1e-4, 'link_faults.drop': 0.1}})
    refused_before_anything(path, 'dynamics', key, capsys, monkeypatch, '>= 0')


def test_a_control_period_below_a_nanosecond_is_refused(tmp_path, capsys, monkeypatch):
    """The time grid is in integer ns: 1e-10 s rounded to a 0 ns period."""
    path = make_scenario(tmp_path, {'dynamics': {'control_period': 1e-10, 'integrator.max_step': 1e-10,
                                                 'duration': 1e-8}})
    refused_before_anything(path, 'dynamics', 'control_period', capsys, monkeypatch, '1e-09')


def test_thousands_of_wheels_are_refused(tmp_path, capsys, monkeypatch):
    """1000 wheels validated, then the first step took about a minute (the command's message template)."""
    n = 1000
    rng = np.random.default_rng(0)
    axes = rng.normal(size=(n, 3))
    axes = (axes / np.linalg.norm(axes, axis=1, keepdims=True)).ravel().tolist()
    wheels = {'wheels.names': [f'rw_{i}' for i in range(n)], 'wheels.axes': axes, 'wheels.max_torque': [0.01] * n}
    path = make_scenario(tmp_path, {'dynamics': {**wheels, 'wheels.spin_inertia': [1e-5] * n,
                                                 'wheels.max_speed': [600.0] * n},
                                    'pd_controller': {k: list(v) for k, v in wheels.items()}})   # no YAML alias
    refused_before_anything(path, 'dynamics', 'wheels.names', capsys, monkeypatch, '1000 wheels', 'at most 64')


def test_a_bag_larger_than_the_free_disk_is_refused(tmp_path, capsys, monkeypatch):
    """600 steps x 11 messages x 128 B ~ 0.8 MiB against 100 kB free at --out's disk."""
    usage = namedtuple('usage', 'total used free')
    seen = []
    monkeypatch.setattr(scenario_checks.shutil, 'disk_usage',
                        lambda where: seen.append(where) or usage(10 ** 12, 10 ** 12 - 10 ** 5, 10 ** 5))
    err = refused_before_anything(make_scenario(tmp_path), 'dynamics', 'duration', capsys, monkeypatch,
                                  '601 steps x 11 messages', 'free on the disk of')
    assert tmp_path in seen and str(tmp_path) in err


# --- the estimator's parameters: refused, or run finite --------------------------------------------

# log10 of each sigma: mostly within and around the bounds (1e-330 is 0 as a double), sometimes the
# issue's huge values
EXPONENTS = st.one_of(st.floats(-330.0, 3.0), st.sampled_from([77.0, 155.0, 200.0]))
BASES = {name: load_params_file(str(CONFIG / name)) for name in ('microsat_gsmn_slew_mekf.yaml', LEO)}
STEPS = 5


def _finite_or_refused(base: str, overrides: dict, period: float) -> None:
    sections = {name: dict(values) for name, values in BASES[base].items()}
    sections['mekf_estimator'].update(overrides)
    sections['dynamics'].update({'control_period': period, 'integrator.max_step': period,
                                 'duration': STEPS * period})
    try:
        validated = validate_sections(sections, base)
    except ParameterError:
        return
    result = BatchSimulation.from_runs([validated]).run()
    assert result.failure == [None] and int(result.n_steps[0]) == STEPS, (overrides, result.failure)
    for key in ('q', 'w', 'bias', 'cov'):
        assert np.isfinite(result.estimate[key]).all(), (overrides, key)
    assert np.isfinite(result.q).all() and np.isfinite(result.w).all()


def _sigma(exponent: float) -> float:
    return 10.0 ** exponent if exponent < 308 else math.inf


KEYS = ('gyro.sigma_v', 'gyro.sigma_u', 'initial.attitude_sigma', 'initial.bias_sigma', 'measurement')
ORDINARY = st.fixed_dictionaries({key: st.floats(-8.0, -1.0) for key in KEYS})


@settings(derandomize=True, max_examples=60, deadline=None)
@given(base=st.sampled_from(sorted(BASES)), ordinary=ORDINARY, which=st.sampled_from(KEYS),
       extreme=st.one_of(st.none(), EXPONENTS), period=st.sampled_from([0.01, 1.0]))
def test_fuzzed_filter_parameters_are_refused_or_run_finite(base, ordinary, which, extreme, period):
    """Ordinary sigmas (1e-8..1e-1), one of them (or none) anywhere from 1e-330 to 1e200."""
    e = {**ordinary, **({} if extreme is None else {which: extreme})}
    overrides = {'gyro.sigma_v': _sigma(e['gyro.sigma_v']), 'gyro.sigma_u': _sigma(e['gyro.sigma_u']),
                 'initial.attitude_sigma': [_sigma(e['initial.attitude_sigma'])] * 3,
                 'initial.bias_sigma': [_sigma(e['initial.bias_sigma'])] * 3}
    if base == LEO:   # the magnetometer's sigma in T: a direction noise of sigma / ~3e-5 T
        overrides.update({'sun.sigma': _sigma(e['measurement']), 'magnetometer.sigma': _sigma(e['measurement'] - 4.5)})
    else:
        overrides['star_tracker.sigma'] = [_sigma(e['measurement'])] * 3
    _finite_or_refused(base, overrides, period)
