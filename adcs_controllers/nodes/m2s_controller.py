"""M2sController: seed 001's adaptive motion-to-spin compensator (Theorem 2, eq. 31-46) on the graph.

Commands the external torquers (``torque_cmd``) with cutoff or scaling saturation, the varying
adaptation gain and extremum tracking as configured. The compensator's estimator states live in
the law object and are integrated between state messages (continuous time). The law:
laws/motion_to_spin.py (saturation and VAG: laws/saturation.py)."""
from __future__ import annotations

from adcs_controllers.families import M2S
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class M2sController(ControllerNode):
    family = M2S


main = entry_point(M2sController)

if __name__ == '__main__':
    main()
