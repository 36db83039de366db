"""The bag's ``/tf`` channel: ``tf2_msgs/TFMessage`` made from the graph's ``TransformStamped`` frames.

Why the recorder writes it: RViz and every tf2 tool read transforms only from ``/tf``
(``tf2_msgs/TFMessage``); Foxglove's 3D panel reads ``/tf`` and also any
``geometry_msgs/TransformStamped`` topic. There is no ``tf2_msgs`` wheel for Jazzy on PyPI, so no
node of this graph can publish a TFMessage; the dynamics node publishes its frames as
``TransformStamped`` (``frames/body``, ``frames/orbit``: Foxglove shows them live) and the
recorder, which already receives them as CDR bytes, writes each one a second time as a
one-transform TFMessage on ``/tf``, serialized with rosbags' type store (the Jazzy definitions
the bag's schemas come from). Same stamp, same log time: two lockstep runs still write identical
bags. Pure (no ROS): rosbags and the kernel only.

A transform that does not decode, or carries an empty or oversized frame id, a non-finite
translation or a rotation that is not a unit quaternion, is refused (ValueError): the recorder
counts it as a rejected message of its topic and writes nothing on ``/tf`` for it.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_core.attitude import quat_norm
from adcs_sim.bag.storage import typestore

TF_TYPE = 'tf2_msgs/msg/TFMessage'
TRANSFORM_TYPE = 'geometry_msgs/msg/TransformStamped'
MAX_FRAME_ID = 256          # characters
UNIT_TOLERANCE = 1e-6       # as adcs_msgs_py.conversions.UNIT_QUATERNION_TOLERANCE


def checked_transform(data: bytes):
    """Decode and check a serialized ``TransformStamped`` (rosbags message object); ValueError with
    the reason otherwise."""
    try:
        msg = typestore().deserialize_cdr(bytes(data), TRANSFORM_TYPE)
    except Exception as exc:  # noqa: BLE001 - rosbags raises assorted errors on bytes that are no message
        raise ValueError(f'not a {TRANSFORM_TYPE} ({type(exc).__name__}: {exc})') from None
    stamp = msg.header.stamp
    if stamp.sec < 0 or not 0 <= stamp.nanosec < 1_000_000_000:
        raise ValueError(f'stamp out of range (sec {stamp.sec}, nanosec {stamp.nanosec})')
    for what, frame in (('frame_id', msg.header.frame_id), ('child_frame_id', msg.child_frame_id)):
        if not frame or len(frame) > MAX_FRAME_ID or not frame.isprintable():
            raise ValueError(f'{what} {frame[:40]!r}: empty, longer than {MAX_FRAME_ID} or not printable')
    if msg.header.frame_id == msg.child_frame_id:
        raise ValueError(f'frame {msg.child_frame_id!r} is its own parent')
    t, r = msg.transform.translation, msg.transform.rotation
    values = [t.x, t.y, t.z, r.x, r.y, r.z, r.w]
    if not all(map(math.isfinite, values)):
        raise ValueError(f'non-finite value in the transform {values}')
    norm = float(quat_norm(np.array(values[3:])))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ValueError(f'rotation norm {norm:.9g} is not 1 (tolerance {UNIT_TOLERANCE:g})')
    return msg


def tf_message_cdr(data: bytes) -> bytes:
    """A serialized ``TransformStamped`` -> the serialized one-transform ``TFMessage`` (little
    endian CDR); ValueError for a transform :func:`checked_transform` refuses."""
    store = typestore()
    message = store.types[TF_TYPE](transforms=[checked_transform(data)])
    return bytes(store.serialize_cdr(message, TF_TYPE))
