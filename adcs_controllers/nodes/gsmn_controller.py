"""GsmnController: seed 004's gain-scheduled minimum-norm law (eq. 17) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import GSMN_SCHEMA
from adcs_sim.nodes.base import entry_point


class GsmnController(ControllerNode):
    schema = GSMN_SCHEMA  # law: adcs_controllers.laws.inverse_optimal.GsmnLaw (adcs_sim.registry)


main = entry_point(GsmnController)

if __name__ == '__main__':
    main()
