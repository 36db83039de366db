"""The Earth's shadow: the illuminated fraction of the solar disk (0 in umbra, 1 in sunlight) seen from
a satellite, Montenbruck & Gill, Satellite Orbits (2000), section 3.4.2 "Eclipse conditions".

Cylindrical model (M&G 3.4.2, first model): the shadow is the cylinder of radius ``R_E`` behind the
Earth along the Sun direction ``s``: in shadow iff ``r . s < 0`` and ``|r - (r . s) s| < R_E``. No
penumbra: the fraction is 0 or 1.

Conical model (M&G 3.4.2, the occultation of two disks): with the apparent radii of the Sun and the
Earth seen from the satellite and their apparent separation::

    a = asin(R_sun / |r_sun - r|),  b = asin(R_E / |r|),  c = acos(-r . (r_sun - r) / (|r| |r_sun - r|))

    c >= a + b:          nu = 1                       (no occultation)
    c <= b - a:          nu = 0                       (umbra: the Earth covers the whole Sun)
    c <  a - b:          nu = 1 - b^2 / a^2           (annular; only where the Earth looks smaller)
    otherwise (partial): x = (c^2 + a^2 - b^2) / (2 c),  y = sqrt(a^2 - x^2)
                         A = a^2 acos(x / a) + b^2 acos((c - x) / b) - c y
                         nu = 1 - A / (pi a^2)

(disks treated as flat, no limb darkening, no atmosphere: the Earth's radius is the equatorial one).
Both take positions (..., 3) in metres in any one frame (ECI here) and broadcast them.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_core.environment.frames import WGS84_A
from adcs_core.environment.sun import SUN_RADIUS

EARTH_RADIUS = WGS84_A


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def shadow_cylindrical(r_sat, r_sun, earth_radius: float = EARTH_RADIUS) -> np.ndarray:
    """Illuminated fraction (...) in {0, 1} for satellite positions ``r_sat`` and Sun positions ``r_sun``
    (both (..., 3), m, geocentric)."""
    r = np.asarray(r_sat, dtype=float)
    s = np.asarray(r_sun, dtype=float)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    along = _dot(r, s)
    across = np.linalg.norm(r - along[..., None] * s, axis=-1)
    return np.where((along < 0.0) & (across < earth_radius), 0.0, 1.0)


def apparent_geometry(r_sat, r_sun, earth_radius: float = EARTH_RADIUS, sun_radius: float = SUN_RADIUS):
    """(a, b, c) of the conical model (rad): apparent Sun radius, apparent Earth radius, separation."""
    r = np.asarray(r_sat, dtype=float)
    to_sun = np.asarray(r_sun, dtype=float) - r
    d_sun = np.linalg.norm(to_sun, axis=-1)
    d_earth = np.linalg.norm(r, axis=-1)
    a = np.arcsin(np.clip(sun_radius / d_sun, 0.0, 1.0))
    b = np.arcsin(np.clip(earth_radius / d_earth, 0.0, 1.0))
    c = np.arccos(np.clip(-_dot(r, to_sun) / (d_earth * d_sun), -1.0, 1.0))
    return a, b, c


def occulted_fraction(a, b, c) -> np.ndarray:
    """The lit fraction ``nu`` of a disk of apparent radius ``a`` behind one of radius ``b`` at
    separation ``c`` (rad, broadcast), the four cases of the module docstring."""
    a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (a, b, c)))
    safe_c = np.where(c > 0.0, c, 1.0)
    x = (c * c + a * a - b * b) / (2.0 * safe_c)
    y = np.sqrt(np.clip(a * a - x * x, 0.0, None))
    area = (a * a * np.arccos(np.clip(x / a, -1.0, 1.0)) + b * b * np.arccos(np.clip((c - x) / b, -1.0, 1.0))
            - c * y)
    partial = 1.0 - area / (math.pi * a * a)
    nu = np.where(c >= a + b, 1.0, np.where(c <= b - a, 0.0, np.where(c < a - b, 1.0 - (b * b) / (a * a),
                                                                      partial)))
    return np.clip(nu, 0.0, 1.0)


def shadow_conical(r_sat, r_sun, earth_radius: float = EARTH_RADIUS, sun_radius: float = SUN_RADIUS) -> np.ndarray:
    """Illuminated fraction (...) in [0, 1] (umbra 0, penumbra in between, sunlight 1)."""
    return occulted_fraction(*apparent_geometry(r_sat, r_sun, earth_radius, sun_radius))
