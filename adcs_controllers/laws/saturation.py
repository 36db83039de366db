"""Torque-saturation handling of the inertia-free laws, seed 001 sections 6-7: saturation of the
commanded torque (cutoff, scaling), the varying adaptation gain (VAG) of M2S and the extremum
tracking of its commanded spin rate. Pure numpy, no rclpy; arrays take an optional leading batch
axis.

Saturation (section 6) of the commanded u (eq. 41), box ``B(u_max) = {|u_i| ≤ u_max,i}``::

    cutoff  u'_i = sat(u_i, u_max,i)                                     (47, 48)
    scaling u' = α_max u,  α_max = max{α ∈ (0, 1]: α u ∈ B} = min(1, min_i u_max,i/|u_i|)   (49-51)

Varying adaptation gain (section 7.1), ``Q = q Q₀`` (eq. 55, Q₀ = I6 in the paper), per control
step k, with u the commanded (unsaturated) torque::

    q_k = q_{k-1}                                 if u ∈ B(u_max)
          q_max                                   if q_{k-1} ≥ q_max
          (1 + K_Q ‖|u| - u_max‖/‖u_max‖) q_{k-1}   otherwise (capped at q_max, "not allowed to
                                                  increase above q_max")              (56-58)

VAG-C = cutoff + eq. 56, VAG-S = scaling + eq. 56. ``excess='printed'`` uses ``‖|u| - u_max‖``
over all three axes as printed; ``excess='positive'`` only the exceeding parts (R6).

Extremum tracking (section 7.4) of the commanded spin rate ``ω̄`` (``ω_d = ω̄ ω̂_d``)::

    φ̃_k = acos(ω̂_kᵀ ω̂_d)   (ω̂_k body rate direction, ω̂_d the desired body spin axis)  (60)
    Δt = t - t̄_k   (time of the last command change)                                 (61)
    ω̄_{k+1} = ω̄_k - δ_{k+1}   if φ̃_k > φ̃_max and Δt > t_max
              ω̄_k + δ_{k+1}   if φ̃_k ≤ φ̃_max and ω̄_k < ω̄_0 and Δt > t_max
              ω̄_k             otherwise                                              (62)
    δ_{k+1} = K_ω δ_k  (at each command change; δ_0 = ω̄_0: a bisection of (0, ω̄_0])  (63)
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import dot

__all__ = [
    'MODE_UNSATURATED', 'MODE_SATURATED', 'MODE_NAMES', 'SAT_CODES', 'sat_cutoff', 'sat_scaling',
    'saturate', 'outside_box', 'qsat', 'extremum_tracking_step',
]

MODE_UNSATURATED = 0  # commanded torque inside the box B(u_max)
MODE_SATURATED = 1    # commanded torque outside the box: cutoff/scaling applied
MODE_NAMES = {MODE_UNSATURATED: 'unsaturated', MODE_SATURATED: 'saturated'}


def sat_cutoff(u: np.ndarray, u_max) -> np.ndarray:
    """Torque cutoff, eq. (47)-(48): per component ``sat(u_i, u_max,i)``."""
    u_max = np.asarray(u_max, dtype=float)
    return np.clip(u, -u_max, u_max)


def sat_scaling(u: np.ndarray, u_max) -> np.ndarray:
    """Torque scaling, eq. (49)-(51), box region: ``α_max u`` with ``α_max = min(1, min_i u_max,i/|u_i|)``
    (direction kept, largest vector inside the box)."""
    u = np.asarray(u, dtype=float)
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), u.shape)
    au = np.abs(u)
    ratio = np.where(au > u_max, u_max / np.where(au > 0, au, 1.0), 1.0)
    alpha = np.minimum(np.minimum(ratio[..., 0], ratio[..., 1]), ratio[..., 2])
    return alpha[..., None] * u


def saturate(u, u_max, method: str):
    """``method``: ``'none'``, ``'cutoff'`` (eq. 48) or ``'scaling'`` (eq. 51)."""
    if method == 'cutoff':
        return sat_cutoff(u, u_max)
    if method == 'scaling':
        return sat_scaling(u, u_max)
    if method == 'none':
        return np.asarray(u, dtype=float)
    raise ValueError(f"saturation must be 'none', 'cutoff' or 'scaling', got {method!r}")


# 'clip'/'scale': the names of the controller sections' common ``saturation`` parameter
SAT_CODES = {'none': 0, 'cutoff': 1, 'clip': 1, 'scaling': 2, 'scale': 2}


def outside_box(u, u_max):
    """Whether ``u`` (..., 3) lies outside the box ``B(u_max)`` (any ``|u_i| > u_max,i``)."""
    return np.any(np.abs(u) > u_max, axis=-1)


def qsat(q, q_max, u, u_max, K_Q, excess: str = 'printed'):
    """Adaptation-rate saturation function, eq. (56): the new q of ``Q = q I6`` (eq. 55).

    ``u`` the commanded (unsaturated) torque (..., 3); ``u_max`` scalar or (..., 3). ``excess``:
    ``'printed'`` = ``‖|u| - u_max‖/‖u_max‖`` (all axes), ``'positive'`` = only exceeding parts.
    Increase capped at ``q_max`` (the text: q "is not allowed to increase above" q_max)."""
    u = np.asarray(u, dtype=float)
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), u.shape)
    q = np.asarray(q, dtype=float)
    d = np.abs(u) - u_max
    if excess == 'positive':
        d = np.maximum(d, 0.0)
    elif excess != 'printed':
        raise ValueError(f"excess must be 'printed' or 'positive', got {excess!r}")
    with np.errstate(invalid='ignore', divide='ignore'):  # u_max = inf: never outside, unused
        ratio = np.sqrt(dot(d, d)) / np.sqrt(dot(u_max, u_max))
    grown = np.minimum((1.0 + np.asarray(K_Q, dtype=float) * ratio) * q, q_max)
    return np.where(outside_box(u, u_max), np.where(q >= q_max, q_max, grown), q)


def extremum_tracking_step(t, w, axis, omega_bar, omega_bar0, delta, t_last, t_max, phi_max, K_omega):
    """One evaluation of eq. (60)-(64) at time ``t``.

    ``w`` (..., 3) body rate, ``axis`` (..., 3) unit desired spin axis ω̂_d, ``omega_bar`` current
    commanded rate ω̄_k, ``delta`` δ_k, ``t_last`` t̄_k. Returns ``(omega_bar, delta, t_last, phi)``
    after the step (δ and t̄ change only with the command)."""
    w = np.asarray(w, dtype=float)
    n = np.sqrt(dot(w, w))
    cosphi = dot(w, axis) / np.where(n > 0, n, 1.0)
    phi = np.where(n > 0, np.arccos(np.clip(cosphi, -1.0, 1.0)), np.pi)
    due = (t - t_last) > t_max
    new_delta = K_omega * delta
    down = due & (phi > phi_max)
    up = due & (phi <= phi_max) & (omega_bar < omega_bar0)
    change = down | up
    omega_new = np.where(down, omega_bar - new_delta, np.where(up, omega_bar + new_delta, omega_bar))
    return (omega_new, np.where(change, new_delta, delta), np.where(change, t, t_last), phi)
