"""Compiled one-run kernels of the PD law (seed 004 eq. 13) and the wheels' actuation (numba).

The fused closed loop of the batch engine (:mod:`adcs_sim.app.batch.fused`) calls these from compiled
code, run by run; the numpy objects (:class:`adcs_controllers.laws.pd.PdLaw`,
:class:`adcs_controllers.laws.allocation.Actuation`) stay the reference and the node's path. Every
function does the numpy code's operations in the numpy code's order, so a run gets the same bits:

* :func:`normalize_row`: :func:`adcs_core.attitude.quat_normalize` (``q / sqrt(((q0² + q1²) + q2²)
  + q3²)``), what the controller does to the attitude it receives;
* :func:`pd_torque_row`: :func:`adcs_controllers.laws.pd.pd_torque` with its target:
  :func:`~adcs_core.attitude.error_quaternion` = ``quat_multiply(quat_conjugate(q_ref), q)``
  (``v = (p4 q_v + q4 p_v) + p_v × q_v``, ``s = p4 q4 - ((p1 q1 + p2 q2) + p3 q3)``: numpy sums 3
  components in sequence, ``tests/test_fused_loop.py`` checks it on batches of 1 and 500),
  ``w - w_ref``, the optional shortest-path flip, ``-matvec(I, kp q_v + kd w_e)``;
* :func:`wheel_command_row`: :meth:`~adcs_controllers.laws.allocation.WheelActuation.command` for
  wheels: ``matvec(M, u)`` with the minimum-norm allocation matrix ``M`` (n, 3), then
  :func:`~adcs_controllers.laws.allocation.saturate` (``clip``: numpy's ``np.clip`` rule, NaN
  propagating; ``scale``: ``tau / maximum(max(|tau| / limit), 1)``).

Compiled as :mod:`adcs_sim.truth.kernel` is: no ``fastmath`` (no reassociation, no FMA
contraction), ``error_model='numpy'``, cached, inlined into the caller.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from adcs_core import compile_log  # noqa: F401 - a compilation prints one line (kernel, types, seconds)

_INNER = dict(cache=True, error_model='numpy', nogil=True, inline='always')
CLIP, SCALE = 0, 1   # saturation modes of wheel_command_row


@njit(**_INNER)
def normalize_row(q, qo, out):
    """out[0:4] = quat_normalize(q[qo:qo+4])."""
    n = np.sqrt(((q[qo] * q[qo] + q[qo + 1] * q[qo + 1]) + q[qo + 2] * q[qo + 2]) + q[qo + 3] * q[qo + 3])
    for i in range(4):
        out[i] = q[qo + i] / n


@njit(**_INNER)
def pd_torque_row(q, w, wo, inertia, kp, kd, q_ref, w_ref, shortest, out):
    """out[0:3] = pd_torque(q, w[wo:wo+3], inertia (9, row-major), kp, kd, q_ref, w_ref, shortest)."""
    p0, p1, p2, p3 = -q_ref[0], -q_ref[1], -q_ref[2], q_ref[3]   # quat_conjugate(q_ref)
    c0 = p1 * q[2] - p2 * q[1]                                     # cross(p_v, q_v)
    c1 = p2 * q[0] - p0 * q[2]
    c2 = p0 * q[1] - p1 * q[0]
    e0 = (p3 * q[0] + q[3] * p0) + c0
    e1 = (p3 * q[1] + q[3] * p1) + c1
    e2 = (p3 * q[2] + q[3] * p2) + c2
    e3 = p3 * q[3] - ((p0 * q[0] + p1 * q[1]) + p2 * q[2])
    if shortest and e3 < 0:
        e0, e1, e2 = -e0, -e1, -e2
    v0 = kp * e0 + kd * (w[wo] - w_ref[0])
    v1 = kp * e1 + kd * (w[wo + 1] - w_ref[1])
    v2 = kp * e2 + kd * (w[wo + 2] - w_ref[2])
    for i in range(3):
        out[i] = -((inertia[3 * i] * v0 + inertia[3 * i + 1] * v1) + inertia[3 * i + 2] * v2)


@njit(**_INNER)
def _clip(x, lo, hi):
    """np.clip(x, lo, hi) of one float: numpy's rule min(max(x, lo), hi), a NaN operand first wins."""
    m = x if (x != x or x > lo) else lo
    return m if (m != m or m < hi) else hi


@njit(**_INNER)
def wheel_command_row(u, alloc, limit, mode, out, oo):
    """out[oo:oo+n] = Actuation.command(u)[0] for wheels: the saturated minimum-norm motor torques
    (alloc (n, 3) the allocation matrix, limit (n,) the torque limits, mode CLIP or SCALE)."""
    n = alloc.shape[0]
    for j in range(n):
        out[oo + j] = (alloc[j, 0] * u[0] + alloc[j, 1] * u[1]) + alloc[j, 2] * u[2]
    if mode == CLIP:
        for j in range(n):
            out[oo + j] = _clip(out[oo + j], -limit[j], limit[j])
        return
    ratio = abs(out[oo]) / limit[0]   # np.max over the wheels: a NaN wins
    for j in range(1, n):
        r = abs(out[oo + j]) / limit[j]
        if ratio == ratio and (r != r or r > ratio):
            ratio = r
    scale = ratio if (ratio != ratio or ratio > 1.0) else 1.0   # np.maximum(ratio, 1.0)
    for j in range(n):
        out[oo + j] = out[oo + j] / scale
