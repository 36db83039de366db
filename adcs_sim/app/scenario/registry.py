"""The node executables of the package: section name -> module, parameter schema and role.

A scenario file has one section per node, named like the executable (``dynamics``,
``pd_controller``, ``recorder``); the runner starts exactly those. The simulator's own nodes are
listed here; the estimators are their families (:data:`adcs_controllers.estimators.families.ESTIMATOR_FAMILIES`:
schema, estimator); the controllers are their families (:data:`adcs_controllers.families.FAMILIES`: schema,
law, actuation), which the node and the batch engine (:mod:`adcs_sim.app.batch.engine`) both build. Keep in
step with setup.py's ``NODES`` (a test checks it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from adcs_controllers.estimators.families import ESTIMATOR_FAMILIES, EstimatorFamily
from adcs_controllers.families import FAMILIES, ControllerFamily
from adcs_msgs_py.params import Schema
from adcs_sim.bag.schema import RECORDER_SCHEMA
from adcs_sim.truth.fault_schedule import FAULT_SCHEMA
from adcs_sim.truth.schema import DYNAMICS_SCHEMA


@dataclass(frozen=True)
class NodeInfo:
    module: str
    schema: Schema
    role: str  # 'dynamics', 'controller' (subscribes to state, sends commands), 'recorder', 'faults',
    #            'estimator' (subscribes to the sensors, publishes estimate/state)
    family: ControllerFamily | EstimatorFamily | None = None  # controllers: schema, law and actuation;
    #                                                           estimators: schema and estimator

    @property
    def law(self) -> Any:
        return getattr(self.family, 'law', None)


NODES: dict[str, NodeInfo] = {
    'dynamics': NodeInfo('adcs_sim.nodes.dynamics', DYNAMICS_SCHEMA, 'dynamics'),
    'recorder': NodeInfo('adcs_sim.nodes.recorder', RECORDER_SCHEMA, 'recorder'),
    'fault_injector': NodeInfo('adcs_sim.nodes.fault_injector', FAULT_SCHEMA, 'faults'),
    **{name: NodeInfo(f.module, f.schema, 'controller', f) for name, f in FAMILIES.items()},
    **{name: NodeInfo(f.module, f.schema, 'estimator', f) for name, f in ESTIMATOR_FAMILIES.items()},
}
