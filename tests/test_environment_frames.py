"""Frames and time of adcs_core.environment.frames against published values and closed forms.

Published values: the Earth rotation angle at J2000.0 (IERS Conventions 2010 eq. 5.15); Vallado,
Fundamentals of Astrodynamics and Applications (4th ed.), Example 3-3 (ECEF -> geodetic); Vallado,
Crawford, Hujsak & Kelso 2006 (AIAA 2006-6753) TEME -> PEF example.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from adcs_core.environment import frames as F
from adcs_core.environment.tle import CircularOrbitSource
from adcs_core.orbit import CircularOrbit, orbit_frame_matrix


def test_julian_date_of_j2000_and_iso_forms():
    assert F.julian_date('2000-01-01T12:00:00Z') == 2451545.0
    assert F.parse_epoch('2000-01-01T12:00:00') == 0.0                    # no offset: UTC
    assert F.parse_epoch('2000-01-01T13:00:00+01:00') == 0.0              # offsets converted
    assert F.julian_date('2006-04-02T00:00:00Z') == 2453827.5             # Vallado Example 5-1's JD
    assert F.parse_epoch('2000-01-02T00:00:00.5Z') == pytest.approx(0.5 + 0.5 / 86400, abs=1e-12)


def test_era_at_j2000_equals_the_iers_constant():
    """IERS 2010 eq. 5.15 at T_u = 0: ERA = 2 pi 0.7790572732640 (exact up to one rounding)."""
    assert F.earth_rotation_angle(0.0) == pytest.approx(2 * math.pi * 0.7790572732640, rel=0, abs=1e-15)


def test_era_turns_once_per_sidereal_day():
    """dERA/dt = 2 pi 1.00273781191135448 per UT1 day: after one solar day the angle has advanced by
    2 pi 0.00273781191135448 (mod 2 pi), to round-off."""
    d0 = 9000.25
    step = F.earth_rotation_angle(d0 + 1.0) - F.earth_rotation_angle(d0)
    assert np.mod(step, 2 * math.pi) == pytest.approx(2 * math.pi * 0.00273781191135448, abs=1e-11)
    assert F.EARTH_ROTATION_RATE == pytest.approx(7.2921151467e-5, rel=1e-10)


def test_eci_ecef_round_trip_and_batch():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(4, 5, 3)) * 7e6
    d = rng.uniform(0, 1e4, size=(4, 5))
    back = F.ecef_to_eci(F.eci_to_ecef(r, d), d)
    np.testing.assert_allclose(back, r, rtol=0, atol=1e-8)          # m, round-off of 7e6 m vectors
    single = F.eci_to_ecef(r[2, 3], d[2, 3])                        # one element alone = in the batch
    np.testing.assert_array_equal(single, F.eci_to_ecef(r, d)[2, 3])
    np.testing.assert_allclose(np.linalg.norm(F.eci_to_ecef(r, d), axis=-1), np.linalg.norm(r, axis=-1), rtol=1e-15)


def test_teme_to_earth_fixed_matches_vallado_2006():
    """Vallado et al. 2006 (AIAA 2006-6753) TEME example: at 2004-04-06 07:51:28.386009 UTC,
    r_TEME = (5094.18016210, 6127.64465950, 6380.34453270) km -> r_PEF = (-1033.4750312, 7901.3055856,
    6380.3445328) km with UT1 - UTC = -0.4399619 s. Ours: R3(ERA) R3(GMST - ERA) r_TEME = R3(GMST) r_TEME.
    With the published UT1 the tolerance is 1 m (GMST2006 vs GMST82, < 1 mas); with UT1 = UTC (the
    package's assumption) the published point is 0.44 s of Earth rotation away: 3.2e-5 rad x 7968 km =
    0.26 km, tolerance 0.3 km."""
    r_teme = np.array([5094.18016210, 6127.64465950, 6380.34453270]) * 1e3
    r_pef = np.array([-1033.4750312, 7901.3055856, 6380.3445328]) * 1e3
    d_utc = F.parse_epoch('2004-04-06T07:51:28.386009Z')
    d_ut1 = d_utc - 0.4399619 / 86400.0
    ours = F.eci_to_ecef(F.equinox_to_eci(r_teme, d_ut1), d_ut1)
    assert np.linalg.norm(ours - r_pef) < 1.0
    approx = F.eci_to_ecef(F.equinox_to_eci(r_teme, d_utc), d_utc)
    assert 0.2e3 < np.linalg.norm(approx - r_pef) < 0.3e3


def test_gmst_minus_era_is_the_precession_in_right_ascension():
    """IERS 2010 eq. 5.32: GMST - ERA = 0.014506" at J2000 and grows by 4612.16"/century (0.0128 deg/yr)."""
    assert F.gmst_minus_era(-F.TT_MINUS_UTC / 86400.0) == pytest.approx(0.014506 * F.ARCSEC, rel=1e-12)
    per_year = F.gmst_minus_era(365.25) - F.gmst_minus_era(0.0)
    assert math.degrees(per_year) == pytest.approx(4612.156534 / 100 / 3600, rel=1e-4)


def test_geodetic_of_vallado_example_3_3():
    """Vallado Example 3-3: r_ECEF = (6524.834, 6862.875, 6448.296) km -> phi_gd = 34.352496 deg,
    lambda = 46.4464 deg, h_ellp = 5085.22 km, and phi_gc = 34.173429 deg the geocentric latitude of the
    point below it on the ellipsoid (tan phi_gc = (1 - e^2) tan phi_gd). Tolerances: half the last printed
    digit (the example's rounding), except the geodetic latitude: ours 34.3524952 deg on WGS-84, the
    example's Earth has e = 0.081819221456 (WGS-84: 0.0818191908), 1e-6 deg apart; 2e-6 deg."""
    r = np.array([6524.834, 6862.875, 6448.296]) * 1e3
    lat, lon, h = F.geodetic(r)
    assert math.degrees(lat) == pytest.approx(34.352496, abs=2e-6)
    assert math.degrees(lon) == pytest.approx(46.4464, abs=5e-5)
    assert h == pytest.approx(5085.22e3, abs=5.0)
    foot = F.geodetic_to_ecef(lat, lon, 0.0)
    assert math.degrees(F.geocentric(foot)[0]) == pytest.approx(34.173429, abs=2e-6)


@pytest.mark.parametrize('lat_deg, lon_deg, h', [(0, 0, 0), (90, 0, 0), (-90, 30, 1000), (45, -120, 500e3),
                                                 (-33.3, 151.2, 35786e3), (89.9999, 10, 400e3)])
def test_geodetic_round_trip_and_known_points(lat_deg, lon_deg, h):
    """geodetic(geodetic_to_ecef(x)) = x to 1e-12 rad and 1 mm, poles included; (0, 0, 0) is (a, 0, 0)
    and the pole is (0, 0, b) with b = a (1 - f)."""
    r = F.geodetic_to_ecef(math.radians(lat_deg), math.radians(lon_deg), h)
    lat, lon, hh = F.geodetic(r)
    assert lat == pytest.approx(math.radians(lat_deg), abs=1e-12)
    assert hh == pytest.approx(h, abs=1e-3)
    if abs(lat_deg) != 90:
        assert lon == pytest.approx(math.radians(lon_deg), abs=1e-12)
    if (lat_deg, h) == (0, 0):
        np.testing.assert_allclose(r, [F.WGS84_A, 0, 0], atol=1e-9)
    if lat_deg == 90:
        np.testing.assert_allclose(r, [0, 0, F.WGS84_A * (1 - F.WGS84_F)], atol=1e-6)


def test_ned_and_enu_are_right_handed_and_point_where_they_say():
    lat, lon = math.radians(30.0), math.radians(60.0)
    ned = F.ned_matrix(lat, lon)
    np.testing.assert_allclose(ned.T @ ned, np.eye(3), atol=1e-15)
    assert np.linalg.det(ned) == pytest.approx(1.0)
    up = F.geodetic_to_ecef(lat, lon, 1.0) - F.geodetic_to_ecef(lat, lon, 0.0)
    np.testing.assert_allclose(ned[:, 2], -up / np.linalg.norm(up), atol=1e-9)     # down = -normal
    assert ned[2, 0] > 0                                                            # north has +z
    enu = F.enu_matrix(lat, lon)
    assert np.linalg.det(enu) == pytest.approx(1.0)
    np.testing.assert_array_equal(enu[:, 0], ned[:, 1])


def test_orbit_frame_from_state_equals_the_circular_orbit_frame():
    """The general orbit frame (r, v) reuses adcs_core.orbit's definition: equal on a circular orbit."""
    orbit = CircularOrbit(altitude=550e3, inclination=math.radians(51.6), raan=0.4, arg_latitude0=1.0)
    source = CircularOrbitSource(orbit, epoch_days=0.0)
    for t in (0.0, 1234.5, 5000.0):
        r, v = source.state(t / 86400.0)
        np.testing.assert_allclose(F.orbit_frame_from_state(r, v), orbit_frame_matrix(orbit, t), atol=1e-12)
        np.testing.assert_allclose(r / np.linalg.norm(r), orbit.position_unit(t), atol=1e-12)


def test_earth_fixed_point_has_zero_velocity_relative_to_the_earth():
    """A point fixed in ECEF moves in ECI with v = w_E x r: eci_to_ecef_velocity gives 0 (to round-off
    of the 465 m/s equatorial speed) and the position it maps to does not change with time."""
    r_ecef = F.geodetic_to_ecef(math.radians(20.0), math.radians(-70.0), 400e3)
    d = F.parse_epoch('2026-03-20T12:00:00Z') + np.array([0.0, 0.01, 0.2])
    r_eci = F.ecef_to_eci(r_ecef, d)
    w = np.array([0.0, 0.0, F.EARTH_ROTATION_RATE])
    v_eci = np.cross(w, r_eci)
    np.testing.assert_allclose(F.eci_to_ecef_velocity(r_eci, v_eci, d), 0.0, atol=1e-9)
    np.testing.assert_allclose(F.eci_to_ecef(r_eci, d), np.broadcast_to(r_ecef, (3, 3)), atol=1e-7)
    # and the ERA's rate is that w: a sidereal day later the ECI position repeats
    np.testing.assert_allclose(F.ecef_to_eci(r_ecef, d[0] + 1.0 / F.ERA_RATE), r_eci[0], atol=1e-6)
