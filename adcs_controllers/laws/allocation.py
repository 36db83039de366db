"""Body torque -> actuator commands: minimum-norm allocation over the available wheels, saturation.

Reaction wheel ``i`` with spin axis ``a_i`` and motor torque ``tau_i`` puts ``-a_i tau_i`` on the
body (the papers' ``N = -dh/dt``). For a desired body torque ``u`` the minimum-norm motor torques
over the available wheels are ``tau = -A_av^+ u`` with ``A_av`` the 3 x m matrix of available axes
(Moore-Penrose pseudo-inverse, :func:`numpy.linalg.pinv`); failed wheels get zero.
"""
from __future__ import annotations

import numpy as np


def wheel_allocation_matrix(axes: np.ndarray, available: np.ndarray | None = None) -> np.ndarray:
    """n x 3 matrix ``M`` with ``tau = M u`` the minimum-norm wheel torques for body torque ``u``.

    ``axes`` is (n, 3); rows of unavailable wheels are zero. Compute it once per fault
    configuration, not per step.
    """
    axes = np.asarray(axes, dtype=float)
    n = axes.shape[0]
    available = np.ones(n, dtype=bool) if available is None else np.asarray(available, dtype=bool)
    M = np.zeros((n, 3))
    if available.any():
        A = axes[available].T  # 3 x m
        M[available] = -np.linalg.pinv(A)
    return M


def saturate(tau: np.ndarray, limit: np.ndarray, mode: str = 'clip') -> np.ndarray:
    """Saturate actuator torques at ``limit`` (per actuator).

    ``clip``: each actuator independently (what a wheel's electronics do; the papers' per-wheel
    limit). ``scale``: the whole vector scaled by one factor so that none exceeds its limit,
    keeping the torque direction.
    """
    limit = np.asarray(limit, dtype=float)
    if mode == 'clip':
        return np.clip(tau, -limit, limit)
    if mode == 'scale':
        ratio = np.max(np.abs(tau) / limit, axis=-1, keepdims=True)
        return tau / np.maximum(ratio, 1.0)
    raise ValueError(f"saturation mode must be 'clip' or 'scale', got {mode!r}")


def body_torque_from_wheels(axes: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Body torque ``-sum_i a_i tau_i`` produced by wheel motor torques ``tau`` (..., n)."""
    return -(tau @ np.asarray(axes, dtype=float))
