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

from adcs_msgs_py.sensor_interfaces import SENSOR_INTERFACES, SENSORS

__all__ = ['SENSORS', 'UNIT_AS_IS', 'Estimate', 'Measurements', 'Reading', 'received_unit_vector']
# A received sun vector within this of unit norm is taken as it is (not renormalised): the sensor model's
# unit vectors then read back bit for bit, so an estimator on the graph sees the batch engine's numbers
# (the message side, adcs_msgs_py.conversions_determination, and the batch engine's as_received both apply it).
UNIT_AS_IS = 8 * float(np.finfo(float).eps)


def received_unit_vector(v: np.ndarray) -> tuple[np.ndarray, float]:
    """(the direction an estimator receives for a measured unit vector ``v`` (3,), its norm): ``v`` as it
    is within :data:`UNIT_AS_IS` of unit norm (and the zero vector), else ``v`` divided by its norm
    (``math.hypot``: no overflow). The one rule of the message side (``sun_from_msg``) and of the batch
    engine (``as_received``), so both give the same bits."""
    n = math.hypot(*v)
    if n == 0.0 or abs(n - 1.0) <= UNIT_AS_IS:
        return v, n
    return v / n, n


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
