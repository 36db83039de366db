"""MinNormController: seed 004's standard minimum-norm law (eq. 14) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.families import MINNORM
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class MinNormController(ControllerNode):
    family = MINNORM


main = entry_point(MinNormController)

if __name__ == '__main__':
    main()
