"""Spacecraft plant: rigid body + actuators + environment, integrated with fixed-step RK4 (no ROS).

Inertia convention
------------------
``inertia`` (J) is the **total** inertia of the spacecraft with its wheels locked, i.e. it
*includes* each wheel's spin inertia. With wheel ``i`` of spin axis ``a_i`` (unit, body axes),
spin inertia ``Js_i`` and speed ``Omega_i`` **relative to the body**, the total angular momentum in
body axes is::

    H = J w + sum_i a_i Js_i Omega_i

and the equations of motion are (``J_s = J - sum_i Js_i a_i a_i^T``, the inertia without the
wheels' spin inertia about their axes)::

    J_s dw/dt = -w x H + tau_ext - sum_i a_i tau_i        (body)
    Js_i (a_i . dw/dt + dOmega_i/dt) = tau_i              (wheel i, tau_i = motor + friction)

so the body feels ``-a_i tau_i`` (seed 004: ``N = -dh/dt``). Seed 004's ``I`` (eq. 2-3, "body of
the satellite" with absolute wheel momentum ``h``) is our ``J_s``; for the papers' small wheels the
difference is below 0.1 % and the scenario files state which one they give. A wheel spin-up from
rest changes the body rate by exactly ``-J^{-1} a Js dOmega`` (total ``J``, momentum conservation).

Actuators
---------
An actuator is an :class:`Actuator`: it may carry states (appended to the state vector), store
angular momentum, remove spin inertia from ``J``, and apply a body torque computed from the
zero-order-hold command and the state. The integrator knows nothing about any particular actuator,
so new actuator models (thrusters, magnetorquers) are added as new classes, not by editing it.

Every array function accepts a leading batch axis: ``x`` of shape ``(..., n_states)``. So do the
physical parameters a Monte Carlo campaign disperses (inertia ``(..., 3, 3)``, wheel spin
inertia and limits ``(..., n)``, torquer limits, initial state): one :class:`Plant` then holds a
whole batch of different spacecraft (:mod:`adcs_sim.app.batch.engine`). Matrix-vector products are
:func:`~adcs_core.attitude.matvec` (fixed summation order), so a run's numbers do not depend on
the other runs of its batch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from adcs_core.attitude import cross, matvec, quat_kinematics, rotate_to_inertial
from adcs_core.faults import FAULT_ERROR_MODES, FAULT_OK_MODES
from adcs_core.inertia import check_inertias
from adcs_core.orbit import CircularOrbit
from adcs_sim.truth.kernel_kinds import TORQUERS, WHEELS

# --- actuators -------------------------------------------------------------------------------

class Actuator:
    """Interface of a plant actuator. Subclasses override what applies to them."""

    name: str = 'actuator'
    n_states: int = 0
    kernel_kind: int | None = None  # the compiled kernel's model of this actuator (adcs_sim.truth.kernel)

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.n_states)

    def spin_inertia_matrix(self) -> np.ndarray:
        """Inertia about the actuator's own spin axes, included in J but not rigidly attached."""
        return np.zeros((3, 3))

    def momentum(self, xa: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Angular momentum stored in the actuator beyond ``J_s w`` (body axes)."""
        return np.zeros(w.shape)

    def torque(self, t: float, xa: np.ndarray, w: np.ndarray, cmd: Any) -> tuple[np.ndarray, Any]:
        """Body torque (..., 3) under command ``cmd`` and an auxiliary value for :meth:`derivative`."""
        raise NotImplementedError

    # Kinematic constraints (a stuck wheel): inertia that currently turns rigidly with the body
    # although it is not in ``J_s``. ``constraint_version`` changes whenever it may have changed,
    # so the plant re-solves its body equation only then.
    constraint_version: int = 0

    def locked_inertia_matrix(self) -> np.ndarray | None:
        """Spin inertia (..., 3, 3) rigidly locked to the body now, or None for none."""
        return None

    def derivative(self, t: float, xa: np.ndarray, w: np.ndarray, wdot: np.ndarray,
                   cmd: Any, aux: Any) -> np.ndarray:
        return np.zeros(xa.shape)

    def zero_command(self) -> Any:
        raise NotImplementedError

    def command_from(self, *parts) -> Any:
        """This actuator's command from a controller's parts
        (:meth:`adcs_controllers.laws.allocation.Actuation.plant_commands`)."""
        raise NotImplementedError


class WheelCommand(NamedTuple):
    """Zero-order-hold wheel command: per wheel a value and whether it is a speed (else torque)."""

    value: np.ndarray      # (..., n): motor torque (N m) or speed set-point relative to body (rad/s)
    speed_mode: np.ndarray  # (n,) or (..., n) bool


@dataclass
class ReactionWheels(Actuator):
    """Reaction wheels with arbitrary spin axes, torque and speed limits, friction, faults.

    States: speeds ``Omega`` (rad/s, relative to the body) then angles (rad).
    Motor torque: in torque mode the saturated command; in speed mode a proportional speed loop
    ``tau = Js * speed_gain * (Omega_cmd - Omega)`` saturated at the torque limit (the wheel
    drive electronics' loop, used by seed 000's zero-momentum law). At the speed limit, motor
    torque that would spin the wheel faster is cut. Friction ``-viscous*Omega - coulomb*sign(Omega)``
    acts between wheel and body. A wheel marked unavailable (failed) produces no motor torque.

    Faults (:meth:`apply_fault`, one mode per wheel, each replacing the previous one):

    * ``failed``: ``available[i] = False``, no motor torque (friction still acts);
    * ``degraded``: the motor torque limit becomes ``min(max_torque, value)``;
    * ``bias``: a constant extra motor torque ``value`` (after saturation of the command);
    * ``stuck``: the speed relative to the body is frozen. The motor applies whatever torque keeps
      it so: with ``dOmega_i/dt = 0`` the wheel equation gives ``tau_i = Js_i a_i . dw/dt``, and
      substituted in the body equation ``(J_s + sum_stuck Js_i a_i a_i^T) dw/dt = -w x H +
      tau_ext - sum_free a_i tau_i``: the stuck wheel's spin inertia turns with the body. The
      plant solves that linear system exactly (:meth:`locked_inertia_matrix`), so total angular
      momentum is conserved. The holding torque is internal and not part of :meth:`motor_torque`
      (reported 0 for a stuck wheel) nor of the body torque returned by :meth:`torque`;
    * ``recovered`` / ``nominal``: back to nominal.
    """

    names: list[str]
    axes: np.ndarray                 # (n, 3), normalised here
    spin_inertia: np.ndarray         # (n,)
    max_torque: np.ndarray           # (n,), inf = unlimited
    max_speed: np.ndarray            # (n,), inf = unlimited
    viscous: np.ndarray | None = None
    coulomb: np.ndarray | None = None
    speed_gain: np.ndarray | None = None  # (n,) 1/s
    initial_speed: np.ndarray | None = None
    name: str = 'wheels'
    available: np.ndarray = field(init=False)
    kernel_kind = WHEELS

    def __post_init__(self) -> None:
        n = len(self.names)
        self.axes = np.asarray(self.axes, dtype=float).reshape(n, 3)
        self.axes = self.axes / np.linalg.norm(self.axes, axis=1, keepdims=True)
        as_n = lambda v, d: _per_wheel(v, d, n)  # noqa: E731
        self.spin_inertia = as_n(self.spin_inertia, 0.0)
        self.max_torque = as_n(self.max_torque, np.inf)
        self.max_speed = as_n(self.max_speed, np.inf)
        self.viscous = as_n(self.viscous, 0.0)
        self.coulomb = as_n(self.coulomb, 0.0)
        self.speed_gain = as_n(self.speed_gain, 1.0)
        self.initial_speed = as_n(self.initial_speed, 0.0)
        self.n_states = 2 * n
        self._axes_t = np.ascontiguousarray(self.axes.T)
        self.available = np.ones(n, dtype=bool)
        self.fault_limit = np.full(n, np.inf)   # degraded motor torque limit (N m)
        self.bias = np.zeros(n)                  # constant extra motor torque (N m)
        self.stuck = np.zeros(n, dtype=bool)     # speed relative to the body frozen
        self.modes = ['nominal'] * n
        self.constraint_version = 0
        self._limit = self.max_torque
        self._faulty = False
        self._has_friction = bool(np.any(self.viscous) or np.any(self.coulomb))
        self._speed_limited = bool(np.any(np.isfinite(self.max_speed)))

    @property
    def count(self) -> int:
        return len(self.names)

    def initial_state(self) -> np.ndarray:
        speed = self.initial_speed
        return np.concatenate([speed, np.zeros(speed.shape)], axis=-1)

    def spin_inertia_matrix(self) -> np.ndarray:
        return np.einsum('...i,ij,ik->...jk', self.spin_inertia, self.axes, self.axes)

    def momentum(self, xa, w):
        # Absolute spin (relative speed + body rate about the axis): J_s w + this = J w + sum a Js Omega.
        absolute = xa[..., :self.count] + matvec(self.axes, w)
        return matvec(self._axes_t, absolute * self.spin_inertia)

    def zero_command(self) -> WheelCommand:
        return WheelCommand(np.zeros(self.count), np.zeros(self.count, dtype=bool))

    def command_from(self, value: np.ndarray, speed_mode: np.ndarray) -> WheelCommand:
        return WheelCommand(value, speed_mode)

    FAULT_MODES = FAULT_OK_MODES + FAULT_ERROR_MODES

    def apply_fault(self, index: int, mode: str, value: float = 0.0) -> None:
        """Put wheel ``index`` in fault ``mode`` (see the class doc); replaces its previous mode.

        ``value``: the degraded torque limit (N m, >= 0) or the bias torque (N m); else ignored.
        """
        if mode not in self.FAULT_MODES:
            raise ValueError(f'unknown wheel fault mode {mode!r}; known: {list(self.FAULT_MODES)}')
        if mode == 'degraded' and not value >= 0:
            raise ValueError(f'degraded torque limit must be >= 0, got {value!r}')
        i = int(index)
        was_stuck = bool(self.stuck[i])
        self.available[i] = mode != 'failed'
        self.stuck[i] = mode == 'stuck'
        self.fault_limit[i] = float(value) if mode == 'degraded' else np.inf
        self.bias[i] = float(value) if mode == 'bias' else 0.0
        self.modes[i] = 'nominal' if mode == 'recovered' else mode
        self._limit = np.minimum(self.max_torque, self.fault_limit)
        self._faulty = bool(self.stuck.any() or np.any(self.bias) or np.isfinite(self.fault_limit).any())
        if was_stuck != bool(self.stuck[i]):
            self.constraint_version += 1

    def apply_faults(self, snapshot) -> None:
        """Apply a fault snapshot ``{wheel name: FaultState}`` (a ``faults`` message's or a
        schedule's, :func:`adcs_sim.truth.fault_schedule.fault_schedule`) with :meth:`apply_fault`."""
        for name, fault in snapshot.items():
            self.apply_fault(self.names.index(name), fault.mode, fault.value)

    def locked_inertia_matrix(self) -> np.ndarray | None:
        if not self.stuck.any():
            return None
        Js = np.where(self.stuck, self.spin_inertia, 0.0)
        return np.einsum('...i,ij,ik->...jk', Js, self.axes, self.axes)

    def motor_torque(self, speed: np.ndarray, cmd: WheelCommand) -> np.ndarray:
        """Motor torque actually produced for wheel speeds ``speed`` under ``cmd``."""
        value = cmd.value
        if cmd.speed_mode.any():
            loop = self.spin_inertia * self.speed_gain * (value - speed)
            value = np.where(cmd.speed_mode, loop, value)
        tau = np.minimum(np.maximum(value, -self._limit), self._limit)
        if self._faulty:
            tau = tau + self.bias
        if self._speed_limited:
            tau = np.where((np.abs(speed) >= self.max_speed) & (tau * speed > 0), 0.0, tau)
        if self._faulty:
            tau = np.where(self.stuck, 0.0, tau)
        return tau * self.available

    def friction_torque(self, speed: np.ndarray) -> np.ndarray:
        return -self.viscous * speed - self.coulomb * np.sign(speed)

    def torque(self, t, xa, w, cmd):
        speed = xa[..., :self.count]
        tau = self.motor_torque(speed, cmd)
        if self._has_friction:
            tau = tau + self.friction_torque(speed)
            if self._faulty:  # a stuck wheel's friction is part of its (internal) holding torque
                tau = np.where(self.stuck, 0.0, tau)
        return -matvec(self._axes_t, tau), tau

    def derivative(self, t, xa, w, wdot, cmd, aux):
        speed = xa[..., :self.count]
        accel = aux / self.spin_inertia - matvec(self.axes, wdot)
        if self._faulty:
            accel = np.where(self.stuck, 0.0, accel)
        return np.concatenate([accel, speed], axis=-1)


@dataclass
class Torquers(Actuator):
    """Ideal external torquers (seed 001): the commanded body torque, saturated per axis."""

    max_torque: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    name: str = 'torquers'
    kernel_kind = TORQUERS

    def __post_init__(self) -> None:
        limit = np.asarray(self.max_torque, dtype=float)
        self.max_torque = np.broadcast_to(limit, limit.shape[:-1] + (3,) if limit.ndim else (3,)).copy()

    def zero_command(self) -> np.ndarray:
        return np.zeros(3)

    def command_from(self, torque: np.ndarray) -> np.ndarray:
        return torque

    def torque(self, t, xa, w, cmd):
        return np.clip(cmd, -self.max_torque, self.max_torque), None


# --- environment ------------------------------------------------------------------------------

@dataclass
class Disturbance:
    """Body-frame disturbance ``c + A sin(f t + phi)`` (N m; f in rad/s), per axis."""

    constant: np.ndarray = field(default_factory=lambda: np.zeros(3))
    amplitude: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frequency: np.ndarray = field(default_factory=lambda: np.zeros(3))
    phase: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ('constant', 'amplitude', 'frequency', 'phase'):   # (3,), or (N, 3) dispersed in a batch
            value = np.asarray(getattr(self, name), dtype=float)
            setattr(self, name, value.reshape(value.shape[:-1] + (3,)) if value.ndim > 1 else value.reshape(3))

    @property
    def batched(self) -> bool:
        """Whether the runs of a batch have their own disturbances (the compiled kernel shares one)."""
        return any(getattr(self, name).ndim > 1 for name in ('constant', 'amplitude', 'frequency', 'phase'))

    @property
    def active(self) -> bool:
        return bool(np.any(self.constant) or np.any(self.amplitude))

    def torque(self, t: float) -> np.ndarray:
        return self.constant + self.amplitude * np.sin(self.frequency * t + self.phase)


# --- the plant --------------------------------------------------------------------------------


class Plant:
    """Rigid spacecraft with actuators, disturbances and optional gravity gradient.

    State vector ``x = [q (4, x y z w), w (3, rad/s), actuator states...]`` with optional leading
    batch axes. ``commands`` is a dict actuator name -> zero-order-hold command.
    """

    def __init__(self, inertia, actuators: list[Actuator] = (), disturbance: Disturbance | None = None,
                 orbit: CircularOrbit | None = None, gravity_gradient: bool = False, warm: bool = True) -> None:
        self.inertia = np.asarray(inertia, dtype=float)
        check_inertias(self.inertia, 'inertia')
        self.actuators = list(actuators)
        names = [a.name for a in self.actuators]
        if len(set(names)) != len(names):
            raise ValueError(f'actuator names must be unique, got {names}')
        self.disturbance = disturbance if disturbance is not None and disturbance.active else None
        if gravity_gradient and orbit is None:
            raise ValueError('gravity gradient needs an orbit')
        self.orbit = orbit
        self.gravity_gradient = gravity_gradient
        spin = sum((a.spin_inertia_matrix() for a in self.actuators), np.zeros((3, 3)))
        self.inertia_struct = self.inertia - spin
        check_inertias(self.inertia_struct, 'inertia minus wheel spin inertia')
        self.inertia_struct_inv = np.linalg.inv(self.inertia_struct)
        self.slices: dict[str, slice] = {}
        start = 7
        for a in self.actuators:
            self.slices[a.name] = slice(start, start + a.n_states)
            start += a.n_states
        self.n_states = start
        self._actuator_slices = [(a, self.slices[a.name]) for a in self.actuators]
        self._constraint_key = self._constraints()
        self._body_inv = self.inertia_struct_inv
        from adcs_sim.truth import kernel   # numba: loaded with the first plant, not by every importer
        self.kernel = kernel.KernelPlan.of(self)  # None: stepped by step_numpy
        if warm:
            self.warm()

    def warm(self) -> None:
        """Load the compiled kernel's machine code now (compiling it on a cold cache), not in the
        first step. The constructor does it unless given ``warm=False`` (the dynamics node then calls
        it once its endpoints exist, so discovery runs meanwhile)."""
        if self.kernel is not None:
            self.kernel.warm(self)

    def _constraints(self) -> tuple[int, ...]:
        return tuple(a.constraint_version for a in self.actuators)

    def body_inertia_inverse(self) -> np.ndarray:
        """Inverse of the inertia turning with the body now: ``J_s`` plus locked (stuck) spin
        inertia; recomputed only when an actuator's constraints changed."""
        key = self._constraints()
        if key != self._constraint_key:
            J = self.inertia_struct
            for a in self.actuators:
                locked = a.locked_inertia_matrix()
                if locked is not None:
                    J = J + locked
            self._body_inv = np.linalg.inv(J)
            self._constraint_key = key
        return self._body_inv

    def actuator(self, name: str) -> Actuator:
        for a in self.actuators:
            if a.name == name:
                return a
        raise KeyError(name)

    def initial_state(self, q, w) -> np.ndarray:
        """State vector from attitude and rate; batch axes of any part (and of the actuators'
        initial states) broadcast against each other."""
        parts = [np.asarray(q, dtype=float), np.asarray(w, dtype=float)]
        parts += [a.initial_state() for a in self.actuators]
        batch = np.broadcast_shapes(*(p.shape[:-1] for p in parts))
        return np.concatenate([np.broadcast_to(p, batch + p.shape[-1:]) for p in parts], axis=-1)

    def zero_commands(self) -> dict[str, Any]:
        return {a.name: a.zero_command() for a in self.actuators}

    def environment_torque(self, t: float, q: np.ndarray) -> np.ndarray | float:
        tau = 0.0
        if self.disturbance is not None:
            tau = tau + self.disturbance.torque(t)
        if self.gravity_gradient:
            tau = tau + self.orbit.gravity_gradient(t, q, self.inertia)
        return tau

    def angular_momentum(self, x: np.ndarray) -> np.ndarray:
        """Total angular momentum in body axes."""
        w = x[..., 4:7]
        H = matvec(self.inertia_struct, w)
        for a in self.actuators:
            H = H + a.momentum(x[..., self.slices[a.name]], w)
        return H

    def inertial_momentum(self, x: np.ndarray) -> np.ndarray:
        """Total angular momentum in inertial axes (conserved without external torque)."""
        q = x[..., :4]
        return rotate_to_inertial(q, self.angular_momentum(x))

    def kinetic_energy(self, x: np.ndarray) -> np.ndarray:
        """Rotational kinetic energy of body and wheels."""
        w = x[..., 4:7]
        T = 0.5 * np.sum(w * matvec(self.inertia_struct, w), axis=-1)
        for a in self.actuators:
            if isinstance(a, ReactionWheels):
                s = x[..., self.slices[a.name]][..., :a.count]
                absolute = s + matvec(a.axes, w)
                T = T + 0.5 * np.sum(a.spin_inertia * absolute ** 2, axis=-1)
        return T

    def control_torque(self, t: float, x: np.ndarray, commands: dict[str, Any]) -> np.ndarray:
        """Body torque from all actuators at state ``x`` (what the ZOH command produces now); on the
        compiled kernel when it models every actuator (same numbers), else :meth:`control_torque_numpy`."""
        if self.kernel is not None:
            tau = self.kernel.control_torque(self, t, x, commands)
            if tau is not None:
                return tau
        return self.control_torque_numpy(t, x, commands)

    def control_torque_numpy(self, t: float, x: np.ndarray, commands: dict[str, Any]) -> np.ndarray:
        """:meth:`control_torque` with numpy arrays (the reference the kernel equals)."""
        w = x[..., 4:7]
        tau = np.zeros(w.shape)
        for a in self.actuators:
            tau = tau + a.torque(t, x[..., self.slices[a.name]], w, commands[a.name])[0]
        return tau

    def derivative(self, t: float, x: np.ndarray, commands: dict[str, Any]) -> np.ndarray:
        q, w = x[..., :4], x[..., 4:7]
        H = matvec(self.inertia_struct, w)
        tau = self.environment_torque(t, q)
        evaluated = []
        for a, sl in self._actuator_slices:
            xa, cmd = x[..., sl], commands[a.name]
            H = H + a.momentum(xa, w)
            ta, aux = a.torque(t, xa, w, cmd)
            tau = tau + ta
            evaluated.append((a, xa, cmd, aux))
        wdot = matvec(self.body_inertia_inverse(), tau - cross(w, H))
        parts = [quat_kinematics(q, w), wdot]
        for a, xa, cmd, aux in evaluated:
            parts.append(a.derivative(t, xa, w, wdot, cmd, aux))
        return np.concatenate(parts, axis=-1)

    def step(self, t: float, x: np.ndarray, commands: dict[str, Any], period: float,
             max_step: float) -> np.ndarray:
        """Advance ``period`` seconds holding ``commands`` (zero-order hold), fixed-step RK4.

        The period is split into ``ceil(period / max_step)`` equal RK4 steps; the quaternion is
        renormalised after each. Runs on the compiled kernel (:mod:`adcs_sim.truth.kernel`, the same
        numbers bit for bit) when it models every actuator, else :meth:`step_numpy`.
        """
        if self.kernel is not None:
            x_new = self.kernel.step(self, t, x, commands, period, max_step)
            if x_new is not None:
                return x_new
        return self.step_numpy(t, x, commands, period, max_step)

    def step_numpy(self, t: float, x: np.ndarray, commands: dict[str, Any], period: float,
                   max_step: float) -> np.ndarray:
        """:meth:`step` with numpy arrays and :meth:`derivative` (the reference the kernel equals)."""
        n = max(1, math.ceil(period / max_step - 1e-9))
        h = period / n
        f = self.derivative
        half, sixth, third = 0.5 * h, h / 6.0, h / 3.0
        for i in range(n):
            ti = t + i * h
            k1 = f(ti, x, commands)
            k2 = f(ti + half, x + half * k1, commands)
            k3 = f(ti + half, x + half * k2, commands)
            k4 = f(ti + h, x + h * k3, commands)
            x = x + sixth * (k1 + k4) + third * (k2 + k3)
            q = x[..., :4]
            q /= np.sqrt((q * q).sum(axis=-1, keepdims=True))
        return x


def _per_wheel(value, default: float, n: int) -> np.ndarray:
    """A per-wheel parameter as an array (..., n): ``default`` when None, batch axes kept."""
    if value is None:
        return np.full(n, default, dtype=float)
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f'expected one value per wheel ({n}), got shape {arr.shape}')
    return arr


