"""PointingAController: seed 003's controller A (single-axis pointing with two wheels and a
non-zero angular momentum) on the graph. The law: laws/single_axis.py (PointingALaw); it needs
the wheels' momentum of the same step, which the base class pairs by stamp (nodes/base.py)."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import POINTING_A_SCHEMA
from adcs_sim.nodes.base import entry_point


class PointingAController(ControllerNode):
    schema = POINTING_A_SCHEMA  # law: single_axis.PointingALaw (adcs_sim.registry)


main = entry_point(PointingAController)

if __name__ == '__main__':
    main()
