"""Environment.sample and the environment.* parameter block: shapes, determinism, physics closed forms
along a whole orbit, and bad input (epochs, times, TLEs) refused by ValueError naming the problem."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_core.environment.eclipse import EARTH_RADIUS
from adcs_core.environment.environment import Environment, EnvironmentSample, build_environment
from adcs_core.environment.frames import parse_epoch
from adcs_core.environment.magnetic import IgrfModel
from adcs_core.environment.options import IGRF_YEARS
from adcs_core.environment.tle import TleOrbit
from adcs_msgs_py.blocks import check_environment, environment_params
from adcs_msgs_py.params import ParameterError, Schema

LINE1 = '1 00005U 58002B   00179.78495062  .00000023  00000-0  28098-4 0  4753'
LINE2 = '2 00005  34.2682 348.7242 1859667 331.7664  19.3264 10.82419157413667'
SCHEMA = Schema('environment_test', environment_params(), cross_check=check_environment)
EQUINOX = '2026-03-20T14:46:00Z'      # USNO: the Sun crosses the equator, declination 0


@pytest.fixture(scope='module')
def env():
    return build_environment(SCHEMA.validate({'environment.epoch': EQUINOX}))


def test_defaults_build_a_circular_igrf_conical_environment(env):
    assert isinstance(env, Environment)
    assert env.shadow_model == 'conical' and env.magnetic.max_degree == 13
    s = env.sample(0.0)
    assert isinstance(s, EnvironmentSample)
    assert s.r_eci.shape == (3,) and s.shadow.shape == ()
    assert np.linalg.norm(s.r_eci) == pytest.approx(EARTH_RADIUS + 500e3)
    assert np.linalg.norm(s.sun_eci) == pytest.approx(1.0, abs=1e-15)
    assert 1.47e11 < s.sun_distance < 1.53e11
    assert 18e-6 < np.linalg.norm(s.b_eci) < 60e-6
    np.testing.assert_allclose(s.nadir_eci, -s.r_eci / np.linalg.norm(s.r_eci), atol=1e-16)
    again = build_environment(SCHEMA.validate({'environment.epoch': EQUINOX}))
    assert again.magnetic is env.magnetic and not env.magnetic.g.flags.writeable   # one read-only model


def test_sample_batches_any_shape_and_is_deterministic(env):
    """Same inputs, same bits; a time alone gives the bits it has inside a batch (as adcs_core's
    products: no BLAS reduction whose order depends on the batch)."""
    t = np.arange(12.0).reshape(3, 4) * 97.0
    s = env.sample(t)
    for field in ('r_eci', 'v_eci', 'sun_eci', 'b_eci', 'nadir_eci'):
        assert getattr(s, field).shape == (3, 4, 3), field
    for field in ('sun_distance', 'shadow'):
        assert getattr(s, field).shape == (3, 4), field
    again = env.sample(t)
    one = env.sample(t[2, 1])
    for field in ('r_eci', 'v_eci', 'sun_eci', 'sun_distance', 'shadow', 'b_eci', 'nadir_eci'):
        np.testing.assert_array_equal(getattr(again, field), getattr(s, field))
        np.testing.assert_array_equal(getattr(one, field), getattr(s, field)[2, 1])   # same bits alone
    with pytest.raises(AttributeError):
        s.shadow = None                      # frozen


def test_equatorial_orbit_at_equinox_eclipse_fraction(env):
    """Equatorial 500 km orbit at the equinox: the Sun is in the orbit plane (declination < 0.05 deg
    over the orbit: 0.002 deg at the instant, 0.4 deg/day after), so the time in shadow (umbra + half the penumbra) is asin(R_E / r) / pi = 0.3778
    of the period, within 2e-3 (the Sun's 0.06 deg/orbit motion and 1 s sampling)."""
    period = 2 * math.pi / math.sqrt(3.986004418e14 / (EARTH_RADIUS + 500e3) ** 3)
    s = env.sample(np.arange(0.0, period, 1.0))
    assert abs(s.sun_eci[..., 2]).max() < math.sin(math.radians(0.05))
    assert np.mean(1.0 - s.shadow) == pytest.approx(math.asin(EARTH_RADIUS / (EARTH_RADIUS + 500e3)) / math.pi,
                                                   abs=2e-3)
    assert np.all(s.shadow[np.einsum('...i,...i', s.r_eci, s.sun_eci) > 0] == 1.0)   # day side lit


def test_tle_dipole_cylindrical_from_params():
    p = SCHEMA.validate({'environment.orbit': 'tle', 'environment.tle.line1': LINE1, 'environment.tle.line2': LINE2,
                         'environment.magnetic_model': 'dipole', 'environment.shadow_model': 'cylindrical',
                         'environment.epoch': '2000-06-28T00:00:00Z'})
    env = build_environment(p)
    assert isinstance(env.orbit, TleOrbit)
    s = env.sample(np.arange(0.0, 3600.0, 60.0))
    assert set(np.unique(s.shadow)) <= {0.0, 1.0}
    r = np.linalg.norm(s.r_eci, axis=-1)
    assert 6.4e6 < r.min() and r.max() < 1.2e7                         # e = 0.186, a ~ 8600 km
    igrf = build_environment({**p, 'environment.magnetic_model': 'igrf'}).sample(0.0).b_eci
    angle = math.degrees(math.acos(np.dot(igrf, s.b_eci[0]) / np.linalg.norm(igrf) / np.linalg.norm(s.b_eci[0])))
    assert angle < 40.0                                                # the dipole's bound


@pytest.mark.parametrize('given, key, match', [
    ({'environment.epoch': '2026-13-01T00:00:00Z'}, 'environment.epoch', 'not an ISO-8601'),
    ({'environment.epoch': '2026-12-31T23:59:60Z'}, 'environment.epoch', 'not an ISO-8601'),
    ({'environment.epoch': '2150-01-01T00:00:00Z'}, 'environment.epoch', '1900-2100'),
    ({'environment.epoch': '2031-01-01T00:00:00Z'}, 'environment.epoch', 'IGRF-14'),
    ({'environment.orbit': 'kepler'}, 'environment.orbit', 'must be one of'),
    ({'environment.circular.altitude': 0.0}, 'environment.circular.altitude', '> 0'),
    ({'environment.orbit': 'tle'}, 'environment.tle.line1', 'required'),
    ({'environment.orbit': 'tle', 'environment.tle.line1': LINE1}, 'environment.tle.line2', 'required'),
    ({'environment.tle.line2': LINE2[:-1] + '1'}, 'environment.tle.line2', 'checksum'),
    ({'environment.tle.line1': LINE1[:30]}, 'environment.tle.line1', '69 characters'),
    ({'environment.orbit': 'tle', 'environment.tle.line1': LINE1,
      'environment.tle.line2': LINE2.replace('00005', '00006', 1)[:-1] + '8'}, 'environment.tle.line1', 'malformed'),
    ({'environment.magnetic_model': 'wmm'}, 'environment.magnetic_model', 'must be one of'),
    ({'environment.shadow_model': 'none'}, 'environment.shadow_model', 'must be one of'),
])
def test_bad_parameters_name_the_key(given, key, match):
    with pytest.raises(ParameterError, match=match) as info:
        SCHEMA.validate(given)
    assert info.value.key == key


@settings(derandomize=True, max_examples=200, deadline=None)
@given(text=st.one_of(st.text(max_size=32), st.from_regex(r'\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z?', fullmatch=True)))
def test_any_epoch_string_parses_or_is_refused_by_value_error(text):
    try:
        d = parse_epoch(text)
    except ValueError as exc:
        assert 'epoch' in str(exc)
        return
    assert math.isfinite(d) and -36525 <= d <= 36525


@settings(derandomize=True, max_examples=60, deadline=None)
@given(t=st.lists(st.floats(min_value=-1e7, max_value=1e7)
                  | st.sampled_from([math.nan, math.inf, -math.inf]), min_size=1, max_size=5))
def test_non_finite_times_are_refused_and_finite_ones_give_finite_values(env, t):
    t = np.array(t)
    if not np.all(np.isfinite(t)):
        with pytest.raises(ValueError, match='finite'):
            env.sample(t)
        return
    s = env.sample(t)
    for field in ('r_eci', 'v_eci', 'sun_eci', 'sun_distance', 'shadow', 'b_eci', 'nadir_eci'):
        assert np.all(np.isfinite(getattr(s, field))), field
    assert np.all((s.shadow >= 0) & (s.shadow <= 1))


def test_the_parameter_checks_igrf_span_is_the_coefficient_files():
    """options.IGRF_YEARS (used by the parameter check, which must not import the model) is the span of
    the file magnetic.IgrfModel reads."""
    epochs = IgrfModel().epochs
    assert parse_epoch(f'{IGRF_YEARS[0]}-01-01T00:00:00Z') == pytest.approx(epochs[0], abs=1e-9)
    assert parse_epoch(f'{IGRF_YEARS[1]}-01-01T00:00:00Z') == pytest.approx(epochs[-1], abs=1e-9)


def test_scalar_non_finite_time_is_refused(env):
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError, match='finite'):
            env.sample(bad)
