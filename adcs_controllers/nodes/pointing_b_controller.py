"""PointingBController: seed 003's controller B (single-axis pointing with two wheels and a
non-zero angular momentum) on the graph. The law: laws/single_axis.py (PointingBLaw); it needs
the wheels' momentum of the same step, which the base class pairs by stamp (nodes/base.py)."""
from __future__ import annotations

from adcs_controllers.families import POINTING_B
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class PointingBController(ControllerNode):
    family = POINTING_B


main = entry_point(PointingBController)

if __name__ == '__main__':
    main()
