"""Parameter schemas of the controller nodes (pure; the runner validates files with them)."""
from __future__ import annotations

from adcs_msgs_py.params import Param, Schema, non_negative, positive
from adcs_sim.scenario import (check_unit_quaternion, check_wheels, inertia_param, startup_params,
                               wheel_params)


def _actuator_check(v: dict) -> None:
    from adcs_msgs_py.params import ParameterError
    if v['actuator'] == 'wheels':
        check_wheels(v, with_physics=False)
        if not v['wheels.names']:
            raise ParameterError('wheels.names', "actuator 'wheels' needs the wheel names, axes and "
                                 'torque limits (the controller\'s model of the wheels)')


def controller_params() -> list[Param]:
    """Parameters every controller node has: its actuators and the startup handshake."""
    return [
        Param('actuator', 'string', default='wheels', choices=('wheels', 'torquers'),
              doc='command reaction wheels (wheels/cmd) or ideal torquers (torque_cmd)'),
        *wheel_params(with_physics=False),
        Param('saturation', 'string', default='clip', choices=('clip', 'scale'),
              doc='torque saturation: per actuator (clip) or whole vector (scale)'),
        Param('torquers.max_torque', 'double', default=float('inf'), check=positive, finite=False,
              doc='torquer limit per axis (N m; .inf for none) when actuator is torquers', batch=True),
        *startup_params(),
    ]


PD_SCHEMA = Schema('pd_controller', [
    inertia_param("the controller's inertia model (kg m^2): 3 principal moments or 9 entries"),
    Param('kp', 'double', check=non_negative, doc='proportional gain (1/s^2), multiplied by the inertia', batch=True),
    Param('kd', 'double', check=non_negative, doc='derivative gain (1/s), multiplied by the inertia', batch=True),
    Param('target.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
          check=check_unit_quaternion, doc='commanded attitude [x, y, z, w]', batch=True),
    Param('target.rate', 'double_array', default=[0.0, 0.0, 0.0], length=3, doc='commanded rate (rad/s)', batch=True),
    Param('shortest_path', 'bool', default=False,
          doc='flip q when q4 < 0 (not in seed 004 eq. 13, which is applied as printed by default)'),
    *controller_params(),
], cross_check=_actuator_check, doc='quaternion PD benchmark law, seed 004 eq. (13)')
