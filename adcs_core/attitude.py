"""Quaternion kinematics and attitude errors (numpy, batchable, no ROS).

Convention: Hamilton quaternion, scalar last, ``q = (x, y, z, w)`` of the body frame in
the inertial frame, i.e. ``R(q)`` maps body vectors to inertial ones. This is numerically the
papers' ``[q1 q2 q3 q4]`` (seeds 000, 001, 004) and ``scipy.spatial.transform.Rotation.from_quat``.
Every function takes a leading batch axis (``q`` of shape ``(..., 4)``).

Matrix-to-quaternion conversions use :mod:`scipy.spatial.transform`; what the papers define
(kinematics, error quaternion, eigenaxis angle) is written here, and the 2-1-3 Euler angles as
scipy computes them, bit for bit (:func:`euler_213`, without scipy's import and call overhead).

Rotation matrices (seed 001 works on them): ``R`` (..., 3, 3) maps body vectors to inertial ones
(:func:`rotation_from_quaternion` of the scalar-last quaternion), ``dR/dt = R ω×``; the attitude
error is ``R̃ = R_dᵀ R`` and its eigenaxis angle ``θ = acos((tr R̃ - 1)/2)``. Matrix products go
through :func:`matmul` (built on :func:`matvec`): a run in a batch gives the same bits as alone.
"""
from __future__ import annotations

import math

import numpy as np


def scipy_rotation():
    """scipy's ``Rotation`` class, imported on first use: ``scipy.spatial`` costs 0.4-1.1 s at import
    (it brings scipy.sparse and the k-d trees), which every node process paid at start while only
    the Euler-angle and matrix-to-quaternion conversions use it (``adcs-run``'s start-up, issue #18)."""
    from scipy.spatial.transform import Rotation
    return Rotation

# 2-1-3 Euler sequence (rotate about body y, then x, then z): intrinsic 'YXZ' in scipy's notation.
# Angles come back in sequence order: (theta_2, theta_1, theta_3).
EULER_213 = 'YXZ'


_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of 3-vectors along the last axis (batchable).

    Same result as :func:`numpy.cross`, which spends ~30 µs per call on argument handling: this
    is the plant's innermost operation (8 calls per RK4 step), so it is written out.
    """
    return a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product of 3-vectors along the last axis, summed in a fixed order (``a1 b1 + a2 b2 +
    a3 b3``): a row gives the same bits alone or in a batch."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm(a: np.ndarray) -> np.ndarray:
    """Euclidean norm of 3-vectors along the last axis, ``sqrt(dot(a, a))``."""
    return np.sqrt(dot(a, a))


def unit(a: np.ndarray) -> np.ndarray:
    """``a / |a|`` along the last axis (no guard: a zero vector gives NaN)."""
    return a / norm(a)[..., None]


def gain_vector(k) -> np.ndarray:
    """A gain, scalar or one per batch element (...,), shaped to multiply (..., 3) vectors: a scalar
    stays a scalar, an array gets a trailing axis."""
    k = np.asarray(k, dtype=float)
    return k[..., None] if k.ndim else k


def transpose(M: np.ndarray) -> np.ndarray:
    """The transpose of each matrix of a stack (..., m, n) -> (..., n, m)."""
    return np.swapaxes(M, -1, -2)


def matvec(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M v`` for matrices ``M`` (..., m, k) and vectors ``v`` (..., k), batch axes broadcast.

    Written as ``k`` element-wise multiply-adds in a fixed order (no BLAS), so a run's result
    does not depend on which other runs share its batch nor on the batch size: a campaign gives
    the same numbers bit for bit however it is split (BLAS kernels change their summation
    order with the array shapes). For the papers' 3 x 3 and n x 3 matrices it is also faster
    than ``einsum`` on small batches.
    """
    M = np.asarray(M)
    out = M[..., 0] * v[..., None, 0]
    for j in range(1, M.shape[-1]):
        out = out + M[..., j] * v[..., None, j]
    return out


def quat_kinematics(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """dq/dt for body rate ``w`` (seed 004 eq. 4): dq_v = 1/2 (q4 w - w x q_v), dq4 = -1/2 w.q_v."""
    qv, q4 = q[..., :3], q[..., 3:4]
    dqv = 0.5 * (q4 * w - cross(w, qv))
    dq4 = -0.5 * (w * qv).sum(axis=-1, keepdims=True)
    return np.concatenate([dqv, dq4], axis=-1)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (scalar last)."""
    pv, p4 = p[..., :3], p[..., 3:4]
    qv, q4 = q[..., :3], q[..., 3:4]
    v = p4 * qv + q4 * pv + cross(pv, qv)
    s = p4 * q4 - (pv * qv).sum(axis=-1, keepdims=True)
    return np.concatenate([v, s], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion)."""
    return np.concatenate([-q[..., :3], q[..., 3:4]], axis=-1)


ROTATION_VECTOR_SMALL = 1e-8   # |q_v| below which rotation_vector uses its series (truncation ~1e-24)


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """The rotation vector ``φ`` (..., 3) of the unit quaternion ``q`` (..., 4): ``exp(φ/2) = ±q``,
    the shorter of the two (``|φ| <= π``): ``φ = 2 atan2(|q_v|, |q_4|) sign(q_4) q_v / |q_v|``,
    the series ``2 sign(q_4) q_v / |q_4| (1 − |q_v|²/(3 q_4²))`` for a tiny ``|q_v|``."""
    q = np.asarray(q, dtype=float)
    sign = np.where(q[..., 3] < 0.0, -1.0, 1.0)
    v, w = q[..., :3] * sign[..., None], np.abs(q[..., 3])
    n = np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])
    small = n < ROTATION_VECTOR_SMALL
    w_safe = np.where(small, np.where(w > 0.0, w, 1.0), 1.0)
    factor = np.where(small, 2.0 / w_safe * (1.0 - n * n / (3.0 * w_safe * w_safe)),
                      2.0 * np.arctan2(n, w) / np.where(small, 1.0, n))
    return factor[..., None] * v


def quat_norm(q: np.ndarray) -> np.ndarray:
    """Norm of quaternions (..., 4), summed in a fixed order: a row gives the same bits alone or in
    a batch."""
    q = np.asarray(q, dtype=float)
    return np.sqrt(q[..., 0] * q[..., 0] + q[..., 1] * q[..., 1] + q[..., 2] * q[..., 2] + q[..., 3] * q[..., 3])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Project onto the unit sphere with :func:`quat_norm` (the operation of
    :func:`adcs_msgs_py.measurements.received_attitude`, the controllers' rule for a received attitude)."""
    q = np.asarray(q, dtype=float)
    return q / quat_norm(q)[..., None]


def error_quaternion(q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """Attitude error ``q_ref* ⊗ q``: the body attitude relative to the reference frame.

    For ``q_ref`` = identity this is ``q`` itself, which is how seed 004 regulates to the origin.
    """
    return quat_multiply(quat_conjugate(q_ref), q)


def eigenaxis_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, pi]) of the error quaternion ``q`` about its eigenaxis."""
    return 2.0 * np.arctan2(np.linalg.norm(q[..., :3], axis=-1), np.abs(q[..., 3]))


def euler_213(q: np.ndarray) -> np.ndarray:
    """2-1-3 Euler angles (rad) of ``q``, in sequence order (about y, then x, then z); NaN for a
    non-finite or zero quaternion (a diverged run's last sample).

    scipy's ``Rotation.from_quat(q).as_euler('YXZ')`` bit for bit without scipy: one quaternion in
    Python (:func:`_euler_213_one`, the dynamics node's viewer topic converts one a step), more in
    the compiled :func:`adcs_core.euler_kernel.euler_213_rows` (the operations and why they are
    scipy's bits: that module's docstring; ``tests/test_euler.py``)."""
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):
        return np.array(_euler_213_one(*q.tolist()))
    if q.size <= 4 * SMALL_BATCH:   # a few rows: not worth importing numba (0.4-0.7 s) for
        return np.array([_euler_213_one(*row) for row in q.reshape(-1, 4).tolist()]).reshape(q.shape[:-1] + (3,))
    from adcs_core.euler_kernel import euler_213_rows   # numba: imported at the first batch
    flat = np.ascontiguousarray(q.reshape(-1, 4))
    out = np.empty((flat.shape[0], 3))
    euler_213_rows(flat, out)
    return out.reshape(q.shape[:-1] + (3,))


SMALL_BATCH = 16   # euler_213 converts up to this many quaternions in Python


def _libm_hypot(a: float, b: float) -> float:
    """The C library's ``hypot`` (numpy's float64 ``hypot`` loop calls it; Python's ``math.hypot``
    is CPython's own algorithm and differs in the last bit for ~0.5 % of arguments)."""
    return float(np.hypot(a, b))


def _euler_213_one(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """:func:`adcs_core.euler_kernel.euler_213_row` of one quaternion in Python floats (the same
    operations: ``math.atan2`` calls the C library's ``atan2`` for finite arguments)."""
    finite = math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)
    n = math.sqrt((x * x + y * y + z * z) + w * w) if finite else 0.0
    if n == 0.0:   # non-finite, zero, or a norm that underflows: scipy refuses it
        return math.nan, math.nan, math.nan
    x, y, z, w = x / n, y / n, z / n, w / n
    a, b, c, d = w - x, z + y, x + w, y - z
    theta = 2 * math.atan2(_libm_hypot(c, d), _libm_hypot(a, b))
    half_sum, half_diff = math.atan2(b, a), math.atan2(d, c)
    if abs(theta) <= 1e-7:
        first, third = 2 * half_sum, 0.0
    elif abs(theta - math.pi) <= 1e-7:
        first, third = 2 * half_diff, 0.0
    else:
        first, third = half_sum + half_diff, half_sum - half_diff
    return _wrap_pi(first), _wrap_pi(theta - math.pi / 2), _wrap_pi(third)


def _wrap_pi(angle: float) -> float:
    """scipy's wrap of an Euler angle: one +-2 pi into [-pi, pi]."""
    if angle < -math.pi:
        return angle + 2 * math.pi
    if angle > math.pi:
        return angle - 2 * math.pi
    return angle


def rotate_to_body(q: np.ndarray, v_inertial: np.ndarray) -> np.ndarray:
    """``R(q)^T v``: an inertial vector in body axes (``q`` body-in-inertial, scalar last)."""
    qv, q4 = q[..., :3], q[..., 3:4]
    t = 2.0 * cross(v_inertial, qv)
    return v_inertial + q4 * t + cross(t, qv)


def rotate_to_inertial(q: np.ndarray, v_body: np.ndarray) -> np.ndarray:
    """``R(q) v``: a body vector in inertial axes."""
    return rotate_to_body(np.concatenate([-q[..., :3], q[..., 3:4]], axis=-1), v_body)


def pointing_error(q: np.ndarray, sigma: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Angle (rad, in [0, π]) between the body axis ``σ̂`` and the inertial direction ``τ̂`` at
    attitude ``q`` (seed 003's pointing error; ``sigma`` and ``tau`` normalised here)."""
    s = unit(np.asarray(sigma, dtype=float))
    t = rotate_to_body(np.asarray(q, dtype=float), unit(np.asarray(tau, dtype=float)))
    return np.arctan2(norm(cross(s, t)), dot(s, t))


# --- rotation matrices (seed 001's attitude representation) -----------------------------------

def matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` for (..., m, k) and (..., k, n) matrices, batch axes broadcast: ``k`` element-wise
    multiply-adds of whole matrices in the fixed order of :func:`matvec` (element ``ij`` is
    ``A[i,0] B[0,j] + A[i,1] B[1,j] + ...`` from the left, the same operations as ``matvec`` of each
    column, so the same bits), without BLAS and without a call per column (seed 001's laws make
    eight products a step)."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    out = A[..., :, 0, None] * B[..., None, 0, :]
    for k in range(1, A.shape[-1]):
        out = out + A[..., :, k, None] * B[..., None, k, :]
    return out


def hat(w: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``w×`` (..., 3, 3) of ``w`` (..., 3)."""
    w = np.asarray(w, dtype=float)
    z = np.zeros(w.shape[:-1])
    x, y, s = w[..., 0], w[..., 1], w[..., 2]
    return np.stack([np.stack([z, -s, y], -1), np.stack([s, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def rotation_from_quaternion(q: np.ndarray) -> np.ndarray:
    """``R`` (..., 3, 3) of a scalar-last quaternion ``q = [x, y, z, w]`` (normalised here): maps
    body vectors to inertial ones, seed 001's R and ``Rotation.from_quat(q).as_matrix()``."""
    q = np.asarray(q, dtype=float)
    q = q / np.sqrt(q[..., 0] ** 2 + q[..., 1] ** 2 + q[..., 2] ** 2 + q[..., 3] ** 2)[..., None]
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def quaternion_from_rotation(R: np.ndarray) -> np.ndarray:
    """Scalar-last unit quaternion (..., 4) of rotation matrices ``R`` (..., 3, 3), with ``w ≥ 0``
    (scipy's ``Rotation.from_matrix``, applied element by element along the batch axes)."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    q = np.stack([scipy_rotation().from_matrix(m).as_quat() for m in flat]) if len(flat) else np.zeros((0, 4))
    q = np.where(q[:, 3:4] < 0, -q, q)
    return q.reshape(R.shape[:-2] + (4,))


def rotation_exp(w: np.ndarray, t) -> np.ndarray:
    """``exp(t w×)`` (..., 3, 3), Rodrigues' formula: the rotation in ``t`` seconds at body rate
    ``w`` (so ``R_d(t) = R_d(0) exp(t ω_d×)`` solves seed 001 eq. 5, ``dR_d/dt = R_d ω_d×``, for
    constant ω_d)."""
    w = np.asarray(w, dtype=float)
    n = np.sqrt(dot(w, w))
    th = n * t
    safe = np.where(n > 0, n, 1.0)
    s = np.where(n > 0, np.sin(th) / safe, t)
    c = np.where(n > 0, (1.0 - np.cos(th)) / (safe * safe), 0.5 * t * t)
    K = hat(w)
    return np.eye(3) + s[..., None, None] * K + c[..., None, None] * matmul(K, K)


def attitude_error(R: np.ndarray, R_d: np.ndarray) -> np.ndarray:
    """``R̃ = R_dᵀ R`` (seed 001 eq. 7): the attitude ``R`` relative to the desired ``R_d``."""
    return matmul(transpose(np.asarray(R_d, dtype=float)), R)


def eigenaxis_error(R_err: np.ndarray) -> np.ndarray:
    """Eigenaxis attitude error ``θ = acos((tr R̃ - 1)/2)`` (seed 001 eq. 10), rad in [0, π]."""
    tr = R_err[..., 0, 0] + R_err[..., 1, 1] + R_err[..., 2, 2]
    return np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))
