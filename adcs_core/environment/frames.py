"""Time scales and frames (conventions: the package docstring of :mod:`adcs_core.environment`).

Time: :func:`parse_epoch` (an ISO-8601 UTC string -> days since J2000.0), :func:`julian_date`,
:func:`days_since_j2000` (scenario seconds -> days), TT = UTC + 69.184 s (:data:`TT_MINUS_UTC`),
UT1 ~= UTC.

Earth rotation: :func:`earth_rotation_angle` (IERS Conventions 2010, eq. 5.15),
:func:`gmst_minus_era` (eq. 5.32 without its ERA term: the accumulated precession in right ascension),
ECI <-> ECEF (:func:`eci_to_ecef`, :func:`ecef_to_eci`, :func:`eci_to_ecef_velocity`: one rotation about z
by the ERA), TEME / mean-of-date -> ECI (:func:`equinox_to_eci`).

Earth-fixed coordinates on WGS-84 (NIMA TR8350.2, a = 6378137 m, 1/f = 298.257223563):
:func:`geocentric`, :func:`geodetic` (Vallado, Fundamentals of Astrodynamics and Applications, 4th ed.,
alg. 12, iterated a fixed number of times), :func:`geodetic_to_ecef` (Vallado eq. 3-7), local frames
:func:`ned_matrix` and :func:`enu_matrix`; the orbit frame of a general orbit from its state
(:func:`orbit_frame_from_state`, equal to :func:`adcs_core.orbit.orbit_frame_matrix` on a circular orbit).

``R3(a)`` below is the frame rotation about z by ``a``: ``x' = cos a x + sin a y``, ``y' = -sin a x +
cos a y``, ``z' = z``.
"""
from __future__ import annotations

import math
from datetime import datetime, timedelta, timezone

import numpy as np

J2000_JD = 2451545.0            # JD of J2000.0 (2000-01-01 12:00 TT; used here on the UTC/UT1 axis)
SECONDS_PER_DAY = 86400.0
DAYS_PER_CENTURY = 36525.0
TT_MINUS_UTC = 69.184           # s: TAI - UTC = 37 s (since 2017-01-01) + TT - TAI = 32.184 s
ERA_AT_J2000 = 0.7790572732640  # revolutions, IERS 2010 eq. 5.15
ERA_RATE = 1.00273781191135448  # revolutions per UT1 day, IERS 2010 eq. 5.15
EARTH_ROTATION_RATE = 2.0 * math.pi * ERA_RATE / SECONDS_PER_DAY  # rad/s, 7.2921151467e-5
ARCSEC = math.pi / (180.0 * 3600.0)
# IERS 2010 eq. 5.32: GMST - ERA in arcsec, polynomial in Julian centuries of TT since J2000.
_GMST_POLY = (0.014506, 4612.156534, 1.3915817, -0.00000044, -0.000029956, -0.0000000368)
WGS84_A = 6378137.0             # m
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
GEODETIC_ITERATIONS = 6         # each gains a factor ~e^2 = 0.0067: 6 give < 1e-12 rad from LEO to GEO

_J2000_UTC = datetime(2000, 1, 1, 12, 0, 0, tzinfo=timezone.utc)


def parse_epoch(epoch: str) -> float:
    """An ISO-8601 instant (``"2026-03-20T12:00:00Z"``, ``"2026-03-20 12:00:00.5+00:00"``; no offset means
    UTC) -> days since J2000.0 on the UTC axis (``JD_UTC - 2451545.0``). Raises ValueError naming the
    problem: not a string, not ISO-8601, a leap second (``:60``), or outside 1900-2100 (the validity of
    the formulas used with it)."""
    if not isinstance(epoch, str):
        raise ValueError(f'epoch must be an ISO-8601 UTC string such as "2026-03-20T12:00:00Z", got {epoch!r}')
    text = epoch.strip()
    try:
        when = datetime.fromisoformat(text[:-1] + '+00:00' if text.endswith(('Z', 'z')) else text)
    except ValueError as exc:
        raise ValueError(f'epoch {epoch!r} is not an ISO-8601 date and time ({exc}); '
                         'write e.g. "2026-03-20T12:00:00Z"') from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    when = when.astimezone(timezone.utc)
    if not 1900 <= when.year <= 2100:
        raise ValueError(f'epoch {epoch!r} is outside 1900-2100 (the solar ephemeris and the Earth '
                         'rotation polynomials are for that span)')
    delta: timedelta = when - _J2000_UTC
    return delta.days + (delta.seconds + delta.microseconds * 1e-6) / SECONDS_PER_DAY


def julian_date(epoch: str) -> float:
    """Julian date (UTC) of an ISO-8601 epoch; ``julian_date("2000-01-01T12:00:00Z") == 2451545.0``."""
    return J2000_JD + parse_epoch(epoch)


def days_since_j2000(epoch_days: float, t) -> np.ndarray:
    """Scenario time ``t`` (s since the epoch; float or array) -> days since J2000.0 (UTC ~= UT1).
    Raises ValueError for a non-finite time."""
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(t)):
        raise ValueError(f'time t must be finite seconds since the epoch, got {t[~np.isfinite(t)].ravel()[:3]}')
    return epoch_days + t / SECONDS_PER_DAY


def tt_centuries(d_utc) -> np.ndarray:
    """Julian centuries of TT since J2000.0 from days since J2000.0 on the UTC axis (TT = UTC + 69.184 s)."""
    return (np.asarray(d_utc, dtype=float) + TT_MINUS_UTC / SECONDS_PER_DAY) / DAYS_PER_CENTURY


def earth_rotation_angle(d_ut1) -> np.ndarray:
    """ERA (rad, in [0, 2 pi)) at ``d_ut1`` days since J2000.0 (UT1), IERS Conventions 2010 eq. 5.15:
    ``ERA = 2 pi (0.7790572732640 + 1.00273781191135448 T_u)``, ``T_u = JD_UT1 - 2451545.0``; the whole
    days of ``T_u`` are dropped first (they are whole turns) to keep the fraction's precision."""
    d = np.asarray(d_ut1, dtype=float)
    turns = np.mod(d, 1.0) + ERA_AT_J2000 + (ERA_RATE - 1.0) * d
    return 2.0 * math.pi * np.mod(turns, 1.0)


def gmst_minus_era(d_utc) -> np.ndarray:
    """GMST - ERA (rad) at ``d_utc`` days since J2000.0: the polynomial part of IERS 2010 eq. 5.32,
    ``0.014506" + 4612.156534" t + 1.3915817" t^2 - ...`` with ``t`` in centuries of TT. It is the angle
    from the CIO (our ECI x axis) to the mean equinox along the equator: +0.34 deg in 2026."""
    t = tt_centuries(d_utc)
    acc = np.zeros_like(t)
    for coeff in reversed(_GMST_POLY):
        acc = acc * t + coeff
    return acc * ARCSEC


def rotate_z(v, angle) -> np.ndarray:
    """``R3(angle) v`` for vectors (..., 3) and angles (...) (frame rotation about z)."""
    v = np.asarray(v, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    x, y = v[..., 0], v[..., 1]
    return np.stack(np.broadcast_arrays(c * x + s * y, -s * x + c * y, v[..., 2]), axis=-1)


def eci_to_ecef(r_eci, d_ut1) -> np.ndarray:
    """ECI -> ECEF: ``R3(ERA) r`` (positions or any vector, e.g. a field direction)."""
    return rotate_z(r_eci, earth_rotation_angle(d_ut1))


def ecef_to_eci(r_ecef, d_ut1) -> np.ndarray:
    """ECEF -> ECI: ``R3(-ERA) r``."""
    return rotate_z(r_ecef, -earth_rotation_angle(d_ut1))


def eci_to_ecef_velocity(r_eci, v_eci, d_ut1) -> np.ndarray:
    """Velocity relative to the rotating Earth in ECEF axes: ``R3(ERA) v - w_E x r_ECEF``."""
    r = eci_to_ecef(r_eci, d_ut1)
    v = eci_to_ecef(v_eci, d_ut1)
    w = EARTH_ROTATION_RATE
    return v - np.stack(np.broadcast_arrays(-w * r[..., 1], w * r[..., 0], 0.0 * r[..., 2]), axis=-1)


def equinox_to_eci(v_equinox, d_utc) -> np.ndarray:
    """A vector in equinox-based axes of date (SGP4's TEME, the Almanac's mean-of-date Sun) -> ECI:
    ``R3(GMST - ERA) v``, so that ``R3(ERA) r_ECI = R3(GMST) r_TEME`` (Vallado et al. 2006, TEME -> PEF).
    The rotation rate (precession, 2e-11 rad/s) is negligible: velocities turn the same way."""
    return rotate_z(v_equinox, gmst_minus_era(d_utc))


def geocentric(r_ecef) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(geocentric latitude, longitude (rad, east), radius (m)) of ECEF positions (..., 3)."""
    r = np.asarray(r_ecef, dtype=float)
    p = np.hypot(r[..., 0], r[..., 1])
    return np.arctan2(r[..., 2], p), np.arctan2(r[..., 1], r[..., 0]), np.hypot(p, r[..., 2])


def geodetic(r_ecef) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(geodetic latitude, longitude (rad), height above the WGS-84 ellipsoid (m)) of ECEF positions.

    Vallado alg. 12: ``phi <- atan2(z + e^2 N(phi) sin phi, p)``, ``N = a / sqrt(1 - e^2 sin^2 phi)``,
    from ``phi_0 = atan2(z, (1 - e^2) p)``, iterated :data:`GEODETIC_ITERATIONS` times (a fixed count:
    the same operations for every element of a batch); the height as ``p cos phi + z sin phi -
    a sqrt(1 - e^2 sin^2 phi)``, which holds at the poles too."""
    r = np.asarray(r_ecef, dtype=float)
    z = r[..., 2]
    p = np.hypot(r[..., 0], r[..., 1])
    phi = np.arctan2(z, (1.0 - WGS84_E2) * p)
    for _ in range(GEODETIC_ITERATIONS):
        s = np.sin(phi)
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * s * s)
        phi = np.arctan2(z + WGS84_E2 * n * s, p)
    s, c = np.sin(phi), np.cos(phi)
    h = p * c + z * s - WGS84_A * np.sqrt(1.0 - WGS84_E2 * s * s)
    return phi, np.arctan2(r[..., 1], r[..., 0]), h


def geodetic_to_ecef(lat, lon, h) -> np.ndarray:
    """ECEF position (..., 3) of geodetic latitude, longitude (rad) and ellipsoidal height (m), Vallado
    eq. 3-7: ``((N + h) cos phi cos lam, (N + h) cos phi sin lam, (N (1 - e^2) + h) sin phi)``."""
    lat, lon, h = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (lat, lon, h)))
    s = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * s * s)
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - WGS84_E2) + h) * s], axis=-1)


def ned_matrix(lat, lon) -> np.ndarray:
    """(..., 3, 3): columns North, East, Down in ECEF axes at (geodetic or geocentric) latitude and
    longitude; ``v_ecef = M v_ned``, ``v_ned = M^T v_ecef``."""
    sp, cp, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    north = np.stack(np.broadcast_arrays(-sp * cl, -sp * sl, cp), axis=-1)
    east = np.stack(np.broadcast_arrays(-sl, cl, 0.0 * sl), axis=-1)
    down = np.stack(np.broadcast_arrays(-cp * cl, -cp * sl, -sp), axis=-1)
    return np.stack([north, east, down], axis=-1)


def enu_matrix(lat, lon) -> np.ndarray:
    """(..., 3, 3): columns East, North, Up in ECEF axes; ``v_ecef = M v_enu``."""
    ned = ned_matrix(lat, lon)
    return np.stack([ned[..., 1], ned[..., 0], -ned[..., 2]], axis=-1)


def orbit_frame_from_state(r, v) -> np.ndarray:
    """``R^i_o`` (..., 3, 3) of any orbit from its state: ``z_o = -r/|r|`` (nadir), ``y_o = -(r x v)/|r x
    v|`` (negative orbit normal), ``x_o = y_o x z_o`` (along track; the velocity direction on a circular
    orbit): the frame of :mod:`adcs_core.orbit` (seed 002 section 2.1), which it equals there."""
    r = np.asarray(r, dtype=float)
    v = np.asarray(v, dtype=float)
    z = -r / np.linalg.norm(r, axis=-1, keepdims=True)
    h = np.cross(r, v)
    y = -h / np.linalg.norm(h, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)
