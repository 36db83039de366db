"""Body torque -> actuator commands: minimum-norm allocation over the available wheels, saturation.

Reaction wheel ``i`` with spin axis ``a_i`` and motor torque ``tau_i`` puts ``-a_i tau_i`` on the
body (the papers' ``N = -dh/dt``). For a desired body torque ``u`` the minimum-norm motor torques
over the available wheels are ``tau = -A_av^+ u`` with ``A_av`` the 3 x m matrix of available axes
(Moore-Penrose pseudo-inverse, :func:`numpy.linalg.pinv`); failed wheels get zero.

A law may instead command the wheels' angular momentum ``h`` in body axes (seed 000's zero-momentum
controller, eq. 13): the minimum-norm wheel momenta are ``A_av^+ h`` and the speed commands
(relative to the body, the plant's speed mode) ``Ω_i = (A_av^+ h)_i / Js_i``.
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import matvec
from adcs_core.faults import FAULT_UNUSABLE_MODES, NOMINAL


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
    return -matvec(np.asarray(axes, dtype=float).T, tau)


class Actuation:
    """The controller's side of its actuators: desired body torque -> actuator commands.

    Built from a validated controller section (``actuator``, ``wheels.*``, ``saturation``,
    ``torquers.max_torque``; limits may carry a batch axis). :meth:`command` is what the
    controller node publishes and what the batch engine applies, so both saturate and allocate
    identically.
    """

    def __init__(self, p: dict) -> None:
        self.kind = p['actuator']
        self.saturation = p['saturation']
        if self.kind == 'wheels':
            names = p['wheels.names']
            self.wheel_names = list(names)
            self.axes = np.asarray(p['wheels.axes'], dtype=float).reshape(len(names), 3)
            self.axes = self.axes / np.linalg.norm(self.axes, axis=1, keepdims=True)
            self.limit = np.asarray(p['wheels.max_torque'], dtype=float)
            spin = p.get('wheels.spin_inertia', [])
            self.spin_inertia = np.asarray(spin, dtype=float) if len(spin) else None
            bias = p.get('wheels.bias_speed', [])
            self.bias_speed = np.asarray(bias, dtype=float) if len(bias) else np.zeros(len(names))
            self.set_available(np.ones(len(names), dtype=bool))
        else:
            self.limit = np.asarray(p['torquers.max_torque'], dtype=float)[..., None] * np.ones(3)

    def set_available(self, available: np.ndarray) -> None:
        """Re-allocate over the wheels marked available (a wheel failure)."""
        self.available = np.asarray(available, dtype=bool)
        self.allocation = wheel_allocation_matrix(self.axes, self.available)

    def follow_faults(self, snapshot) -> bool:
        """Allocate over the wheels a fault snapshot ``{wheel name: FaultState}`` leaves usable
        (not ``failed`` or ``stuck``; a wheel it does not name stays usable). Returns whether the
        usable wheels changed (the node and the batch engine then tell the law)."""
        available = np.array([snapshot.get(n, NOMINAL).mode not in FAULT_UNUSABLE_MODES
                              for n in self.wheel_names])
        if np.array_equal(available, self.available):
            return False
        self.set_available(available)
        return True

    def command(self, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(command values, body torque they produce) for desired body torque ``torque`` (..., 3).

        Wheels: minimum-norm motor torques over the available wheels, saturated per wheel
        (``clip``) or as a vector (``scale``); torquers: the torque saturated per axis.
        """
        if self.kind == 'wheels':
            tau = saturate(matvec(self.allocation, torque), self.limit, self.saturation)
            return tau, body_torque_from_wheels(self.axes, tau)
        applied = saturate(torque, self.limit, self.saturation)
        return applied, applied

    def wheel_momentum(self, speed: np.ndarray) -> np.ndarray:
        """The wheels' angular momentum RELATIVE to the body in body axes, ``h = sum_i a_i Js_i Ω_i``
        (..., 3), for speeds ``speed`` (..., n) relative to the body (``wheels/state``'s velocity):
        the papers' ``h`` with ``H = J ω + h``, ``J`` the total inertia (wheels locked), the plant's
        convention (:mod:`adcs_sim.truth.plant`: its ``Js_i a_i·ω`` part is in ``J ω``). Needs
        ``wheels.spin_inertia``. One fixed summation order (:func:`adcs_core.attitude.matvec`), so the
        node and the batch engine get the same bits."""
        if self.kind != 'wheels' or self.spin_inertia is None:
            raise ValueError('the wheel momentum needs wheels with their spin inertia '
                             '(wheels.spin_inertia in the controller section)')
        return matvec(np.ascontiguousarray(self.axes.T), np.asarray(speed, dtype=float) * self.spin_inertia)

    def command_momentum(self, h: np.ndarray) -> np.ndarray:
        """Wheel speed commands (..., n) (rad/s, relative to the body) for the commanded wheel
        momentum ``h`` (..., 3) in body axes: minimum-norm over the available wheels (zero for the
        others), divided by the spin inertias (``wheels.spin_inertia``, required), plus each
        available wheel's bias speed (``wheels.bias_speed``, default 0)."""
        if self.kind != 'wheels' or self.spin_inertia is None:
            raise ValueError('a wheel momentum command needs wheels with their spin inertia '
                             '(wheels.spin_inertia in the controller section)')
        return -matvec(self.allocation, h) / self.spin_inertia + np.where(self.available, self.bias_speed, 0.0)
