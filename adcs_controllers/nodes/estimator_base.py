"""The estimator-node template: the fitted sensors' messages of one step in, the estimate of that step
out, stamped with the sensors' stamp.

A concrete estimator is its family (:mod:`adcs_controllers.estimators.families`): a schema and an
estimator object with ``step(measurements) -> (Estimate, status)``, which the batch engine builds from
the same family, so it runs the very same object. The base class

* validates parameters (schema) and builds the estimator;
* before subscribing to the sensors, waits until ``estimate/state`` is matched by the controllers
  flying on it (``startup.estimate_subscribers``) and the recorder when one is expected, and
  ``estimator/status`` by the recorder: by the time the dynamics node sees this node's sensor
  subscriptions (it waits for them before t = 0), every estimate it sends is delivered and recorded;
* keeps each step's sensor messages by stamp (:class:`StampGroups`) and runs the step once every
  sensor it uses has delivered that stamp (lockstep: each sensor publishes every step, marked when
  it has no measurement), in stamp order;
* publishes ``estimate/state`` (:func:`~adcs_msgs_py.conversions_determination.estimate_to_msg`) and
  ``estimator/status`` (bias, NIS and innovation per sensor, measurements used, missing and rejected
  counts, rejected messages) stamped ``t_k``;
* rejects, counts and warns about bad messages (:mod:`adcs_msgs_py.guard`); a stamp that is not after
  the last step answered is rejected too. Noise levels come from the parameters, never from the
  messages' covariances.
* stops the run when the filter cannot answer a step (it raises, or its estimate is not finite:
  :class:`~adcs_controllers.nodes.base.FlightSoftwareStop`, exit status 6 naming the node, the
  time and the error): what reaches the filter has passed the message checks, so the failure is
  its own arithmetic, and every later step would wait out the lockstep timeout.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.estimators.families import EstimatorFamily
from adcs_controllers.nodes.base import FlightSoftwareStop
from adcs_controllers.step import EstimationStep
from adcs_msgs_py import cdr
from adcs_msgs_py import conversions_determination as cd
from adcs_msgs_py import topics
from adcs_msgs_py.conversions import InvalidMessage
from adcs_msgs_py.measurements import Measurements
from adcs_msgs_py.names import SENSOR_TOPICS
from adcs_msgs_py.node import AdcsNode

FROM_MSG = {name: codec.from_msg for name, codec in cd.SENSOR_CODECS.items()}


class StampGroups:
    """Groups one message per name by stamp, whichever arrives first: :meth:`add` returns
    ``{name: value}`` once every name has the stamp, and drops the older stamps (they can no longer
    be completed in order); incomplete stamps are kept up to ``keep``."""

    def __init__(self, names, keep: int = 8) -> None:
        self.names = tuple(names)
        self.keep = keep
        self.pending: dict[int, dict] = {}   # stamp -> {name: value}

    def add(self, name: str, t_ns: int, value) -> dict | None:
        group = self.pending.setdefault(t_ns, {})
        group[name] = value
        if len(group) == len(self.names):
            for old in [s for s in self.pending if s <= t_ns]:
                del self.pending[old]
            return group
        while len(self.pending) > self.keep:
            del self.pending[min(self.pending)]
        return None


def _plain(value):
    """A status value as status_to_msg writes it: numpy scalars and 0-d arrays as Python scalars."""
    return value.item() if isinstance(value, (np.ndarray, np.generic)) else value


class EstimatorNode(FlightSoftwareStop, AdcsNode):
    """Base class of the estimator nodes. Subclasses set ``family``
    (:class:`~adcs_controllers.estimators.families.EstimatorFamily`)."""

    family: EstimatorFamily

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        cls.schema = cls.family.schema

    def __init__(self, context, references=None) -> None:
        super().__init__(context)
        # the estimation step (adcs_controllers/step.py): the object the batch engine drives too
        self.flight = EstimationStep(self.get_name(), self.family.build(self.params, references))
        self.estimator = self.flight.estimator
        self.sensors = tuple(self.params['sensors'])
        self.pub_estimate = self.publisher(topics.ESTIMATE_STATE)
        self.pub_status = self.publisher(topics.ESTIMATOR_STATUS)
        self.groups = StampGroups(self.sensors)
        self.subs: dict = {}
        self.steps = 0              # steps answered (the acknowledgement pacing counts them)
        self.last_ns: int | None = None

    def connect(self, executor) -> None:
        """Wait for the estimate's subscribers (the recorder's readers too: spinning ``executor``),
        then subscribe to the sensors."""
        p = self.params
        recorder = 1 if p['startup.expect_recorder'] else 0
        self.wait_for_publishers({self.pub_estimate: p['startup.estimate_subscribers'] + recorder,
                                  self.pub_status: recorder}, p['startup.timeout'])
        self.wait_recorder_matched([self.pub_estimate, self.pub_status], executor)
        for name in self.sensors:
            self.subs[name] = self.subscription(SENSOR_TOPICS[name], lambda msg, n=name: self._on_sensor(n, msg))

    def run(self, executor) -> None:
        self.connect(executor)
        self.spin(executor)

    def _on_sensor(self, name: str, msg) -> None:
        topic = SENSOR_TOPICS[name]
        parsed = self.rejects.accept(topic, lambda: self._checked(name, msg))
        if parsed is None:
            return
        group = self.groups.add(name, *parsed)
        if group is not None:
            self.step(parsed[0], group)

    def _checked(self, name: str, msg):
        t_ns, reading = FROM_MSG[name](msg, SENSOR_TOPICS[name])
        if self.last_ns is not None and t_ns <= self.last_ns:
            raise InvalidMessage(f'{SENSOR_TOPICS[name]}: stamp {t_ns} ns is not after the last step '
                                 f'answered ({self.last_ns} ns)')
        return t_ns, reading

    def step(self, t_ns: int, readings: dict) -> None:
        """Run the family's step on the sensors' readings stamped ``t_ns``; publish its estimate and status."""
        self.steps += 1
        self.last_ns = t_ns
        self.answer_step(self.steps, lambda: self._answer(t_ns, readings), (self.pub_estimate, self.pub_status))

    def _answer(self, t_ns: int, readings: dict) -> None:
        est, status = self.flight.step(Measurements(t_ns, **readings))
        self.pub_estimate.publish(cd.estimate_to_msg(est))
        if self.pub_status.get_subscription_count():   # after the estimate: off the critical path
            values = {k: _plain(v) for k, v in status.items()}
            values['used'] = ','.join(n for n in self.sensors if values.get(f'used_{n}')) or 'none'
            values['rejected_messages'] = self.rejects.total
            self.pub_status.publish(cdr.status_bytes(t_ns, self.get_name(), values))   # status_to_msg's bytes
