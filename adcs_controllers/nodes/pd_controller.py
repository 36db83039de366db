"""PD controller node: seed 004's benchmark law (eq. 13) on the graph. The law: laws/pd.py."""
from __future__ import annotations

from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import PD_SCHEMA
from adcs_sim.nodes.base import entry_point


class PdController(ControllerNode):
    schema = PD_SCHEMA  # law: adcs_controllers.laws.pd.PdLaw (adcs_sim.registry)


main = entry_point(PdController)

if __name__ == '__main__':
    main()
