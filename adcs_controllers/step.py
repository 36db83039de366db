"""The flight-software steps: what a controller node and an estimator node do with one step's input,
pure (no ROS, no truth model), on one run or a batch; the nodes and the batch engine drive these very
objects (docs/architecture.md, "One step, two drivers").

:class:`FlightStep` (a controller section): due faults (the latest snapshot stamped ``<= t_k``,
:meth:`adcs_core.faults.FaultTracker.due`: the actuation follows it and tells the law) → the law (with
the wheel momentum of the same step for a law that needs it) → the actuation → the command values.
:class:`EstimationStep` (an estimator section): the sensors' readings of ``t_k`` → the estimate.

What a message does to a value on its way (the controller's renormalised attitude, the estimator's
readings) is one rule each in :mod:`adcs_msgs_py.measurements` (:func:`received_attitude`,
:func:`received_readings`): the node's decoding applies it (:mod:`adcs_msgs_py.conversions`,
:mod:`adcs_msgs_py.conversions_determination`); the batch engine, which sends no message, asks for it
here (``batch=True``).

The failure rule stays :mod:`adcs_controllers.laws.failure`. A node (one run) counts a state its law
refuses (:func:`adcs_controllers.laws.base.checked_control`, ``LawOutputRejected`` is raised to it) and
publishes the actuation's status; a batch cannot skip one run's step, so a law that raises fails the
batch (:class:`~adcs_controllers.laws.failure.FlightSoftwareError`, split by a campaign) and a
non-finite torque goes to the plant (the run diverges).
"""
from __future__ import annotations

from typing import Any, Callable, NamedTuple

import numpy as np

from adcs_controllers.laws.base import LawOutputRejected, checked_control
from adcs_controllers.laws.failure import answer, estimate_step
from adcs_core.faults import FaultTracker
from adcs_msgs_py.measurements import Measurements, received_attitude, received_readings

NS_PER_S = 1_000_000_000
MOMENTUM = 'wheel_momentum'


class FlightAnswer(NamedTuple):
    """One step's answer: the law's ``output`` kind (``torque`` or ``wheel_momentum``) and ``value``,
    its ``status``, the command ``values`` (wheel speeds in momentum mode), and for one run the body
    torque they ask for (``applied``) and the actuation's status values (``extra``)."""

    output: str
    value: np.ndarray
    status: dict
    values: Any
    applied: np.ndarray | None = None
    extra: dict = {}


class FlightStep:
    """A controller section's law and actuation (:meth:`adcs_controllers.families.ControllerFamily.build`)
    and its fault snapshots; ``name`` is the node's (in a FlightSoftwareError)."""

    def __init__(self, name: str, law, actuation) -> None:
        self.name, self.law, self.actuation = name, law, actuation
        self.faults = FaultTracker()
        self.needs_wheel_momentum = bool(getattr(law, 'needs_wheel_momentum', False))
        #: the step pairs its state with the wheel speeds of the same step (the law's h, or the allocation's)
        self.needs_wheel_speed = self.needs_wheel_momentum or bool(actuation.needs_wheel_speed)
        self.note = actuation.inform(law)   # what the law said of the actuators at start, or None

    @classmethod
    def build(cls, name: str, family, p: dict) -> 'FlightStep':
        return cls(name, *family.build(p))

    def apply_due_faults(self, t_ns: int) -> list[str]:
        """Follow the fault snapshot due at ``t_ns`` (if not yet in force): re-allocate over the usable
        actuators and tell the law; returns what to log (nothing when the usable actuators are unchanged)."""
        snapshot = self.faults.due(t_ns)
        if snapshot is None or not self.actuation.follow_faults(snapshot):
            return []
        note = self.actuation.inform(self.law)
        return [f't = {t_ns / NS_PER_S:g} s: allocating over {self.actuation.usable() or "no wheels"}',
                *([note] if note else [])]

    def control(self, t: float, q: np.ndarray, w: np.ndarray, h: np.ndarray | None = None):
        """The law's ``(output, status)`` for state (q, w) at ``t`` (with the wheel momentum ``h`` for a
        law that needs it)."""
        if self.needs_wheel_momentum:
            return self.law.control(t, q, w, h)
        return self.law.control(t, q, w)

    def step(self, t_ns: int, q: np.ndarray, w: np.ndarray, speed: np.ndarray | None = None,
             batch: bool = False, log: Callable[[str], None] | None = None) -> FlightAnswer:
        """The answer to the state (q, w) stamped ``t_ns`` (``speed``: the controller's wheels' speeds of
        the same step, when :attr:`needs_wheel_speed`). ``batch``: (q, w) as the truth model gives them
        (the received attitude is made here), a leading run axis, no refusal (module doc); else one
        run's decoded message. ``log`` gets the fault notes."""
        if not batch or self.faults.snapshots:   # a batch holds its schedule from the start: none, none due
            # (a node checks every step: a snapshot received late is counted, FaultTracker.late)
            notes = (self.apply_due_faults(t_ns) if batch
                     else answer(self.name, t_ns, lambda: self.apply_due_faults(t_ns)))
            if log is not None:
                for note in notes:
                    log(note)
        if batch:
            q = received_attitude(q)
        output = self.law.output   # torque or wheel momentum (a reconfiguring law's current phase)
        h = self.actuation.wheel_momentum(speed) if self.needs_wheel_momentum else None
        t = t_ns / NS_PER_S
        if batch:
            value, status = answer(self.name, t_ns, lambda: self.control(t, q, w, h))
            value = np.broadcast_to(value, np.shape(w)[:-1] + (3,))
        else:   # a law refusing the state or giving a non-finite output: LawOutputRejected, counted by the node
            value, status = answer(self.name, t_ns, lambda: checked_control(self, self.name, t, q, w, h),
                                   refusals=(LawOutputRejected,))
        if batch:   # the allocation's arithmetic on a batch is not wrapped (np.errstate costs ~us a step)
            values = (self.actuation.command_momentum(value) if output == MOMENTUM
                      else self.actuation.command_values(value, w, speed))
            return FlightAnswer(output, value, status, values)
        if output == MOMENTUM:
            return FlightAnswer(output, value, status, answer(self.name, t_ns,
                                                              lambda: self.actuation.command_momentum(value)))
        values, applied, extra = answer(self.name, t_ns, lambda: self.actuation.actuate(value, w, speed))
        return FlightAnswer(output, value, status, values, applied, extra)


class EstimationStep:
    """An estimator section's estimator (:meth:`adcs_controllers.estimators.families.EstimatorFamily.build`):
    the estimate of a step's readings through :func:`adcs_controllers.laws.failure.estimate_step`."""

    def __init__(self, name: str, estimator) -> None:
        self.name, self.estimator = name, estimator

    def step(self, m: Measurements, batch: bool = False):
        """``(Estimate, status)`` of the readings ``m`` (``batch``: as the truth model gives them, the
        message round trip made here, :func:`received_readings`; else one run's decoded messages)."""
        return estimate_step(self.name, self.estimator, received_readings(m) if batch else m)
