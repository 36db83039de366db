"""The Sun's position: the Astronomical Almanac's low-precision solar coordinates, as Vallado,
Fundamentals of Astrodynamics and Applications (4th ed., 2013), alg. 29 "SUN" (the same series as
Montenbruck & Gill, Satellite Orbits, 2000, section 3.3.2). Stated accuracy 0.01 deg in direction
(1950-2050); its distance agrees with Meeus' Example 25.a to 1e-6 au (tests). It is referred to the
mean equator and equinox of date, which :func:`adcs_core.environment.frames.equinox_to_eci` takes to
our ECI (package docstring).

Alg. 29, with ``T`` Julian centuries since J2000.0 (UT1 for the mean longitude, TDB ~= TT for the rest)::

    lambda_M = 280.460 deg + 36000.771 T            (mean longitude)
    M        = 357.5291092 deg + 35999.05034 T      (mean anomaly)
    lambda   = lambda_M + 1.914666471 deg sin M + 0.019994643 deg sin 2M   (ecliptic longitude)
    r        = 1.000140612 - 0.016708617 cos M - 0.000139589 cos 2M       (au)
    eps      = 23.439291 deg - 0.0130042 T          (obliquity)
    r_sun    = r (cos lambda, cos eps sin lambda, sin eps sin lambda)
"""
from __future__ import annotations

import math

import numpy as np

from adcs_core.environment.frames import DAYS_PER_CENTURY, equinox_to_eci, tt_centuries

AU = 149597870700.0       # m (IAU 2012 resolution B2)
SUN_RADIUS = 6.957e8      # m (IAU 2015 resolution B3, nominal solar radius)
_DEG = math.pi / 180.0


def sun_position_mod(d_utc) -> np.ndarray:
    """The Sun's geocentric position (..., 3) in metres, mean equator and equinox of date (alg. 29),
    at ``d_utc`` days since J2000.0 (UT1 ~= UTC)."""
    d = np.asarray(d_utc, dtype=float)
    t_ut1 = d / DAYS_PER_CENTURY
    t_tdb = tt_centuries(d)
    mean_longitude = (280.460 + 36000.771 * t_ut1) * _DEG
    m = (357.5291092 + 35999.05034 * t_tdb) * _DEG
    lam = mean_longitude + (1.914666471 * np.sin(m) + 0.019994643 * np.sin(2.0 * m)) * _DEG
    r = (1.000140612 - 0.016708617 * np.cos(m) - 0.000139589 * np.cos(2.0 * m)) * AU
    eps = (23.439291 - 0.0130042 * t_tdb) * _DEG
    return np.stack([r * np.cos(lam), r * np.cos(eps) * np.sin(lam), r * np.sin(eps) * np.sin(lam)], axis=-1)


def sun_position_eci(d_utc) -> np.ndarray:
    """The Sun's geocentric position (..., 3) in metres in ECI (mean-of-date rotated by GMST - ERA)."""
    return equinox_to_eci(sun_position_mod(d_utc), d_utc)


def sun_direction_eci(d_utc) -> tuple[np.ndarray, np.ndarray]:
    """(unit vector (..., 3) from the Earth's centre to the Sun in ECI, distance (...) in m)."""
    s = sun_position_eci(d_utc)
    dist = np.linalg.norm(s, axis=-1)
    return s / dist[..., None], dist


def right_ascension_declination(v) -> tuple[np.ndarray, np.ndarray]:
    """(right ascension in [0, 2 pi), declination) (rad) of vectors (..., 3) in their own axes."""
    v = np.asarray(v, dtype=float)
    ra = np.mod(np.arctan2(v[..., 1], v[..., 0]), 2.0 * math.pi)
    return ra, np.arctan2(v[..., 2], np.hypot(v[..., 0], v[..., 1]))
