"""What sensors measure and what an estimator estimates, as plain numpy (no ROS): the one layout the
truth model's sensor models produce, the estimators consume and :mod:`adcs_msgs_py.conversions_determination`
turns into (and back from) the standard messages.

Conventions (the same as :mod:`adcs_core.attitude` and :mod:`adcs_controllers.estimators.mekf`):

* vectors in **body axes**; the attitude quaternion ``q = [x, y, z, w]`` (scalar last) is the body in
  the inertial frame;
* a covariance given here is in **body axes**: for an attitude, that of the small rotation ``δθ`` with
  ``q_true = q ⊗ δq(δθ)`` (rad²); for a rate, (rad/s)²; for a field, T²;
* every array may carry a leading batch axis (one entry per run of a batch): ``value`` (..., 3) or
  (..., 4), ``cov`` (..., 3, 3), ``valid`` (...,);
* ``valid`` False: no measurement this step (a star tracker outage, not due at its update rate, a sun
  sensor in eclipse, a failed magnetometer). The message still goes out every step (lockstep: an
  estimator knows when it has all of a step's messages) with the "no measurement" marker of
  :mod:`adcs_msgs_py.conversions_determination`; ``value`` is then meaningless.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass

import numpy as np

from adcs_core.attitude import quat_norm
from adcs_msgs_py.sensor_interfaces import BY_NAME, SENSOR_INTERFACES, SENSORS

__all__ = ['SENSORS', 'UNIT_AS_IS', 'Estimate', 'Measurements', 'Reading', 'received_attitude',
           'received_readings', 'received_unit_vector']
# A received sun vector within this of unit norm is taken as it is (not renormalised): the sensor model's
# unit vectors then read back bit for bit, so an estimator on the graph sees the batch engine's numbers
# (the message side, adcs_msgs_py.conversions_determination, and received_readings, the batch engine's, both apply it).
UNIT_AS_IS = 8 * float(np.finfo(float).eps)


def received_unit_vector(v: np.ndarray) -> tuple[np.ndarray, float]:
    """(the direction an estimator receives for a measured unit vector ``v`` (3,), its norm): ``v`` as it
    is within :data:`UNIT_AS_IS` of unit norm (and the zero vector), else ``v`` divided by its norm
    (``math.hypot``: no overflow). The one rule of the message side (``sun_from_msg``) and of the batch
    engine (:func:`received_readings`), so both give the same bits."""
    n = math.hypot(*v)
    if n == 0.0 or abs(n - 1.0) <= UNIT_AS_IS:
        return v, n
    return v / n, n


def received_attitude(q: np.ndarray, norm=None) -> np.ndarray:
    """The attitude a flight-software node receives for a sent quaternion ``q`` (..., 4): ``q`` divided
    by its norm (:func:`adcs_core.attitude.quat_norm`, or ``norm`` when the caller has it). The one rule
    of the message side (:func:`adcs_msgs_py.conversions.checked_quaternion`, which also refuses a norm
    too far from 1) and of the batch engine's flight step (:class:`adcs_controllers.step.FlightStep`)."""
    q = np.asarray(q, dtype=float)
    return q / (quat_norm(q)[..., None] if norm is None else norm)


def received_readings(m: 'Measurements') -> 'Measurements':
    """The readings as an estimator node receives them from the messages
    (:mod:`adcs_msgs_py.conversions_determination`), by each sensor's declared ``received`` rule
    (:mod:`adcs_msgs_py.sensor_interfaces`): a quaternion by :func:`received_attitude` (the identity
    when it has no measurement: what the message carries), a unit vector by
    :func:`received_unit_vector` (the zero vector without a measurement); the rest as sent. The
    batch engine's estimator (:class:`adcs_controllers.step.EstimationStep`) sees the very bits of
    the graph's."""
    out = {}
    for name in m.fitted():
        r = getattr(m, name)
        value, valid = np.asarray(r.value, dtype=float), np.asarray(r.valid, dtype=bool)[..., None]
        rule = BY_NAME[name].received
        if rule == 'quaternion':     # no measurement: the message carries the identity
            value = np.where(valid, received_attitude(value), [0.0, 0.0, 0.0, 1.0])
        elif rule == 'unit_vector':  # no measurement: the zero vector; else sun_from_msg's own rule
            rows, ok = value.reshape(-1, 3), np.broadcast_to(valid[..., 0], value.shape[:-1]).reshape(-1)
            value = np.array([received_unit_vector(v)[0] if good else np.zeros(3)
                              for v, good in zip(rows, ok)]).reshape(value.shape)
        out[name] = Reading(value, r.cov, r.valid)
    return Measurements(m.t_ns, **out)


@dataclass(frozen=True)
class Reading:
    """One sensor's reading at one step (of one run, or of each run of a batch)."""

    value: np.ndarray   # (..., 3) vector, body axes; (..., 4) quaternion for the star tracker
    cov: np.ndarray     # (..., 3, 3) body axes; zeros when the sensor reports none (the sun sensor)
    valid: np.ndarray   # (...,) bool


def _fitted(self) -> tuple[str, ...]:
    """Names (of :data:`SENSORS`) of the sensors this step carries."""
    return tuple(name for name in SENSORS if getattr(self, name) is not None)


# All sensor readings stamped ``t_ns`` (the step's simulated time), one field per declared sensor
# (adcs_msgs_py.sensor_interfaces, in its order; None: not fitted), e.g. ``gyro`` (rad/s: true rate +
# bias + noise), ``star_tracker`` (attitude quaternion), ``sun`` (unit Sun direction), ``magnetometer``
# (field, T).
Measurements = make_dataclass(
    'Measurements', [('t_ns', int)] + [(s.name, 'Reading | None', field(default=None)) for s in SENSOR_INTERFACES],
    frozen=True, namespace={'fitted': _fitted, '__module__': __name__,
                            '__doc__': 'All sensor readings stamped t_ns; one field per declared sensor '
                                       '(None: not fitted).'})


@dataclass(frozen=True)
class Estimate:
    """An estimator's output at ``t_ns`` (published on ``estimate/state`` and ``estimator/status``).

    ``cov`` is the error-state covariance (..., 6, 6) of ``[δθ, Δβ]`` in body axes (rad², rad²/s,
    (rad/s)²), as :mod:`adcs_controllers.estimators.mekf`; ``rate_cov`` (..., 3, 3) that of ``w``.
    A single-frame estimator has no bias: ``bias`` zeros and its block of ``cov`` zeros.
    """

    t_ns: int
    q: np.ndarray         # (..., 4) body in inertial, scalar last
    w: np.ndarray         # (..., 3) rad/s, body axes (gyro rate minus the estimated bias)
    bias: np.ndarray      # (..., 3) rad/s
    cov: np.ndarray       # (..., 6, 6)
    rate_cov: np.ndarray  # (..., 3, 3)
