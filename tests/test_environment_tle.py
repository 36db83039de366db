"""SGP4 orbits through our wrapper (adcs_core.environment.tle) and the circular orbit behind the same
interface.

Published test vector: Vallado, Crawford, Hujsak & Kelso 2006, "Revisiting Spacetrack Report #3"
(AIAA 2006-6753), verification case satellite 00005 (the sgp4 library's SGP4-VER.TLE / tcppver.out),
TEME, km and km/s:

    t = 0 min:    r = ( 7022.46529266, -1400.08296755,     0.03995155)  v = ( 1.893841015,  6.405893759,  4.534807250)
    t = 360 min:  r = (-7154.03120202, -3783.17682504, -3536.19412294)  v = ( 4.741887409, -4.151817765, -2.093935425)
    t = 720 min:  r = (-7134.59340119,  6531.68641334,  3260.27186483)  v = (-4.113793027, -2.911922039, -2.557327851)
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_core.environment import frames as F
from adcs_core.environment.tle import CircularOrbitSource, TleOrbit, parse_tle, tle_line_problem
from adcs_core.orbit import MU_EARTH, CircularOrbit

LINE1 = '1 00005U 58002B   00179.78495062  .00000023  00000-0  28098-4 0  4753'
LINE2 = '2 00005  34.2682 348.7242 1859667 331.7664  19.3264 10.82419157413667'
PUBLISHED = {
    0.0: ((7022.46529266, -1400.08296755, 0.03995155), (1.893841015, 6.405893759, 4.534807250)),
    360.0: ((-7154.03120202, -3783.17682504, -3536.19412294), (4.741887409, -4.151817765, -2.093935425)),
    720.0: ((-7134.59340119, 6531.68641334, 3260.27186483), (-4.113793027, -2.911922039, -2.557327851)),
}


def test_satellite_00005_through_our_wrapper():
    """Ours equals the published vectors to their printed digits: 1e-8 km (0.01 mm) and 1e-9 km/s,
    with 2x margin for the last digit's rounding."""
    orbit = TleOrbit(LINE1, LINE2)
    minutes = np.array(sorted(PUBLISHED))
    r, v = orbit.teme(orbit.epoch_days + minutes / 1440.0)
    for i, m in enumerate(minutes):
        np.testing.assert_allclose(r[i], PUBLISHED[m][0], rtol=0, atol=2e-8)
        np.testing.assert_allclose(v[i], PUBLISHED[m][1], rtol=0, atol=2e-9)


def test_tle_epoch_and_eci_state():
    """Epoch 00179.78495062 = 2000-06-27 18:50:19.7336 UTC (the tcppver.out times are epoch + t); the
    ECI state is the TEME one in metres turned by GMST - ERA about z (norms and z unchanged)."""
    orbit = TleOrbit(LINE1, LINE2)
    assert orbit.epoch_days == pytest.approx(F.parse_epoch('2000-06-27T18:50:19.733571Z'), abs=1e-9)
    d = orbit.epoch_days + np.array([0.0, 0.25, 0.5])
    r_teme, v_teme = orbit.teme(d)
    r, v = orbit.state(d)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), 1e3 * np.linalg.norm(r_teme, axis=-1), rtol=1e-14)
    np.testing.assert_allclose(r[:, 2], 1e3 * r_teme[:, 2], rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), 1e3 * np.linalg.norm(v_teme, axis=-1), rtol=1e-14)
    np.testing.assert_allclose(r, F.equinox_to_eci(1e3 * r_teme, d), rtol=1e-15)


def test_batch_equals_one_time_at_a_time_and_keeps_shape():
    orbit = TleOrbit(LINE1, LINE2)
    d = orbit.epoch_days + np.linspace(0, 1, 6).reshape(2, 3)
    r, v = orbit.state(d)
    assert r.shape == v.shape == (2, 3, 3)
    for idx in np.ndindex(2, 3):
        r1, v1 = orbit.state(d[idx])
        np.testing.assert_array_equal(r1, r[idx])
        np.testing.assert_array_equal(v1, v[idx])


@pytest.mark.parametrize('line1, line2, match', [
    (LINE1, LINE2[:-1] + '0', 'checksum'),
    (LINE1[:-1] + '9', LINE2, 'checksum'),
    (LINE1[:40], LINE2, '69 characters'),
    (LINE2, LINE1, 'must start with "1 "'),
    (LINE1, LINE2.replace('34.2682', '34x2682'), 'malformed'),     # 'x' and '.' both count 0
    (LINE1, LINE2[:52] + '-' + LINE2[53:], 'malformed'),   # negative mean motion ('-' counts 1, as '1')
    (LINE1, LINE2.replace('00005', '00006', 1)[:-1] + '8', 'malformed'),       # object numbers differ
    (1234, LINE2, 'must be a string'),
])
def test_malformed_tles_raise_value_error_naming_the_problem(line1, line2, match):
    with pytest.raises(ValueError, match=match):
        parse_tle(line1, line2)


@settings(derandomize=True, max_examples=150, deadline=None)
@given(position=st.integers(0, 68), char=st.sampled_from(list('0123456789 .-+xE')), which=st.integers(1, 2))
def test_any_one_character_corruption_is_refused_or_still_a_valid_tle(position, char, which):
    """Bad input never crashes: a corrupted line gives ValueError, or (a change the format and checksum
    still accept) a Satrec that propagates; nothing else escapes."""
    lines = [LINE1, LINE2]
    line = lines[which - 1]
    lines[which - 1] = line[:position] + char + line[position + 1:]
    try:
        sat = parse_tle(*lines)
    except ValueError as exc:
        assert str(exc)
        return
    assert tle_line_problem(lines[0], 1) is None and tle_line_problem(lines[1], 2) is None
    assert sat.sgp4(sat.jdsatepoch, sat.jdsatepochF)[0] in range(7)


def test_circular_orbit_source_is_the_circular_orbit():
    """|r| = R_E + h, v perpendicular to r with |v| = sqrt(mu / r), direction = CircularOrbit.position_unit
    at the same scenario time, and the epoch offsets time."""
    orbit = CircularOrbit(altitude=500e3, inclination=math.radians(97.4), raan=1.0, arg_latitude0=0.3)
    source = CircularOrbitSource(orbit, epoch_days=9000.5)
    t = np.array([0.0, 600.0, 4000.0])
    r, v = source.state(9000.5 + t / 86400.0)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), orbit.radius, rtol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), math.sqrt(MU_EARTH / orbit.radius), rtol=1e-14)
    np.testing.assert_allclose(np.sum(r * v, axis=-1), 0.0, atol=1e-3)
    for i, ti in enumerate(t):
        np.testing.assert_allclose(r[i] / orbit.radius, orbit.position_unit(ti), atol=1e-9 / orbit.radius * 1e3)
