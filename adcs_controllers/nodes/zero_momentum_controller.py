"""ZeroMomentumController: seed 000's two-wheel zero-momentum law (eq. 12-13; wheel speed commands) on the graph.

Two wheels from the start, or (``three_wheel.enabled``) the three-wheel PD until the fault topic
reports a wheel lost, then the two-wheel law. The laws: laws/underactuated.py; the switch:
laws/reconfiguration.py."""
from __future__ import annotations

from adcs_controllers.families import ZERO_MOMENTUM
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class ZeroMomentumController(ControllerNode):
    family = ZERO_MOMENTUM


main = entry_point(ZeroMomentumController)

if __name__ == '__main__':
    main()
