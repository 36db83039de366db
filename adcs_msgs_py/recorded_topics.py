"""The topics the recorder writes itself, from what it records (issue 18).

``/clock`` and the per-step viewer topics (``frames/body``, ``frames/orbit``, ``error/eigenaxis``,
``error/euler_213``, ``markers``: :data:`adcs_msgs_py.names.RECORDED_VISUAL_TOPICS`) are functions
of what the bag already holds: the state's stamps, the true attitude, the wheel speeds and the
thrusters' on-times. Sending them through DDS cost the lockstep loop five of its eight messages a
step, in the dynamics node's publishing and in the recorder's taking, on the 2-core machine's
critical path. So the dynamics node publishes once, latched, on ``dynamics/recording``
(:data:`~adcs_msgs_py.names.RECORDING_CONFIG`, ``std_msgs/String``) the JSON of what the recorder
needs (:func:`config_text`: the topic whose stamps are the clock ticks, and the viewer config:
:attr:`adcs_msgs_py.visual.VisualMessages.config`, the topic that holds the true attitude, the
viewer topics it has), and publishes ``/clock`` and the viewer topics only to subscribers (the
fault injector, the runner's progress bar, a live viewer). The recorder never subscribes to them
(nor, once a ``dynamics/recording`` publisher is in the graph, to a ``/clock`` it discovers): it
builds the same :class:`~adcs_msgs_py.visual.VisualMessages` from that config and writes, for each
recorded message, what the dynamics node would have sent: the same bytes, zero-padded to 4 as DDS
delivers them, the same stamps and so the same log times (``tests/test_recorded_topics.py``).

* ``/clock`` of step ``t``: from the ``state`` of ``t`` (the dynamics node publishes both, with one
  stamp, at every step).
* ``frames/*``, ``error/*`` of step ``t``: from the attitude message of ``t`` (``truth/state``
  when the dynamics node publishes one, else ``state``, which is then the true state). The
  quaternion is taken as sent (not renormalised, which could move its last bit), after the
  checks the graph applies (finite, unit within
  :data:`~adcs_msgs_py.conversions.UNIT_QUATERNION_TOLERANCE`).
* ``markers`` of step ``t`` (the wheel momentum at its start, the thrusters that fire in it): once
  the step is integrated, i.e. when ``actuators/torque`` of ``t``, ``wheels/state`` of ``t`` (with
  wheels) and ``thrusters/state`` of ``t`` (with thrusters) are all here, in whatever order they
  arrive, however far (up to :data:`MAX_LAG` steps) one of them runs ahead of the others: two
  lockstep runs record the same markers whatever the load. :data:`MAX_PENDING` incomplete steps
  are held; one more is a broken invariant (or a hostile source): the step that has waited
  longest is given up, counted (:attr:`ViewerRecording.lost`, the bag's
  ``recorder.viewer_steps_lost``) and reported (the recorder logs an error), never silently (32
  were held until issue 31: under load 758 of 10 000 steps lost their markers unnoticed).

Everything here is untrusted input: a config that is not exactly what the dynamics node sends
(keys, types, finite numbers, sizes), or a source message that does not check, raises
:class:`~adcs_msgs_py.conversions.InvalidMessage` (the recorder counts it and keeps recording).
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from nav_msgs.msg import Odometry

from adcs_core.orbit import R_EARTH, CircularOrbit
from adcs_msgs_py import conversions as cv
from adcs_msgs_py.cdr import ClockCodec, JointStateCodec, StateCodec, deserialized
from adcs_msgs_py.names import (
    APPLIED_TORQUE,
    CLOCK,
    FRAMES_ORBIT,
    MARKERS,
    RECORDED_VISUAL_TOPICS,
    STATE,
    THRUSTERS_STATE,
    TRUTH_STATE,
    WHEELS_STATE,
)
from adcs_msgs_py.topics import DEPTH
from adcs_msgs_py.visual import VisualMessages

MAX_CONFIG_CHARS = 65536
MAX_ACTUATORS = 64   # wheels, thrusters
# How far one source of the markers can run ahead of another, in steps. The recorder takes messages
# in their order of arrival (its events executor), and the writers of the per-step topics wait
# every topics.ACK_INTERVAL steps until every reader holds what they sent (adcs_msgs_py.topics): when the
# recorder takes a message of step s, every input of the steps before s - ACK_INTERVAL has been
# taken. Allowed: the writers' history DEPTH (> ACK_INTERVAL: the margin the pacing keeps for a wait
# that times out), as an input further behind than that has left its writer's history (KEEP_LAST).
MAX_LAG = DEPTH
# Incomplete steps held: a lagging step and the MAX_LAG steps after it, and the last state's wheels
# state (its step is never integrated). More is a broken invariant: counted and reported.
MAX_PENDING = MAX_LAG + 2
ATTITUDE_TOPICS = (TRUTH_STATE, STATE)
KEYS = ('target', 'axis_length', 'wheel_axes', 'spin_inertia', 'max_speed', 'thruster_positions',
        'thruster_directions', 'orbit', 'attitude_topic', 'topics')   # of the viewer config
CLOCK_SOURCES = (STATE,)
WHAT = 'dynamics/recording'
ORBIT_KEYS = tuple(f.name for f in CircularOrbit.__dataclass_fields__.values())


def config_text(clock_topic: str | None, visual: VisualMessages | None = None, attitude_topic: str = STATE,
                topics=()) -> str:
    """The ``dynamics/recording`` message's text: ``/clock`` from the stamps of ``clock_topic`` (None:
    the dynamics node sends /clock to the recorder itself), the viewer topics ``topics`` of ``visual``
    (None: no viewer topics) with the true attitude on ``attitude_topic``."""
    viewer = None if visual is None else {**visual.config, 'attitude_topic': attitude_topic, 'topics': list(topics)}
    return json.dumps({'clock': clock_topic, 'viewer': viewer})


@dataclass(frozen=True)
class RecordingConfig:
    """A checked ``dynamics/recording``: where /clock comes from, and the viewer's config (or None)."""

    clock: str | None
    viewer: VisualConfig | None


def parse_config(text) -> RecordingConfig:
    """``dynamics/recording`` text -> :class:`RecordingConfig`; InvalidMessage naming what is wrong."""
    if not isinstance(text, str) or len(text) > MAX_CONFIG_CHARS:
        raise cv.InvalidMessage(f'{WHAT}: not a text of at most {MAX_CONFIG_CHARS} characters')
    try:
        raw = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise cv.InvalidMessage(f'{WHAT}: not JSON ({exc})') from None
    if not isinstance(raw, dict) or set(raw) != {'clock', 'viewer'}:
        raise cv.InvalidMessage(f'{WHAT}: not an object with exactly the keys clock, viewer')
    if raw['clock'] is not None and raw['clock'] not in CLOCK_SOURCES:
        raise cv.InvalidMessage(f'{WHAT}: clock must be null or one of {list(CLOCK_SOURCES)}')
    return RecordingConfig(raw['clock'], None if raw['viewer'] is None else _viewer(raw['viewer']))


@dataclass(frozen=True)
class VisualConfig:
    """The viewer part of a ``dynamics/recording``: the :class:`VisualMessages` arguments, what to derive."""

    arguments: dict
    attitude_topic: str
    topics: tuple[str, ...]


def _viewer(raw) -> VisualConfig:
    """The viewer part of the config, checked."""
    if not isinstance(raw, dict) or set(raw) != set(KEYS):
        raise cv.InvalidMessage(f'{WHAT} viewer: not an object with exactly the keys {list(KEYS)}')
    wheels, thrusters = _count(raw, 'wheel_axes'), _count(raw, 'thruster_positions')
    args = {'target': _numbers(raw, 'target', (4,)), 'axis_length': _number(raw['axis_length'], 'axis_length'),
            'wheel_axes': _numbers(raw, 'wheel_axes', (wheels, 3)),
            'spin_inertia': _numbers(raw, 'spin_inertia', (wheels,)),
            'max_speed': _numbers(raw, 'max_speed', (wheels,), infinite=True),
            'thruster_positions': _numbers(raw, 'thruster_positions', (thrusters, 3)),
            'thruster_directions': _numbers(raw, 'thruster_directions', (thrusters, 3)),
            'orbit': _orbit(raw['orbit'])}
    if not math.hypot(*args['target']) > 0 or not args['axis_length'] > 0:
        raise cv.InvalidMessage(f'{WHAT} viewer: a zero target quaternion or a non-positive axis length')
    topics = raw['topics']
    if (raw['attitude_topic'] not in ATTITUDE_TOPICS or not isinstance(topics, list)
            or not all(t in RECORDED_VISUAL_TOPICS for t in topics) or len(set(topics)) != len(topics)
            or (FRAMES_ORBIT in topics and args['orbit'] is None)):
        raise cv.InvalidMessage(f'{WHAT} viewer: attitude_topic must be one of {list(ATTITUDE_TOPICS)} '
                                f'and topics distinct ones of {list(RECORDED_VISUAL_TOPICS)} '
                                '(frames/orbit with an orbit)')
    return VisualConfig(args, raw['attitude_topic'], tuple(topics))


def _count(raw: dict, key: str) -> int:
    value = raw[key]
    if value is None:
        return 0
    if not isinstance(value, list) or not 0 < len(value) <= MAX_ACTUATORS:
        raise cv.InvalidMessage(f'{WHAT} viewer: {key} must be null or a list of 1 to {MAX_ACTUATORS} rows')
    return len(value)


def _number(value, key: str, infinite: bool = False) -> float:
    try:   # an int beyond a double's range: OverflowError
        number = float(value) if type(value) in (int, float) else math.nan
    except OverflowError:
        number = math.nan
    if math.isnan(number) or (math.isinf(number) and not infinite):
        raise cv.InvalidMessage(f'{WHAT} viewer: {key} holds {str(value)[:40]!r}, not a finite number')
    return number


def _numbers(raw: dict, key: str, shape: tuple[int, ...], infinite: bool = False):
    """``raw[key]``: a (nested) list of numbers of ``shape`` (None for no actuators)."""
    value = raw[key]
    if shape[0] == 0:
        if value is not None:
            raise cv.InvalidMessage(f'{WHAT} viewer: {key} given without the actuators it belongs to')
        return None
    rows = value if len(shape) == 2 else [value]
    width = shape[-1]
    if not isinstance(value, list) or len(value) != shape[0] or not all(
            isinstance(r, list) and len(r) == width for r in rows):
        raise cv.InvalidMessage(f'{WHAT} viewer: {key} must have shape {list(shape)}')
    out = [[_number(v, key, infinite) for v in r] for r in rows]
    return out if len(shape) == 2 else out[0]


def _orbit(value) -> CircularOrbit | None:
    if value is None:
        return None
    if not isinstance(value, dict) or set(value) != set(ORBIT_KEYS):
        raise cv.InvalidMessage(f'{WHAT} viewer: orbit must be null or have exactly the keys {list(ORBIT_KEYS)}')
    orbit = CircularOrbit(**{k: _number(value[k], f'orbit.{k}') for k in ORBIT_KEYS})
    if not (orbit.mu > 0 and orbit.altitude > -R_EARTH):
        raise cv.InvalidMessage(f'{WHAT} viewer: orbit needs mu > 0 and a positive radius')
    return orbit


class ViewerRecording:
    """The viewer messages of the recorded messages, as the dynamics node of ``config`` builds them."""

    def __init__(self, config: VisualConfig, on_lost: Callable[[int], None] | None = None) -> None:
        self.config = config
        self.on_lost = on_lost   # called with the stamp of each step given up (MAX_PENDING exceeded)
        self.lost = 0            # steps given up
        self.visual = VisualMessages(**config.arguments)
        self.topics = config.topics
        self.wheels = len(config.arguments['wheel_axes'] or ())
        self.thrusters = len(config.arguments['thruster_positions'] or ())
        self._state = StateCodec(config.attitude_topic)
        self._joints = {WHEELS_STATE: JointStateCodec(WHEELS_STATE), THRUSTERS_STATE: JointStateCodec(THRUSTERS_STATE)}
        self.marker_inputs = frozenset()
        if MARKERS in self.topics:
            self.marker_inputs = frozenset({APPLIED_TORQUE} | ({WHEELS_STATE} if self.wheels else set())
                                           | ({THRUSTERS_STATE} if self.thrusters else set()))
        self.attitude_topics = tuple(t for t in self.topics if t != MARKERS)   # of the true attitude
        attitude = {config.attitude_topic} if self.attitude_topics else set()
        self.sources = frozenset(attitude | self.marker_inputs)
        self._pending: dict[int, dict] = {}

    def derive(self, topic: str, data: bytes, t_ns: int) -> list[tuple[str, bytes]]:
        """The viewer messages (topic, CDR bytes as the dynamics node encodes them) that the message
        ``data`` on ``topic``, stamped ``t_ns`` (checked), completes."""
        out = []
        if topic == self.config.attitude_topic and self.attitude_topics:
            out += self.visual.attitude_cdr(t_ns, self._attitude(data), self.attitude_topics)
        if topic in self.marker_inputs:
            out += self._markers(topic, data, t_ns)
        return out

    def _attitude(self, data: bytes) -> tuple:
        """The quaternion of an attitude message, as sent (checked, not renormalised)."""
        v = self._state.template.decode(data)
        if v is None:   # another layout of an Odometry: read it whole
            o = deserialized(data, Odometry, self.config.attitude_topic).pose.pose.orientation
            q = (o.x, o.y, o.z, o.w)
        else:
            q = tuple(v[2:6])
        cv.checked_quaternion(f'{self.config.attitude_topic} orientation', q)
        return q

    def _markers(self, topic: str, data: bytes, t_ns: int) -> list[tuple[str, bytes]]:
        value = None
        if topic in self._joints:
            msg = self._joints[topic].message(data)
            value = tuple(float(v) for v in msg.velocity)   # wheel speeds / thruster on-times
            count = self.wheels if topic == WHEELS_STATE else self.thrusters
            if len(value) != count or not all(math.isfinite(v) for v in value):
                raise cv.InvalidMessage(f'{topic}: {len(value)} velocities, not {count} finite ones')
        entry = self._pending.get(t_ns)
        if entry is None:
            if len(self._pending) >= MAX_PENDING:
                self._give_up()
            entry = self._pending[t_ns] = {}
        entry[topic] = value
        if not self.marker_inputs <= entry.keys():
            return []
        del self._pending[t_ns]
        speed = np.array(entry[WHEELS_STATE]) if self.wheels else None
        return [(MARKERS, self.visual.marker_array_cdr(t_ns, speed, entry.get(THRUSTERS_STATE, ())))]

    def _give_up(self) -> None:
        """More incomplete steps than MAX_PENDING: a broken invariant (or steps of a hostile source
        that never complete). The one that has waited longest goes (not the smallest stamp: a
        hostile far-future one would stay forever), counted and reported."""
        t_ns = next(iter(self._pending))
        del self._pending[t_ns]
        self.lost += 1
        if self.on_lost is not None:
            self.on_lost(t_ns)


class RecordedTopics:
    """What the recorder writes itself for one ``dynamics/recording`` config: ``/clock`` (with
    ``config.clock``) and the viewer topics (with ``config.viewer``)."""

    def __init__(self, config: RecordingConfig, on_lost: Callable[[int], None] | None = None) -> None:
        self.config = config
        self.viewer = ViewerRecording(config.viewer, on_lost) if config.viewer is not None else None
        self.topics = ((CLOCK,) if config.clock else ()) + (self.viewer.topics if self.viewer else ())
        self.sources = frozenset(({config.clock} if config.clock else set())
                                 | (self.viewer.sources if self.viewer else set()))
        self._clock = ClockCodec()

    @property
    def lost(self) -> int:
        """Steps whose markers were given up (:data:`MAX_PENDING` exceeded): 0 unless an invariant broke."""
        return self.viewer.lost if self.viewer is not None else 0

    def derive(self, topic: str, data: bytes) -> list[tuple[str, bytes]]:
        """The messages (topic, CDR bytes as a subscriber receives them: DDS pads a message to a
        multiple of 4 bytes with zeros) that the message ``data`` on ``topic`` completes."""
        if topic not in self.sources:
            return []
        out = []
        t_ns = cv.checked_cdr_stamp(topic, data)   # every source is a header-first message
        if topic == self.config.clock:
            out.append((CLOCK, self._clock.encode(t_ns)))
        if self.viewer is not None and topic in self.viewer.sources:
            out += self.viewer.derive(topic, data, t_ns)
        return [(name, message + bytes(-len(message) % 4)) for name, message in out]
