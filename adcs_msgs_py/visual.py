"""Messages for viewers: the body (and orbit) frame as transforms, markers, attitude-error series.

What Foxglove's 3D panel and RViz draw, and what a plot panel plots without computing anything
(:data:`adcs_msgs_py.names.VISUAL_TOPICS`, published by the dynamics node with
``visualization.enabled``):

* ``frames/body``, ``frames/orbit`` (``geometry_msgs/TransformStamped``): parent ``inertial``,
  child ``body`` (rotation = the true attitude, body in inertial, so ``R(q)`` takes body vectors
  to inertial axes, the tf convention) and ``orbit`` (:func:`adcs_core.orbit.orbit_frame_attitude`).
  No translation: attitude only, every frame at one origin. The recorder also writes them into
  the bag as ``/tf`` (``tf2_msgs/TFMessage``: :mod:`adcs_sim.bag.tf`).
* ``markers/static`` (``visualization_msgs/MarkerArray``, latched, published once at t = 0):
  a translucent body box and the body axes (frame ``body``, ``frame_locked``: they move with the
  transform) and the target attitude's axes (frame ``inertial``, oriented by the target).
* ``markers`` (every step, every moving marker in every array, so the latest array alone draws
  the scene): the wheels' momentum ``sum_i Js_i Omega_i a_i`` (an arrow in body axes; length
  ``axis_length * |h| / sum_i Js_i max_speed_i``, or ``axis_length`` per N m s with unlimited
  wheels) and one LINE_LIST with a segment for each thruster firing in the step, from the
  thruster against its force (its plume; no segment while it is off). In a step where no
  thruster fires the plume marker is a DELETE of that marker (same ``ns`` and ``id``, no points):
  a LINE_LIST without points is an invalid marker to viewers (Lichtblick and Foxglove flag the
  topic), and an omitted marker would leave the last plume drawn.
* ``error/eigenaxis`` (``x``: the eigenaxis angle, deg; y, z: 0) and ``error/euler_213`` (the
  2-1-3 Euler angles of the error, deg, stored by axis: x, y, z = the rotations about body x, y,
  z), of ``q_e = q_ref* (x) q``: :func:`adcs_core.attitude.error_quaternion`,
  :func:`~adcs_core.attitude.eigenaxis_angle` and :func:`~adcs_core.attitude.euler_213`, the
  functions the offline analysis uses (``adcs_sim.app.analysis.metrics.attitude_errors``).

The per-step ones (``frames/*``, ``markers``, ``error/*``) go out only to live subscribers: the
recorder builds them itself, from :attr:`VisualMessages.config` (published once on
``dynamics/recording``) and the messages it records (:mod:`adcs_msgs_py.recorded_topics`).

Each message is built once and updated in place every step (the dynamics loop pays a few field
writes, not the construction); what never changes goes out once (its serialisation, ~1 ms for
seven markers, would otherwise cost every step).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from geometry_msgs.msg import Point, TransformStamped, Vector3Stamped
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from adcs_core.attitude import eigenaxis_angle, error_quaternion, euler_213, quat_multiply
from adcs_core.orbit import CircularOrbit, orbit_frame_attitude, orbit_rate
from adcs_msgs_py.cdr import STAMP, Template, TransformCodec, VectorCodec
from adcs_msgs_py.conversions import BODY_FRAME, INERTIAL_FRAME, NS_PER_S, stamp_from_ns
from adcs_msgs_py.names import ERROR_EIGENAXIS, ERROR_EULER_213, FRAMES_BODY, FRAMES_ORBIT, MARKERS, VISUAL_TOPICS

ORBIT_FRAME = 'orbit'
AXIS_COLORS = ((0.9, 0.1, 0.1), (0.1, 0.8, 0.1), (0.1, 0.3, 0.95))   # x red, y green, z blue
TARGET_ALPHA = 0.45
MOMENTUM_COLOR = (0.55, 0.2, 0.85)     # purple
PLUME_COLOR = (1.0, 0.5, 0.0)          # orange
PLUME_LENGTH = 0.35    # of axis_length
BOX_SIZE = 0.5         # edge of the body box, of axis_length


def _color(rgb, alpha: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def _listed(values) -> list | None:
    return None if values is None else np.asarray(values, dtype=float).tolist()


def _point(v) -> Point:
    return Point(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _arrow(ns: str, index: int, frame: str, tail, head, rgb, alpha: float, width: float) -> Marker:
    m = Marker(ns=ns, id=index, type=Marker.ARROW, action=Marker.ADD)
    m.header.frame_id = frame
    m.frame_locked = frame == BODY_FRAME
    m.pose.orientation.w = 1.0
    m.points = [_point(tail), _point(head)]
    m.scale.x, m.scale.y, m.scale.z = width, 2.0 * width, 3.0 * width   # shaft, head diameters, head length
    m.color = _color(rgb, alpha)
    return m


def transform_msg(parent: str, child: str) -> TransformStamped:
    """A transform ``parent -> child`` at the origin (update its stamp and rotation with :func:`set_transform`)."""
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.transform.rotation.w = 1.0
    return msg


def set_transform(msg: TransformStamped, t_ns: int, q) -> TransformStamped:
    """Stamp ``t_ns`` and rotation ``q`` (x, y, z, w: child in parent) into ``msg``."""
    msg.header.stamp = stamp_from_ns(t_ns)
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    return msg


class VisualMessages:
    """The viewer messages of one spacecraft (module doc); one instance per dynamics node.

    ``wheel_axes`` (n, 3) unit, ``spin_inertia`` and ``max_speed`` (n,); ``thruster_positions``,
    ``thruster_directions`` (m, 3) body axes (unit directions); ``target`` the regulation target
    (x, y, z, w, body in inertial); ``orbit`` a :class:`~adcs_core.orbit.CircularOrbit` or None."""

    def __init__(self, target, axis_length: float = 1.0, wheel_axes=None, spin_inertia=None, max_speed=None,
                 thruster_positions=None, thruster_directions=None, orbit: CircularOrbit | None = None) -> None:
        # What builds these messages, as JSON-able numbers (float repr round-trips: the recorder's
        # copy, adcs_msgs_py.recorded_topics, is built from the very same values)
        self.config = {'target': _listed(target), 'axis_length': float(axis_length),
                       'wheel_axes': _listed(wheel_axes), 'spin_inertia': _listed(spin_inertia),
                       'max_speed': _listed(max_speed), 'thruster_positions': _listed(thruster_positions),
                       'thruster_directions': _listed(thruster_directions),
                       'orbit': dataclasses.asdict(orbit) if orbit is not None else None}
        self.target = np.asarray(target, dtype=float) / np.linalg.norm(target)
        self.length = float(axis_length)
        self.body = transform_msg(INERTIAL_FRAME, BODY_FRAME)
        self.orbit = transform_msg(INERTIAL_FRAME, ORBIT_FRAME) if orbit is not None else None
        if orbit is not None:   # q_io(t) = q_io(0) (x) the rotation by w_io^o t about the orbit normal
            self._orbit0 = orbit_frame_attitude(orbit, 0.0)
            self._orbit_rate = orbit_rate(orbit)[1]
        # The per-step messages' CDR bytes (adcs_msgs_py.cdr): what the dynamics node publishes.
        self._body_cdr = TransformCodec(INERTIAL_FRAME, BODY_FRAME)
        self._orbit_cdr = TransformCodec(INERTIAL_FRAME, ORBIT_FRAME) if orbit is not None else None
        self._error_cdr = VectorCodec('error', BODY_FRAME)   # error/*: the numbers of errors()
        self.eigenaxis = Vector3Stamped()
        self.euler = Vector3Stamped()
        for msg in (self.eigenaxis, self.euler):
            msg.header.frame_id = BODY_FRAME
        n = 0 if wheel_axes is None else len(wheel_axes)
        self.wheel_axes = np.asarray(wheel_axes if n else np.zeros((0, 3)), dtype=float).reshape(n, 3)
        self.spin = np.asarray(spin_inertia if n else [], dtype=float)
        capacity = float(np.sum(self.spin * np.asarray(max_speed if n else [], dtype=float)))
        self.momentum_scale = self.length / capacity if math.isfinite(capacity) and capacity > 0 else self.length
        self.momentum = (_arrow('wheel_momentum', 0, BODY_FRAME, (0, 0, 0), (0, 0, 0), MOMENTUM_COLOR, 1.0,
                                0.04 * self.length) if n else None)
        self.plumes = self._plumes(thruster_positions, thruster_directions)
        self.markers = MarkerArray(markers=[m for m in (self.momentum, self.plumes) if m is not None])
        # the viewer topics this spacecraft has: no orbit frame without an orbit, no moving markers
        # when nothing moves but the body (torquers only)
        skip = ({FRAMES_ORBIT} if orbit is None else set()) | (set() if self.markers.markers else {MARKERS})
        self.topics = tuple(t for t in VISUAL_TOPICS if t not in skip)
        self._markers_cdr: dict[tuple, Template] = {}   # per set of firing thrusters

    def static_markers(self, t_ns: int) -> MarkerArray:
        """What never moves in its frame (published once): the body box and axes, the target axes."""
        L, w = self.length, 0.03 * self.length
        box = Marker(ns='body', id=0, type=Marker.CUBE, action=Marker.ADD, frame_locked=True)
        box.header.frame_id = BODY_FRAME
        box.pose.orientation.w = 1.0
        box.scale.x = box.scale.y = box.scale.z = BOX_SIZE * L
        box.color = _color((0.7, 0.7, 0.75), 0.35)
        out = [box]
        for i, rgb in enumerate(AXIS_COLORS):
            out.append(_arrow('body_axes', i, BODY_FRAME, (0, 0, 0), L * np.eye(3)[i], rgb, 1.0, w))
        for i, rgb in enumerate(AXIS_COLORS):
            m = _arrow('target_axes', i, INERTIAL_FRAME, (0, 0, 0), 1.2 * L * np.eye(3)[i], rgb, TARGET_ALPHA, w)
            o = m.pose.orientation
            o.x, o.y, o.z, o.w = (float(v) for v in self.target)
            out.append(m)
        stamp = stamp_from_ns(t_ns)
        for m in out:
            m.header.stamp = stamp
        return MarkerArray(markers=out)

    def _plumes(self, positions, directions) -> Marker | None:
        """One LINE_LIST for all the thrusters: a segment from each firing one against its force."""
        if positions is None or not len(positions):
            return None
        self._plume_ends = []
        for p, u in zip(np.asarray(positions, dtype=float).reshape(-1, 3),
                        np.asarray(directions, dtype=float).reshape(-1, 3)):
            self._plume_ends.append((_point(p), _point(p - PLUME_LENGTH * self.length * u)))
        m = Marker(ns='thrusters', id=0, type=Marker.LINE_LIST, action=Marker.ADD, frame_locked=True)
        m.header.frame_id = BODY_FRAME
        m.pose.orientation.w = 1.0
        m.scale.x = 0.05 * self.length
        m.color = _color(PLUME_COLOR, 0.9)
        return m

    # --- per step ------------------------------------------------------------------------

    def body_frame(self, t_ns: int, q) -> TransformStamped:
        """inertial -> body at ``t_ns``: rotation ``q`` (the attitude, body in inertial)."""
        return set_transform(self.body, t_ns, q)

    def body_frame_cdr(self, t_ns: int, q) -> bytes:
        """The CDR bytes of :meth:`body_frame`."""
        return self._body_cdr.encode(t_ns, q)

    def orbit_frame(self, t_ns: int) -> TransformStamped:
        """inertial -> orbit at ``t_ns`` (:func:`adcs_core.orbit.orbit_frame_attitude`, propagated in
        closed form: the orbit frame turns at ``w_io^o`` about its y axis)."""
        return set_transform(self.orbit, t_ns, self.orbit_attitude(t_ns))

    def orbit_frame_cdr(self, t_ns: int) -> bytes:
        """The CDR bytes of :meth:`orbit_frame`."""
        return self._orbit_cdr.encode(t_ns, self.orbit_attitude(t_ns))

    def orbit_attitude(self, t_ns: int) -> np.ndarray:
        """The orbit frame's attitude (x, y, z, w; w >= 0, as orbit_frame_attitude) at ``t_ns``."""
        half = 0.5 * t_ns / NS_PER_S * float(self._orbit_rate[1])   # w_io^o = [0, -w_o, 0]
        spin = np.array([0.0, math.sin(half), 0.0, math.cos(half)])
        q = quat_multiply(self._orbit0, spin)
        return q if q[3] >= 0 else -q

    def error_values(self, q) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """The vectors of (error/eigenaxis, error/euler_213) of attitude ``q`` against the target:
        (angle, 0, 0) and the Euler angles by body axis (deg)."""
        qe = error_quaternion(np.asarray(q, dtype=float), self.target)
        angle = math.degrees(float(eigenaxis_angle(qe)))
        y, x, z = np.degrees(euler_213(qe))       # sequence order: about y, then x, then z
        return (angle, 0.0, 0.0), (float(x), float(y), float(z))

    def errors(self, t_ns: int, q) -> tuple[Vector3Stamped, Vector3Stamped]:
        """(error/eigenaxis, error/euler_213) of attitude ``q`` against the target."""
        stamp = stamp_from_ns(t_ns)
        self.eigenaxis.header.stamp = self.euler.header.stamp = stamp
        for msg, values in zip((self.eigenaxis, self.euler), self.error_values(q)):
            v = msg.vector
            v.x, v.y, v.z = values
        return self.eigenaxis, self.euler

    def errors_cdr(self, t_ns: int, q) -> tuple[bytes, bytes]:
        """The CDR bytes of :meth:`errors` (:class:`~adcs_msgs_py.cdr.VectorCodec`)."""
        eigenaxis, euler = self.error_values(q)
        return self._error_cdr.encode(t_ns, eigenaxis), self._error_cdr.encode(t_ns, euler)

    def attitude_cdr(self, t_ns: int, q, wanted) -> list[tuple[str, bytes]]:
        """(topic, CDR bytes) of the messages of the true attitude ``q`` at ``t_ns`` whose topic is in
        ``wanted``: ``frames/body``, ``frames/orbit``, ``error/eigenaxis``, ``error/euler_213``
        (the dynamics node's, to its live subscribers; the recorder's, adcs_msgs_py.recorded_topics)."""
        out = []
        if FRAMES_BODY in wanted:
            out.append((FRAMES_BODY, self.body_frame_cdr(t_ns, q)))
        if FRAMES_ORBIT in wanted:
            out.append((FRAMES_ORBIT, self.orbit_frame_cdr(t_ns)))
        if ERROR_EIGENAXIS in wanted or ERROR_EULER_213 in wanted:
            for topic, data in zip((ERROR_EIGENAXIS, ERROR_EULER_213), self.errors_cdr(t_ns, q)):
                if topic in wanted:
                    out.append((topic, data))
        return out

    def marker_array(self, t_ns: int, wheel_speed=None, on_time: Sequence[float] = ()) -> MarkerArray:
        """The step's moving markers: the wheel momentum from the speeds (rad/s, relative to the
        body), a plume for each thruster with a positive ``on_time`` over the step."""
        stamp = stamp_from_ns(t_ns)
        for m in self.markers.markers:
            m.header.stamp = stamp
        if self.momentum is not None and wheel_speed is not None:
            h = (self.spin * np.asarray(wheel_speed, dtype=float)) @ self.wheel_axes
            self.momentum.points[1] = _point(self.momentum_scale * h)
        if self.plumes is not None:
            self.plumes.points = [p for ends, on in zip(self._plume_ends, on_time) if on > 0 for p in ends]
            self.plumes.action = Marker.ADD if self.plumes.points else Marker.DELETE   # module doc
        return self.markers

    def marker_array_cdr(self, t_ns: int, wheel_speed=None, on_time: Sequence[float] = ()):
        """The CDR bytes of :meth:`marker_array` (a template per set of firing thrusters, the stamps
        and the momentum arrow's head written in); the message itself without wheel speeds."""
        if wheel_speed is None and self.momentum is not None:
            return self.marker_array(t_ns, wheel_speed, on_time)
        firing = tuple(on > 0 for on in on_time) if self.plumes is not None else ()
        template = self._markers_cdr.get(firing)
        if template is None:
            template = self._markers_cdr[firing] = self._marker_template(on_time)
        sec, nanosec = divmod(int(t_ns), NS_PER_S)
        values = []
        if self.momentum is not None:
            h = (self.spin * np.asarray(wheel_speed, dtype=float)) @ self.wheel_axes
            p = self.momentum_scale * h
            values += [sec, nanosec, float(p[0]), float(p[1]), float(p[2])]
        if self.plumes is not None:
            values += [sec, nanosec]
        return template.encode(values)

    def _marker_template(self, on_time) -> Template:
        msg = self.marker_array(0, np.zeros(len(self.spin)) if self.momentum is not None else None, on_time)
        slots = []
        for i, m in enumerate(msg.markers):
            slots += [f'markers[{i}].{s}' for s in STAMP]
            if m is self.momentum:
                slots += [f'markers[{i}].points[1].{c}' for c in 'xyz']
        return Template(msg, slots)
