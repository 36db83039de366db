"""The interface half of each sensor, declared once (no ROS import): its name, topic, message, codec,
fault modes, NIS dimension, what an estimator receives, and what it measures.

Everything that lists or dispatches on sensors reads :data:`SENSOR_INTERFACES`:
:data:`adcs_msgs_py.measurements.SENSORS` and the fields of ``Measurements``, ``names.SENSOR_TOPICS``
and ``PUBLISHER_ROLES``, the ``TopicSpec`` of each sensor topic (``topics.TOPICS``, with its QoS
reason), the message conversions (``conversions_determination.CODECS``), the dynamics node's
publishers, the estimator node's decoders, the fault schedule's targets and modes
(:data:`SENSOR_FAULT_MODES`), the batch engine's ``as_received``, the estimators' vector sensors and
the analysis' NIS dimensions (``adcs_sim.app.analysis.estimation.NIS_DOF``). The truth half (the model, its
``sensors.<name>.*`` parameters, its environment inputs) is declared once in
:mod:`adcs_sim.truth.sensor_schema` (``SENSOR_MODELS``), in this order.

Sensor faults (issue 20): the fault schedule may name the targets of :data:`SENSOR_FAULT_MODES` beside
the wheels, each with the modes it allows (besides ``adcs_core.faults.FAULT_OK_MODES``). ``failed``:
the sensor gives no measurement (a star tracker outage until ``recovered``, a failed magnetometer or
sun sensor); ``bias``: the gyro axis reads ``value`` rad/s more (a bias jump, held until recovered);
``stuck``: the gyro axis repeats, from the fault's step on, the reading of that step. A snapshot
carries them only when the schedule names them, so an actuator-only schedule's messages are unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass, field

# The codecs of adcs_msgs_py.conversions_determination.CODECS and the message type each one writes.
CODEC_MESSAGES = {'imu': 'sensor_msgs/msg/Imu', 'quaternion': 'geometry_msgs/msg/PoseWithCovarianceStamped',
                  'unit_vector': 'geometry_msgs/msg/Vector3Stamped', 'field': 'sensor_msgs/msg/MagneticField'}
_FAILED = ('failed',)
_LOCKSTEP_LIKE_STAR_TRACKER = 'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as sensors/star_tracker.'


@dataclass(frozen=True)
class SensorInterface:
    """One sensor as the interface sees it.

    ``measures``: ``rate`` (the gyro: propagation, no update), ``attitude`` (a quaternion update),
    ``direction`` (a unit vector of the inertial direction ``reference``, noise in rad) or ``field``
    (a vector of the inertial ``reference`` field, noise in T). ``received``: the rule an estimator
    node's decoder applies to the value and that the batch engine's ``as_received`` repeats
    (``quaternion``: divided by its norm, the identity when not valid; ``unit_vector``:
    ``received_unit_vector``, the zero vector when not valid; None: as sent)."""

    name: str
    label: str                       # for people: 'sun sensor'
    topic: str
    codec: str                       # a key of CODEC_MESSAGES
    measures: str                    # rate, attitude, direction, field
    description: str                 # the TopicSpec's
    qos_reason: str                  # topics.QOS_RATIONALE's
    fault_modes: dict = field(default_factory=lambda: {})   # {fault target: modes}; default {name: failed}
    nis_dof: int | None = None       # dimension of its NIS (None: no update)
    received: str | None = None
    reference: str | None = None     # the references.<key> of the inertial vector it measures

    @property
    def message(self) -> str:
        return CODEC_MESSAGES[self.codec]

    @property
    def targets(self) -> dict:
        """Its fault targets and their modes."""
        return self.fault_modes or {self.name: _FAILED}


SENSOR_INTERFACES: tuple[SensorInterface, ...] = (
    SensorInterface(
        'gyro', 'gyro', 'sensors/imu', 'imu', 'rate',
        'gyro: measured body rate (rad/s, body axes) with its covariance; orientation and acceleration '
        'not measured (covariance[0] = -1); covariance[0] = -1 on the rate: no measurement this step',
        'RELIABLE: the estimator propagates with every gyro sample; a lost one is a step it cannot '
        'answer (a missed step downstream) and a hole in the recording. VOLATILE: a late joiner must '
        'not integrate old rates. KEEP_LAST lockstep depth, as state.',
        fault_modes={f'gyro.{axis}': ('bias', 'stuck') for axis in 'xyz'}),
    SensorInterface(
        'star_tracker', 'star tracker', 'sensors/star_tracker', 'quaternion', 'attitude',
        'star tracker: measured attitude (body in inertial, x y z w), rotation covariance about the '
        'inertial axes (rad^2); covariance[21] = -1: no measurement (outage, not due)',
        'RELIABLE, VOLATILE, KEEP_LAST lockstep depth, as sensors/imu: published every step (marked '
        'when there is no measurement) so the estimator knows it has the whole step.',
        nis_dof=3, received='quaternion'),
    SensorInterface(
        'sun', 'sun sensor', 'sensors/sun', 'unit_vector', 'direction',
        'sun sensor: unit Sun direction in body axes; the zero vector: no Sun (eclipse, out of the '
        'field of view, failed)', _LOCKSTEP_LIKE_STAR_TRACKER,
        nis_dof=2, received='unit_vector', reference='sun'),
    SensorInterface(
        'magnetometer', 'magnetometer', 'sensors/magnetometer', 'field', 'field',
        'three-axis magnetometer: field in body axes (T) with its covariance (T^2); covariance[0] = -1: '
        'no measurement', _LOCKSTEP_LIKE_STAR_TRACKER,
        nis_dof=2, reference='magnetometer'),
    SensorInterface(
        'fine_sun_sensor', 'fine sun sensor', 'sensors/fine_sun', 'unit_vector', 'direction',
        'fine (two-axis) sun sensor: unit Sun direction in body axes from its two measured angles; the '
        'zero vector: no Sun (eclipse, out of the field of view, failed)', _LOCKSTEP_LIKE_STAR_TRACKER,
        nis_dof=2, received='unit_vector', reference='sun'),
)

SENSORS = tuple(s.name for s in SENSOR_INTERFACES)   # the fields of Measurements, in this order
BY_NAME = {s.name: s for s in SENSOR_INTERFACES}
SENSOR_TOPICS = {s.name: s.topic for s in SENSOR_INTERFACES}
NIS_DOF = {s.name: s.nis_dof for s in SENSOR_INTERFACES if s.nis_dof is not None}
VECTOR_SENSORS = tuple(s.name for s in SENSOR_INTERFACES if s.measures in ('direction', 'field'))
# Whole-sensor targets first, then the per-axis ones (``gyro.x``): the order of a snapshot's entries,
# which the fault messages and the recorded bags keep.
SENSOR_FAULT_MODES: dict[str, tuple[str, ...]] = dict(sorted(
    ((t, m) for s in SENSOR_INTERFACES for t, m in s.targets.items()), key=lambda tm: '.' in tm[0]))
FAULT_TARGET_SENSOR = {t: s.name for s in SENSOR_INTERFACES for t in s.targets}   # target -> sensor


def split_snapshot(snapshot: dict) -> tuple[dict, dict]:
    """(actuator part, sensor part) of a fault snapshot: the sensor part holds the targets of
    :data:`SENSOR_FAULT_MODES`."""
    sensors = {n: s for n, s in snapshot.items() if n in SENSOR_FAULT_MODES}
    return {n: s for n, s in snapshot.items() if n not in SENSOR_FAULT_MODES}, sensors
