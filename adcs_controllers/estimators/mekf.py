"""The multiplicative extended Kalman filter (MEKF) with gyro-bias states: pure numpy, leading batch
axis, no ROS (Markley & Crassidis 2014, ch. 6, "Sequential Attitude Estimation", the MEKF section;
Lefferts, Markley and Shuster, J. Guidance 5(5):417-429, 1982). The equations are written out in each
docstring; equation numbers are not quoted because they were not checked against the book.

State: the attitude ``q`` (..., 4) (scalar last, body in inertial, :mod:`adcs_core.attitude`) and
the gyro bias ``β`` (..., 3) rad/s; the filter's error state ``x = [δθ, Δβ]`` (..., 6) with
``q_true = q ⊗ δq(δθ)`` (``δθ`` a small rotation in body axes, ``δq ≈ [δθ/2, 1]``, the same
``δθ`` as :func:`adcs_controllers.estimators.single_frame.quest_covariance`) and ``β_true = β + Δβ``;
its covariance ``P`` (..., 6, 6).

Gyro model (Farrenkopf): ``ω_meas = ω + β + η_v``, ``β̇ = η_u``, with the angle random walk
``σ_v`` (rad/√s) and the rate random walk ``σ_u`` (rad/s^1.5). Error dynamics:
``δθ̇ = −[ω̂×] δθ − Δβ − η_v``, ``Δβ̇ = η_u``, with ``ω̂ = ω_meas − β``.
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import cross, dot, hat, quat_conjugate, quat_multiply

_SMALL_ANGLE = 1e-5   # |ω̂| Δt below which the series forms are used (their truncation ~1e-20)


def _finite(name: str, x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if not np.isfinite(x).all():
        raise ValueError(f'MEKF: {name} is not finite')
    return x


def rotation_quaternion(phi: np.ndarray) -> np.ndarray:
    """``exp(φ/2)``: the unit quaternion (..., 4) of the rotation vector ``φ`` (..., 3), closed form
    ``[sin(|φ|/2) φ/|φ|, cos(|φ|/2)]`` (series below ``_SMALL_ANGLE``)."""
    a = np.sqrt(dot(phi, phi))
    small = a < _SMALL_ANGLE
    s = np.where(small, 0.5 - a * a / 48.0, np.sin(0.5 * a) / np.where(small, 1.0, a))
    return np.concatenate([s[..., None] * phi, np.cos(0.5 * a)[..., None]], axis=-1)


def transition(omega: np.ndarray, dt: float) -> np.ndarray:
    """The discrete error-state transition ``Φ`` (..., 6, 6) over ``dt`` at constant ``ω̂``:
    ``Φ11 = I − [ω̂×] sin θ/|ω̂| + [ω̂×]² (1 − cos θ)/|ω̂|²``,
    ``Φ12 = −I Δt + [ω̂×] (1 − cos θ)/|ω̂|² − [ω̂×]² (θ − sin θ)/|ω̂|³``, ``Φ21 = 0``, ``Φ22 = I``,
    ``θ = |ω̂| Δt`` (the exact exponential of ``F = [[−[ω̂×], −I], [0, 0]]``)."""
    w = np.sqrt(dot(omega, omega))
    th = w * dt
    small = th < _SMALL_ANGLE
    ws = np.where(small, 1.0, w)
    c1 = np.where(small, dt - w * w * dt ** 3 / 6.0, np.sin(th) / ws)
    c2 = np.where(small, dt * dt / 2.0, (1.0 - np.cos(th)) / ws ** 2)
    c3 = np.where(small, dt ** 3 / 6.0, (th - np.sin(th)) / ws ** 3)
    W = hat(omega)
    W2 = W @ W
    eye = np.broadcast_to(np.eye(3), W.shape)
    phi11 = eye - c1[..., None, None] * W + c2[..., None, None] * W2
    phi12 = -dt * eye + c2[..., None, None] * W - c3[..., None, None] * W2
    top = np.concatenate([phi11, phi12], axis=-1)
    bottom = np.concatenate([np.zeros_like(W), eye], axis=-1)
    return np.concatenate([top, bottom], axis=-2)


def process_noise(dt: float, sigma_v, sigma_u) -> np.ndarray:
    """The discrete process noise ``Q`` (..., 6, 6) of the gyro model over ``dt`` (the standard
    small-rate form): ``Q11 = (σ_v² Δt + σ_u² Δt³/3) I``, ``Q12 = Q21 = −(σ_u² Δt²/2) I``,
    ``Q22 = σ_u² Δt I``."""
    # one batch shape for both (a campaign may disperse either: sigma_v (N,) with sigma_u scalar)
    sv2, su2 = np.broadcast_arrays(np.asarray(sigma_v, dtype=float)[..., None, None] ** 2,
                                   np.asarray(sigma_u, dtype=float)[..., None, None] ** 2)
    eye = np.eye(3)
    top = np.concatenate([(sv2 * dt + su2 * dt ** 3 / 3.0) * eye, -su2 * dt ** 2 / 2.0 * eye], axis=-1)
    bottom = np.concatenate([-su2 * dt ** 2 / 2.0 * eye, su2 * dt * eye], axis=-1)
    return np.concatenate([top, bottom], axis=-2)


def propagate(q, beta, P, omega_meas, dt: float, sigma_v, sigma_u):
    """One gyro step: ``ω̂ = ω_meas − β``, ``q⁺ = q ⊗ exp(ω̂ Δt / 2)`` (exact for a constant rate over
    the step), ``β⁺ = β``, ``P⁺ = Φ P Φᵀ + Q`` (:func:`transition`, :func:`process_noise`).
    Returns ``(q, beta, P)``."""
    q, beta, P = _finite('q', q), _finite('beta', beta), _finite('P', P)
    omega = _finite('omega_meas', omega_meas) - beta
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f'MEKF: dt must be positive, got {dt}')
    q_new = quat_multiply(q, rotation_quaternion(omega * dt))
    Phi = transition(omega, dt)
    P_new = Phi @ P @ np.swapaxes(Phi, -1, -2) + process_noise(dt, sigma_v, sigma_u)
    return q_new, beta.copy(), 0.5 * (P_new + np.swapaxes(P_new, -1, -2))


def reset(q, beta, dx):
    """Fold the error-state estimate ``dx = [δθ, Δβ]`` into the global state and zero it:
    ``q ← (q ⊗ [δθ/2, 1]) / |·|`` (the multiplicative update), ``β ← β + Δβ``."""
    dq = np.concatenate([0.5 * dx[..., :3], np.ones(dx.shape[:-1] + (1,))], axis=-1)
    q_new = quat_multiply(q, dq)
    q_new = q_new / np.sqrt((q_new * q_new).sum(axis=-1))[..., None]
    return q_new, beta + dx[..., 3:]


def _availability(available, shape) -> np.ndarray | None:
    """The per-element measurement mask (``shape`` = the batch shape), or None for all."""
    if available is None:
        return None
    return np.broadcast_to(np.asarray(available, dtype=bool), shape)


def kalman_update(q, beta, P, y, H, R, available=None):
    """The linear update of the error state from the innovation ``y`` (..., m), measurement matrix
    ``H`` (..., m, 6) and noise ``R`` (..., m, m): ``S = H P Hᵀ + R``, ``K = P Hᵀ S⁻¹``,
    ``dx = K y``, Joseph form ``P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ``, then :func:`reset`.
    Returns ``(q, beta, P, nis)`` with the normalised innovation squared ``yᵀ S⁻¹ y``. Where the
    optional mask ``available`` (batch shape) is False (an outage in that run) the state is returned
    unchanged and ``nis`` is NaN (no measurement)."""
    Ht = np.swapaxes(H, -1, -2)
    S = H @ P @ Ht + R
    K = np.swapaxes(np.linalg.solve(S, H @ P), -1, -2)      # P Hᵀ S⁻¹ (P and S symmetric)
    dx = (K @ y[..., None])[..., 0]
    IKH = np.eye(6) - K @ H
    P_new = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    nis = (y * np.linalg.solve(S, y[..., None])[..., 0]).sum(axis=-1)
    q_new, beta_new = reset(q, beta, dx)
    P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
    mask = _availability(available, nis.shape)
    if mask is not None:
        q_new = np.where(mask[..., None], q_new, q)
        beta_new = np.where(mask[..., None], beta_new, beta)
        P_new = np.where(mask[..., None, None], P_new, P)
        nis = np.where(mask, nis, np.nan)
    return q_new, beta_new, P_new, nis


def update_quaternion(q, beta, P, q_meas, R, available=None):
    """Star tracker update: the measured attitude ``q_meas = q_true ⊗ δq(v)``, ``v ~ N(0, R)`` in
    body (sensor) axes, ``R`` (..., 3, 3) rad². Innovation: twice the Gibbs vector of
    ``δq = q* ⊗ q_meas``, ``y = 2 δq_v / δq4`` (= δθ to first order), ``H = [I 0]``. The Gibbs form
    is the one :func:`reset` inverts exactly (``[y/2, 1]/|·|`` is ``δq``), so a large first error
    (the 10° of an acquisition) is corrected without the second-order residue of ``2 δq_v``.
    Rejects a measurement 180° away (``δq4 = 0``) with ValueError. ``available``: see
    :func:`kalman_update` (the measurements of unavailable elements are ignored, NaN allowed)."""
    q = _finite('q', q)
    q_meas = np.asarray(q_meas, dtype=float)
    mask = _availability(available, np.broadcast_shapes(q.shape, q_meas.shape)[:-1])
    if mask is not None:
        q_meas = np.where(mask[..., None], q_meas, q)
    q_meas = _finite('q_meas', q_meas)
    if not (np.sqrt((q_meas * q_meas).sum(axis=-1)) > 0).all():
        raise ValueError('MEKF: zero star tracker quaternion')
    q_meas = q_meas / np.sqrt((q_meas * q_meas).sum(axis=-1))[..., None]
    dq = quat_multiply(quat_conjugate(q), q_meas)
    if not (np.abs(dq[..., 3]) > 1e-6).all():
        raise ValueError('MEKF: star tracker measurement 180 degrees from the estimate')
    y = 2.0 * dq[..., :3] / dq[..., 3:4]
    H = np.broadcast_to(np.concatenate([np.eye(3), np.zeros((3, 3))], axis=-1), y.shape[:-1] + (3, 6))
    R = np.broadcast_to(_finite('R', R), y.shape[:-1] + (3, 3))
    return kalman_update(q, _finite('beta', beta), _finite('P', P), y, H, R, mask)


def update_vectors(q, beta, P, b_meas, r, sigma, available=None):
    """Unit-vector update (sun sensor, magnetometer): ``n`` measured body directions ``b_meas``
    (..., n, 3) of the reference directions ``r`` (..., n, 3), each with noise ``σ_i`` (rad,
    (..., n)). Prediction ``b̂ = R(q)ᵀ r``, innovation ``y = b_meas − b̂`` (stacked, 3n),
    ``H_i = [[b̂_i×] 0]`` (``b_true = b̂ + [b̂×] δθ`` to first order), ``R = diag(σ_i² I₃)``.
    ``available``: see :func:`kalman_update` (all vectors of an unavailable element are ignored)."""
    q, r = _finite('q', q), _finite('r', r)
    sigma = _finite('sigma', sigma)
    if not (sigma > 0).all():
        raise ValueError('MEKF: sigma must be positive')
    if not (np.sqrt(dot(r, r)) > 0).all():
        raise ValueError('MEKF: zero-length reference vector')
    r = r / np.sqrt(dot(r, r))[..., None]
    qv, q4 = q[..., None, :3], q[..., None, 3:4]
    t = 2.0 * cross(r, qv)
    b_hat = r + q4 * t + cross(t, qv)                         # rotate_to_body, per vector
    b_meas = np.asarray(b_meas, dtype=float)
    mask = _availability(available, np.broadcast_shapes(b_hat.shape, b_meas.shape)[:-2])
    if mask is not None:
        b_meas = np.where(mask[..., None, None], b_meas, b_hat)
    b_meas = _finite('b_meas', b_meas)
    if not (np.sqrt(dot(b_meas, b_meas)) > 0).all():
        raise ValueError('MEKF: zero-length measured vector')
    b_meas = b_meas / np.sqrt(dot(b_meas, b_meas))[..., None]
    n = b_hat.shape[-2]
    batch = b_hat.shape[:-2]
    H = np.concatenate([hat(b_hat), np.zeros(b_hat.shape + (3,))], axis=-1).reshape(batch + (3 * n, 6))
    y = (b_meas - b_hat).reshape(batch + (3 * n,))
    var = np.repeat(np.broadcast_to(sigma, batch + (n,)) ** 2, 3, axis=-1)
    R = var[..., None] * np.eye(3 * n)
    return kalman_update(q, _finite('beta', beta), _finite('P', P), y, H, R, mask)


def attitude_error(q, q_true) -> np.ndarray:
    """``δθ`` (..., 3), rad, body axes: twice the Gibbs vector of ``q* ⊗ q_true`` (``q_true = q ⊗ δq``)."""
    dq = quat_multiply(quat_conjugate(q), q_true)
    return 2.0 * dq[..., :3] / dq[..., 3:4]


def nees(q, beta, P, q_true, beta_true) -> np.ndarray:
    """The normalised estimation error squared ``eᵀ P⁻¹ e``, ``e = [δθ, Δβ]`` with ``δθ`` twice the
    Gibbs vector of ``q* ⊗ q_true`` (the filter's parameterisation, :func:`update_quaternion`) and
    ``Δβ = β_true − β``: χ² with 6 degrees of freedom for a consistent filter."""
    e = np.concatenate([attitude_error(q, q_true), beta_true - beta], axis=-1)
    return (e * np.linalg.solve(P, e[..., None])[..., 0]).sum(axis=-1)
