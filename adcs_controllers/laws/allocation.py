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
from adcs_msgs_py.blocks import check_wheels
from adcs_msgs_py.names import TORQUE_CMD, WHEELS_CMD
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.sections import Section, as_section


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
    """The controller's side of its actuators: desired body torque -> actuator commands. One
    subclass per kind (the ``actuator`` parameter): :class:`WheelActuation`, :class:`TorquerActuation`
    and seed 002's :class:`~adcs_controllers.laws.backstepping.ThrusterActuation`; what differs
    between kinds is in their methods, so that the controller node and the batch engine never ask
    which kind they hold. Built from a validated controller section (the family's
    ``actuation_class``: :data:`ACTUATION_KINDS` or its own); limits
    may carry a batch axis. :meth:`command` is what the controller node publishes and what the
    batch engine applies, so both saturate and allocate identically.
    """

    kind = ''   # the value of the controller section's ``actuator`` parameter
    #: the dynamics section's actuators this kind commands (the batch engine checks they exist)
    plant_actuators: tuple[str, ...] = ()
    #: the wheels it commands by name (their faults are followed), in the command's order
    wheel_names: list[str] = []
    #: the topics its commands go out on (:meth:`command_messages`)
    command_topics: tuple[str, ...] = ()

    @staticmethod
    def section(p: dict | Section) -> Section:
        """``p`` as a typed section (a plain ``{dotted.name: value}`` dict: a section of its keys)."""
        return as_section(p)

    @staticmethod
    def check_section(v: dict) -> None:
        """Validate what a controller section needs for this kind (schema check; ParameterError)."""

    def command(self, torque: np.ndarray):
        raise NotImplementedError

    def command_messages(self, values) -> list[tuple[str, list[str] | None, str | None, np.ndarray]]:
        """The command messages of ``values`` (what :meth:`command` gave): ``(topic, joint names or
        None for a vector message, JointState field or None, array)`` each; the node encodes them."""
        raise NotImplementedError

    def plant_commands(self, values, speed_mode: bool = False) -> dict[str, tuple[np.ndarray, ...]]:
        """The batch engine's commands of ``values``: ``{plant actuator: (values,)}``, or for wheels
        ``(values, speed-mode flags)`` (the plant's WheelCommand, which this layer does not import)."""
        raise NotImplementedError

    def thruster_on_time(self, values):
        """The thruster on-times in ``values`` (0.0: this kind fires none)."""
        return 0.0

    #: whether :meth:`command_values` needs the wheel speeds (seed 002's allocation does)
    needs_wheel_speed = False

    def command_values(self, torque: np.ndarray, w: np.ndarray, wheel_speed: np.ndarray | None):
        """The command values of desired body torque ``torque`` for rate ``w`` and wheel speeds
        ``wheel_speed`` (None unless :attr:`needs_wheel_speed`): :meth:`command`'s values."""
        return self.command(torque)[0]

    def actuate(self, torque: np.ndarray, w: np.ndarray, wheel_speed: np.ndarray | None):
        """The controller node's step: ``(command values, the body torque they ask for, status
        values of this kind)``."""
        values, applied = self.command(torque)
        return values, applied, {}

    def usable_status(self) -> dict:
        """The status values naming the usable actuators (after the rejected-message count)."""
        return {'available_wheels': self.usable() or 'none'}

    def follow_faults(self, snapshot) -> bool:
        """Follow a fault snapshot ``{actuator name: FaultState}``; whether the usable actuators changed
        (the node and the batch engine then :meth:`inform` the law). Kinds with nothing to follow: False."""
        return False

    def inform(self, law) -> str | None:
        """Tell ``law`` which actuators it has now (a wheel law re-plans over the usable wheels); the
        law's note, if any."""
        return None

    def usable(self) -> str:
        """The usable actuators' names, comma-separated ('' for a kind with no named actuators)."""
        return ''

    def wheel_momentum(self, speed: np.ndarray) -> np.ndarray:
        raise ValueError('the wheel momentum needs wheels with their spin inertia '
                         '(wheels.spin_inertia in the controller section)')

    def command_momentum(self, h: np.ndarray) -> np.ndarray:
        raise ValueError('a wheel momentum command needs wheels with their spin inertia '
                         '(wheels.spin_inertia in the controller section)')


class WheelActuation(Actuation):
    """Reaction wheels: minimum-norm motor torques over the available wheels, saturated per wheel
    (``clip``) or as a vector (``scale``); or wheel speeds for a commanded momentum. Keys:
    ``wheels.names/axes/max_torque`` (``spin_inertia``, ``bias_speed`` where needed), ``saturation``."""

    kind = 'wheels'
    plant_actuators = ('wheels',)
    command_topics = (WHEELS_CMD,)

    def __init__(self, p) -> None:
        p = self.section(p)
        self.saturation = p.saturation
        wheels = p.wheels
        names = wheels.names
        self.wheel_names = list(names)
        self.axes = np.asarray(wheels.axes, dtype=float).reshape(len(names), 3)
        self.axes = self.axes / np.linalg.norm(self.axes, axis=1, keepdims=True)
        self.limit = np.asarray(wheels.max_torque, dtype=float)
        # Only the sections of laws that command momentum have the spin inertia and bias speed
        # (their schemas: empty by default, as here: no spin inertia, no bias).
        spin = wheels.spin_inertia if hasattr(wheels, 'spin_inertia') else ()
        self.spin_inertia = np.asarray(spin, dtype=float) if len(spin) else None
        bias = wheels.bias_speed if hasattr(wheels, 'bias_speed') else ()
        self.bias_speed = np.asarray(bias, dtype=float) if len(bias) else np.zeros(len(names))
        self.set_available(np.ones(len(names), dtype=bool))

    @staticmethod
    def check_section(v: dict) -> None:
        check_wheels(v, with_physics=False)
        if not v['wheels.names']:
            raise ParameterError('wheels.names', "actuator 'wheels' needs the wheel names, axes and "
                                 'torque limits (the controller\'s model of the wheels)')

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

    def inform(self, law) -> str | None:
        return law.on_wheels(self.axes, self.available)

    def usable(self) -> str:
        return ','.join(n for n, ok in zip(self.wheel_names, self.available) if ok)

    def command(self, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(motor torques, body torque they produce) for desired body torque ``torque`` (..., 3)."""
        tau = saturate(matvec(self.allocation, torque), self.limit, self.saturation)
        return tau, body_torque_from_wheels(self.axes, tau)

    def command_messages(self, values):
        return [(WHEELS_CMD, self.wheel_names, 'effort', values)]

    def momentum_messages(self, speed: np.ndarray):
        """The speed commands of a commanded momentum (:meth:`command_momentum`), to the available
        wheels only (the others are not named: they keep their last command, and produce no torque)."""
        ok = self.available
        return [(WHEELS_CMD, [n for n, a in zip(self.wheel_names, ok) if a], 'velocity', speed[ok])]

    def plant_commands(self, values, speed_mode: bool = False):
        return {'wheels': (values, np.full(np.shape(values), speed_mode))}

    def wheel_momentum(self, speed: np.ndarray) -> np.ndarray:
        """The wheels' angular momentum RELATIVE to the body in body axes, ``h = sum_i a_i Js_i Ω_i``
        (..., 3), for speeds ``speed`` (..., n) relative to the body (``wheels/state``'s velocity):
        the papers' ``h`` with ``H = J ω + h``, ``J`` the total inertia (wheels locked), the plant's
        convention (:mod:`adcs_sim.truth.plant`: its ``Js_i a_i·ω`` part is in ``J ω``). Needs
        ``wheels.spin_inertia``. One fixed summation order (:func:`adcs_core.attitude.matvec`), so the
        node and the batch engine get the same bits."""
        if self.spin_inertia is None:
            return super().wheel_momentum(speed)
        return matvec(np.ascontiguousarray(self.axes.T), np.asarray(speed, dtype=float) * self.spin_inertia)

    def command_momentum(self, h: np.ndarray) -> np.ndarray:
        """Wheel speed commands (..., n) (rad/s, relative to the body) for the commanded wheel
        momentum ``h`` (..., 3) in body axes: minimum-norm over the available wheels (zero for the
        others), divided by the spin inertias (``wheels.spin_inertia``, required), plus each
        available wheel's bias speed (``wheels.bias_speed``, default 0)."""
        if self.spin_inertia is None:
            return super().command_momentum(h)
        return -matvec(self.allocation, h) / self.spin_inertia + np.where(self.available, self.bias_speed, 0.0)


class TorquerActuation(Actuation):
    """Ideal body torquers (seed 001's "continuously variable torques"): the torque saturated per
    axis at ``torquers.max_torque`` (``clip``) or as a vector (``scale``)."""

    kind = 'torquers'
    plant_actuators = ('torquers',)
    command_topics = (TORQUE_CMD,)

    def __init__(self, p) -> None:
        p = self.section(p)
        self.saturation = p.saturation
        self.limit = np.asarray(p.torquers.max_torque, dtype=float)[..., None] * np.ones(3)

    def command(self, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(torquer torques, the same body torque) for desired body torque ``torque`` (..., 3)."""
        applied = saturate(torque, self.limit, self.saturation)
        return applied, applied

    def command_messages(self, values):
        return [(TORQUE_CMD, None, None, values)]

    def plant_commands(self, values, speed_mode: bool = False):
        return {'torquers': (values,)}


#: The actuation class of each value of a controller section's ``actuator`` (seed 002's
#: thrusters are their family's own: ``ControllerFamily.actuation``).
ACTUATION_KINDS: dict[str, type[Actuation]] = {c.kind: c for c in (WheelActuation, TorquerActuation)}

