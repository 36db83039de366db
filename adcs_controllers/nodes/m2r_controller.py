"""M2rController: seed 001's inertia-free motion-to-rest law (eq. 11-25) on the graph.

Commands the external torquers (``torque_cmd``); the gains are checked at start against the torque
bound of Proposition 1 or 2 for the torquer limit. The law: laws/motion_to_rest.py."""
from __future__ import annotations

from adcs_controllers.families import M2R
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class M2rController(ControllerNode):
    family = M2R


main = entry_point(M2rController)

if __name__ == '__main__':
    main()
