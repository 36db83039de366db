"""2-1-3 Euler angles of a batch of quaternions, compiled (numba): scipy's conversion without scipy.

:func:`euler_213_rows` is ``Rotation.from_quat(q).as_euler('YXZ')`` of scipy 1.17 (its Cython
backend, ``_rotation_cy.pyx``: ``from_quat`` normalises each row with ``_normalize4``, ``as_euler``
applies Bernardes & Viollet's method, PLoS ONE 17(11) e0276302, 2022) written out for the one
sequence the project uses, with the same operations in the same order, so the same bits:

* ``n = sqrt((x x + y y + z z) + w w)`` and each component divided by ``n``;
* for intrinsic 'YXZ' scipy reverses the axes to 'zxy' (i = z, j = x, k = y, even permutation:
  sign +1, whose products ``q_k * sign`` are exact and left out): ``a = w - x``, ``b = z + y``,
  ``c = x + w``, ``d = y - z``;
* ``theta = 2 atan2(hypot(c, d), hypot(a, b))``; within 1e-7 of 0 or pi (gimbal lock) the third
  angle is 0 and the first ``2 atan2(b, a)`` resp. ``2 atan2(d, c)``, else the first is
  ``atan2(b, a) + atan2(d, c)`` and the third ``atan2(b, a) - atan2(d, c)``; the second is
  ``theta - pi/2``; each angle is wrapped into [-pi, pi] by one +-2 pi.

``math.atan2`` and ``math.hypot`` compile to the C library's ``atan2`` and ``hypot``, the functions
scipy's Cython calls (numpy's ``arctan2`` may use SIMD approximations instead, and Python's
``math.hypot`` is CPython's own algorithm: neither gives libm's bits everywhere). Compiled without
fastmath (no FMA contraction, no reassociation) and with ``error_model='numpy'``; cached beside this
module. ``tests/test_euler.py`` compares it with scipy bit for bit (hypothesis, gimbal-lock
neighbourhoods, sign flips, non-unit quaternions) and checks the compile options.

Rows that scipy refuses (a non-finite component, or a zero norm: also the underflowing norm of a
tiny quaternion) give NaN: a diverged run's samples have no angles. scipy's "Gimbal lock detected"
warning is not raised.

Imported at first use by :func:`adcs_core.attitude.euler_213` (numba costs 0.4-0.7 s at import),
which converts one quaternion with the same operations in Python.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from adcs_core import compile_log  # noqa: F401 - a compilation prints one line (kernel, types, seconds)

_HALF_PI = math.pi / 2
_TWO_PI = 2 * math.pi
GIMBAL_EPS = 1e-7   # scipy's threshold on the second angle's distance from 0 or pi


@njit(cache=True, error_model='numpy', nogil=True, inline='always')
def _wrap(angle):
    """scipy's wrap: one +-2 pi into [-pi, pi] (NaN stays)."""
    if angle < -math.pi:
        return angle + _TWO_PI
    if angle > math.pi:
        return angle - _TWO_PI
    return angle


@njit(cache=True, error_model='numpy', nogil=True, inline='always')
def euler_213_row(x, y, z, w, out, r):
    """out[r] = the 2-1-3 angles (rad, sequence order y, x, z) of quaternion (x, y, z, w)."""
    finite = np.isfinite(x) and np.isfinite(y) and np.isfinite(z) and np.isfinite(w)
    n = math.sqrt((x * x + y * y + z * z) + w * w) if finite else 0.0
    if n == 0.0:   # non-finite, zero, or a norm that underflows: scipy refuses it
        out[r, 0] = out[r, 1] = out[r, 2] = np.nan
        return
    x, y, z, w = x / n, y / n, z / n, w / n
    a, b, c, d = w - x, z + y, x + w, y - z
    theta = 2 * math.atan2(math.hypot(c, d), math.hypot(a, b))
    half_sum = math.atan2(b, a)
    half_diff = math.atan2(d, c)
    if abs(theta) <= GIMBAL_EPS:
        first, third = 2 * half_sum, 0.0
    elif abs(theta - math.pi) <= GIMBAL_EPS:
        first, third = 2 * half_diff, 0.0
    else:
        first, third = half_sum + half_diff, half_sum - half_diff
    out[r, 0] = _wrap(first)
    out[r, 1] = _wrap(theta - _HALF_PI)
    out[r, 2] = _wrap(third)


@njit(parallel=True, cache=True, error_model='numpy', nogil=True)
def euler_213_rows(q, out):
    """out[r] = :func:`euler_213_row` of q[r] for every row of q (R, 4) (rows in parallel)."""
    for r in prange(q.shape[0]):
        euler_213_row(q[r, 0], q[r, 1], q[r, 2], q[r, 3], out, r)
