"""PD controller node: seed 004's benchmark law (eq. 13) on the graph. The law: laws/pd.py."""
from __future__ import annotations

from adcs_controllers.families import PD
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class PdController(ControllerNode):
    family = PD


main = entry_point(PdController)

if __name__ == '__main__':
    main()
