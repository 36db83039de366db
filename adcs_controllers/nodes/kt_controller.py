"""KtController: the Krstic-Tsiotras inverse-optimal law (seed 004 eq. 18) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.families import KT
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class KtController(ControllerNode):
    family = KT


main = entry_point(KtController)

if __name__ == '__main__':
    main()
