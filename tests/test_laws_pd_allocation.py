"""Control-law cores without ROS: seed 004's PD law (eq. 13) and wheel torque allocation."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from adcs_controllers.laws.allocation import body_torque_from_wheels, saturate, wheel_allocation_matrix
from adcs_controllers.laws.pd import pd_torque

I_SEED4 = np.diag([12.0, 14.0, 10.0])
Q0_SEED4 = np.array([0.3062, 0.1768, 0.1768, 0.9186])
RNG = np.random.default_rng(2024)


def hamilton(p, q):
    """Hamilton product p ⊗ q, scalar last, written out as the 4x4 left-multiplication matrix."""
    x, y, z, w = p
    L = np.array([[w, -z, y, x],
                  [z, w, -x, y],
                  [-y, x, w, z],
                  [-x, -y, -z, w]])
    return L @ q


# --- PD law (seed 004 eq. 13) ---------------------------------------------------------------------

def test_pd_eq13_identity_target():
    """u = -kp I q_v - kd I w (seed 004 eq. 13) with the seed's numbers and a full inertia."""
    kp, kd = 0.002, 0.05
    w = np.array([0.01, -0.02, 0.005])
    assert_allclose(pd_torque(Q0_SEED4, w, I_SEED4, kp, kd),
                    -kp * I_SEED4 @ Q0_SEED4[:3] - kd * I_SEED4 @ w, rtol=1e-15)
    # t = 0 of the seed's slew (w = 0): u = -kp I q_v
    assert_allclose(pd_torque(Q0_SEED4, np.zeros(3), I_SEED4, kp, kd),
                    [-0.002 * 12 * 0.3062, -0.002 * 14 * 0.1768, -0.002 * 10 * 0.1768], rtol=1e-15)
    J = np.array([[10.0, 0.5, 0.2], [0.5, 12.0, -0.3], [0.2, -0.3, 8.0]])
    assert_allclose(pd_torque(Q0_SEED4, w, J, kp, kd), -J @ (kp * Q0_SEED4[:3] + kd * w), rtol=1e-14)
    # identity reference and zero rate reference change nothing
    assert_array_equal(pd_torque(Q0_SEED4, w, J, kp, kd, q_ref=np.array([0, 0, 0, 1.0]), w_ref=np.zeros(3)),
                       pd_torque(Q0_SEED4, w, J, kp, kd))


def test_pd_with_target_uses_error_quaternion():
    """With a commanded attitude q_c the law acts on q_e = q_c* ⊗ q (Hamilton, scalar last) and
    w - w_c; q_e is the body attitude relative to the target: R(q_e) = R(q_c)^T R(q)."""
    kp, kd = 0.3, 0.7
    q = Rotation.random(random_state=RNG).as_quat()
    qc = Rotation.random(random_state=RNG).as_quat()
    w, wc = RNG.normal(size=3), RNG.normal(size=3)
    qc_conj = np.concatenate([-qc[:3], qc[3:]])
    qe = hamilton(qc_conj, q)
    assert_allclose(Rotation.from_quat(qe).as_matrix(),
                    Rotation.from_quat(qc).as_matrix().T @ Rotation.from_quat(q).as_matrix(), atol=1e-14)
    assert_allclose(pd_torque(q, w, I_SEED4, kp, kd, q_ref=qc, w_ref=wc),
                    -I_SEED4 @ (kp * qe[:3] + kd * (w - wc)), rtol=1e-13, atol=1e-15)
    # on target: no torque
    assert_allclose(pd_torque(qc, wc, I_SEED4, kp, kd, q_ref=qc, w_ref=wc), 0.0, atol=1e-15)


def test_pd_shortest_path_flip():
    """q4 < 0: as printed (default) the law uses q_v as is (long way round); shortest_path uses -q."""
    kp, kd = 0.002, 0.05
    q = -Q0_SEED4  # same attitude, q4 < 0
    w = np.array([0.01, 0.0, -0.01])
    printed = pd_torque(q, w, I_SEED4, kp, kd)
    assert_allclose(printed, -kp * I_SEED4 @ q[:3] - kd * I_SEED4 @ w, rtol=1e-15)
    short = pd_torque(q, w, I_SEED4, kp, kd, shortest_path=True)
    assert_allclose(short, pd_torque(Q0_SEED4, w, I_SEED4, kp, kd), rtol=1e-15)
    assert not np.allclose(printed, short)
    # q4 > 0: the flag changes nothing
    assert_array_equal(pd_torque(Q0_SEED4, w, I_SEED4, kp, kd, shortest_path=True),
                       pd_torque(Q0_SEED4, w, I_SEED4, kp, kd))
    # the flip applies to the error quaternion, not to q
    qc = Rotation.from_rotvec([0.0, 0.0, 3.0]).as_quat()
    q_far = Rotation.from_rotvec([0.0, 0.0, -3.0]).as_quat()  # 6 rad from qc the long way: q_e4 < 0
    qe = hamilton(np.concatenate([-qc[:3], qc[3:]]), q_far)
    assert qe[3] < 0 and q_far[3] > 0
    assert_allclose(pd_torque(q_far, np.zeros(3), I_SEED4, kp, kd, q_ref=qc, shortest_path=True),
                    kp * I_SEED4 @ qe[:3], rtol=1e-13)


def test_pd_batch_with_per_run_gains():
    """Batch shapes q (N, 4), w (N, 3), kp and kd (N,), inertia (3, 3) or (N, 3, 3): row i equals
    the scalar call with run i's values."""
    N = 7
    q = Rotation.random(N, random_state=RNG).as_quat()
    q[::2] *= -1  # some with q4 < 0
    w = RNG.normal(scale=0.01, size=(N, 3))
    kp = RNG.uniform(0.001, 0.01, size=N)
    kd = RNG.uniform(0.01, 0.1, size=N)
    qc = Rotation.random(N, random_state=RNG).as_quat()
    Js = np.stack([np.diag(RNG.uniform(8, 14, size=3)) for _ in range(N)])
    for shortest in (False, True):
        u = pd_torque(q, w, I_SEED4, kp, kd, shortest_path=shortest)
        assert u.shape == (N, 3)
        for i in range(N):
            assert_allclose(u[i], pd_torque(q[i], w[i], I_SEED4, kp[i], kd[i], shortest_path=shortest), rtol=1e-15)
        u = pd_torque(q, w, Js, kp, kd, q_ref=qc, shortest_path=shortest)
        for i in range(N):
            assert_allclose(u[i], pd_torque(q[i], w[i], Js[i], kp[i], kd[i], q_ref=qc[i], shortest_path=shortest),
                            rtol=1e-14, atol=1e-17)
    # scalar gains broadcast over the batch
    assert_allclose(pd_torque(q, w, I_SEED4, 0.002, 0.05), -(0.002 * q[:, :3] + 0.05 * w) @ I_SEED4.T, rtol=1e-14)


# --- allocation ------------------------------------------------------------------------------------

ORTHO = np.eye(3)
# 3 orthogonal + 1 skewed wheel, and a 4-wheel pyramid (not unit: allocation must cope)
SKEW4 = np.vstack([np.eye(3), np.ones(3) / np.sqrt(3)])
PYRAMID = np.array([[1.0, 1.0, 1.0], [-1.0, 1.0, 1.0], [-1.0, -1.0, 1.0], [1.0, -1.0, 1.0]]) / np.sqrt(3)


@pytest.mark.parametrize('axes', [ORTHO, SKEW4, PYRAMID], ids=['orthogonal', 'skewed4', 'pyramid'])
def test_allocation_reproduces_body_torque(axes):
    """Body torque -(tau @ axes) of tau = M u equals u exactly (full-rank wheel sets), batched."""
    M = wheel_allocation_matrix(axes)
    assert M.shape == (len(axes), 3)
    u = RNG.normal(scale=0.01, size=(50, 3))
    tau = u @ M.T
    assert_allclose(body_torque_from_wheels(axes, tau), u, rtol=0, atol=1e-16)
    assert_allclose(-(tau @ axes), u, rtol=0, atol=1e-16)
    if len(axes) == 3:  # orthogonal triad: each wheel takes minus its own axis component
        assert_allclose(M, -np.eye(3), atol=1e-15)


@pytest.mark.parametrize('axes', [SKEW4, PYRAMID], ids=['skewed4', 'pyramid'])
def test_allocation_is_minimum_norm(axes):
    """Any other wheel torque set giving the same body torque (tau + s n, n in the null space of
    the axes) has a larger norm; the allocated one is orthogonal to the null space."""
    M = wheel_allocation_matrix(axes)
    null = np.linalg.svd(axes.T)[2][-1]  # 3 x 4 matrix of axes: one null vector
    assert_allclose(axes.T @ null, 0.0, atol=1e-15)
    for _ in range(20):
        u = RNG.normal(scale=0.01, size=3)
        tau = M @ u
        assert abs(tau @ null) < 1e-16
        for s in (1e-6, -1e-3, 0.05):
            other = tau + s * null
            assert_allclose(body_torque_from_wheels(axes, other), u, rtol=0, atol=1e-15)
            assert np.linalg.norm(other) > np.linalg.norm(tau)


def test_allocation_with_unavailable_wheels():
    """Failed wheels get zero torque; the remaining wheels reproduce u where they can: exactly if
    they still span 3-D, otherwise the least-squares projection of u onto their span."""
    u = np.array([0.01, -0.02, 0.03])
    # 3 orthogonal wheels, z failed: x and y components only
    M = wheel_allocation_matrix(ORTHO, [True, True, False])
    assert_array_equal(M[2], 0.0)
    assert_allclose(body_torque_from_wheels(ORTHO, M @ u), [0.01, -0.02, 0.0], atol=1e-17)
    # two non-orthogonal available wheels of a pyramid: projection onto their span
    M = wheel_allocation_matrix(PYRAMID, [True, False, True, False])
    assert_array_equal(M[[1, 3]], 0.0)
    A = PYRAMID[[0, 2]].T
    P = A @ np.linalg.solve(A.T @ A, A.T)
    produced = body_torque_from_wheels(PYRAMID, M @ u)
    assert_allclose(produced, P @ u, atol=1e-16)
    assert abs((u - produced) @ PYRAMID[0]) < 1e-17 and abs((u - produced) @ PYRAMID[2]) < 1e-17
    # skewed set with one of the triad failed: the other 3 still span, exact
    M = wheel_allocation_matrix(SKEW4, [True, False, True, True])
    assert_array_equal(M[1], 0.0)
    assert_allclose(body_torque_from_wheels(SKEW4, M @ u), u, atol=1e-16)
    # all failed: nothing
    assert_array_equal(wheel_allocation_matrix(SKEW4, [False] * 4), 0.0)


def test_saturate_clip_and_scale():
    """clip: each wheel independently at its limit; scale: whole vector by one factor so the worst
    wheel sits at its limit (direction kept); below the limits both leave tau alone."""
    limit = np.array([0.01, 0.02, 0.01, 0.05])
    tau = np.array([0.02, -0.01, -0.03, 0.01])
    assert_array_equal(saturate(tau, limit, 'clip'), [0.01, -0.01, -0.01, 0.01])
    scaled = saturate(tau, limit, 'scale')
    assert_allclose(scaled, tau / 3.0, rtol=1e-15)  # wheel 2 is 3x over
    assert np.all(np.abs(scaled) <= limit * (1 + 1e-15))
    assert_allclose(np.max(np.abs(scaled) / limit), 1.0, rtol=1e-15)
    small = np.array([0.001, -0.002, 0.003, 0.0])
    assert_array_equal(saturate(small, limit, 'clip'), small)
    assert_array_equal(saturate(small, limit, 'scale'), small)
    # batch: one factor per row
    batch = np.stack([tau, small, 2 * tau])
    out = saturate(batch, limit, 'scale')
    assert_allclose(out, [tau / 3.0, small, tau / 3.0], rtol=1e-15)
    # infinite limit = unlimited
    assert_array_equal(saturate(tau, np.full(4, np.inf), 'scale'), tau)
    with pytest.raises(ValueError, match='saturation mode'):
        saturate(tau, limit, 'wrap')
