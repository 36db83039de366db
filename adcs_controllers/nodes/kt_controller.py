"""KtController: the Krstic-Tsiotras inverse-optimal law (seed 004 eq. 18) on the graph.

The law: laws/inverse_optimal.py."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import KT_SCHEMA
from adcs_sim.nodes.base import entry_point


class KtController(ControllerNode):
    schema = KT_SCHEMA  # law: adcs_controllers.laws.inverse_optimal.KtLaw (adcs_sim.registry)


main = entry_point(KtController)

if __name__ == '__main__':
    main()
