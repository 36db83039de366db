"""Orbit geometry shared by the truth model and flight software (pure numpy, no ROS).

A circular orbit (:class:`CircularOrbit`) and the orbit frame of seed 002 section 2.1: ``z_o`` to
nadir, ``x_o`` along the velocity (tangential for a circular orbit), ``y_o = z_o x x_o`` (the
negative orbit normal). The frame turns at ``ω_o = sqrt(μ / r_c³)`` (eq. 1) about ``-y_o``:
``ω_io`` in orbit axes is ``[0, -ω_o, 0]``, which with eq. (17) gives ``ω_ob = ω_ib + ω_o c_2``
(``c_2`` = ``y_o`` in body axes). :func:`orbit_frame_attitude` gives the quaternion of the orbit
frame in the inertial frame (scalar last; ``R(q_io)`` maps orbit axes to inertial ones);
:func:`directional_cosines` gives ``c_1, c_2, c_3`` of eq. (3) (the columns of ``R^b_o``).
Gravity gradient, eq. (19): ``τ_g = 3 ω_o² c_3 x (J c_3)`` is exactly
:meth:`CircularOrbit.gravity_gradient` (``c_3`` = nadir in body axes);
:func:`gravity_gradient_principal` is its closed form for a principal-axes inertia.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adcs_core.attitude import cross, matvec, quat_multiply, rotate_to_body, scipy_rotation

MU_EARTH = 3.986004418e14  # m^3/s^2


R_EARTH = 6378137.0  # m


@dataclass
class CircularOrbit:
    """Circular orbit; angles in rad. Position at time t: argument of latitude ``u0 + n t``."""

    altitude: float
    inclination: float = 0.0
    raan: float = 0.0
    arg_latitude0: float = 0.0
    mu: float = MU_EARTH

    @property
    def radius(self) -> float:
        return R_EARTH + self.altitude

    @property
    def mean_motion(self) -> float:
        return math.sqrt(self.mu / self.radius ** 3)

    def position_unit(self, t: float) -> np.ndarray:
        """Unit position vector in the inertial frame (equatorial axes)."""
        u = self.arg_latitude0 + self.mean_motion * t
        cO, sO = math.cos(self.raan), math.sin(self.raan)
        ci, si = math.cos(self.inclination), math.sin(self.inclination)
        cu, su = math.cos(u), math.sin(u)
        return np.array([cO * cu - sO * ci * su, sO * cu + cO * ci * su, si * su])

    def gravity_gradient(self, t: float, q: np.ndarray, inertia: np.ndarray) -> np.ndarray:
        """Gravity-gradient torque ``3 n^2 c x (J c)``, c = nadir unit vector in body axes."""
        c = rotate_to_body(q, -self.position_unit(t))
        return 3.0 * self.mean_motion ** 2 * cross(c, matvec(inertia, c))


def orbit_frame_matrix(orbit: CircularOrbit, t: float) -> np.ndarray:
    """``R^i_o`` (3, 3): columns ``x_o`` (along track), ``y_o`` (negative orbit normal) and ``z_o``
    (nadir) in inertial axes at time ``t`` (section 2.1)."""
    u = orbit.arg_latitude0 + orbit.mean_motion * t
    cO, sO = math.cos(orbit.raan), math.sin(orbit.raan)
    ci, si = math.cos(orbit.inclination), math.sin(orbit.inclination)
    cu, su = math.cos(u), math.sin(u)
    r = np.array([cO * cu - sO * ci * su, sO * cu + cO * ci * su, si * su])
    v = np.array([-cO * su - sO * ci * cu, -sO * su + cO * ci * cu, si * cu])  # dr/du
    z = -r
    x = v
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def orbit_frame_attitude(orbit: CircularOrbit, t: float) -> np.ndarray:
    """Quaternion (scalar last) of the orbit frame in the inertial frame at time ``t``."""
    q = scipy_rotation().from_matrix(orbit_frame_matrix(orbit, t)).as_quat()
    return q if q[3] >= 0 else -q


def orbit_rate(orbit: CircularOrbit) -> tuple[float, np.ndarray]:
    """``(ω_o, ω_io^o)``: the orbit rate of eq. (1) (rad/s) and the orbit frame's angular velocity
    relative to the inertial frame in orbit axes, ``[0, -ω_o, 0]``."""
    n = orbit.mean_motion
    return n, np.array([0.0, -n, 0.0])


def directional_cosines(orbit: CircularOrbit, t: float, q: np.ndarray) -> np.ndarray:
    """``R^b_o = [c_1 c_2 c_3]`` of eq. (3) for body attitude ``q`` (..., 4) (body in inertial):
    (..., 3, 3), column ``k`` the orbit axis ``k`` in body axes."""
    R = orbit_frame_matrix(orbit, t)
    cols = [rotate_to_body(np.asarray(q, dtype=float), R[:, k]) for k in range(3)]
    return np.stack(cols, axis=-1)


def gravity_gradient_principal(omega_o: float, c3: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """Eq. (19) written out for principal axes ``J = diag(Jx, Jy, Jz)``::

        τ_g = 3 ω_o² [(Jz - Jy) c3y c3z, (Jx - Jz) c3z c3x, (Jy - Jx) c3x c3y]
    """
    c3 = np.asarray(c3, dtype=float)
    Jx, Jy, Jz = np.asarray(moments, dtype=float)
    x, y, z = c3[..., 0], c3[..., 1], c3[..., 2]
    k = 3.0 * omega_o ** 2
    return k * np.stack([(Jz - Jy) * y * z, (Jx - Jz) * z * x, (Jy - Jx) * x * y], axis=-1)


def body_in_orbit(orbit: CircularOrbit, t: float, q: np.ndarray) -> np.ndarray:
    """Quaternion of the body relative to the orbit frame (``q_io* ⊗ q``), scalar last."""
    qo = orbit_frame_attitude(orbit, t)
    return quat_multiply(np.concatenate([-qo[:3], qo[3:]]), np.asarray(q, dtype=float))
