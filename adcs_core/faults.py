"""Fault schedule bookkeeping shared by the nodes that act on faults (pure, no ROS).

Design (deterministic in lockstep): the fault injector publishes its **whole schedule at start**
on the latched ``faults`` topic, one DiagnosticArray per distinct event time, stamped with that
time, each the full state of every actuator after the events up to it, numbered ``event`` of
``events``. A node that acts on faults (the dynamics node, the controllers) collects them
(:class:`FaultTracker`), waits before t = 0 until it has all of them (``startup.expect_faults``),
and at each step ``t_k`` applies the latest snapshot whose stamp is ``<= t_k``: a fault stamped
``t_k`` holds over ``[t_k, t_k+1]``; one stamped between two steps applies from the next step.
A snapshot that arrives after the step it was due at (no complete schedule before the run) is
applied at the next step boundary and counted as *late*.
"""
from __future__ import annotations

from typing import NamedTuple


class FaultState(NamedTuple):
    """One actuator's fault state in a snapshot: ``mode`` (FAULT_ERROR_MODES or FAULT_OK_MODES),
    ``value`` (degraded torque limit or bias torque, N m; 0 otherwise) and ``time`` (s) of its
    last event. A snapshot is ``{actuator name: FaultState}``: the schedule's
    (:func:`adcs_sim.truth.fault_schedule.fault_schedule`) and a ``faults`` message's
    (:func:`adcs_msgs_py.conversions.faults_from_msg`) alike."""

    mode: str
    value: float = 0.0
    time: float = 0.0


NOMINAL = FaultState('nominal')


class FaultTracker:
    """Received fault snapshots and which one applies at a step."""

    def __init__(self) -> None:
        self.snapshots: dict[int, tuple[int, dict]] = {}  # event index -> (t_ns, {name: FaultState})
        self.events: int | None = None
        self.applied = -1           # index of the snapshot in force
        self._current: int | None = None
        self._previous: int | None = None
        self.late = 0

    def add(self, t_ns: int, event: int, events: int, snapshot: dict) -> None:
        if events > 0:
            self.events = events
        self.snapshots[event] = (t_ns, snapshot)

    def hold(self, schedule: list) -> None:
        """Hold a whole schedule ``[(t_ns, snapshot)]`` (:func:`adcs_sim.truth.fault_schedule.fault_schedule`),
        as a node holds it once the latched ``faults`` topic has delivered every snapshot (the batch engine's way)."""
        for i, (t_ns, snapshot) in enumerate(schedule):
            self.add(t_ns, i, len(schedule), snapshot)

    def rewind(self) -> None:
        """Back to before t = 0: no snapshot in force (a batch engine's new run)."""
        self.applied, self._current, self._previous, self.late = -1, None, None, 0

    @property
    def complete(self) -> bool:
        return self.events is not None and all(i in self.snapshots for i in range(self.events))

    def due(self, step_ns: int) -> dict | None:
        """The snapshot to apply at step ``step_ns`` if it differs from the one in force, else None.

        May be called more than once per step (before publishing the step's state and again
        before integrating it, to catch a late arrival)."""
        if step_ns != self._current:
            self._previous, self._current = self._current, step_ns
        latest, newly = self.applied, []
        for i, (t_ns, _) in self.snapshots.items():
            if t_ns <= step_ns and i > self.applied:
                newly.append(t_ns)
                latest = max(latest, i)
        if latest == self.applied:
            return None
        if self._previous is not None:
            self.late += sum(1 for t_ns in newly if t_ns <= self._previous)
        self.applied = latest
        return self.snapshots[latest][1]


# Wheel states carried on FAULTS (one status per actuator): the faults (level ERROR) and the
# nominal states (level OK). The plant, the fault schedule and the message conversions share them.
FAULT_ERROR_MODES = ('failed', 'degraded', 'bias', 'stuck')


FAULT_OK_MODES = ('nominal', 'recovered')


# Faults under which a wheel produces no commanded torque: controllers allocate around it.
FAULT_UNUSABLE_MODES = ('failed', 'stuck')

# Sensor faults (issue 20): their targets and modes are declared with each sensor's interface
# (adcs_msgs_py.sensor_interfaces: SENSOR_FAULT_MODES, split_snapshot).
