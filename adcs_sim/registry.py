"""The node executables of the package: section name -> module and parameter schema.

A scenario file has one section per node, named like the executable (``dynamics``,
``pd_controller``, ``recorder``); the runner starts exactly those. A controller's entry also
names its pure law class: the node and the batch engine (:mod:`adcs_sim.batch`) both build it. Keep in step with setup.py's
``NODES`` (a test checks it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from adcs_msgs_py.params import Schema
from adcs_controllers.laws.backstepping import BacksteppingLaw, ThrusterActuation
from adcs_controllers.laws.inertia_free import M2rLaw, M2sLaw
from adcs_controllers.laws.inverse_optimal import GsmnLaw, KtLaw, MinNormLaw
from adcs_controllers.laws.pd import PdLaw
from adcs_controllers.laws.reconfiguration import TwoWheelReconfiguration
from adcs_controllers.laws.single_axis import PointingALaw, PointingBLaw
from adcs_controllers.laws.underactuated import SnlcGsmnLaw, SnlcLaw, SnlcMinNormLaw, ZeroMomentumLaw
from adcs_controllers.schemas import (BACKSTEPPING_SCHEMA, GSMN_SCHEMA, KT_SCHEMA, M2R_SCHEMA, M2S_SCHEMA,
                                      MINNORM_SCHEMA, PD_SCHEMA, POINTING_A_SCHEMA, POINTING_B_SCHEMA,
                                      SNLC_GSMN_SCHEMA, SNLC_MINNORM_SCHEMA, SNLC_SCHEMA, ZERO_MOMENTUM_SCHEMA)
from adcs_sim.scenario import DYNAMICS_SCHEMA, FAULT_SCHEMA, RECORDER_SCHEMA


def _pointing(law_class):
    """Seed 003's laws from a validated section: the section's ``momentum`` is the law's ``H``."""
    def build(p: dict):
        return law_class({**p, 'H': p['momentum']})
    build.__name__ = f'{law_class.__name__}_from_section'
    return build


@dataclass(frozen=True)
class NodeInfo:
    module: str
    schema: Schema
    role: str  # 'dynamics', 'controller' (subscribes to state, sends commands), 'recorder', 'faults'
    law: Any = None  # controllers: the pure law class (or builder), called with the validated section
    actuation: Any = None  # controllers with their own actuators (seed 002's thrusters): its builder


NODES: dict[str, NodeInfo] = {
    'dynamics': NodeInfo('adcs_sim.nodes.dynamics', DYNAMICS_SCHEMA, 'dynamics'),
    'recorder': NodeInfo('adcs_sim.nodes.recorder', RECORDER_SCHEMA, 'recorder'),
    'fault_injector': NodeInfo('adcs_sim.nodes.fault_injector', FAULT_SCHEMA, 'faults'),
    'pd_controller': NodeInfo('adcs_controllers.nodes.pd_controller', PD_SCHEMA, 'controller', PdLaw),
    'minnorm_controller': NodeInfo('adcs_controllers.nodes.minnorm_controller', MINNORM_SCHEMA,
                                   'controller', MinNormLaw),
    'gsmn_controller': NodeInfo('adcs_controllers.nodes.gsmn_controller', GSMN_SCHEMA, 'controller', GsmnLaw),
    'kt_controller': NodeInfo('adcs_controllers.nodes.kt_controller', KT_SCHEMA, 'controller', KtLaw),
    # seed 000: two wheels (optionally after a three-wheel PD phase, switching on a wheel fault)
    'zero_momentum_controller': NodeInfo('adcs_controllers.nodes.zero_momentum_controller', ZERO_MOMENTUM_SCHEMA,
                                         'controller', TwoWheelReconfiguration.factory(ZeroMomentumLaw)),
    'snlc_controller': NodeInfo('adcs_controllers.nodes.snlc_controller', SNLC_SCHEMA, 'controller',
                                TwoWheelReconfiguration.factory(SnlcLaw)),
    'snlc_minnorm_controller': NodeInfo('adcs_controllers.nodes.snlc_minnorm_controller', SNLC_MINNORM_SCHEMA,
                                        'controller', TwoWheelReconfiguration.factory(SnlcMinNormLaw)),
    'snlc_gsmn_controller': NodeInfo('adcs_controllers.nodes.snlc_gsmn_controller', SNLC_GSMN_SCHEMA,
                                     'controller', TwoWheelReconfiguration.factory(SnlcGsmnLaw)),
    # seed 001: inertia-free laws on ideal external torquers
    'm2r_controller': NodeInfo('adcs_controllers.nodes.m2r_controller', M2R_SCHEMA, 'controller', M2rLaw),
    'm2s_controller': NodeInfo('adcs_controllers.nodes.m2s_controller', M2S_SCHEMA, 'controller', M2sLaw),
    # seed 003: single-axis pointing, two wheels, non-zero momentum (laws need the wheel momentum)
    'pointing_a_controller': NodeInfo('adcs_controllers.nodes.pointing_a_controller', POINTING_A_SCHEMA,
                                      'controller', _pointing(PointingALaw)),
    'pointing_b_controller': NodeInfo('adcs_controllers.nodes.pointing_b_controller', POINTING_B_SCHEMA,
                                      'controller', _pointing(PointingBLaw)),
    # seed 002: thrusters + pitch wheel, backstepping tracking
    'backstepping_controller': NodeInfo('adcs_controllers.nodes.backstepping_controller', BACKSTEPPING_SCHEMA,
                                        'controller', BacksteppingLaw, ThrusterActuation),
}
