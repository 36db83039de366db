"""One object for the environment of a scenario: :class:`Environment` (built from the ``environment.*``
parameters by :func:`build_environment`), whose :meth:`Environment.sample` gives, at scenario times
``t`` (s since the epoch; a float or an array of any shape), the orbit state, the Sun direction and
distance, the illuminated fraction and the magnetic field, all in ECI (conventions: the package
docstring of :mod:`adcs_core.environment`). Deterministic: a pure function of the parameters and ``t``;
an element's values do not depend on the other times of the array.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from adcs_core.environment.eclipse import shadow_conical, shadow_cylindrical
from adcs_core.environment.frames import SECONDS_PER_DAY, days_since_j2000, parse_epoch
from adcs_core.environment.magnetic import DipoleModel, IgrfModel, load_igrf
from adcs_core.environment.options import IGRF_YEARS, MAGNETIC_MODELS, ORBIT_KINDS, SHADOW_MODELS
from adcs_core.environment.sun import sun_position_eci
from adcs_core.environment.tle import CircularOrbitSource, OrbitSource, TleOrbit
from adcs_core.attitude import cross, matvec, rotate_to_body
from adcs_core.orbit import MU_EARTH, CircularOrbit

_SHADOWS = {'cylindrical': shadow_cylindrical, 'conical': shadow_conical}


@dataclass(frozen=True)
class EnvironmentSample:
    """The environment at times ``t`` (shape ``S``): vectors (S + (3,)), scalars (S), SI units, ECI."""

    t: np.ndarray             # s since the scenario epoch
    r_eci: np.ndarray         # m
    v_eci: np.ndarray         # m/s
    sun_eci: np.ndarray       # unit vector, Earth's centre to the Sun
    sun_distance: np.ndarray  # m, Earth's centre to the Sun
    shadow: np.ndarray        # illuminated fraction of the solar disk seen from the satellite, 0..1
    b_eci: np.ndarray         # T, Earth's main field at the satellite
    nadir_eci: np.ndarray     # unit vector, satellite to the Earth's centre (-r/|r|)


class Environment:
    """Orbit + Sun + shadow + magnetic field for one scenario, from its UTC ``epoch`` (ISO-8601)."""

    def __init__(self, epoch: str, orbit: OrbitSource, magnetic: IgrfModel | DipoleModel,
                 shadow_model: str = 'conical') -> None:
        if shadow_model not in _SHADOWS:
            raise ValueError(f'shadow model must be one of {list(SHADOW_MODELS)}, got {shadow_model!r}')
        self.epoch = epoch
        self.epoch_days = parse_epoch(epoch)
        self.orbit = orbit
        self.magnetic = magnetic
        self.shadow_model = shadow_model
        self._shadow = _SHADOWS[shadow_model]

    def sample(self, t) -> EnvironmentSample:
        """The environment at ``t`` (s since the epoch); ValueError for a non-finite time."""
        t = np.asarray(t, dtype=float)
        d = days_since_j2000(self.epoch_days, t)
        r, v = self.orbit.state(d)
        sun = sun_position_eci(d)
        distance = np.linalg.norm(sun, axis=-1)
        radius = np.linalg.norm(r, axis=-1)
        return EnvironmentSample(t=t, r_eci=r, v_eci=v, sun_eci=sun / distance[..., None], sun_distance=distance,
                                 shadow=self._shadow(r, sun), b_eci=self.magnetic.field_eci(r, d),
                                 nadir_eci=-r / radius[..., None])


def circular_orbit_from_params(p: Mapping[str, Any]) -> CircularOrbit:
    return CircularOrbit(altitude=p['environment.circular.altitude'],
                         inclination=math.radians(p['environment.circular.inclination_deg']),
                         raan=math.radians(p['environment.circular.raan_deg']),
                         arg_latitude0=math.radians(p['environment.circular.arg_latitude_deg']))


def orbit_source(p: Mapping[str, Any]) -> OrbitSource:
    """The orbit of validated ``environment.*`` parameters (what :func:`build_environment` samples and
    what the truth model's gravity gradient follows, :class:`SourceOrbit`), without the field model."""
    kind = p['environment.orbit']
    if kind == 'circular':
        return CircularOrbitSource(circular_orbit_from_params(p), parse_epoch(p['environment.epoch']))
    if kind == 'tle':
        return TleOrbit(p['environment.tle.line1'], p['environment.tle.line2'])
    raise ValueError(f'environment.orbit must be one of {list(ORBIT_KINDS)}, got {kind!r}')


class SourceOrbit:
    """An :class:`OrbitSource` (SGP4 of a TLE) as the plant's orbit: the gravity-gradient torque
    ``3 mu / |r|^3 c x (J c)``, ``c = -r / |r|`` in body axes, at the position the environment gives at
    ``t`` (s since ``epoch_days``). For a circular orbit ``mu / r^3 = n^2``: the torque of
    :meth:`adcs_core.orbit.CircularOrbit.gravity_gradient` (whose own object the plant then uses)."""

    def __init__(self, source: OrbitSource, epoch_days: float, mu: float = MU_EARTH) -> None:
        self.source, self.epoch_days, self.mu = source, epoch_days, mu

    def position(self, t: float) -> np.ndarray:
        """ECI position (m) at ``t`` s since the epoch."""
        return self.source.state(days_since_j2000(self.epoch_days, np.asarray(t, dtype=float)))[0]

    def gravity_gradient(self, t: float, q: np.ndarray, inertia: np.ndarray) -> np.ndarray:
        r = self.position(t)
        radius = float(np.linalg.norm(r))
        c = rotate_to_body(q, -r / radius)
        return 3.0 * (self.mu / radius ** 3) * cross(c, matvec(inertia, c))


def build_environment(p: Mapping[str, Any]) -> Environment:
    """The :class:`Environment` of validated ``environment.*`` parameters (dotted names, the block of
    :func:`adcs_msgs_py.blocks.environment_params`). The dipole's coefficients are the IGRF's at the
    epoch."""
    epoch = p['environment.epoch']
    epoch_days = parse_epoch(epoch)
    orbit = orbit_source(p)
    model = p['environment.magnetic_model']
    if model not in MAGNETIC_MODELS:
        raise ValueError(f'environment.magnetic_model must be one of {list(MAGNETIC_MODELS)}, got {model!r}')
    igrf = load_igrf()
    magnetic = igrf if model == 'igrf' else igrf.dipole(epoch_days)
    return Environment(epoch, orbit, magnetic, p['environment.shadow_model'])


def span_problem(p: Mapping[str, Any], duration: float, period: float) -> tuple[str, str] | None:
    """Whether the environment of validated ``environment.*`` parameters can be sampled by a run over
    ``[epoch, epoch + duration]`` every ``period`` s, as it is at its start: ``('field', why)`` when the
    span leaves the IGRF's years (the dipole's coefficients are frozen at the epoch), ``('orbit', why)``
    when a trial SGP4 propagation of the TLE fails inside it (:meth:`TleOrbit.span_problem`), else None."""
    start = parse_epoch(p['environment.epoch'])
    end = start + duration / SECONDS_PER_DAY
    year = 2000.0 + end / 365.25   # the epoch check's rule (adcs_msgs_py.blocks.check_environment)
    if p['environment.magnetic_model'] == 'igrf' and not year < IGRF_YEARS[1]:
        return 'field', (f'the run ends in {year:.2f} (epoch {p["environment.epoch"]} + {duration:g} s), beyond '
                         f'the IGRF-14 field model\'s {IGRF_YEARS[0]}-{IGRF_YEARS[1]}')
    if p['environment.orbit'] == 'tle':
        orbit = TleOrbit(p['environment.tle.line1'], p['environment.tle.line2'])
        problem = orbit.span_problem(start, duration, period)
        if problem is not None:
            return 'orbit', f'inside the run (epoch + 0..{duration:g} s): {problem}'
    return None
