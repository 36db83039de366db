"""The campaign metrics of full runs in two compiled passes over each run's samples (numba).

:func:`adcs_sim.app.batch_metrics.batch_run_metrics` computes :func:`~adcs_sim.app.analysis.run_metrics`
of every full run of a batch at once. Written with numpy over ``(runs, samples)`` arrays it made
~40 passes over the history (error quaternions, Euler angles, degrees, absolute values, maxima,
settling masks, reversed ``argmax``, products and sums), each allocating its result. Here
:func:`first_pass` computes, run by run in one pass over its samples, everything but the eigenaxis
angle; numpy's ``arctan2`` gives the angle (its vectorised loop is not the C library's ``atan2``:
it stays numpy's call, on the same contiguous arrays as before); :func:`second_pass` takes the
settling time and final value of the angle. Every value is the numpy code's bit for bit:

* the error quaternion and ``|q_v|``: :func:`adcs_sim.app.batch_metrics.error_quaternions`' own
  operations; the 2-1-3 Euler angles: :func:`adcs_core.euler_kernel.euler_213_row`;
  ``np.degrees(x)`` is ``x * (180 / pi)`` (numpy's ``npy_rad2deg``);
* the settling times need, of each Euler error, only which samples are outside the band and the
  values at the last exit: :func:`_euler_sides` tells inside from outside with a few products
  (the angles' tangents and sine from the kernel's own ``a, b, c, d``, no ``atan2`` or ``hypot``:
  ~10x cheaper), leaving to the kernel's exact computation every sample within a relative 1e-9
  (and an absolute 1e-10 rad) of the band's edge, near gimbal lock, non-finite, or any band of 45
  degrees or more; the margin is ~1e5 times the rounding of either computation;
* ``np.maximum`` and ``max`` propagate a NaN; the settling time is
  :func:`~adcs_sim.app.batch_metrics.settling_times`' expression on the last sample outside the band
  and the next one, tracked while the samples go by;
* ``np.sum(p, axis=-1)`` of a C-contiguous ``(runs, K)`` array is ``0.0 + pairwise(row)``: numpy's
  pairwise summation (:func:`pairwise_sum`: fewer than 8 terms in sequence, up to 128 in 8
  interleaved accumulators combined as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))`` then the
  remainder in sequence, more split at half rounded down to a multiple of 8);
* ``u ** 2`` is ``u * u`` (numpy's power by the scalar 2 is ``np.square``).

Compiled as the plant kernel is: no fastmath (no reassociation, no FMA contraction),
``error_model='numpy'``, cached (``make install`` compiles it). ``tests/test_metrics_kernel.py``
compares every column with the numpy code on random batches and edge cases.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from adcs_core.euler_kernel import euler_213_row

_INNER = dict(cache=True, error_model='numpy', nogil=True, inline='always')
DEG = 180.0 / math.pi   # numpy's rad2deg factor (180.0 / NPY_PI)
# the columns of first_pass's / second_pass's output, in run_metrics' order
DURATION, SETTLE_EIGEN, SETTLE_EULER, SETTLE_AXIS, FINAL_EIGEN, TORQUE, ENERGY, PEAK_TORQUE, PEAK_SPEED = \
    0, 1, 2, 3, 6, 7, 8, 9, 12
N_COLUMNS = 13
MARGIN = 1e-10   # what _euler_sides leaves to the exact computation: ~1e5 times its rounding errors


def euler_bands(tol_deg: float) -> np.ndarray:
    """_euler_sides' bounds for a band of tol_deg: tan and sin of the band, each 1e-9 (relative) in
    and out, and whether to use them at all (below 45 degrees)."""
    band = math.radians(tol_deg)
    tan, sin = math.tan(band), math.sin(band)
    return np.array([tan * (1 - 1e-9), tan * (1 + 1e-9), sin * (1 - 1e-9), sin * (1 + 1e-9),
                     1.0 if tol_deg < 45.0 else 0.0])


@njit(**_INNER)
def _block_sum(a, lo, n):
    """numpy's pairwise sum of a[lo:lo + n], n <= 128: the leaves of its recursion."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        j = lo + i
        r0, r1, r2, r3 = r0 + a[j], r1 + a[j + 1], r2 + a[j + 2], r3 + a[j + 3]
        r4, r5, r6, r7 = r4 + a[j + 4], r5 + a[j + 5], r6 + a[j + 6], r7 + a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(**_INNER)
def _half(n):
    """Where numpy's pairwise sum splits n > 128 terms: half, rounded down to a multiple of 8."""
    n2 = n // 2
    return n2 - n2 % 8


@njit(cache=True, error_model='numpy', nogil=True)
def pairwise_sum(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]`` (``DOUBLE_pairwise_sum``; module docstring): its
    recursion walked with an explicit stack (a recursive function called from a ``prange`` crashes
    numba's parallel backend). ``phase``: 0 not split yet, 1 left half pending, 2 right half pending."""
    if n <= 128:
        return _block_sum(a, lo, n)
    los, ns = np.empty(64, np.int64), np.empty(64, np.int64)
    phase, left = np.zeros(64, np.int64), np.empty(64)
    sp, los[0], ns[0] = 0, lo, n
    while True:
        if ns[sp] > 128:                 # split: its left half first
            phase[sp] = 1
            sp += 1
            los[sp], ns[sp], phase[sp] = los[sp - 1], _half(ns[sp - 1]), 0
            continue
        v = _block_sum(a, los[sp], ns[sp])
        while True:                      # hand v up until a node still needs its right half
            sp -= 1
            if sp < 0:
                return v
            if phase[sp] == 1:
                left[sp], phase[sp] = v, 2
                n2 = _half(ns[sp])
                sp += 1
                los[sp], ns[sp], phase[sp] = los[sp - 1] + n2, ns[sp - 1] - n2, 0
                break
            v = left[sp] + v


@njit(**_INNER)
def _nanmax(a, b):
    """np.maximum(a, b) / max: a NaN operand wins (the first one)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@njit(**_INNER)
def _track(st, s, k, value, tol):
    """Sample ``k`` of series ``s`` for its settling time: st[s] = (last index outside the band,
    its value, the next sample's value)."""
    if not value <= tol:
        st[s, 0] = k
        st[s, 1] = value
    elif k == st[s, 0] + 1:
        st[s, 2] = value


@njit(**_INNER)
def _settling(st, s, t, tol):
    """settling_times' value from the tracked (last outside, e0, e1) of series ``s``."""
    last = int(st[s, 0])
    n = t.shape[0]
    if last < 0:
        return t[0]
    if last == n - 1:
        return math.inf
    nxt = last + 1
    e0, e1 = st[s, 1], st[s, 2]
    if not np.isfinite(e0):
        return t[nxt]
    return t[last] + (e0 - tol) / (e0 - e1) * (t[nxt] - t[last])


@njit(**_INNER)
def _error(q, r, k, p0, p1, p2, p3):
    """The error quaternion of sample k of run r (quat_conjugate(q_ref) = (p0, p1, p2, p3))."""
    x0, x1, x2, x3 = q[r, k, 0], q[r, k, 1], q[r, k, 2], q[r, k, 3]
    e0 = (p3 * x0 + x3 * p0) + (p1 * x2 - p2 * x1)
    e1 = (p3 * x1 + x3 * p1) + (p2 * x0 - p0 * x2)
    e2 = (p3 * x2 + x3 * p2) + (p0 * x1 - p1 * x0)
    return e0, e1, e2, p3 * x3 - ((p0 * x0 + p1 * x1) + p2 * x2)


@njit(**_INNER)
def _exact_euler(e0, e1, e2, e3, eul):
    """eul[0] = np.abs(np.degrees(euler_213(e))): the absolute 2-1-3 Euler errors, degrees."""
    euler_213_row(e0, e1, e2, e3, eul, 0)
    eul[0, 0], eul[0, 1], eul[0, 2] = abs(eul[0, 0] * DEG), abs(eul[0, 1] * DEG), abs(eul[0, 2] * DEG)


@njit(**_INNER)
def _side(x, y, scale, lo, hi):
    """0 if x <= lo y certainly (with a margin of MARGIN scale), 1 if x >= hi y certainly, else 2."""
    if x <= lo * y - MARGIN * scale:
        return 0
    if x >= hi * y + MARGIN * scale:
        return 1
    return 2


@njit(**_INNER)
def _euler_sides(e0, e1, e2, e3, bands, side):
    """side[i]: whether Euler angle i of e is certainly inside the band (0), certainly outside (1) or
    too close to tell (2: compute it), from euler_213_row's a, b, c, d without atan2 or hypot:
    first = arg((a + ib)(c + id)), third = arg((a + ib)(c - id)) and sin(second) = (v - u) / (u + v)
    (u = a² + b², v = c² + d²). Unknown near gimbal lock (the kernel's other branches), for a
    non-finite or zero e, and when bands[4] is 0 (a band of 45 degrees or more)."""
    a, b, c, d = e3 - e0, e2 + e1, e0 + e3, e1 - e2
    u, v = a * a + b * b, c * c + d * d
    if not (bands[4] > 0.0 and abs(v - u) < (1.0 - 1e-6) * (u + v)):
        side[0] = side[1] = side[2] = 2
        return
    scale = (abs(a) + abs(b)) * (abs(c) + abs(d))
    side[0] = _side(abs(a * d + b * c), a * c - b * d, scale, bands[0], bands[1])
    side[2] = _side(abs(b * c - a * d), a * c + b * d, scale, bands[0], bands[1])
    side[1] = _side(abs(v - u), u + v, u + v, bands[2], bands[3])


@njit(**_INNER)
def _euler_value(q, r, k, p0, p1, p2, p3, axis, eul):
    """Sample k's absolute Euler error about ``axis`` (3: the largest, NaN first), degrees."""
    e0, e1, e2, e3 = _error(q, r, k, p0, p1, p2, p3)
    _exact_euler(e0, e1, e2, e3, eul)
    if axis == 3:
        return _nanmax(_nanmax(eul[0, 0], eul[0, 1]), eul[0, 2])
    return eul[0, axis]


@njit(**_INNER)
def _euler_settling(q, r, p0, p1, p2, p3, axis, last, t, tol, eul):
    """settling_times of the Euler error ``axis`` whose last sample outside the band is ``last``."""
    n = t.shape[0]
    if last < 0:
        return t[0]
    if last == n - 1:
        return math.inf
    e0 = _euler_value(q, r, last, p0, p1, p2, p3, axis, eul)
    e1 = _euler_value(q, r, last + 1, p0, p1, p2, p3, axis, eul)
    if not np.isfinite(e0):
        return t[last + 1]
    return t[last] + (e0 - tol) / (e0 - e1) * (t[last + 1] - t[last])


@njit(**_INNER)
def _attitude_columns(q, r, p0, p1, p2, p3, t, tol, bands, vn, aq, out):
    """Run r's |q_v| and |q4| (into vn, aq) and Euler settling times: each sample's angles are
    computed only when :func:`_euler_sides` cannot tell, and at the last exits."""
    last, side, eul = np.full(3, -1), np.empty(3, np.int64), np.empty((1, 3))
    for k in range(q.shape[1]):
        e0, e1, e2, e3 = _error(q, r, k, p0, p1, p2, p3)
        vn[r, k] = np.sqrt((e0 * e0 + e1 * e1) + e2 * e2)
        aq[r, k] = abs(e3)
        _euler_sides(e0, e1, e2, e3, bands, side)
        if side[0] == 2 or side[1] == 2 or side[2] == 2:
            _exact_euler(e0, e1, e2, e3, eul)
            for i in range(3):
                side[i] = 0 if eul[0, i] <= tol else 1
        for i in range(3):
            if side[i] == 1:
                last[i] = k
    out[r, SETTLE_EULER] = _euler_settling(q, r, p0, p1, p2, p3, 3, max(last[0], max(last[1], last[2])),
                                           t, tol, eul)
    for i in range(3):
        out[r, SETTLE_AXIS + i] = _euler_settling(q, r, p0, p1, p2, p3, i, last[i], t, tol, eul)


@njit(**_INNER)
def _torque_columns(u, r, zoh, held, out):
    """Run r's integrated |u|, energy and peak |u_i| (out[r, TORQUE:PEAK_TORQUE + 3])."""
    K = zoh.shape[0]
    m0 = m1 = m2 = 0.0
    for k in range(K):
        u0, u1, u2 = u[r, k, 0], u[r, k, 1], u[r, k, 2]
        held[0, k] = np.sqrt((u0 * u0 + u1 * u1) + u2 * u2) * zoh[k]
        held[1, k] = ((u0 * u0 + u1 * u1) + u2 * u2) * zoh[k]
        m0, m1, m2 = _nanmax(m0, abs(u0)), _nanmax(m1, abs(u1)), _nanmax(m2, abs(u2))
    out[r, TORQUE] = 0.0 + pairwise_sum(held[0], 0, K)
    out[r, ENERGY] = 0.0 + pairwise_sum(held[1], 0, K)
    out[r, PEAK_TORQUE], out[r, PEAK_TORQUE + 1], out[r, PEAK_TORQUE + 2] = m0, m1, m2


@njit(parallel=True, cache=True, error_model='numpy', nogil=True)
def first_pass(q, q_ref, u, speed, t, zoh, tol, bands, vn, aq, out):
    """Every column of run_metrics but the eigenaxis ones, for each run r of q (R, K + 1, 4) (its
    target q_ref[r], torques u (R, K, 3), wheel speeds (R, K + 1, n), n >= 1; or n = 0: NaN) on times
    t (K + 1,) with hold durations zoh (K,); vn[r], aq[r]: |q_v| and |q4| of the error quaternions;
    bands: :func:`euler_bands` of the settling band."""
    R, n = q.shape[0], q.shape[1]
    for r in prange(R):
        _attitude_columns(q, r, -q_ref[r, 0], -q_ref[r, 1], -q_ref[r, 2], q_ref[r, 3], t, tol, bands, vn, aq, out)
        out[r, DURATION] = t[n - 1]
        _torque_columns(u, r, zoh, np.empty((2, zoh.shape[0])), out)
        peak = np.nan
        if speed.shape[2]:
            peak = 0.0
            for k in range(n):
                for j in range(speed.shape[2]):
                    peak = _nanmax(peak, abs(speed[r, k, j]))
        out[r, PEAK_SPEED] = peak


@njit(parallel=True, cache=True, error_model='numpy', nogil=True)
def second_pass(half_angle, t, tol, out):
    """The eigenaxis error's settling time and final value of each run r from numpy's
    ``arctan2(|q_v|, |q4|)`` half_angle (R, K + 1): the error is ``degrees(2 * half_angle)``."""
    R, n = half_angle.shape
    for r in prange(R):
        st = np.empty((1, 3))
        st[0, 0], st[0, 1], st[0, 2] = -1.0, np.nan, np.nan
        e = np.nan
        for k in range(n):
            e = (2.0 * half_angle[r, k]) * DEG
            _track(st, 0, k, e, tol)
        out[r, SETTLE_EIGEN] = _settling(st, 0, t, tol)
        out[r, FINAL_EIGEN] = e
