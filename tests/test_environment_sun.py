"""The Astronomical Almanac's low-precision Sun (adcs_core.environment.sun) against published values.

- Vallado, Fundamentals of Astrodynamics and Applications (4th ed.), Example 5-1: 2006 April 2, 0h UTC
  (JD 2453827.5): r_sun = (0.9771945, 0.1924424, 0.0834308) au, mean equator and equinox of date. This is
  alg. 29 itself worked by hand: it checks our transcription, to the example's 7 digits.
- Meeus, Astronomical Algorithms (2nd ed.), Example 25.a (the low-accuracy solar coordinates, checked
  there against the VSOP87 theory): 1992 October 13.0 TD, apparent RA = 198.38083 deg,
  Dec = -7.78507 deg, R = 0.99766 au. An independent almanac-class value: it checks the method's stated
  accuracy, 0.01 deg.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from adcs_core.environment import frames as F
from adcs_core.environment import sun as S


def _separation_deg(ra1, dec1, ra2, dec2) -> float:
    c = (math.sin(dec1) * math.sin(dec2) + math.cos(dec1) * math.cos(dec2) * math.cos(ra1 - ra2))
    return math.degrees(math.acos(min(1.0, c)))


def test_vallado_example_5_1():
    """Published (0.9771945, 0.1924424, 0.0834308) au; ours within 2e-6 au per component: the example
    rounds to 5e-8 au and takes T_TDB = T_UT1 where we add TT - UTC = 69.184 s to the mean anomaly's
    time (a 5e-7 rad shift of the longitude); 2e-6 au is 1e-4 deg, far inside the method's 0.01 deg."""
    d = F.parse_epoch('2006-04-02T00:00:00Z')
    r = S.sun_position_mod(d) / S.AU
    np.testing.assert_allclose(r, [0.9771945, 0.1924424, 0.0834308], rtol=0, atol=2e-6)


def test_meeus_example_25a_to_the_methods_accuracy():
    """Published apparent RA 198.38083 deg, Dec -7.78507 deg, R = 0.99766 au at 1992-10-13 0h TD
    (TD - UTC = 58.184 s in 1992). Ours within 0.01 deg in direction (the Almanac's stated accuracy;
    measured 0.0063 deg) and 2e-5 au in distance (the example's 5 digits; the Almanac quotes ~1e-4 au)."""
    d = F.parse_epoch('1992-10-13T00:00:00Z') - 58.184 / 86400.0
    r = S.sun_position_mod(d)
    ra, dec = S.right_ascension_declination(r)
    assert _separation_deg(float(ra), float(dec), math.radians(198.38083), math.radians(-7.78507)) < 0.01
    assert np.linalg.norm(r) / S.AU == pytest.approx(0.99766, abs=2e-5)


def test_eci_sun_is_the_mean_of_date_sun_turned_by_gmst_minus_era():
    """ECI right ascension = mean-of-date right ascension - (GMST - ERA) (package docstring), same
    declination and distance; the unit vector is unit."""
    d = np.array([F.parse_epoch('2026-03-20T12:00:00Z'), F.parse_epoch('2030-07-01T00:00:00Z')])
    mod, eci = S.sun_position_mod(d), S.sun_position_eci(d)
    ra_mod, dec_mod = S.right_ascension_declination(mod)
    ra_eci, dec_eci = S.right_ascension_declination(eci)
    np.testing.assert_allclose(np.mod(ra_mod - ra_eci, 2 * math.pi), F.gmst_minus_era(d), atol=1e-12)
    np.testing.assert_allclose(dec_eci, dec_mod, atol=1e-13)
    unit, dist = S.sun_direction_eci(d)
    np.testing.assert_allclose(np.linalg.norm(unit, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(dist, np.linalg.norm(mod, axis=-1), rtol=1e-15)


def test_seasons_closed_forms():
    """At the 2026 March equinox (2026-03-20 14:46 UTC, USNO) the declination is ~0 and near the June
    solstice (2026-06-21 08:24 UTC) it is the obliquity, 23.44 deg; within 0.02 deg (the method's 0.01 deg
    plus the Sun's 0.004 deg/min of declination change against the minute-rounded instants)."""
    _, dec_eq = S.right_ascension_declination(S.sun_position_mod(F.parse_epoch('2026-03-20T14:46:00Z')))
    assert abs(math.degrees(dec_eq)) < 0.02
    _, dec_sol = S.right_ascension_declination(S.sun_position_mod(F.parse_epoch('2026-06-21T08:24:00Z')))
    assert math.degrees(dec_sol) == pytest.approx(23.436, abs=0.02)
