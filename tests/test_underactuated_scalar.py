"""The one-state float path of the two-wheel GSMN law (adcs_controllers/laws/underactuated_scalar.py)
gives the numpy law's bits: torque, every status value and its type, signed zeros included, on
fuzzed states, on the edge states (q1 = q2 = 0, saturated ratios, zero torque mode, exact zeros),
for every unactuated axis, a reference attitude and rate, both snlc forms; and the showcase's law
object (the node's) still equals the batch engine's numpy call on a batch."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_controllers.laws.reconfiguration import TwoWheelReconfiguration
from adcs_controllers.laws.underactuated import SnlcGsmnLaw, gsmn_torque

FUZZ = settings(derandomize=True, max_examples=300, deadline=None, database=None)
SHOWCASE = {'inertia': [40.45, 42.09, 42.36], 'k1': 0.02, 'g1': 0.08, 'K1': 10.0, 'k2': 0.2, 'g2': 1.2,
            'K2': 10.0, 'gamma': 0.01, 'sigma': 0.04, 'epsilon': 0.02, 'a1': 0.025, 'a2': 0.025,
            'target.attitude': [0.0, 0.0, 0.0, 1.0], 'target.rate': [0.0, 0.0, 0.0]}


def numpy_call(law: SnlcGsmnLaw, q, w):
    """The law's numpy path, as before the float path existed (same wrapper, same axes)."""
    saved, law._scalar = law._scalar, (law.unactuated_axis, None)
    try:
        return law.control(0.0, q, w)
    finally:
        law._scalar = saved


def same_bits(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def assert_same(law: SnlcGsmnLaw, q, w) -> None:
    q, w = np.asarray(q, dtype=float), np.asarray(w, dtype=float)
    u_ref, s_ref = numpy_call(law, q, w)
    u, s = law.control(0.0, q, w)
    assert law._scalar[1] is not None   # the float path ran
    assert same_bits(u, u_ref), (u, u_ref)
    assert s.keys() == s_ref.keys()
    for key in s:
        assert type(s[key]) is type(s_ref[key]), key
        assert same_bits(s[key], s_ref[key]), (key, s[key], s_ref[key])
    assert law.published_status(s) == law.published_status(s_ref)


def _law(**over) -> SnlcGsmnLaw:
    return SnlcGsmnLaw({**SHOWCASE, **over})


unit = st.floats(-1.0, 1.0, allow_nan=False, width=64)
rate = st.floats(-0.2, 0.2, allow_nan=False, width=64)


@FUZZ
@given(st.tuples(unit, unit, unit, unit).filter(lambda v: np.linalg.norm(v) > 1e-3),
       st.tuples(rate, rate, rate), st.sampled_from('xyz'))
def test_float_path_equals_numpy_fuzzed(v, w, axis):
    _same_on_axis(v, w, axis)


def _same_on_axis(v, w, axis) -> None:
    """The showcase's law with ``axis`` unactuated, at the normalised ``v`` and the rate ``w``."""
    law = _law()
    law.set_unactuated_axis(axis)
    assert_same(law, np.asarray(v) / np.linalg.norm(v), w)


@pytest.mark.parametrize('q, w', [
    ([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0]),              # at rest: signed zeros everywhere
    ([0.0, 0.0, 0.6, 0.8], [0.0, 0.0, 0.01]),             # q1 = q2 = 0: the singular ratio is 0
    ([0.0, 0.0, -0.6, 0.8], [-0.0, 0.0, -0.01]),
    ([1e-9, 0.0, 0.7, 0.71414284285], [0.0, 1e-4, 0.0]),  # saturated ratios
    ([0.2236068, 0.2236068, 0.2236068, 0.9219544], [0.001, -0.002, 0.0005]),
    ([0.5, -0.5, 0.5, -0.5], [0.1, 0.1, -0.1]),           # q4 < 0
    ([0.01, 0.01, 0.0, 0.9999], [0.0, 0.0, 0.0]),         # small torques: high-gain mode
])
@pytest.mark.parametrize('axis', ['x', 'y', 'z'])
def test_float_path_equals_numpy_edges(q, w, axis):
    _same_on_axis(q, w, axis)


@pytest.mark.parametrize('over', [
    {'target.attitude': [0.1, -0.2, 0.3, 0.9], 'target.rate': [0.001, 0.0, -0.002], 'shortest_path': True},
    {'scale_by_inertia': True, 'eps_den': 1e-4, 'a1': np.inf, 'a2': 0.5},
    {'inertia': [40.0, 0.5, -0.3, 0.5, 42.0, 0.2, -0.3, 0.2, 41.0]},
])
def test_float_path_equals_numpy_options(over):
    law = _law(**over)
    rng = np.random.default_rng(7)
    for _ in range(200):
        q = rng.normal(size=4)
        assert_same(law, q / np.linalg.norm(q), rng.normal(scale=0.05, size=3))


def test_modes_all_reached():
    """The fuzz above covers the three GSMN modes (not only zero torque)."""
    law, rng, modes = _law(), np.random.default_rng(3), set()
    for scale in ([0.05, 0.05, 0.05, 1.0], [0.01, 0.01, 0.0, 1.0]):   # q3 = 0: small high-gain torques
        for _ in range(200):
            q, w = rng.normal(size=4) * scale, rng.normal(scale=1e-4, size=3)
            assert_same(law, q / np.linalg.norm(q), w)
            modes.add(int(law.control(0.0, q / np.linalg.norm(q), w)[1]['mode']))
    assert modes == {0, 1, 2}


def test_zero_saturation_limit_keeps_numpy():
    """a = 0 is left to numpy (its clip's own sign-of-zero rule)."""
    law = _law(a1=0.0)
    law.control(0.0, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
    assert law._scalar[1] is None


def test_node_call_equals_batch_call():
    """The showcase's law object on one state (float path) equals gsmn_torque on a batch of them,
    as the batch engine calls it (same law object, leading batch axis)."""
    law = TwoWheelReconfiguration(None, _law())
    rng = np.random.default_rng(11)
    q = rng.normal(size=(64, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w = rng.normal(scale=0.03, size=(64, 3))
    u_batch, s_batch = law.control(0.0, q, w)
    u_ref, _ = gsmn_torque(q, w, law.two_wheel.law_inertia, *law.two_wheel.gains, epsilon=0.02, a1=0.025,
                           a2=0.025)
    assert same_bits(u_batch, u_ref)
    for i in range(len(q)):
        u, s = law.control(0.0, q[i], w[i])
        assert same_bits(u, u_batch[i])
        assert same_bits(s['V'], s_batch['V'][i]) and same_bits(s['wd'], s_batch['wd'][i])
