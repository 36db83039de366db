"""Plants for the kernel tests: four reaction wheels (one skewed), a full inertia, random states and
wheel commands, each seeded (the same draws in every module that uses them). No ROS."""
from __future__ import annotations

import numpy as np

from adcs_sim.truth.plant import Plant, ReactionWheels, WheelCommand

AXES = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.577, 0.577, 0.577]]


def wheels(batch=(), **kw) -> ReactionWheels:
    rng = np.random.default_rng(3)
    n = len(AXES)
    kw.setdefault('max_torque', 0.02 + 0.01 * rng.random(batch + (n,)))
    kw.setdefault('max_speed', np.full(n, 300.0))
    return ReactionWheels([f'rw{i}' for i in range(n)], AXES, 0.01 + 0.002 * rng.random(batch + (n,)), **kw)


def inertia(batch=()):
    rng = np.random.default_rng(4)
    J = np.array([[40.0, 1.2, -0.7], [1.2, 42.0, 0.4], [-0.7, 0.4, 45.0]])
    return J + np.eye(3) * rng.normal(0.0, 1.0, batch + (1, 1))


def state(plant: Plant, batch=(), scale=1.0):
    rng = np.random.default_rng(5)
    q = rng.normal(size=batch + (4,))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    x = plant.initial_state(q, scale * 0.05 * rng.normal(size=batch + (3,)))
    x = np.array(np.broadcast_to(x, batch + (plant.n_states,)))
    sl = plant.slices.get('wheels')
    if sl is not None:
        n = plant.actuator('wheels').count
        x[..., sl.start:sl.start + n] = scale * rng.uniform(-320, 320, batch + (n,))
    return x


def wheel_command(batch=(), speed_mode=(False, True, False, True)):
    rng = np.random.default_rng(6)
    value = np.where(speed_mode, rng.uniform(-200, 200, batch + (4,)), rng.uniform(-0.04, 0.04, batch + (4,)))
    return WheelCommand(value, np.array(speed_mode))
