"""PointingAController: seed 003's controller A (single-axis pointing with two wheels and a
non-zero angular momentum) on the graph. The law: laws/single_axis.py (PointingALaw); it needs
the wheels' momentum of the same step, which the base class pairs by stamp (nodes/base.py)."""
from __future__ import annotations

from adcs_controllers.families import POINTING_A
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class PointingAController(ControllerNode):
    family = POINTING_A


main = entry_point(PointingAController)

if __name__ == '__main__':
    main()
