"""PD controller node: seed 004's benchmark law (eq. 13) on the graph. See laws/pd.py."""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.pd import pd_torque
from adcs_controllers.nodes.base import ControllerNode
from adcs_controllers.schemas import PD_SCHEMA
from adcs_sim.nodes.base import main_for


class PdController(ControllerNode):
    schema = PD_SCHEMA

    def __init__(self, context) -> None:
        super().__init__(context)
        p = self.params
        self.q_ref = np.asarray(p['target.attitude'], dtype=float)
        self.q_ref /= np.linalg.norm(self.q_ref)
        self.w_ref = np.asarray(p['target.rate'], dtype=float)

    def control(self, t, q, w):
        p = self.params
        u = pd_torque(q, w, self.inertia, p['kp'], p['kd'], self.q_ref, self.w_ref, p['shortest_path'])
        return u, {'mode': 'pd'}


def main(args=None) -> None:
    raise SystemExit(main_for(PdController, args))


if __name__ == '__main__':
    main()
