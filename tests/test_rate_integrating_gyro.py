"""The truth model's gyro is rate-integrating, and the MEKF's default propagation uses it exactly.

The gyro's sample of ``t_k`` carries the body rate over ``[t_{k-1}, t_k]`` as the rotation vector of
``q(t_{k-1})* ⊗ q(t_k)`` over ``Δt`` (a strapdown unit's coning-compensated angle increment); the
MEKF's default ``gyro.propagation: increment`` propagates that interval with that sample. Without
noise the filter's propagation then reproduces the true attitude whatever the rate does within a
step (closed forms below); with the instantaneous-rate sample and ``hold`` (the former defaults) a
slew's star tracker outage made the filter overconfident by two orders of magnitude (NEES ~500 for
6 dof), which the outage scenario's test now bounds (tests/test_determination_scenarios.py).
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from adcs_controllers.estimators import mekf
from adcs_controllers.estimators.families import MEKF
from adcs_core.attitude import quat_conjugate, quat_multiply, rotation_vector
from adcs_msgs_py.measurements import Measurements, Reading
from adcs_sim.truth.sensor_models import Gyro

DT = 0.1


def _tumbling(steps: int, seed: int = 3) -> np.ndarray:
    """Attitudes (steps, 4) of a body whose rate changes in size and direction within every step:
    each step's rotation is the product of three random sub-rotations (not one constant rate)."""
    rng = np.random.default_rng(seed)
    q = [np.array([0.0, 0.0, 0.0, 1.0])]
    for _ in range(steps - 1):
        step = np.array([0.0, 0.0, 0.0, 1.0])
        for _ in range(3):
            step = quat_multiply(step, mekf.rotation_quaternion(0.02 * rng.normal(size=3)))
        q.append(quat_multiply(q[-1], step))
    return np.array(q)


@settings(derandomize=True, max_examples=100, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3), st.sampled_from([1e-14, 1e-9, 1e-4, 1.0]),
       st.booleans())
def test_rotation_vector_inverts_the_rotation_quaternion(axis, scale, negate):
    phi = np.asarray(axis) * scale
    if np.linalg.norm(phi) >= np.pi:
        phi = phi / np.linalg.norm(phi) * 3.0
    q = mekf.rotation_quaternion(phi)
    assert_allclose(rotation_vector(-q if negate else q), phi, rtol=1e-12, atol=1e-15)


def test_the_gyro_reads_the_mean_rate_of_the_step_that_ended():
    """Noise-free: sample k is rotation_vector(q_{k-1}* q_k)/Δt (the true rate at the first), and
    holding it over the step takes q_{k-1} to q_k to rounding."""
    q = _tumbling(50)
    w0 = np.array([0.01, -0.02, 0.03])
    gyro = Gyro(7, DT)
    first = gyro.read(0, q[0], w0, None).value
    assert_allclose(first, w0, rtol=0, atol=0)
    for k in range(1, len(q)):
        rate = gyro.read(k, q[k], np.zeros(3), None).value    # the instantaneous rate is not used
        assert_allclose(rate, rotation_vector(quat_multiply(quat_conjugate(q[k - 1]), q[k])) / DT, rtol=1e-13)
        held = quat_multiply(q[k - 1], mekf.rotation_quaternion(rate * DT))
        assert_allclose(held * np.sign(held[3] * q[k][3]), q[k], atol=1e-14)


def test_a_batch_of_gyros_reads_each_run_as_alone():
    q = np.stack([_tumbling(20, seed) for seed in (1, 2, 3)], axis=1)        # (steps, runs, 4)
    whole = Gyro([5, 6, 7], DT, arw=1e-4, rrw=1e-6)
    alone = Gyro([6], DT, arw=1e-4, rrw=1e-6)
    for k in range(q.shape[0]):
        a = whole.read(k, q[k], np.zeros((3, 3)), None).value
        b = alone.read(k, q[k, 1:2], np.zeros((1, 3)), None).value
        np.testing.assert_array_equal(a[1], b[0])


@pytest.mark.parametrize('propagation, exact', [('increment', True), ('hold', False), ('average', False)])
def test_the_default_propagation_follows_the_truth_exactly_on_the_gyro_alone(propagation, exact):
    """No star tracker image, no noise, no bias: the filter propagates on the gyro only.
    With ``increment`` (the default) its attitude stays on the truth to rounding over 200 steps of a
    rate that changes within every step; ``hold`` and ``average`` drift (their rule does not fit this
    gyro): the closed form is what tells them apart."""
    assert MEKF.schema.validate({})['gyro.propagation'] == 'increment'
    q = _tumbling(200)
    gyro = Gyro(1, DT)
    est = MEKF.build(MEKF.schema.validate({'sensors': ['gyro', 'star_tracker'], 'initial.attitude': list(q[0]),
                                           'gyro.propagation': propagation}))
    blind = Reading(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros((3, 3)), False)   # never an image
    errors = []
    for k in range(len(q)):
        reading = gyro.read(k, q[k], np.zeros(3), None)
        e, _ = est.step(Measurements(round(k * DT * 1e9), gyro=Reading(reading.value, reading.cov, True),
                                     star_tracker=blind))
        errors.append(np.linalg.norm(mekf.attitude_error(e.q, q[k])))
    worst = max(errors)
    if exact:
        assert worst < 1e-12
    else:
        assert worst > 1e-6
