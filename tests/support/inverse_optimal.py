"""Seed 004's inverse optimal laws under test: the paper's parameters (section III.F, Table I), random
and near-coasting states, and the equations of motion written out independently of the package. No ROS."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from adcs_core.attitude import quat_kinematics

# Section III.F (micro-satellite) and Table I (Krstic-Tsiotras comparison) parameters.
I_3F = np.diag([12.0, 14.0, 10.0])
GAINS_3F = dict(kp1=0.002, kd1=0.05, kp2=0.02, kd2=0.15, gamma=0.02)
I_T1 = np.diag([10.0, 15.0, 20.0])
GAINS_T1 = dict(kp1=5.0, kd1=5.0, kp2=30.0, kd2=10.0, gamma=0.8)
I_FULL = np.array([[10.0, 0.5, 0.2], [0.5, 15.0, -0.3], [0.2, -0.3, 20.0]])


def random_states(rng, n, w_max):
    """Attitudes with log-uniform angles in (1e-4 pi, pi] (q4 >= 0), rates log-uniform up to w_max."""
    angle = np.pi * 10 ** rng.uniform(-4, 0, n)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = Rotation.from_rotvec(angle[:, None] * axis).as_quat()
    w = rng.normal(size=(n, 3))
    w *= (w_max * 10 ** rng.uniform(-4, 0, n) / np.linalg.norm(w, axis=1))[:, None]
    return q, w


def coasting_states(rng, n, w_max, s_lo, s_hi):
    """States near rest-to-rest trajectories: w ≈ -s q_v with s log-uniform in [s_lo, s_hi] (the
    zero-torque wedge between the lines w + γ q = 0 and u2 = 0 lies there), |w| <= w_max."""
    s = 10 ** rng.uniform(np.log10(s_lo), np.log10(s_hi), n)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    qn = np.minimum(0.5, w_max / s) * 10 ** rng.uniform(-3, 0, n)
    qv = qn[:, None] * axis
    q = np.concatenate([qv, np.sqrt(1 - qn ** 2)[:, None]], axis=1)
    w = -s[:, None] * qv * (1 + 0.3 * rng.normal(size=(n, 3)))
    return q, w


def state_derivative(q, w, inertia, u, h):
    """Eq. (3)-(4) written out with numpy (independent of the module)."""
    wdot = np.linalg.solve(inertia, -np.cross(w, inertia @ w + h) + u)
    return quat_kinematics(q, w), wdot
