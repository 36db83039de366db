"""The campaign metrics of full runs in two compiled passes over each run's samples (numba).

:func:`adcs_sim.app.analysis.batch_metrics.batch_run_metrics` computes
:func:`~adcs_sim.app.analysis.metrics.run_metrics` of every full run of a batch at once. Written with numpy over ``(runs, samples)`` arrays it made
~40 passes over the history (error quaternions, Euler angles, degrees, absolute values, maxima,
settling masks, reversed ``argmax``, products and sums), each allocating its result. Here
:func:`first_pass` computes, run by run in one pass over its samples, every column; of the
eigenaxis angle ``degrees(2 arctan2(|q_v|, |q4|))`` it finds which samples are outside the band
(``|q_v| <= tan(band / 2) |q4|``, with the margins below) and numpy's ``arctan2`` (numpy's own
element-wise loop, which need not be the C library's ``atan2``) is then called on the three
samples a run needs (its last exit, the next sample, its last one: :func:`eigen_columns`), or on
all of a run's samples (:func:`second_pass`) when one after its last certain exit is too close to
the band to tell. Every value is the numpy code's bit for bit:

* the error quaternion and ``|q_v|``: :func:`error_quaternions`' own
  operations; the 2-1-3 Euler angles: :func:`adcs_core.euler_kernel.euler_213_row`;
  ``np.degrees(x)`` is ``x * (180 / pi)`` (numpy's ``npy_rad2deg``);
* the settling times need, of each Euler error, only which samples are outside the band and the
  values at the last exit: :func:`_euler_sides` tells inside from outside with a few products
  (the angles' tangents and sine from the kernel's own ``a, b, c, d``, no ``atan2`` or ``hypot``:
  ~10x cheaper), leaving to the kernel's exact computation every sample within a relative 1e-9
  (and an absolute 1e-10 rad) of the band's edge, near gimbal lock, non-finite, or any band of 45
  degrees or more; the margin is ~1e5 times the rounding of either computation;
* ``np.maximum`` and ``max`` propagate a NaN; the settling time is
  :func:`~adcs_sim.app.analysis.batch_metrics.settling_times`' expression on the last sample outside the band
  and the next one, tracked while the samples go by;
* ``np.sum(p, axis=-1)`` of a C-contiguous ``(runs, K)`` array is ``0.0 + pairwise(row)``: numpy's
  pairwise summation (:func:`pairwise_sum`: fewer than 8 terms in sequence, up to 128 in 8
  interleaved accumulators combined as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))`` then the
  remainder in sequence, more split at half rounded down to a multiple of 8);
* ``u ** 2`` is ``u * u`` (numpy's power by the scalar 2 is ``np.square``).

Compiled as the plant kernel is: no fastmath (no reassociation, no FMA contraction),
``error_model='numpy'``, cached (compiled ahead of use: :mod:`adcs_sim.app.batch.kernels`). ``tests/test_metrics_kernel.py``
compares every column with the numpy code on random batches and edge cases.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from adcs_core import compile_log  # noqa: F401 - a compilation prints one line (kernel, types, seconds)
from adcs_core.euler_kernel import euler_213_row
from adcs_sim.truth.kernel import _max as _nanmax   # np.maximum: a NaN operand wins (the first one)

_INNER = dict(cache=True, error_model='numpy', nogil=True, inline='always')
DEG = 180.0 / math.pi   # numpy's rad2deg factor (180.0 / NPY_PI)
# the columns of first_pass's / second_pass's output, in run_metrics' order
DURATION, SETTLE_EIGEN, SETTLE_EULER, SETTLE_AXIS, FINAL_EIGEN, TORQUE, ENERGY, PEAK_TORQUE, PEAK_SPEED = \
    0, 1, 2, 3, 6, 7, 8, 9, 12
N_COLUMNS = 13
MARGIN = 1e-10   # what _euler_sides leaves to the exact computation: ~1e5 times its rounding errors


@njit(parallel=True, cache=True, error_model='numpy', nogil=True)
def error_quaternions(q, q_ref, qe, vnorm):
    """qe[r, k] = error_quaternion(q[r, k], q_ref[r]) and vnorm[r, k] = |qe[r, k, :3]| (q (R, K, 4),
    q_ref (R, 4)): :func:`adcs_core.attitude.quat_multiply` of ``quat_conjugate(q_ref)`` and ``q``
    (``(p4 q_v + q4 p_v) + p_v x q_v``, ``p4 q4 - ((p1 q1 + p2 q2) + p3 q3)``) and
    :func:`numpy.linalg.norm`'s ``sqrt((x1² + x2²) + x3²)`` (numpy sums 3 terms in sequence), the
    same operations in the same order as :func:`~adcs_core.attitude.eigenaxis_angle`'s numpy, compiled
    without fastmath: the same bits, ~20x fewer passes over the (runs, samples) arrays."""
    for r in prange(q.shape[0]):
        p0, p1, p2, p3 = -q_ref[r, 0], -q_ref[r, 1], -q_ref[r, 2], q_ref[r, 3]
        for k in range(q.shape[1]):
            x0, x1, x2, x3 = q[r, k, 0], q[r, k, 1], q[r, k, 2], q[r, k, 3]
            e0 = (p3 * x0 + x3 * p0) + (p1 * x2 - p2 * x1)
            e1 = (p3 * x1 + x3 * p1) + (p2 * x0 - p0 * x2)
            e2 = (p3 * x2 + x3 * p2) + (p0 * x1 - p1 * x0)
            qe[r, k, 0], qe[r, k, 1], qe[r, k, 2] = e0, e1, e2
            qe[r, k, 3] = p3 * x3 - ((p0 * x0 + p1 * x1) + p2 * x2)
            vnorm[r, k] = np.sqrt((e0 * e0 + e1 * e1) + e2 * e2)


def euler_bands(tol_deg: float) -> np.ndarray:
    """_euler_sides' bounds for a band of tol_deg: tan and sin of the band, each 1e-9 (relative) in
    and out, whether to use them at all (below 45 degrees), and _eigen_side's tan of half the band."""
    band = math.radians(tol_deg)
    tan, sin, half = math.tan(band), math.sin(band), math.tan(band / 2)
    return np.array([tan * (1 - 1e-9), tan * (1 + 1e-9), sin * (1 - 1e-9), sin * (1 + 1e-9),
                     1.0 if tol_deg < 45.0 else 0.0, half * (1 - 1e-9), half * (1 + 1e-9)])


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
def _eigen_side(vn, aq, bands):
    """Whether the eigenaxis error degrees(2 arctan2(vn, aq)) is certainly inside the band (0),
    outside (1), or too close to tell (2: numpy's arctan2 decides); vn, aq >= 0."""
    if bands[4] > 0.0:
        return _side(vn, aq, vn + aq, bands[5], bands[6])
    return 2


@njit(**_INNER)
def _eigen_samples(q, r, p0, p1, p2, p3, last, gv, ga):
    """gv[r], ga[r] = |q_v|, |q4| of the samples numpy's arctan2 is needed at: the last exit from
    the band, the next one, and the final sample (as error_quaternions computes them)."""
    n = q.shape[1]
    for j, k in enumerate((max(last, 0), min(last + 1, n - 1), n - 1)):
        e0, e1, e2, e3 = _error(q, r, k, p0, p1, p2, p3)
        gv[r, j], ga[r, j] = np.sqrt((e0 * e0 + e1 * e1) + e2 * e2), abs(e3)


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
def _attitude_columns(q, r, p0, p1, p2, p3, t, tol, bands, eigen, gv, ga, out):
    """Run r's Euler settling times (each sample's angles computed only when :func:`_euler_sides`
    cannot tell, and at the last exits) and its eigenaxis error's last exit: eigen[r] = (last
    sample certainly outside, 1 if a later sample was too close to tell), gv, ga (_eigen_samples)."""
    last, side, eul = np.full(3, -1), np.empty(3, np.int64), np.empty((1, 3))
    last_e, unknown_e = -1, -1
    for k in range(q.shape[1]):
        e0, e1, e2, e3 = _error(q, r, k, p0, p1, p2, p3)
        se = _eigen_side(np.sqrt((e0 * e0 + e1 * e1) + e2 * e2), abs(e3), bands)
        if se == 1:
            last_e = k
        elif se == 2:
            unknown_e = k
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
    eigen[r, 0], eigen[r, 1] = last_e, 1 if unknown_e > last_e else 0
    _eigen_samples(q, r, p0, p1, p2, p3, last_e, gv, ga)


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
def first_pass(q, q_ref, u, speed, t, zoh, tol, bands, eigen, gv, ga, out):
    """Every column of run_metrics but the eigenaxis ones, for each run r of q (R, K + 1, 4) (its
    target q_ref[r], torques u (R, K, 3), wheel speeds (R, K + 1, n), n >= 1; or n = 0: NaN) on times
    t (K + 1,) with hold durations zoh (K,); bands: :func:`euler_bands` of the settling band;
    eigen (R, 2) int, gv, ga (R, 3): what :func:`eigen_columns` needs (_attitude_columns)."""
    R, n = q.shape[0], q.shape[1]
    for r in prange(R):
        _attitude_columns(q, r, -q_ref[r, 0], -q_ref[r, 1], -q_ref[r, 2], q_ref[r, 3], t, tol, bands, eigen, gv, ga,
                          out)
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


@njit(cache=True, error_model='numpy', nogil=True)
def eigen_columns(half_angle, eigen, t, tol, out):
    """The eigenaxis error's settling time and final value of each run r with eigen[r, 1] == 0 (its
    last exit eigen[r, 0] known) from numpy's arctan2 at its _eigen_samples, half_angle (R, 3)."""
    n = t.shape[0]
    for r in range(half_angle.shape[0]):
        if eigen[r, 1]:
            continue
        last = eigen[r, 0]
        out[r, FINAL_EIGEN] = (2.0 * half_angle[r, 2]) * DEG
        if last < 0:
            out[r, SETTLE_EIGEN] = t[0]
        elif last == n - 1:
            out[r, SETTLE_EIGEN] = math.inf
        else:
            e0, e1 = (2.0 * half_angle[r, 0]) * DEG, (2.0 * half_angle[r, 1]) * DEG
            out[r, SETTLE_EIGEN] = t[last + 1] if not np.isfinite(e0) else \
                t[last] + (e0 - tol) / (e0 - e1) * (t[last + 1] - t[last])
