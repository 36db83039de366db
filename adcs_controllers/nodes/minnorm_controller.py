"""MinNormController: seed 004's standard minimum-norm law (eq. 14) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import MINNORM_SCHEMA
from adcs_sim.nodes.base import entry_point


class MinNormController(ControllerNode):
    schema = MINNORM_SCHEMA  # law: adcs_controllers.laws.inverse_optimal.MinNormLaw (adcs_sim.registry)


main = entry_point(MinNormController)

if __name__ == '__main__':
    main()
