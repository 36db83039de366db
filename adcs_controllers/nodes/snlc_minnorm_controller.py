"""SnlcMinNormController: seed 000's two-wheel min-norm law on the snlc benchmark (eq. 25-27) on the graph.

Two wheels from the start, or (``three_wheel.enabled``) the three-wheel PD until the fault topic
reports a wheel lost, then the two-wheel law. The laws: laws/underactuated.py; the switch:
laws/reconfiguration.py."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import SNLC_MINNORM_SCHEMA
from adcs_sim.nodes.base import entry_point


class SnlcMinNormController(ControllerNode):
    schema = SNLC_MINNORM_SCHEMA  # law: TwoWheelReconfiguration around underactuated.SnlcMinNormLaw (adcs_sim.registry)


main = entry_point(SnlcMinNormController)

if __name__ == '__main__':
    main()
