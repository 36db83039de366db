"""BacksteppingController: seed 002's quaternion integrator backstepping on the graph.

The law (:class:`adcs_controllers.laws.backstepping.BacksteppingLaw`, eq. 22-35, with the section
4.2 reference: the target relative to the orbit frame at t = 0, then held inertially) and the
actuation (:class:`~adcs_controllers.laws.backstepping.ThrusterActuation`: eq. 20-21 pseudo-inverse
allocation over four thrusters and the pitch wheel, bang-bang firing with a deadzone) are its
family's (:data:`adcs_controllers.families.BACKSTEPPING`), the objects the batch engine runs.

The common controller node (:class:`~adcs_controllers.nodes.base.ControllerNode`) runs them. Per
step ``t_k`` the allocation needs the state (``state``) and the wheel speed (``wheels/state``,
:attr:`~adcs_controllers.laws.backstepping.ThrusterActuation.needs_wheel_speed`): the node pairs
the two messages by stamp, whichever arrives first, then publishes ``thrusters/cmd`` (on-times
for ``[t_k, t_k+1]``) and ``wheels/cmd`` (motor torque), both stamped ``t_k``, and
``controller/status`` with V1, V2 (eq. 27, 31), W (eq. 33), η̃, the eigenaxis error, the torque
the commands ask for (u_x, u_y, u_z), the number of thrusters firing and the firing count so far
(thruster-periods).
"""
from __future__ import annotations

from adcs_controllers.families import BACKSTEPPING
from adcs_controllers.nodes.base import ControllerNode
from adcs_msgs_py.node import entry_point


class BacksteppingController(ControllerNode):
    family = BACKSTEPPING  # law: BacksteppingLaw, actuation: ThrusterActuation


main = entry_point(BacksteppingController)

if __name__ == '__main__':
    main()
