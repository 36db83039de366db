"""GsmnController: seed 004's gain-scheduled minimum-norm law (eq. 17) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.families import GSMN
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class GsmnController(ControllerNode):
    family = GSMN


main = entry_point(GsmnController)

if __name__ == '__main__':
    main()
