"""Sensor and estimate messages <-> :mod:`adcs_msgs_py.measurements`, with validation of everything that
comes in (the conversions of attitude determination; :mod:`adcs_msgs_py.conversions` has the others).

Standard types only, so any ROS tool reads them:

============================  ==========================================  ==========================
topic                         type                                        content
============================  ==========================================  ==========================
``sensors/imu``               sensor_msgs/Imu                             gyro rate, body axes
``sensors/star_tracker``      geometry_msgs/PoseWithCovarianceStamped     measured attitude
``sensors/sun``               geometry_msgs/Vector3Stamped                unit Sun vector, body axes
``sensors/magnetometer``      sensor_msgs/MagneticField                   field (T), body axes
``estimate/state``            nav_msgs/Odometry                           estimated attitude and rate
============================  ==========================================  ==========================

A sensor declared later reuses one of these codecs (:data:`CODECS`, named by its declaration in
:mod:`adcs_msgs_py.sensor_interfaces`), on its own topic.

**No measurement** (outage, eclipse, failed sensor, not due at the sensor's rate): the message is still
published every step, marked as REP 145 marks a missing quantity of ``sensor_msgs/Imu``: element 0 of
its covariance is ``-1`` (the sun vector, whose type has no covariance: the zero vector, which is also
what a coarse sun sensor reads in eclipse).

**Covariances.** The :class:`~adcs_msgs_py.measurements.Reading` covariances are in body axes. The
gyro's and the magnetometer's go into their messages as they are (those messages are in the body
frame). A pose covariance's rotation block is about the *fixed* axes of the header frame
(``geometry_msgs/PoseWithCovariance``: "fixed-axis representation"), here the inertial frame, so
it is written ``R P Rᵀ`` (``R`` body to inertial, of the message's own attitude) and read back with
``Rᵀ P R``: exact to rounding, not bit for bit, which is why the estimators take their measurement
noise from their own parameters, never from a message. The position blocks are zero (nothing
estimated). The odometry twist covariance is in the child (body) frame, per REP 105.

Every ``*_from_msg`` raises :class:`~adcs_msgs_py.conversions.InvalidMessage` with a reason: a
non-finite number, a quaternion off unit norm, a sun vector neither unit nor zero, a covariance that
is not symmetric positive semi-definite, a wrong frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, MagneticField

from adcs_core.attitude import rotation_from_quaternion
from adcs_msgs_py.conversions import (
    BODY_FRAME,
    INERTIAL_FRAME,
    InvalidMessage,
    _finite,
    checked_quaternion,
    checked_stamp,
    stamp_from_ns,
)
from adcs_msgs_py.measurements import Estimate, Reading, received_unit_vector
from adcs_msgs_py.sensor_interfaces import SENSOR_INTERFACES

NO_MEASUREMENT = -1.0        # element 0 of a covariance: no measurement this step (REP 145)
UNIT_VECTOR_TOLERANCE = 1e-6  # a sun vector whose norm is further than this from 1 (and not 0) is refused
SYMMETRY_TOLERANCE = 1e-9     # on the correlation matrix: asymmetry and negative eigenvalues allowed

_IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
_ZERO3 = np.zeros((3, 3))


# --- covariances ------------------------------------------------------------------------------

def _checked_cov(name: str, values, n: int) -> np.ndarray:
    """A received row-major n x n covariance: finite, non-negative variances, symmetric and positive
    semi-definite; returned exactly symmetric. Checked on the correlation matrix
    (``c_ij / sqrt(c_ii c_jj)``), so the tolerances are relative to each entry's own scale however
    different the variances; a zero variance needs its whole row and column zero."""
    c = _finite(name, values, n * n).reshape(n, n)
    var = np.diag(c).copy()
    if (var < 0).any():
        raise InvalidMessage(f'{name}: negative variance in {var.tolist()}')
    zero = var == 0
    if c[zero].any() or c[:, zero].any():
        raise InvalidMessage(f'{name}: a zero variance with a non-zero covariance')
    d = np.sqrt(np.where(zero, 1.0, var))
    scale = d[:, None] * d[None, :]   # <= 1.8e308: no overflow
    if (np.abs(c) > (1.0 + SYMMETRY_TOLERANCE) * scale).any():
        raise InvalidMessage(f'{name}: a correlation beyond 1 (|c_ij| > sqrt(c_ii c_jj))')
    r = c / scale
    if np.max(np.abs(r - r.T)) > SYMMETRY_TOLERANCE:
        raise InvalidMessage(f'{name}: covariance is not symmetric')
    if np.linalg.eigvalsh(0.5 * (r + r.T))[0] < -SYMMETRY_TOLERANCE:
        raise InvalidMessage(f'{name}: covariance is not positive semi-definite')
    # symmetric within the tolerance, but the estimators get it exactly so: the mean of c_ij and c_ji
    # where they differ (an entry equal to its mirror is kept bit for bit; halves first: no overflow)
    return np.where(c == c.T, c, 0.5 * c + 0.5 * c.T)


def _marked(cov: np.ndarray, valid: bool) -> list[float]:
    """Row-major list of a 3x3 covariance, element 0 set to NO_MEASUREMENT when not valid."""
    out = [float(v) for v in np.asarray(cov, dtype=float).reshape(9)]
    if not valid:
        out[0] = NO_MEASUREMENT
    return out


def _check_frame(name: str, frame: str, expected: str) -> None:
    if frame != expected:
        raise InvalidMessage(f'{name}: frame_id {frame!r}, expected {expected!r}')


def _one(reading: Reading) -> tuple[np.ndarray, np.ndarray, bool]:
    """(value, cov, valid) of a reading of one run (no batch axis)."""
    value, cov, valid = np.asarray(reading.value), np.asarray(reading.cov), np.asarray(reading.valid)
    if valid.ndim:
        raise ValueError('a message carries one run: the reading has a batch axis')
    return value, cov, bool(valid)


# --- gyro: sensor_msgs/Imu --------------------------------------------------------------------

def imu_to_msg(t_ns: int, gyro: Reading) -> Imu:
    """Gyro reading -> sensor_msgs/Imu (orientation and acceleration marked as not measured)."""
    w, cov, valid = _one(gyro)
    msg = Imu()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = BODY_FRAME
    msg.orientation_covariance[0] = NO_MEASUREMENT
    msg.linear_acceleration_covariance[0] = NO_MEASUREMENT
    a = msg.angular_velocity
    a.x, a.y, a.z = (float(v) for v in w)
    msg.angular_velocity_covariance = _marked(cov, valid)
    return msg


def _body_vector_reading(name: str, msg, field: str) -> tuple[int, Reading]:
    """(t_ns, Reading) of a body-frame message with a vector ``field`` and its ``field_covariance``
    (sensor_msgs/Imu's angular_velocity, sensor_msgs/MagneticField's magnetic_field)."""
    t_ns = checked_stamp(name, msg.header.stamp)
    _check_frame(name, msg.header.frame_id, BODY_FRAME)
    covariance = getattr(msg, f'{field}_covariance')
    valid = float(covariance[0]) != NO_MEASUREMENT
    v = getattr(msg, field)
    value = _finite(f'{name}.{field}', (v.x, v.y, v.z), 3)
    cov = _checked_cov(f'{name}.{field}_covariance', covariance, 3) if valid else _ZERO3
    return t_ns, Reading(value, cov, np.bool_(valid))


def imu_from_msg(msg: Imu, name: str = 'sensors/imu') -> tuple[int, Reading]:
    """sensor_msgs/Imu -> (t_ns, gyro Reading); raises InvalidMessage."""
    return _body_vector_reading(name, msg, 'angular_velocity')


# --- star tracker: geometry_msgs/PoseWithCovarianceStamped ---------------------------------------

def star_tracker_to_msg(t_ns: int, reading: Reading) -> PoseWithCovarianceStamped:
    """Star-tracker reading (attitude, body-axes covariance) -> PoseWithCovarianceStamped."""
    q, cov, valid = _one(reading)
    if not valid:
        q = _IDENTITY
    msg = PoseWithCovarianceStamped()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = INERTIAL_FRAME
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    full = np.zeros((6, 6))
    if valid:
        R = rotation_from_quaternion(q)
        full[3:, 3:] = R @ np.asarray(cov, dtype=float) @ R.T
    else:
        full[3, 3] = NO_MEASUREMENT
    msg.pose.covariance = [float(v) for v in full.reshape(36)]
    return msg


def star_tracker_from_msg(msg: PoseWithCovarianceStamped, name: str = 'sensors/star_tracker') -> tuple[int, Reading]:
    """PoseWithCovarianceStamped -> (t_ns, star-tracker Reading, covariance back in body axes)."""
    t_ns = checked_stamp(name, msg.header.stamp)
    _check_frame(name, msg.header.frame_id, INERTIAL_FRAME)
    o = msg.pose.pose.orientation
    q = checked_quaternion(f'{name}.pose.orientation', (o.x, o.y, o.z, o.w))
    full = _finite(f'{name}.pose.covariance', msg.pose.covariance, 36).reshape(6, 6)
    if full[3, 3] == NO_MEASUREMENT:
        return t_ns, Reading(q, _ZERO3, np.bool_(False))
    cov = _checked_cov(f'{name}.pose.covariance', full.reshape(36), 6)[3:, 3:]
    R = rotation_from_quaternion(q)
    return t_ns, Reading(q, R.T @ cov @ R, np.bool_(True))


# --- sun sensor: geometry_msgs/Vector3Stamped ---------------------------------------------------

def sun_to_msg(t_ns: int, reading: Reading) -> Vector3Stamped:
    """Sun reading -> Vector3Stamped (the zero vector when there is no measurement)."""
    s, _, valid = _one(reading)
    msg = Vector3Stamped()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = BODY_FRAME
    if valid:
        msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in s)
    return msg


def sun_from_msg(msg: Vector3Stamped, name: str = 'sensors/sun') -> tuple[int, Reading]:
    """Vector3Stamped -> (t_ns, sun Reading): unit vector, or zero (no measurement)."""
    t_ns = checked_stamp(name, msg.header.stamp)
    _check_frame(name, msg.header.frame_id, BODY_FRAME)
    v = msg.vector
    s, n = received_unit_vector(_finite(f'{name}.vector', (v.x, v.y, v.z), 3))
    if n == 0.0:
        return t_ns, Reading(s, _ZERO3, np.bool_(False))
    if abs(n - 1.0) > UNIT_VECTOR_TOLERANCE:
        raise InvalidMessage(f'{name}: sun vector norm {n:.9g} is neither 1 nor 0')
    return t_ns, Reading(s, _ZERO3, np.bool_(True))


# --- magnetometer: sensor_msgs/MagneticField ----------------------------------------------------

def magnetometer_to_msg(t_ns: int, reading: Reading) -> MagneticField:
    """Magnetometer reading (T, body axes) -> sensor_msgs/MagneticField."""
    b, cov, valid = _one(reading)
    msg = MagneticField()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = BODY_FRAME
    f = msg.magnetic_field
    f.x, f.y, f.z = (float(v) for v in b)
    msg.magnetic_field_covariance = _marked(cov, valid)
    return msg


def magnetometer_from_msg(msg: MagneticField, name: str = 'sensors/magnetometer') -> tuple[int, Reading]:
    """sensor_msgs/MagneticField -> (t_ns, magnetometer Reading); raises InvalidMessage."""
    return _body_vector_reading(name, msg, 'magnetic_field')


# --- each sensor's codec (adcs_msgs_py.sensor_interfaces: SensorInterface.codec) -------------

@dataclass(frozen=True)
class Codec:
    """A sensor message's conversions: ``to_msg(t_ns, reading)``, ``from_msg(msg, name) -> (t_ns, reading)``."""

    to_msg: Callable
    from_msg: Callable


CODECS = {'imu': Codec(imu_to_msg, imu_from_msg), 'quaternion': Codec(star_tracker_to_msg, star_tracker_from_msg),
          'unit_vector': Codec(sun_to_msg, sun_from_msg), 'field': Codec(magnetometer_to_msg, magnetometer_from_msg)}
SENSOR_CODECS = {s.name: CODECS[s.codec] for s in SENSOR_INTERFACES}   # by sensor name


# --- estimate: nav_msgs/Odometry ----------------------------------------------------------------

def estimate_to_msg(est: Estimate) -> Odometry:
    """An estimate -> nav_msgs/Odometry: the same layout as ``state`` (a controller reads it with
    :func:`adcs_msgs_py.conversions.state_from_msg`), plus the attitude covariance (rotation block of
    the pose covariance, inertial axes) and the rate covariance (angular block of the twist, body)."""
    q, w = np.asarray(est.q, dtype=float), np.asarray(est.w, dtype=float)
    if q.ndim != 1:
        raise ValueError('a message carries one run: the estimate has a batch axis')
    msg = Odometry()
    msg.header.stamp = stamp_from_ns(est.t_ns)
    msg.header.frame_id = INERTIAL_FRAME
    msg.child_frame_id = BODY_FRAME
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    a = msg.twist.twist.angular
    a.x, a.y, a.z = (float(v) for v in w)
    R = rotation_from_quaternion(q)
    pose, twist = np.zeros((6, 6)), np.zeros((6, 6))
    pose[3:, 3:] = R @ np.asarray(est.cov, dtype=float)[:3, :3] @ R.T
    twist[3:, 3:] = est.rate_cov
    msg.pose.covariance = [float(v) for v in pose.reshape(36)]
    msg.twist.covariance = [float(v) for v in twist.reshape(36)]
    return msg


def estimate_from_msg(msg: Odometry, name: str = 'estimate/state') -> tuple[int, np.ndarray, np.ndarray,
                                                                              np.ndarray, np.ndarray]:
    """nav_msgs/Odometry -> (t_ns, q, w, attitude covariance in body axes, rate covariance)."""
    t_ns = checked_stamp(name, msg.header.stamp)
    _check_frame(name, msg.header.frame_id, INERTIAL_FRAME)
    _check_frame(f'{name}.child', msg.child_frame_id, BODY_FRAME)
    o = msg.pose.pose.orientation
    q = checked_quaternion(f'{name}.pose.orientation', (o.x, o.y, o.z, o.w))
    a = msg.twist.twist.angular
    w = _finite(f'{name}.twist.angular', (a.x, a.y, a.z), 3)
    att = _checked_cov(f'{name}.pose.covariance', msg.pose.covariance, 6)[3:, 3:]
    rate = _checked_cov(f'{name}.twist.covariance', msg.twist.covariance, 6)[3:, 3:]
    R = rotation_from_quaternion(q)
    return t_ns, q, w, R.T @ att @ R, rate
