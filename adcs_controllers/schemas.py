"""Parameter schemas of the controller nodes (pure; the runner validates files with them)."""
from __future__ import annotations

from adcs_msgs_py.params import Param, Schema, non_negative, positive
from adcs_sim.scenario import (check_unit_quaternion, check_wheels, expect_faults_param, inertia_param,
                               startup_params, wheel_params)


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
        expect_faults_param(),
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


def _target_params() -> list[Param]:
    """The regulation target and the sign convention of the attitude error (every law has them)."""
    return [
        Param('target.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
              check=check_unit_quaternion, batch=True, doc='commanded attitude [x, y, z, w]'),
        Param('target.rate', 'double_array', default=[0.0, 0.0, 0.0], length=3, batch=True,
              doc='commanded rate (rad/s)'),
    ]


def _gain(name: str, doc: str) -> Param:
    return Param(name, 'double', check=positive, batch=True, doc=doc)


_INERTIA_MODEL = "the controller's inertia model I (kg m^2): 3 principal moments or 9 entries"
_SHORTEST = Param('shortest_path', 'bool', default=False,
                  doc='flip q when q4 < 0 (not in seed 004, whose laws are applied as printed by default)')

MINNORM_SCHEMA = Schema('minnorm_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('kp', 'PD gain of the reference torque u_PD = -kp I q - kd I w (1/s^2)'),
    _gain('kd', 'PD gain of the reference torque (1/s)'),
    _gain('gamma', 'cross-term weight of the Lyapunov function, eq. (15) (1/s)'),
    *_target_params(), _SHORTEST,
    *controller_params(),
], cross_check=_actuator_check, doc='standard minimum-norm law, seed 004 eq. (14) with V of eq. (15)')

GSMN_SCHEMA = Schema('gsmn_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('kp1', 'low (benchmark) proportional gain, multiplied by I (1/s^2)'),
    _gain('kd1', 'low (benchmark) derivative gain, multiplied by I (1/s)'),
    _gain('kp2', 'high proportional gain, multiplied by I (1/s^2)'),
    _gain('kd2', 'high derivative gain, multiplied by I (1/s)'),
    _gain('gamma', 'cross-term weight of the Lyapunov function, eq. (15) (1/s)'),
    Param('epsilon', 'double', check=positive, batch=True,
          doc='switching threshold on |u2|_inf (N m): high gains below it (eq. 17)'),
    *_target_params(), _SHORTEST,
    *controller_params(),
], cross_check=_actuator_check, doc='gain-scheduled minimum-norm law, seed 004 eq. (17)')

KT_SCHEMA = Schema('kt_controller', [
    inertia_param(_INERTIA_MODEL),
    _gain('k1', 'Krstic-Tsiotras gain k1 (1/s)'),
    _gain('k2', 'Krstic-Tsiotras gain k2 (1/s)'),
    *_target_params(),
    *controller_params(),
], cross_check=_actuator_check, doc='Krstic-Tsiotras inverse-optimal law, seed 004 eq. (18)')
