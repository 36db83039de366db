"""What the dynamics node sends the recorder and publishes to live viewers, for the recorded-topics
tests: its viewer messages for a spacecraft of each kind and the messages of a run of it. Needs the
ROS message packages (through adcs_msgs_py.cdr and .visual)."""
from __future__ import annotations

import math

import numpy as np

from adcs_core.orbit import CircularOrbit
from adcs_msgs_py import cdr, names
from adcs_msgs_py.visual import VisualMessages

PERIOD_NS = 500_000_000
AXES = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5773502691896258] * 3]
THRUSTERS = ([[0.3, 0.1, -0.2], [-0.3, 0.1, 0.2]], [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
ALL = list(names.RECORDED_VISUAL_TOPICS)


def visual_messages(wheels: bool, thrusters: bool, orbit: bool) -> VisualMessages:
    """The viewer messages of a spacecraft with (or without) wheels, thrusters, an orbit."""
    return VisualMessages([0.1, -0.2, 0.3, 0.9], 1.7, *((AXES, [0.01, 0.02, 0.01, 0.03],
                                                        [523.6, math.inf, 300.0, 100.0]) if wheels else (None,) * 3),
                          *(THRUSTERS if thrusters else (None, None)),
                          orbit=CircularOrbit(7.0e5, 1.7, 0.3, 0.1) if orbit else None)


def padded(data: bytes) -> bytes:
    """A message as a subscriber receives it: zero-padded to 4 bytes."""
    return data + bytes(-len(data) % 4)


def dynamics_messages(visual: VisualMessages, attitude: str, steps: int, rng: np.random.Generator):
    """What the dynamics node sends for ``steps`` steps (the sources, in its order) and the viewer
    messages it publishes, as a subscriber receives them."""
    state, joints, vector = cdr.StateCodec(), cdr.JointStateCodec('x'), cdr.VectorCodec()
    n_w, n_t = len(visual.spin), len(visual._plume_ends) if visual.plumes is not None else 0
    sources, viewer = [], []
    for k in range(steps + 1):
        t = k * PERIOD_NS
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        speed = rng.normal(scale=100.0, size=n_w)
        sources.append((attitude, state.encode(t, q, rng.normal(size=3))))
        if n_w:
            sources.append((names.WHEELS_STATE, joints.encode(t, [f'w{i}' for i in range(n_w)], speed, speed, speed)))
        viewer += [(names.FRAMES_BODY, visual.body_frame_cdr(t, q))]
        if visual.orbit is not None:
            viewer.append((names.FRAMES_ORBIT, visual.orbit_frame_cdr(t)))
        viewer += list(zip((names.ERROR_EIGENAXIS, names.ERROR_EULER_213), visual.errors_cdr(t, q)))
        if k == steps:   # the last state: no step is integrated from it
            break
        on = np.where(rng.random(n_t) < 0.5, rng.random(n_t), 0.0)
        sources.append((names.APPLIED_TORQUE, vector.encode(t, rng.normal(size=3))))
        if n_t:
            sources.append((names.THRUSTERS_STATE, joints.encode(t, ['a', 'b'], on, on, on)))
        if visual.markers.markers:
            viewer.append((names.MARKERS, visual.marker_array_cdr(t, speed if n_w else None, on if n_t else ())))
    return sources, [(topic, padded(data)) for topic, data in viewer]
