"""SnlcController: seed 000's two-wheel angular-velocity tracking law snlc (eq. 14/24) on the graph.

Two wheels from the start, or (``three_wheel.enabled``) the three-wheel PD until the fault topic
reports a wheel lost, then the two-wheel law. The laws: laws/underactuated.py; the switch:
laws/reconfiguration.py."""
from __future__ import annotations

from adcs_controllers.families import SNLC
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class SnlcController(ControllerNode):
    family = SNLC


main = entry_point(SnlcController)

if __name__ == '__main__':
    main()
