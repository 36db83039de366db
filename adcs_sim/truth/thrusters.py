"""On/off attitude thrusters as a plant actuator (seed 002; no ROS).

Thrusters (seed 002 section 2.5)
--------------------------------
Thruster ``i`` sits at ``r_i`` (body axes, from the centre of mass, m) and pushes along the unit
direction ``d_i`` (body axes) with force ``F_i`` (N) while it is on, 0 while off. Body force and
torque::

    F = sum_i F_i d_i,        tau = sum_i r_i x (F_i d_i) = T f,   T = [r_1 x d_1, ..., r_n x d_n]

(``T`` is the thruster part of the paper's actuator matrix ``B_a``, eq. 21). The plant is
attitude-only: the net force is reported (:meth:`Thrusters.force`) but moves nothing.

Command for one control period (:class:`ThrusterCommand`, built by :meth:`Thrusters.command`):
an on-time per thruster ``0 <= t_on,i <= period``; the thruster fires from the period's start
``t0`` for ``t_on,i`` seconds at its maximum force (a single pulse, leading edge at the period's
start). A valve cannot open for less than ``min_on_time``: on-times in ``(0, min_on_time)`` are
dropped to 0 (``min_on_rule = 'drop'``, default: the controller's demand is below one minimum
impulse bit) or raised to ``min_on_time`` (``'extend'``). An on-time of the whole period keeps the
thruster on over the closed interval ``[t0, t0 + period]``.

Actuator states: the cumulated impulse ``I_i = ∫ F_i dt`` (N s) per thruster, integrated with the
body so it is part of the state vector and recorded; fuel use is ``sum_i I_i / (Isp g0)``.

Pulse edges inside an RK4 step
------------------------------
The force is a step function of time, so a fixed RK4 step (:meth:`adcs_sim.truth.plant.Plant.step`) that
contains a pulse edge samples it at ``t_k``, ``t_k + h/2`` and ``t_k + h`` with weights 1/6, 4/6,
1/6 (Simpson): the impulse of that step is off by up to ``F h / 3`` (edge just beside the
midpoint). For an exact pulse use :func:`step_pulsed`: it splits the period at every pulse edge
and holds each thruster on or off over each segment (:meth:`Thrusters.segment_command`), so RK4
integrates a piecewise-constant force: the impulse is ``F x on-time`` to rounding and the
attitude is integrated to RK4 accuracy on smooth segments. Bang-bang firing over whole periods
(seed 002's) has no edge inside a period, so both give the same bits there. A time-averaged torque
was rejected: RK4 sees the pulse at three instants, so an average only matches the impulse if the
whole step is averaged, and the actuator does not know the steps.

The orbit frame and the gravity gradient of seed 002 are kernel geometry: :mod:`adcs_core.orbit`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from adcs_core.attitude import cross, matvec
from adcs_sim.truth.kernel_kinds import THRUSTERS
from adcs_sim.truth.plant import Actuator, Plant

__all__ = ['ThrusterCommand', 'Thrusters', 'step_pulsed']


class ThrusterCommand(NamedTuple):
    """One control period's firing: thruster ``i`` on over ``[start, start + on_time[i])``
    (closed at the end when ``on_time[i] >= period``)."""

    start: float
    on_time: np.ndarray    # (..., n) s
    period: float = math.inf


@dataclass
class Thrusters(Actuator):
    """On/off thrusters (module doc). ``positions`` and ``directions`` (n, 3) body axes, or a batch
    (..., n, 3) of geometries (directions normalised here); ``max_force`` (N) scalar, (n,) or a batch (..., n); ``min_on_time`` (s)."""

    names: list[str]
    positions: np.ndarray
    directions: np.ndarray
    max_force: np.ndarray
    min_on_time: float = 0.0
    min_on_rule: str = 'drop'
    name: str = 'thrusters'
    torque_matrix: np.ndarray = field(init=False)   # (3, n): columns r_i x d_i
    force_matrix: np.ndarray = field(init=False)    # (3, n): columns d_i
    kernel_kind = THRUSTERS

    def __post_init__(self) -> None:
        n = len(self.names)
        self.positions = _per_thruster(self.positions, n, 'positions')
        d = _per_thruster(self.directions, n, 'directions')
        norm = np.linalg.norm(d, axis=-1, keepdims=True)
        if not np.all(norm > 0):
            raise ValueError('thruster directions must be non-zero vectors')
        self.directions = d / norm
        force = np.asarray(self.max_force, dtype=float)
        if force.ndim == 0:
            force = np.full(n, float(force))
        if force.shape[-1] != n or not np.all(force >= 0) or not np.all(np.isfinite(force)):
            raise ValueError(f'max_force must be finite, >= 0, one per thruster ({n}); got {force!r}')
        self.max_force = force
        if not (self.min_on_time >= 0 and math.isfinite(self.min_on_time)):
            raise ValueError(f'min_on_time must be finite and >= 0, got {self.min_on_time!r}')
        if self.min_on_rule not in ('drop', 'extend'):
            raise ValueError(f"min_on_rule must be 'drop' or 'extend', got {self.min_on_rule!r}")
        self.n_states = n
        # (..., 3, n): a batch of geometries (the sensitivity grid) gives one matrix per run
        self.torque_matrix = np.ascontiguousarray(np.swapaxes(cross(self.positions, self.directions), -1, -2))
        self.force_matrix = np.ascontiguousarray(np.swapaxes(self.directions, -1, -2))

    @property
    def count(self) -> int:
        return len(self.names)

    # --- commands ---------------------------------------------------------------------------

    def zero_command(self) -> ThrusterCommand:
        return ThrusterCommand(0.0, np.zeros(self.count), math.inf)

    def command(self, start: float, on_time, period: float) -> ThrusterCommand:
        """The firing a valve can do for requested on-times (..., n): clipped to ``[0, period]``,
        then the minimum on-time rule (module doc)."""
        on = np.clip(np.asarray(on_time, dtype=float), 0.0, period)
        if not np.all(np.isfinite(on)):
            raise ValueError('thruster on-times must be finite')
        short = (on > 0.0) & (on < self.min_on_time)
        if self.min_on_rule == 'drop':
            on = np.where(short, 0.0, on)
        else:
            on = np.where(short, min(self.min_on_time, period), on)
        return ThrusterCommand(float(start), on, float(period))

    def is_on(self, t: float, cmd: ThrusterCommand) -> np.ndarray:
        """(..., n) 1.0 where thruster i fires at time ``t`` under ``cmd``, else 0.0."""
        rel = t - cmd.start
        on = cmd.on_time
        # RK4 stage times are t_k + i h (rounded): the period's start and closed end get a
        # relative tolerance of 1e-9 so a full-period firing is never lost at its end point.
        tol = 1e-9 * cmd.period if math.isfinite(cmd.period) else 0.0
        lit = (rel >= -tol) & ((rel < on) | ((on >= cmd.period) & (rel <= cmd.period + tol)))
        return lit.astype(float)

    def forces(self, t: float, cmd: ThrusterCommand) -> np.ndarray:
        """Thrust magnitudes (..., n) at time ``t`` (N)."""
        return self.is_on(t, cmd) * self.max_force

    def force(self, t: float, cmd: ThrusterCommand) -> np.ndarray:
        """Net body force ``sum_i F_i d_i`` (..., 3) (N; reported, not integrated)."""
        return matvec(self.force_matrix, self.forces(t, cmd))

    # --- Actuator interface -----------------------------------------------------------------

    def torque(self, t, xa, w, cmd):
        f = self.forces(t, cmd)
        return matvec(self.torque_matrix, f), f

    def derivative(self, t, xa, w, wdot, cmd, aux):
        return np.broadcast_to(aux, xa.shape)

    # --- exact pulses ---------------------------------------------------------------------------

    def edges(self, cmd: ThrusterCommand) -> np.ndarray:
        """Sorted distinct pulse ends strictly inside ``(0, period)`` (relative to the start),
        over all thrusters and batch runs."""
        on = np.asarray(cmd.on_time, dtype=float).ravel()
        inner = on[(on > 0.0) & (on < cmd.period)]
        return np.unique(inner)

    def segment_command(self, cmd: ThrusterCommand, a: float, b: float) -> ThrusterCommand:
        """A command holding each thruster on (or off) over the whole segment ``[a, b]``
        (relative times inside the period) as it is under ``cmd`` there."""
        mid = 0.5 * (a + b)
        lit = (mid < cmd.on_time) | (cmd.on_time >= cmd.period)
        return ThrusterCommand(cmd.start + a, np.where(lit, math.inf, 0.0), math.inf)


def _per_thruster(values, n: int, what: str) -> np.ndarray:
    """(n, 3) or a batch (..., n, 3) of per-thruster vectors; 3 n flattened values (..., 3 n)
    are reshaped."""
    arr = np.asarray(values, dtype=float)
    if arr.shape[-2:] != (n, 3):
        if arr.shape[-1:] != (3 * n,):
            raise ValueError(f'thruster {what}: expected 3 values per thruster ({n}), got shape {arr.shape}')
        arr = arr.reshape(arr.shape[:-1] + (n, 3))
    return arr


def step_pulsed(plant: Plant, t: float, x: np.ndarray, commands: dict, period: float,
                max_step: float, thrusters: str = 'thrusters') -> np.ndarray:
    """:meth:`Plant.step` over one control period, split at the pulse edges of the thruster
    command ``commands[thrusters]`` so that no RK4 step straddles an edge (module doc).

    Each segment ``[a, b]`` is stepped with at most ``max_step``; the thrusters are held on/off
    over it. Without an edge inside the period this is exactly ``plant.step``.
    """
    act = plant.actuator(thrusters)
    cmd = commands[thrusters]
    if cmd.start != t or cmd.period != period:
        raise ValueError(f'thruster command is for [{cmd.start}, +{cmd.period}], '
                         f'not the step [{t}, +{period}]')
    cuts = act.edges(cmd)
    if cuts.size == 0:
        return plant.step(t, x, commands, period, max_step)
    bounds = np.concatenate([[0.0], cuts, [period]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = dict(commands)
        seg[thrusters] = act.segment_command(cmd, float(a), float(b))
        x = plant.step(t + float(a), x, seg, float(b - a), max_step)
    return x


# --- orbit frame ---------------------------------------------------------------------------------


