"""Property-based fuzzing (hypothesis) of every control law and of the message validation.

The guarantee (README "What survives what", issue #10 item 6): with random and extreme inputs —
NaN, Inf, huge rates, quaternions near −1 and non-unit, the two-wheel laws' singular set
q1² + q2² = 0, saturated or failed wheels, zero torque limits — no exception escapes, and every
output is finite or the input is rejected with a reason:

* message validation (``adcs_msgs_py.conversions``) either returns finite values (a unit
  quaternion) or raises ``InvalidMessage`` with a non-empty reason;
* every law on the graph (all of ``adcs_sim.app.scenario.registry``), given what validation lets through (a
  unit quaternion, finite rates of any size), returns a finite torque / wheel momentum, and the
  actuation turns it into finite commands inside the limits, whatever wheels are left;
* the pure laws not yet on the graph (inertia-free M2R / M2S, backstepping, single-axis pointing)
  return finite outputs or refuse with a ``ValueError`` naming the reason;
* the controller node's last line of defence (:func:`adcs_controllers.laws.base.checked_output`)
  refuses a non-finite law output with a reason instead of publishing it.

Deterministic in CI: the ``adcs-fuzz`` profile derandomizes (examples are a function of the test
source) and keeps example counts modest (the file runs in well under a minute).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from adcs_controllers.families import M2R_SCHEMA, M2S_SCHEMA
from adcs_controllers.laws import backstepping as bs
from adcs_controllers.laws import single_axis as sa
from adcs_controllers.laws.allocation import ACTUATION_KINDS, WheelActuation
from adcs_controllers.laws.base import LawOutputRejected, checked_control, checked_output
from adcs_controllers.laws.motion_to_rest import M2rLaw
from adcs_controllers.laws.motion_to_spin import M2sLaw
from adcs_core.attitude import error_quaternion
from adcs_msgs_py import conversions as cv
from adcs_msgs_py.params import REQUIRED, flatten
from adcs_sim.app.scenario.registry import NODES

settings.register_profile('adcs-fuzz', derandomize=True, max_examples=60, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow], database=None)
settings.load_profile('adcs-fuzz')

CONFIG = Path(__file__).resolve().parents[1] / 'config'

# --- strategies ---------------------------------------------------------------------------------

ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, width=64)
FINITE = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
RATE = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, -0.0, 1e-300, 1e3, -1e3]))


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


@st.composite
def unit_quaternions(draw):
    """Unit quaternions with the corners weighted in: near −1 (w ≈ −1), the identity, 180° turns,
    and the two-wheel laws' singular set q1 = q2 = 0 (rotations about z)."""
    kind = draw(st.sampled_from(['random', 'near_minus_one', 'singular_z', 'half_turn', 'identity']))
    if kind == 'identity':
        return np.array([0.0, 0.0, 0.0, draw(st.sampled_from([1.0, -1.0]))])
    if kind == 'singular_z':
        a = draw(st.floats(-math.pi, math.pi))
        return np.array([0.0, 0.0, math.sin(a), math.cos(a)])
    if kind == 'half_turn':
        v = draw(st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3))
        return np.r_[_unit(v), 0.0]
    v = draw(st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 1e-3))
    q = _unit(v)
    if kind == 'near_minus_one':
        eps = draw(st.floats(0.0, 1e-6))
        q = _unit(np.r_[eps * q[:3], -1.0])
    return q


RATES = st.lists(RATE, min_size=3, max_size=3).map(np.array)


# --- message validation ---------------------------------------------------------------------------

def _check_rejected_or_finite(convert):
    """Either InvalidMessage with a reason, or an all-finite result."""
    try:
        out = convert()
    except cv.InvalidMessage as exc:
        assert str(exc).strip(), 'rejected without a reason'
        return None
    for part in out:
        if isinstance(part, np.ndarray):
            assert np.all(np.isfinite(part)), out
    return out


@given(st.lists(ANY_FLOAT, min_size=4, max_size=4), st.lists(ANY_FLOAT, min_size=3, max_size=3),
       st.integers(0, 2**31 - 1), st.integers(0, 999_999_999))
def test_state_validation_rejects_or_returns_a_finite_unit_quaternion(q, w, sec, nanosec):
    from nav_msgs.msg import Odometry
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = q
    a = msg.twist.twist.angular
    a.x, a.y, a.z = w
    out = _check_rejected_or_finite(lambda: cv.state_from_msg(msg))
    if out is not None:
        t_ns, q_out, w_out = out
        assert t_ns == sec * cv.NS_PER_S + nanosec
        assert abs(np.linalg.norm(q_out) - 1.0) < 1e-12
        assert abs(np.linalg.norm(q) - 1.0) <= cv.UNIT_QUATERNION_TOLERANCE * 1.0001


@given(unit_quaternions(), RATES)
def test_state_validation_accepts_every_unit_quaternion_and_finite_rate(q, w):
    msg = cv.state_to_msg(123, q, w)
    t_ns, q_out, w_out = cv.state_from_msg(msg)
    assert t_ns == 123
    np.testing.assert_allclose(q_out, q, atol=1e-15)
    np.testing.assert_array_equal(w_out, w)


@given(unit_quaternions(), st.floats(1e-5, 10.0), st.sampled_from([1.0, -1.0]))
def test_non_unit_quaternion_is_rejected_with_its_norm(q, scale, sign):
    from nav_msgs.msg import Odometry
    factor = 1.0 + sign * scale
    # a factor of -1 (scale 2, sign -1) gives -q: a unit quaternion, rightly accepted
    assume(abs(abs(factor) - 1.0) > 2 * cv.UNIT_QUATERNION_TOLERANCE)
    bad = q * factor
    msg = cv.state_to_msg(0, [0, 0, 0, 1], [0, 0, 0], Odometry())
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in bad)
    with pytest.raises(cv.InvalidMessage, match='norm'):
        cv.state_from_msg(msg)


WHEELS = {'rw_x': 0, 'rw_y': 1, 'rw_z': 2}


@given(st.lists(st.sampled_from(['rw_x', 'rw_y', 'rw_z', 'rw_q', '']), max_size=4),
       st.lists(ANY_FLOAT, max_size=5), st.lists(ANY_FLOAT, max_size=5))
def test_wheel_command_validation(names, effort, velocity):
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, effort=effort, velocity=velocity)
    out = _check_rejected_or_finite(lambda: cv.wheel_cmd_from_msg(msg, WHEELS))
    if out is not None:
        _, index, values, mode = out
        assert len(index) == len(values) == len(names) == len(set(names))
        assert mode in ('torque', 'speed')


@given(st.lists(st.sampled_from(['rw_x', 'rw_y', 'rw_z']), max_size=3),
       st.lists(ANY_FLOAT, max_size=4), st.lists(ANY_FLOAT, max_size=4), st.lists(ANY_FLOAT, max_size=4))
def test_wheel_state_validation(names, position, velocity, effort):
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    _check_rejected_or_finite(lambda: cv.wheel_state_from_msg(msg))


@given(st.lists(ANY_FLOAT, min_size=3, max_size=3))
def test_torque_command_validation(v):
    from geometry_msgs.msg import Vector3Stamped
    msg = Vector3Stamped()
    msg.vector.x, msg.vector.y, msg.vector.z = v
    out = _check_rejected_or_finite(lambda: cv.vector_from_msg(msg))
    assert (out is None) == (not all(map(math.isfinite, v)))


@given(st.sampled_from(['rw_x', 'rw_q']), st.sampled_from(['failed', 'stuck', 'bogus', 'recovered']),
       st.one_of(ANY_FLOAT.map(repr), st.text(max_size=5)), st.one_of(st.integers().map(str), st.text(max_size=3)))
def test_fault_message_validation(actuator, mode, value, event):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    status = DiagnosticStatus(name=actuator, message=mode, values=[
        KeyValue(key='mode', value=mode), KeyValue(key='value', value=value),
        KeyValue(key='event', value=event), KeyValue(key='events', value='1')])
    try:
        _, _, _, out = cv.faults_from_msg(DiagnosticArray(status=[status]), WHEELS)
    except cv.InvalidMessage as exc:  # the node counts it as a rejected message (RejectCounter)
        assert str(exc).strip()
        return
    assert all(math.isfinite(s.value) and math.isfinite(s.time) for s in out.values())


# --- the laws on the graph (every registered controller) ------------------------------------------

def _sections() -> dict[str, dict]:
    """One validated section per registered controller, from the shipped scenarios (seed 000's
    min-norm law has no scenario of its own: the snlc section plus its two extra gains)."""
    out: dict[str, dict] = {}
    for path in sorted(CONFIG.glob('*.yaml')):
        for node, body in yaml.safe_load(path.read_text()).items():
            if node in NODES and NODES[node].role == 'controller' and node not in out:
                out[node] = flatten(body['ros__parameters'])
    snlc = dict(out['snlc_controller'], gamma=0.01, sigma=0.01)
    out.setdefault('snlc_minnorm_controller', snlc)
    return out


SECTIONS = _sections()
CONTROLLERS = sorted(n for n, info in NODES.items() if info.role == 'controller')


def test_every_registered_controller_is_fuzzed():
    assert sorted(SECTIONS) == CONTROLLERS


# Laws allowed to refuse a state (LawOutputRejected, with the reason), and where: everywhere else
# every registered law must give a finite output.
REFUSING = {
    'kt_controller': 'Gibbs parameters p = q/q4 of the error quaternion: infinite at a 180 deg error',
    'pointing_a_controller': 'seed 003 eq. 14: no final attitude for this momentum (ValueError)',
    'pointing_b_controller': 'seed 003 eq. 14: no final attitude for this momentum (ValueError)',
}
WHEEL_MOMENTUM = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array)


def _build(name: str, **over):
    p = NODES[name].schema.validate({**SECTIONS[name], **over})
    act = NODES[name].family.actuation_class(p)(p) if p.get('actuator') in ACTUATION_KINDS else None
    return NODES[name].law(p), act, p


def _control(law, name, t, q, w, h):
    """The node's call: (t, q, w), plus the wheels' momentum for a law that needs it."""
    extra = (h,) if getattr(law, 'needs_wheel_momentum', False) else ()
    return checked_control(law, name, t, q, w, *extra)


@pytest.mark.parametrize('name', CONTROLLERS)
@given(q=unit_quaternions(), w=RATES, t=st.floats(0.0, 1e6), h=WHEEL_MOMENTUM,
       available=st.lists(st.booleans(), min_size=3, max_size=3))
def test_registered_law_output_is_finite_and_commands_within_limits(name, q, w, t, h, available):
    law, act, p = _build(name)
    if isinstance(act, WheelActuation):
        mask = np.array(available[:len(act.wheel_names)] + [True] * max(0, len(act.wheel_names) - 3))
        act.set_available(mask)              # failed / stuck wheels: allocation over the rest
        law.on_wheels(act.axes, act.available)
    output = law.output
    try:
        value, status = _control(law, name, t, q, w, h)
    except LawOutputRejected as exc:
        # Only where the law itself is undefined (REFUSING), always with the reason.
        assert 'non-finite' in str(exc) or 'refused' in str(exc)
        assert name in REFUSING, (name, q, w, exc)
        if name == 'kt_controller':
            qe = error_quaternion(q, law.q_ref)
            assert abs(qe[3]) < 1e-100, (q, qe, exc)
        return
    if act is None:   # actuation of its own (e.g. thrusters): the law's output is what is checked
        return
    assert value.shape == (3,)
    if output == 'wheel_momentum':
        speed = act.command_momentum(value)
        assert np.all(np.isfinite(speed))
    else:
        cmd, applied = act.command(value)
        assert np.all(np.isfinite(cmd)) and np.all(np.isfinite(applied))
        assert np.all(np.abs(cmd) <= act.limit + 1e-12)     # saturated wheels / torquers
    for v in law.published_status(status).values():
        if isinstance(v, float):
            assert math.isfinite(v), (name, status)


@pytest.mark.parametrize('name', [n for n in CONTROLLERS if isinstance(_build(n)[1], WheelActuation)])
@given(q=unit_quaternions(), w=RATES, h=WHEEL_MOMENTUM)
def test_zero_torque_limits_command_zero(name, q, w, h):
    """Zero motor-torque limits (a wheel that can give nothing): the commands are exactly zero."""
    law, act, _ = _build(name)
    act.limit = np.zeros_like(act.limit)
    try:
        value, _ = _control(law, name, 0.0, q, w, h)
    except LawOutputRejected:
        return   # (REFUSING: see the test above)
    if law.output == 'torque':
        cmd, applied = act.command(value)
        assert np.all(cmd == 0.0) and np.all(applied == 0.0)


# --- the pure laws not yet on the graph -------------------------------------------------------------

J26 = [[5.0, -0.1, -0.5], [-0.1, 2.0, 1.0], [-0.5, 1.0, 3.5]]


def _defaults(schema) -> dict:
    """The section a scenario without the optional keys gives a law: the schema's defaults."""
    return {p.name: p.default for p in schema.params if p.default is not REQUIRED}


def _m2r(u_max):
    return M2rLaw({**_defaults(M2R_SCHEMA), 'inertia': sum(J26, []),
                   'target.attitude': [1.0, 0.0, 0.0, 0.0], 'target.rate': [0.0, 0.0, 0.0],
                   'alpha': u_max / 2, 'beta': u_max / 2, 'A': [1.0, 2.0, 3.0], 'f': 'eq25', 'omega_bar': 0.2,
                   'u_max': u_max})


def _m2s(saturation, u_max):
    return M2sLaw({**_defaults(M2S_SCHEMA), 'inertia': np.diag([1.4947, 3.7997, 5.2056]).tolist(),
                   'target.attitude': [0.0, 0.0, 0.0, 1.0], 'target.rate': [0.0, 0.1, 0.0],
                   'alpha': 1.0, 'beta': 1.0, 'A': [1.0, 2.0, 3.0], 'K1': 1.0, 'Q': 1.0,
                   'J_hat0': [1.0, 1.0, 1.0], 'q_max': 10000.0, 'K_Q': 0.001,
                   'saturation': saturation, 'u_max': u_max})


def _backstepping(hold):
    return bs.BacksteppingLaw({'inertia': [4.350, 4.3370, 3.6640],
                               'target.attitude': _unit([-0.4329, 0.6645, 0.4783, -0.3772]).tolist(),
                               'target.rate': [0.0, 0.0, 0.0], 'K1': 0.1, 'K2': 4.0,
                               'orbit.altitude': 250e3, 'reference.hold_time': hold})


def _finite_or_refused(call):
    try:
        u, status = call()
    except ValueError as exc:
        assert str(exc).strip()
        return None
    assert np.all(np.isfinite(u)), u
    return u


@given(q=unit_quaternions(), w=RATES, t=st.floats(0.0, 1e5), u_max=st.sampled_from([1.0, 0.1, 10.0]))
def test_inertia_free_m2r_is_finite(q, w, t, u_max):
    u = _finite_or_refused(lambda: _m2r(u_max).control(t, q, w))
    assert u is not None and np.all(np.abs(u) <= u_max + 1e-9)


@given(q=unit_quaternions(), w=RATES, steps=st.integers(1, 3),
       sat=st.sampled_from(['cutoff', 'scaling']), u_max=st.sampled_from([0.0, 1.0, 10.0]))
def test_inertia_free_m2s_is_finite(q, w, steps, sat, u_max):
    law = _m2s(sat, u_max)
    for k in range(steps):   # the estimator state carries over from step to step
        u = _finite_or_refused(lambda: law.control(0.1 * k, q, w))
        assert u is not None


@given(q=unit_quaternions(), w=RATES, t=st.floats(0.0, 1e5), hold=st.sampled_from([0.0, None]))
def test_backstepping_is_finite(q, w, t, hold):
    _finite_or_refused(lambda: _backstepping(hold).control(t, q, w))


POINTING = dict(inertia=[10.0, 8.0, 9.0], sigma=[math.cos(0.0873), 0.0, math.sin(0.0873)],
                tau=[math.cos(0.785), 0.0, math.sin(0.785)], K_p=0.25, K_h=0.1, K_Psi=0.1)


@pytest.mark.parametrize('cls', [sa.PointingALaw, sa.PointingBLaw])
@given(q=unit_quaternions(), w=RATES, h=st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array),
       given_H=st.booleans())
def test_single_axis_pointing_is_finite_or_refused(cls, q, w, h, given_H):
    p = dict(POINTING, H=[0.0, 0.0, 0.85]) if given_H else dict(POINTING)
    law = cls(p)
    for k in range(2):
        _finite_or_refused(lambda: law.control(float(k), q, w, h))


# --- the node's last line of defence ------------------------------------------------------------------

@given(st.lists(ANY_FLOAT, min_size=3, max_size=3))
def test_checked_output_refuses_non_finite_law_output_with_a_reason(v):
    v = np.array(v)
    if np.all(np.isfinite(v)):
        assert checked_output('pd', v) is v
    else:
        with pytest.raises(LawOutputRejected, match='non-finite'):
            checked_output('pd', v)


def test_controller_node_refuses_a_non_finite_law_output(ros_domain, tmp_path):
    """The node path: Krstic-Tsiotras at a 180 deg error (Gibbs p = q/q4 infinite) is refused
    with a counted reason and nothing is published; the next, ordinary state is answered."""
    from support.ros_graph import InProcessGraph
    from support.scenarios import make_scenario

    from adcs_controllers.nodes.kt_controller import KtController
    from adcs_core.attitude import quat_multiply
    scenario = make_scenario(tmp_path, base='table1_krstic_tsiotras.yaml')
    with InProcessGraph(scenario) as graph:
        ctl = graph.add(KtController)
        sent = []
        (pub_cmd,) = ctl.pub_cmds.values()   # the one command topic of its actuation
        pub_cmd.publish = sent.append
        target = np.asarray(ctl.law.q_ref)
        flip = np.array([1.0, 0.0, 0.0, 0.0])       # 180 deg about x, composed with the target
        ctl._on_state(cv.state_to_msg(0, quat_multiply(target, flip), [0.0, 0.0, 0.0]))
        assert sent == [] and ctl.rejects.counts['law'] == 1
        ctl._on_state(cv.state_to_msg(1, target, [0.01, 0.0, 0.0]))
        assert len(sent) == 1 and ctl.rejects.counts['law'] == 1
        from rclpy.serialization import deserialize_message
        cmd = deserialize_message(sent[0], pub_cmd.msg_type)   # the node publishes CDR bytes (adcs_msgs_py.cdr)
        assert all(math.isfinite(v) for v in (list(cmd.effort) if hasattr(cmd, 'effort')
                                               else [cmd.vector.x, cmd.vector.y, cmd.vector.z]))
