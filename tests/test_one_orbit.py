"""The truth model has one orbit (issue 32): with ``environment.enabled`` the plant's gravity gradient
follows the environment's orbit (the one the sensors and the estimator references see), and a scenario
naming two different orbits (``orbit.*`` for the gravity gradient, ``environment.*`` for the sensors) is
refused at validation, in one line naming both keys."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from adcs_core.environment.environment import SourceOrbit, build_environment
from adcs_core.orbit import MU_EARTH, R_EARTH, CircularOrbit
from adcs_msgs_py.params import ParameterError
from adcs_sim.truth.schema import DYNAMICS_SCHEMA, build_plant

# config/leo_tle_sun_magnetometer_mekf.yaml's TLE: 500 km, i = 97.4 deg (sun-synchronous-like)
TLE = ('1 90001U          26079.50000000  .00000000  00000-0  20000-4 0    08',
       '2 90001  97.4000  10.0000 0005000  90.0000   0.0000 15.20000000    05')
J = (2.0, 3.0, 4.5)   # principal moments, kg m^2


def section(**changes) -> dict:
    base = {'inertia': list(J), 'duration': 10.0, 'gravity_gradient': True,
            'environment.enabled': True, 'environment.epoch': '2026-03-20T12:00:00Z',
            'environment.magnetic_model': 'dipole'}
    base.update({k.replace('__', '.'): v for k, v in changes.items()})
    return base


def tle(**changes) -> dict:
    return section(environment__orbit='tle', environment__tle__line1=TLE[0], environment__tle__line2=TLE[1],
                   **changes)


def circular(altitude=600e3, inclination=51.6, raan=30.0, u0=10.0, **changes) -> dict:
    return section(environment__orbit='circular', environment__circular__altitude=altitude,
                   environment__circular__inclination_deg=inclination, environment__circular__raan_deg=raan,
                   environment__circular__arg_latitude_deg=u0, **changes)


def refusal(given: dict) -> str:
    with pytest.raises(ParameterError) as info:
        DYNAMICS_SCHEMA.validate(given)
    text = str(info.value)
    assert info.value.key == 'orbit.altitude' and '\n' not in text, text
    assert 'orbit.*' in text and 'environment.orbit' in text, text
    return text


def test_gravity_gradient_on_an_equatorial_circle_and_sensors_on_a_tle_is_refused():
    text = refusal(tle(orbit__altitude=700e3))
    assert 'tle' in text


def test_two_different_circles_are_refused_and_the_same_circle_is_not():
    refusal(circular(orbit__altitude=700e3, orbit__inclination_deg=51.6, orbit__raan_deg=30.0,
                     orbit__arg_latitude_deg=10.0))
    refusal(circular(orbit__altitude=600e3, orbit__inclination_deg=0.0, orbit__raan_deg=30.0,
                     orbit__arg_latitude_deg=10.0))
    same = DYNAMICS_SCHEMA.validate(circular(orbit__altitude=600e3, orbit__inclination_deg=51.6,
                                             orbit__raan_deg=30.0, orbit__arg_latitude_deg=10.0))
    assert build_plant(same, warm=False).orbit == CircularOrbit(600e3, math.radians(51.6), math.radians(30.0),
                                                                 math.radians(10.0))


def test_gravity_gradient_without_any_orbit_is_still_refused():
    with pytest.raises(ParameterError) as info:
        DYNAMICS_SCHEMA.validate(section(environment__enabled=False))
    assert info.value.key == 'orbit.altitude'


def closed_form(r_eci: np.ndarray) -> np.ndarray:
    """Gravity-gradient torque on a principal-axes body at the identity attitude (body = ECI axes):
    ``3 mu / r^3 [(J3 - J2) c2 c3, (J1 - J3) c3 c1, (J2 - J1) c1 c2]``, ``c = -r / |r|``."""
    r = float(np.sqrt(r_eci @ r_eci))
    c1, c2, c3 = -r_eci / r
    J1, J2, J3 = J
    return 3.0 * MU_EARTH / r ** 3 * np.array([(J3 - J2) * c2 * c3, (J1 - J3) * c3 * c1, (J2 - J1) * c1 * c2])


@pytest.mark.parametrize('given', [tle(), circular()], ids=['tle', 'circular'])
def test_gravity_gradient_follows_the_environments_orbit(given):
    v = DYNAMICS_SCHEMA.validate(given)
    plant = build_plant(v, warm=False)
    environment = build_environment(v)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    for t in (0.0, 1234.5, 4000.0):   # the position moves: the torque follows it
        r = environment.sample(t).r_eci
        assert_allclose(plant.environment_torque(t, q), closed_form(r), rtol=1e-9, atol=1e-18)
    # and not some other orbit: the TLE's is at ~500 km, i = 97.4 deg
    r0 = environment.sample(0.0).r_eci
    assert abs(np.linalg.norm(r0) - R_EARTH - (500e3 if 'environment.tle.line1' in given else 600e3)) < 30e3


def test_a_tle_orbit_steps_on_numpy_and_a_circle_on_the_kernel():
    """The SGP4 orbit has no constant mean motion for the compiled kernel: the plant steps on numpy
    (the kernel's reference); the circular one keeps the kernel. Both advance the same state."""
    plant = build_plant(DYNAMICS_SCHEMA.validate(tle()), warm=False)
    assert isinstance(plant.orbit, SourceOrbit)
    x = plant.initial_state(np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9]),
                            np.array([1e-3, -2e-3, 5e-4]))
    commands = plant.zero_commands()
    assert np.array_equal(plant.step(100.0, x, commands, 1.0, 0.5), plant.step_numpy(100.0, x, commands, 1.0, 0.5))
    assert isinstance(build_plant(DYNAMICS_SCHEMA.validate(circular()), warm=False).orbit, CircularOrbit)
