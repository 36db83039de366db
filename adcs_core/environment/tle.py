"""Orbit position and velocity in ECI behind one interface: a TLE propagated by SGP4 (the ``sgp4``
library, Vallado's C++ code: Vallado, Crawford, Hujsak & Kelso 2006, "Revisiting Spacetrack Report #3",
AIAA 2006-6753) and the existing circular orbit (:class:`adcs_core.orbit.CircularOrbit`).

Both are :class:`OrbitSource`: ``state(d) -> (r, v)``, ECI position (m) and velocity (m/s), (..., 3),
at ``d`` days since J2000.0 (UTC); the rest of the code asks one object for r(t), v(t).

TLEs: :func:`parse_tle` checks the two lines (strings, ASCII, the column layout, the mod-10 checksums)
with the library's own Python parser and checksum (``sgp4.io.twoline2rv``, ``sgp4.io.verify_checksum``)
and builds the C++ ``Satrec`` with the WGS-72 constants (those TLEs are fitted with); ValueError names
the problem. Propagation uses ``Satrec.sgp4_array`` (one call for many times, the Julian date split in
whole days and fraction to keep its precision); a non-zero SGP4 error code (decayed, eccentricity out of
range) raises ValueError with the library's message. SGP4 returns TEME (km, km/s): :meth:`TleOrbit.teme`
gives that; :meth:`TleOrbit.state` turns it into our ECI with
:func:`adcs_core.environment.frames.equinox_to_eci` and SI units (package docstring).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from sgp4 import io as sgp4_io
from sgp4.api import SGP4_ERRORS, WGS72, Satrec
from sgp4.earth_gravity import wgs72

from adcs_core.environment.frames import J2000_JD, SECONDS_PER_DAY, equinox_to_eci
from adcs_core.orbit import CircularOrbit


class OrbitSource(Protocol):
    def state(self, d) -> tuple[np.ndarray, np.ndarray]:
        """(r (..., 3) m, v (..., 3) m/s) in ECI at ``d`` days since J2000.0 (UTC)."""


def tle_line_problem(line, number: int) -> str | None:
    """What is wrong with one TLE line on its own (type, length, line number, checksum), or None."""
    if not isinstance(line, str):
        return f'TLE line {number} must be a string, got {type(line).__name__}'
    line = line.rstrip()
    if len(line) != 69:
        return f'TLE line {number} must have 69 characters, got {len(line)}: {line!r}'
    if not line.startswith(f'{number} '):
        return f'TLE line {number} must start with "{number} ", got {line[:2]!r}'
    try:
        sgp4_io.verify_checksum(line)
    except ValueError as exc:
        return f'TLE line {number}: {" ".join(str(exc).split())}'
    return None


def parse_tle(line1: str, line2: str) -> Satrec:
    """The ``Satrec`` of two TLE lines, or ValueError naming what is wrong with them."""
    for number, line in ((1, line1), (2, line2)):
        problem = tle_line_problem(line, number)
        if problem:
            raise ValueError(problem)
    line1, line2 = line1.rstrip(), line2.rstrip()
    try:
        # The library's strict column parser; it also initialises its pure-Python SGP4, which on
        # some corrupt values (a negative mean motion) fails with TypeError/ArithmeticError instead
        # of ValueError: all of them mean the same to the user.
        sgp4_io.twoline2rv(line1, line2, wgs72)
    except (ValueError, TypeError, ArithmeticError, IndexError) as exc:
        raise ValueError(f'TLE is malformed: {" ".join(str(exc).split())}') from None
    sat = Satrec.twoline2rv(line1, line2, WGS72)
    if sat.error:
        raise ValueError(f'TLE rejected by SGP4 initialisation: {SGP4_ERRORS.get(sat.error, sat.error)}')
    return sat


class TleOrbit:
    """SGP4 orbit of a two-line element set; ``epoch_days`` (days since J2000.0) is the TLE's epoch."""

    def __init__(self, line1: str, line2: str) -> None:
        self.satrec = parse_tle(line1, line2)
        self.line1, self.line2 = line1.rstrip(), line2.rstrip()
        self.epoch_days = (self.satrec.jdsatepoch - J2000_JD) + self.satrec.jdsatepochF

    def teme(self, d) -> tuple[np.ndarray, np.ndarray]:
        """SGP4's own output at ``d`` days since J2000.0 (UTC): TEME position (km) and velocity (km/s)."""
        d = np.asarray(d, dtype=float)
        flat = d.reshape(-1)
        whole = np.floor(flat)
        err, r, v = self.satrec.sgp4_array(J2000_JD + whole, flat - whole)
        if np.any(err):
            k = int(np.flatnonzero(err)[0])
            minutes = (flat[k] - self.epoch_days) * 1440.0
            raise ValueError(f'SGP4 failed {minutes:.1f} min from the TLE epoch: '
                             f'{SGP4_ERRORS.get(int(err[k]), int(err[k]))}')
        return r.reshape(d.shape + (3,)), v.reshape(d.shape + (3,))

    def state(self, d) -> tuple[np.ndarray, np.ndarray]:
        """ECI position (m) and velocity (m/s) (..., 3)."""
        r, v = self.teme(d)
        return equinox_to_eci(r * 1e3, d), equinox_to_eci(v * 1e3, d)

    def span_problem(self, d0: float, duration: float, period: float) -> str | None:
        """What SGP4 says of a run sampling this orbit every ``period`` s over ``[d0, d0 + duration]``
        (days since J2000.0; s), or None: a trial propagation at the run's own step times when they
        are few, else at SAMPLES_PER_ORBIT points per revolution and the end (see there)."""
        steps = int(duration // period) + 1
        revolutions = duration * self.satrec.no_kozai / (2.0 * math.pi * 60.0)   # no_kozai: rad/min
        n = min(steps, int(math.ceil(revolutions * SAMPLES_PER_ORBIT)) + 1)
        t = np.arange(steps) * period if n == steps else np.linspace(0.0, duration, n)
        for chunk in np.array_split(t, max(1, len(t) // 100_000)):   # bounded memory
            try:
                self.teme(d0 + chunk / SECONDS_PER_DAY)
            except ValueError as exc:
                return str(exc)
        return None


# A trial propagation samples a run's span at this many points per revolution (or at the run's own step
# times, when fewer): SGP4's decay test (radius below one Earth radius) is first met at a perigee, and at
# 64 a revolution a sample falls within pi/64 of the perigee's eccentric anomaly, where the radius is within
# a e (1 - cos(pi/64)) ~ 1.2e-3 a e of the perigee's (< 100 m for a LEO e < 0.01): a decay inside the span
# is missed only if its perigee dips below the Earth less than that, within the run's last revolution. The
# mean elements' failures (eccentricity, mean motion) evolve secularly, far slower than a revolution. A
# year in LEO is ~360 000 points, about a second of SGP4.
SAMPLES_PER_ORBIT = 64


@dataclass(frozen=True)
class CircularOrbitSource:
    """:class:`adcs_core.orbit.CircularOrbit` as an :class:`OrbitSource`: its time 0 (argument of
    latitude ``arg_latitude0``) is at ``epoch_days``; its inertial axes are our ECI."""

    orbit: CircularOrbit
    epoch_days: float

    def state(self, d) -> tuple[np.ndarray, np.ndarray]:
        """The position of ``CircularOrbit.position_unit`` times the radius, written for arrays of
        times, and its derivative ``r_c n dr_hat/du``."""
        o = self.orbit
        t = (np.asarray(d, dtype=float) - self.epoch_days) * SECONDS_PER_DAY
        u = o.arg_latitude0 + o.mean_motion * t
        cO, sO = math.cos(o.raan), math.sin(o.raan)
        ci, si = math.cos(o.inclination), math.sin(o.inclination)
        cu, su = np.cos(u), np.sin(u)
        r_hat = np.stack([cO * cu - sO * ci * su, sO * cu + cO * ci * su, si * su], axis=-1)
        du = np.stack([-cO * su - sO * ci * cu, -sO * su + cO * ci * cu, si * cu], axis=-1)
        return o.radius * r_hat, (o.radius * o.mean_motion) * du
