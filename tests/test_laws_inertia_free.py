"""Seed 001's inertia-free laws (adcs_controllers.laws: motion_to_rest, motion_to_spin, saturation;
the rotation kernel of adcs_core.attitude; the settling index k0 of adcs_sim.app.analysis.metrics): M2R (eq. 11-25) with the
torque bounds of Propositions 1 and 2, the adaptive M2S compensator (Theorem 2, eq. 31-46), cutoff
and scaling saturation (eq. 47-51), VAG (eq. 55-58) and extremum tracking (eq. 60-67); closed
loops on the pure plant (adcs_sim.truth.plant.Plant with ideal external Torquers, no momentum storage).

Runtime: unit tests ~3 s; closed loops batched (one Plant, several runs per batch): M2R ~5 s,
M2S at 10/1 N m ~5 s; ONE long test (test_LONG_m2s_vag_low_torque_reaches_the_spin, 9000
control steps of 0.1 s for 5 runs) ~20 s. No ROS.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from adcs_controllers.families import M2R_SCHEMA, M2S_SCHEMA
from adcs_controllers.laws import motion_to_rest as m2r
from adcs_controllers.laws import motion_to_spin as m2s
from adcs_controllers.laws import saturation as sat
from adcs_core import attitude as rot
from adcs_msgs_py.params import REQUIRED
from adcs_sim.app.analysis import metrics as analysis
from adcs_sim.truth.plant import Plant, Torquers

# Eq. (26): M2R example inertia; eq. (52): M2S example inertia (kg m²).
J26 = np.array([[5.0, -0.1, -0.5], [-0.1, 2.0, 1.0], [-0.5, 1.0, 3.5]])
J52 = np.diag([1.4947, 3.7997, 5.2056])
A123 = np.array([1.0, 2.0, 3.0])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
Q_RD_M2R = np.array([1.0, 0.0, 0.0, 0.0])          # R_d = diag(1, -1, -1): 180° about x
Q_R0_M2S = np.array([math.sqrt(0.5), 0, 0, math.sqrt(0.5)])  # eq. (53a): 90° about x
W0_M2S = -0.1 / math.sqrt(3.0) * np.ones(3)         # eq. (53b)
WD_INTERMEDIATE = np.array([0.0, 0.1, 0.0])          # eq. (54)
WD_NONPRINCIPAL = 0.1 / math.sqrt(3.0) * np.ones(3)  # eq. (59)


def random_rotations(n, seed):
    return Rotation.random(n, random_state=seed).as_matrix()


def schema_defaults(schema) -> dict:
    """Every parameter of ``schema`` that has a default, at its default: the section a scenario
    without these keys gives the law (the laws keep no defaults of their own)."""
    return {p.name: p.default for p in schema.params if p.default is not REQUIRED}


def m2s_params(**over):
    """Section 6.3 set-up: A = diag(1, 2, 3), α = β = 1, K1 = D = I, Q = I6, Ĵ(0) = I, C_d = 0
    (the schema's defaults for the rest)."""
    p = {**schema_defaults(M2S_SCHEMA), 'inertia': np.diag(J52).tolist(),
         'target.attitude': IDENTITY.tolist(), 'target.rate': WD_INTERMEDIATE.tolist(), 'alpha': 1.0,
         'beta': 1.0, 'A': A123.tolist(), 'K1': 1.0, 'Q': 1.0, 'J_hat0': [1.0, 1.0, 1.0], 'q_max': 10000.0,
         'K_Q': 0.001}
    p.update(over)
    return p


def m2r_params(u_max, **over):
    """Section 4 set-up: R_d = diag(1, -1, -1), ω̄ = 0.2, A = diag(1, 2, 3), α = β = u_max/2."""
    u_max = np.asarray(u_max, dtype=float)
    p = {**schema_defaults(M2R_SCHEMA), 'inertia': J26.ravel().tolist(),
         'target.attitude': Q_RD_M2R.tolist(), 'target.rate': [0.0, 0.0, 0.0], 'alpha': u_max / 2,
         'beta': u_max / 2, 'A': A123.tolist(), 'f': 'eq25', 'omega_bar': 0.2, 'u_max': u_max[..., None]}
    p.update(over)
    return p


def closed_loop(law, J, q0, w0, T, period, u_lim, dist=None, max_step=None, every=1):
    """Run ``law`` on the pure plant (Torquers saturating at ``u_lim``, (N, 3)) for ``T`` s with a
    zero-order hold of ``period``; ``dist`` (N, 3) a constant body disturbance torque (applied as a
    second, unlimited torquer). Returns dict of arrays over the recorded steps: t, q, w, u, and
    the status keys."""
    acts = [Torquers(max_torque=u_lim)]
    if dist is not None:
        acts.append(Torquers(name='disturbance'))
    plant = Plant(J, acts)
    batch = np.shape(u_lim)[:-1]
    x = plant.initial_state(np.broadcast_to(q0, batch + (4,)), np.broadcast_to(w0, batch + (3,)))
    n = int(round(T / period))
    rec = {'t': [], 'q': [], 'w': [], 'u': []}
    st_rec = []
    for k in range(n + 1):
        t = k * period
        u, st = law.control(t, x[..., :4], x[..., 4:7])
        if k % every == 0 or k == n:
            rec['t'].append(t)
            rec['q'].append(x[..., :4].copy())
            rec['w'].append(x[..., 4:7].copy())
            rec['u'].append(u)
            st_rec.append(st)
        if k == n:
            break
        cmd = {'torquers': u}
        if dist is not None:
            cmd['disturbance'] = dist
        x = plant.step(t, x, cmd, period, max_step or period)
    out = {k: np.array(v) for k, v in rec.items()}
    for key in st_rec[0]:
        out[key] = np.array([s[key] for s in st_rec])
    return out


def at(run, t):
    return int(np.argmin(np.abs(run['t'] - t)))


# --- rotation helpers, S, Ṡ ----------------------------------------------------------------------

def test_rotation_helpers_match_scipy_and_round_trip():
    q = Rotation.random(50, random_state=1).as_quat()  # scalar last
    R = rot.rotation_from_quaternion(q)
    assert_allclose(R, Rotation.from_quat(q).as_matrix(), atol=1e-15)
    q2 = rot.quaternion_from_rotation(R)
    assert_allclose(np.abs(np.sum(q2 * q, axis=-1)), 1.0, atol=1e-12)
    assert np.all(q2[:, 3] >= 0)
    w = np.random.default_rng(2).normal(size=(50, 3))
    assert_allclose(rot.rotation_exp(w, 0.7), Rotation.from_rotvec(0.7 * w).as_matrix(), atol=1e-14)
    assert_allclose(rot.hat(w) @ w[:, :, None], 0.0, atol=1e-15)
    # eq. (10): θ of R̃ is the rotation angle
    assert_allclose(rot.eigenaxis_error(Rotation.from_rotvec(0.7 * w).as_matrix()),
                    np.minimum(0.7 * np.linalg.norm(w, axis=1) % (2 * np.pi),
                               2 * np.pi - 0.7 * np.linalg.norm(w, axis=1) % (2 * np.pi)), atol=1e-7)


def test_s_vector_eq13_and_s_dot_eq38():
    R = random_rotations(40, 3)
    a = np.array([0.7, 1.9, 3.2])
    S_def = sum(a[i] * np.cross(R[:, i, :], np.eye(3)[i]) for i in range(3))  # R̃ᵀe_i = row i
    assert_allclose(m2r.s_vector(R, a), S_def, atol=1e-15)
    w = np.random.default_rng(4).normal(size=(40, 3))
    h = 1e-6
    fd = (m2r.s_vector(R @ rot.rotation_exp(w, h), a) - m2r.s_vector(R @ rot.rotation_exp(w, -h), a)) / (2 * h)
    assert_allclose(m2s.s_dot(R, w, a), fd, atol=1e-8)
    assert_array_equal(m2r.s_vector(np.eye(3), a), 0.0)


def _fd(V, x, dx, h=1e-6):
    return (V(*[xi + h * di for xi, di in zip(x, dx)]) - V(*[xi - h * di for xi, di in zip(x, dx)])) / (2 * h)


def test_m2r_lyapunov_derivative_is_eq14():
    """dV/dt along eq. (1)-(2) with u of eq. (12) equals -ωᵀKvω (eq. 14), both f (eq. 24, 25)."""
    rng = np.random.default_rng(5)
    Rd = random_rotations(1, 6)[0]
    for i, R in enumerate(random_rotations(20, 7)):
        w = rng.normal(size=3) * (0.1 if i % 2 else 1.0)
        for f in ('eq24', 'eq25'):
            u, st = m2r.m2r_torque(R, w, Rd, 0.4, 0.6, A123, f=f, omega_bar=0.2)
            wdot = np.linalg.solve(J26, np.cross(J26 @ w, w) + u)
            vd = _fd(lambda R_, w_: m2r.m2r_lyapunov(R_, w_, Rd, J26, 0.4, A123), (R, w),
                     (R @ rot.hat(w), wdot))
            assert_allclose(vd, -np.sum(st['kv'] * w * w), rtol=1e-6, atol=1e-10)


def test_m2s_lyapunov_derivative_is_eq45():
    """Theorem 2: along eq. (1), (2), (5), (34), (37), (39) with u of eq. (41), dV/dt (V of eq. 36,
    finite difference) equals eq. (45), here with a full J, non-diagonal K1, Q, a harmonic plus
    constant disturbance model (A_d skew) and a time-varying R_d. Confirms every sign of eq. 37-44."""
    rng = np.random.default_rng(8)
    K1 = np.array([[1.0, 0.2, 0.0], [0.2, 0.5, 0.1], [0.0, 0.1, 2.0]])
    Kv = np.diag([1.0, 2.0, 0.5])
    Kp = 0.3
    M = rng.normal(size=(6, 6))
    Q = M @ M.T + np.eye(6)
    Ad = np.zeros((5, 5))
    Ad[0, 1], Ad[1, 0] = 0.3, -0.3  # one harmonic at 0.3 rad/s, three constants
    Cd = rng.normal(size=(3, 5))
    D = np.diag([1.0, 2.0, 0.5, 1.5, 1.0])
    for R, Rd in zip(random_rotations(10, 9), random_rotations(10, 10)):
        w, wd, gh = rng.normal(size=3), 0.3 * rng.normal(size=3), rng.normal(size=6)
        d, dh = rng.normal(size=5), rng.normal(size=5)

        def rates(R_, w_, Rd_, gh_, d_, dh_):
            terms = m2s.m2s_terms(R_, w_, Rd_, wd, A123, K1)
            u, _ = m2s.m2s_torque(w_, terms, gh_, Kp, Kv, z_hat=Cd @ dh_)
            g_dot, dh_dot = m2s.m2s_estimator_rates(w_, terms, np.linalg.inv(Q), Ad, Cd,
                                                    np.linalg.inv(D), dh_)
            wdot = np.linalg.solve(J26, np.cross(J26 @ w_, w_) + u + Cd @ d_)
            return (R_ @ rot.hat(w_), wdot, Rd_ @ rot.hat(wd), g_dot, Ad @ d_, dh_dot), terms

        def V(R_, w_, Rd_, gh_, d_, dh_):
            terms = m2s.m2s_terms(R_, w_, Rd_, wd, A123, K1)
            return m2s.m2s_lyapunov(terms, A123, Kp, J26, gh_, Q, d_ - dh_, D)

        x = (R, w, Rd, gh, d, dh)
        dx, terms = rates(*x)
        z, S = terms['z'], terms['S']
        eq45 = -z @ Kv @ z - Kp * S @ K1 @ S  # A_dᵀD + DA_d = 0 only if D commutes: compute it
        dt = d - dh
        eq45 += 0.5 * dt @ (Ad.T @ D + D @ Ad) @ dt
        assert_allclose(_fd(V, x, dx), eq45, rtol=1e-6, atol=1e-9)


# --- batch == loop -------------------------------------------------------------------------------

def test_m2r_batch_equals_loop_bit_for_bit():
    R = random_rotations(32, 11)
    w = np.random.default_rng(12).normal(size=(32, 3))
    alpha = np.linspace(0.1, 0.9, 32)
    Rd = random_rotations(1, 13)[0]
    for f in ('eq24', 'eq25'):
        u, st = m2r.m2r_torque(R, w, Rd, alpha, 0.3, A123, f=f)
        for i in range(32):
            ui, sti = m2r.m2r_torque(R[i], w[i], Rd, alpha[i], 0.3, A123, f=f)
            assert_array_equal(u[i], ui)
            assert_array_equal(st['S'][i], sti['S'])


def test_m2s_law_batch_equals_loop_bit_for_bit():
    """The compensator (γ̂, d̂, q, ω̄, R_d states over 25 calls, RK4 sub-steps, cutoff/scaling/none,
    VAG on/off, extremum tracking firing) gives the same bits in a batch of 3 as alone."""
    sats, vags, umax = ['cutoff', 'scaling', 'none'], [True, False, True], [0.05, 0.2, 1.0]
    alpha = np.array([1.0, 0.5, 2.0])
    wd = np.array([WD_NONPRINCIPAL, WD_INTERMEDIATE, [0.05, 0.0, 0.02]])
    common = dict(extremum=True, t_max=0.3, max_step=0.04, C_d=np.eye(3).ravel().tolist(),
                  d_hat0=0.01, inertia=J26.ravel().tolist())
    batch = m2s.M2sLaw(m2s_params(saturation=sats, vag=vags, u_max=np.array(umax)[:, None],
                                  alpha=alpha, **{'target.rate': wd.tolist()}, **common))
    singles = [m2s.M2sLaw(m2s_params(saturation=sats[i], vag=vags[i], u_max=umax[i], alpha=alpha[i],
                                     **{'target.rate': wd[i].tolist()}, **common)) for i in range(3)]
    rng = np.random.default_rng(14)
    q = Rotation.random(3, random_state=15).as_quat()
    w = rng.normal(size=(3, 3)) * 0.2
    fired = False
    for k in range(25):
        t = 0.1 * k
        u, st = batch.control(t, q, w)
        for i, law in enumerate(singles):
            ui, sti = law.control(t, q[i], w[i])
            assert_array_equal(u[i], ui)
            for key in st:
                assert_array_equal(st[key][i], sti[key], err_msg=key)
        fired |= bool(np.any(st['omega_bar'] != np.linalg.norm(wd, axis=1)))
        q = q + 0.02 * rng.normal(size=q.shape)
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        w = w + 0.02 * rng.normal(size=w.shape)
    assert fired  # extremum tracking changed a commanded rate on the way


B_DIAGONALS = np.array([[1.2, 1.3, 1.4], [1.1, 1.5, 1.3], [1.4, 1.2, 1.25]])   # (3, 3): three runs, not a matrix
B_MATRICES = np.array([[2.0, 0.1, 0.0, -0.1, 2.1, 0.2, 0.0, 0.1, 1.9],
                       [1.8, 0.0, 0.3, 0.2, 2.2, 0.0, -0.2, 0.1, 2.0]])           # (2, 9): two runs


@pytest.mark.parametrize('B, proposition', [(B_DIAGONALS, 1), (B_MATRICES, 2)], ids=['diagonal', 'full'])
def test_inertia_free_laws_take_one_B_per_run(B, proposition):
    """B dispersed (as a campaign's batch stacks it: one row of 3 or 9 values per run): each run of
    either law gives the bits it gives alone, and its own torque."""
    n = len(B)
    q = Rotation.random(n, random_state=21).as_quat()
    w = np.random.default_rng(22).normal(size=(n, 3)) * 0.1
    for build in (lambda b: m2r.M2rLaw(m2r_params(1.0, B=b, proposition=proposition if len(b) else 1)),
                  lambda b: m2s.M2sLaw(m2s_params(B=b))):
        batch, alone = build(B), [build(B[i].tolist()) for i in range(n)]
        for k in range(4):
            u, st = batch.control(0.1 * k, q, w)
            for i, law in enumerate(alone):
                ui, sti = law.control(0.1 * k, q[i], w[i])
                assert_array_equal(u[i], ui)
                for key in st:
                    assert_array_equal(np.broadcast_to(st[key], (n,) + np.shape(sti[key]))[i], sti[key], err_msg=key)
            if k == 0:   # B reaches every run: its first torque is not that of B = I
                u_identity = build([]).control(0.0, q, w)[0]
                assert not np.any(np.all(u == u_identity, axis=-1))


# --- Propositions 1 and 2 -------------------------------------------------------------------------

@pytest.mark.parametrize('f', ['eq24', 'eq25'])
def test_torque_bounds_prop1_prop2_hold_on_random_states(f):
    """No torque component above u_max when eq. (20) (B = I) or eq. (23) (random B) holds with
    equality, on 20 000 random attitudes and rates up to 10 rad/s; the bounds are nearly reached."""
    n = 20000
    rng = np.random.default_rng(16)
    R = random_rotations(n, 17)
    Rd = random_rotations(1, 18)[0]
    w = rng.uniform(-10, 10, size=(n, 3)) * rng.uniform(0, 1, size=(n, 1)) ** 3
    u_max = 1.0
    m2r.check_m2r_gains(0.5, 0.5, u_max)
    u, _ = m2r.m2r_torque(R, w, Rd, 0.5, 0.5, A123, f=f)
    assert np.abs(u).max() <= m2r.prop1_bound(0.5, 0.5) * (1 + 1e-12)
    assert np.abs(u).max() > 0.7 * u_max
    # Proposition 2 with a random B and per-axis limits: largest α = β meeting eq. (23)
    B = np.eye(3) + 0.3 * rng.normal(size=(3, 3))
    B_inv = np.linalg.inv(B)
    u_lim = np.array([1.0, 0.5, 2.0])
    k = np.min(u_lim / (np.linalg.norm(B_inv, axis=1) * (1 + math.sqrt(3))))
    m2r.check_m2r_gains(k, k, u_lim, B, proposition=2)
    u, _ = m2r.m2r_torque(R, w, Rd, k, k, A123, B_inv=B_inv, f=f)
    assert np.all(np.abs(u) <= m2r.prop2_bound(k, k, B) * (1 + 1e-12))
    assert np.all(np.abs(u) <= u_lim * (1 + 1e-12))


def test_parameter_check_refuses_bad_alpha_beta():
    with pytest.raises(ValueError, match=r'alpha=0.6, beta=0.5 violate eq. \(20\).*1.1 N m > u_max = 1'):
        m2r.check_m2r_gains(0.6, 0.5, 1.0)
    with pytest.raises(ValueError, match=r'eq. \(23\) on axis 2'):
        m2r.check_m2r_gains(0.2, 0.2, [1.0, 0.5, 1.0], proposition=2)
    with pytest.raises(ValueError, match='beta'):
        m2r.check_m2r_gains(0.5, -0.1, 1.0)
    with pytest.raises(ValueError, match=r'alpha=0.05, beta=0.06'):  # second run of a batch
        m2r.check_m2r_gains(np.array([0.5, 0.05]), np.array([0.5, 0.06]), np.array([[1.0], [0.1]]))
    with pytest.raises(ValueError, match=r'eq. \(20\)'):
        m2r.M2rLaw(m2r_params(1.0, alpha=0.7))
    # A rotation B: σmin = 1, but ‖B⁻¹x‖∞ can exceed ‖x‖∞: (18) is not a bound (readings R2)
    B = Rotation.from_rotvec([0.3, -0.6, 0.4]).as_matrix()
    with pytest.raises(ValueError, match='Proposition 1'):
        m2r.check_m2r_gains(0.1, 0.1, 1.0, B)
    R = random_rotations(5000, 19)
    w = np.random.default_rng(20).normal(size=(5000, 3)) * 3
    u, _ = m2r.m2r_torque(R, w, np.eye(3), 0.5, 0.5, A123, B_inv=np.linalg.inv(B))
    assert np.abs(u).max() > m2r.prop1_bound(0.5, 0.5, B) * 1.05


def test_m2r_torque_does_not_depend_on_the_scale_of_A():
    """Kp S = α/tr(A) Σ a_i (...) is invariant to A -> cA: A = diag(0.1, 0.2, 0.3) "increases Kp"
    (section 4.1) but gives exactly the same law as diag(1, 2, 3) (readings R4)."""
    R = random_rotations(200, 21)
    w = np.random.default_rng(22).normal(size=(200, 3))
    u1, _ = m2r.m2r_torque(R, w, np.eye(3), 0.5, 0.5, A123)
    u2, st = m2r.m2r_torque(R, w, np.eye(3), 0.5, 0.5, 0.1 * A123)
    assert_allclose(u1, u2, rtol=1e-12, atol=1e-15)
    assert_allclose(st['Kp'], 0.5 / 0.6)


# --- saturation, VAG, extremum tracking ---------------------------------------------------------

def test_cutoff_and_scaling_eq47_51():
    rng = np.random.default_rng(23)
    u = rng.normal(size=(1000, 3)) * 3
    lim = np.array([1.0, 0.5, 2.0])
    c = sat.sat_cutoff(u, lim)
    s = sat.sat_scaling(u, lim)
    inside = np.all(np.abs(u) <= lim, axis=1)
    assert_array_equal(c[inside], u[inside])
    assert_array_equal(s[inside], u[inside])
    assert np.all(np.abs(c) <= lim) and np.all(np.abs(s) <= lim * (1 + 1e-15))
    out = ~inside
    # scaling keeps the direction and touches the box (α_max of eq. 50)
    assert_allclose(np.cross(s[out], u[out]), 0.0, atol=1e-12)
    assert np.all(np.sum(s[out] * u[out], axis=1) > 0)
    assert_allclose(np.max(np.abs(s[out]) / lim, axis=1), 1.0, rtol=1e-12)
    assert_array_equal(c[out], np.clip(u[out], -lim, lim))


def test_qsat_eq56():
    u_max = np.array([0.01, 0.01, 0.01])
    assert sat.qsat(3.0, 10000.0, np.array([0.005, -0.01, 0.0]), u_max, 0.001) == 3.0
    u = np.array([0.03, 0.0, -0.005])
    excess = np.linalg.norm(np.abs(u) - u_max) / np.linalg.norm(u_max)
    assert_allclose(sat.qsat(3.0, 10000.0, u, u_max, 0.001), (1 + 0.001 * excess) * 3.0, rtol=1e-15)
    pos = np.linalg.norm(np.maximum(np.abs(u) - u_max, 0)) / np.linalg.norm(u_max)
    assert_allclose(sat.qsat(3.0, 1e4, u, u_max, 0.001, excess='positive'), (1 + 0.001 * pos) * 3.0)
    assert sat.qsat(9999.9, 10000.0, 100 * u, u_max, 0.001) == 10000.0  # capped
    assert sat.qsat(20000.0, 10000.0, u, u_max, 0.001) == 10000.0


def test_extremum_tracking_bisects_the_spin_rate():
    """Eq. (62)-(63) with δ_0 = ω̄_0: down when the axis error exceeds φ_max, up (never above
    ω̄_0) when within, steps K_ω δ, only after t_max since the last change."""
    axis = np.array([0.0, 0.0, 1.0])
    bad = np.array([1.0, 0.0, 1.0])   # 45° off
    good = np.array([0.0, 0.01, 1.0])
    args = dict(omega_bar0=0.1, t_max=250.0, phi_max=math.radians(10), K_omega=0.5)
    ob, d, tl, phi = sat.extremum_tracking_step(100.0, bad, axis, omega_bar=0.1, delta=0.1, t_last=0.0, **args)
    assert_allclose([ob, d, tl], [0.1, 0.1, 0.0], rtol=0)  # Δt ≤ t_max: no change
    assert_allclose(phi, math.pi / 4)
    ob, d, tl, _ = sat.extremum_tracking_step(251.0, bad, axis, omega_bar=0.1, delta=0.1, t_last=0.0, **args)
    assert_allclose([ob, d, tl], [0.05, 0.05, 251.0], rtol=1e-15)
    ob, d, tl, _ = sat.extremum_tracking_step(502.0, good, axis, omega_bar=ob, delta=d, t_last=tl, **args)
    assert_allclose([ob, d, tl], [0.075, 0.025, 502.0], rtol=1e-15)
    ob2, d2, tl2, _ = sat.extremum_tracking_step(900.0, good, axis, omega_bar=0.1, delta=d, t_last=tl, **args)
    assert_allclose([ob2, d2, tl2], [0.1, 0.025, 502.0], rtol=0)  # at ω̄_0 and aligned: stays


def test_k0_metric_eq29():
    e = np.concatenate([np.linspace(1, 0, 300), np.full(500, 0.01)])
    k = analysis.k0_metric(e, window=200, threshold=0.03)
    first_small = int(np.argmax(e < 0.03))
    assert k == first_small + 200
    assert analysis.k0_metric(np.ones(1000)) == -1


# --- closed loops --------------------------------------------------------------------------------

def test_nonprincipal_spin_steady_torque_eq59():
    """Section 7.3: ω_d × Jω_d = [0.0047, -0.0124, 0.0077] N m (printed "rad/sec"), ‖·‖∞ = 0.0124."""
    tau = np.cross(WD_NONPRINCIPAL, J52 @ WD_NONPRINCIPAL)
    assert_allclose(tau, [0.0047, -0.0124, 0.0077], atol=5e-5)
    assert_allclose(np.abs(tau).max(), 0.0124, atol=5e-5)


@pytest.fixture(scope='module')
def m2r_runs():
    """Section 4: u_max = 1 and 0.1 N m (α = β = u_max/2), then u_max = 1 N m with the constant
    disturbances z_d = 0.1 and 0.2 N m per axis (section 4.1). 450 s, 0.1 s hold, one batch."""
    u_max = np.array([1.0, 0.1, 1.0, 1.0])
    dist = np.array([[0.0] * 3, [0.0] * 3, [0.1] * 3, [0.2] * 3])
    law = m2r.M2rLaw(m2r_params(u_max))
    return closed_loop(law, J26, IDENTITY, [1.0, -1.0, 0.5], 450.0, 0.1,
                       np.repeat(u_max[:, None], 3, 1), dist=dist)


@pytest.mark.slow
def test_m2r_converges_at_1_and_0p1_Nm(m2r_runs):
    """Figures 1-2: from θ = π and ω(0) = [1, -1, 0.5] to rest at R_d; at 0.1 N m slower, θ
    oscillating (spinning past 2π); V never increases; no component above u_max."""
    r = m2r_runs
    th, w, V = r['theta'], np.linalg.norm(r['w'], axis=-1), r['V']
    assert_allclose(th[0], [np.pi] * 4, atol=1e-12)
    assert th[at(r, 60), 0] < 0.01 and w[at(r, 60), 0] < 1e-3        # ours 60 s: 2e-3 rad
    assert th[at(r, 60), 1] > 0.5                                     # still far at 0.1 N m
    assert th[-1, 1] < 1e-3 and w[-1, 1] < 1e-4                       # ours 450 s: 1e-5 rad
    t01 = th[:at(r, 100), 1]
    assert t01[at(r, 20):].max() > t01[at(r, 5):at(r, 20)].min() + 0.5  # θ goes back up
    assert np.all(np.diff(V[:, :2], axis=0) <= 1e-12)
    assert np.abs(r['u'][:, 0]).max() <= 1.0 and np.abs(r['u'][:, 1]).max() <= 0.1


def _max_min_S(a):
    """max over rotations of min_i S_i(R̃) (multi-start Nelder-Mead on the rotation vector)."""
    rng = np.random.default_rng(0)

    def negmin(rv):
        return -m2r.s_vector(Rotation.from_rotvec(rv).as_matrix(), a).min()
    return -min(minimize(negmin, rng.normal(size=3), method='Nelder-Mead').fun for _ in range(20))


@pytest.mark.slow
def test_m2r_constant_disturbance_torque_balance(m2r_runs):
    """Section 4.1, figures 4 and 6, explained by the torque balance at rest: Kp S(R̃) = z_d.
    0.1 N m: the rest attitude solving α/tr(A) S = z_d (θ = 0.586 rad) is reached: a steady error.
    0.2 N m: no attitude gives Kp S = z_d (max_R min_i Kp S_i = 0.184 N m < 0.2): no rest."""
    r = m2r_runs
    Kp = 0.5 / 6.0
    from scipy.optimize import fsolve
    rv = fsolve(lambda v: Kp * m2r.s_vector(Rotation.from_rotvec(v).as_matrix(), A123) - 0.1,
                [0.24, 0.3, 0.4], xtol=1e-13)
    theta_ss = np.linalg.norm(rv)
    assert_allclose(theta_ss, 0.5858, atol=1e-4)
    assert_allclose(r['theta'][-1, 2], theta_ss, atol=1e-4)
    assert np.linalg.norm(r['w'][-1, 2]) < 1e-5
    cap = Kp * _max_min_S(A123)
    assert 0.1 < cap < 0.2
    assert_allclose(cap, 0.1837, atol=2e-4)
    w_tail = np.linalg.norm(r['w'][at(r, 200):, 3], axis=-1)
    assert w_tail.min() > 0.008  # never at rest (ours: ≥ 0.0118 rad/s; a slow tumble, figure 6)
    assert np.abs(r['u'][at(r, 200):, 3]).max() > 0.2  # the law keeps pushing against z_d


@pytest.fixture(scope='module')
def m2s_10_1():
    """Section 6.3 (figures 8-10): unsaturated, cutoff and scaling at 10 N m and at 1 N m; 60 s
    with a 0.02 s hold (readings R7: the unsaturated adaptive loop needs ≤ 0.02 s)."""
    sats = ['none', 'cutoff', 'scaling', 'cutoff', 'scaling']
    u_max = np.array([np.inf, 10.0, 10.0, 1.0, 1.0])
    law = m2s.M2sLaw(m2s_params(saturation=sats, u_max=u_max[:, None], max_step=0.02))
    return closed_loop(law, J52, Q_R0_M2S, W0_M2S, 60.0, 0.02, np.repeat(u_max[:, None], 3, 1),
                       every=10)


@pytest.mark.slow
def test_m2s_cutoff_scaling_converge_at_10_and_diverge_at_1_Nm(m2s_10_1):
    r = m2s_10_1
    th, we = r['theta'], np.linalg.norm(r['w_err'], axis=-1)
    gmax = np.abs(r['gamma_hat']).max(axis=-1)
    # unsaturated: spin reached in well under a minute
    assert th[-1, 0] < 1e-3 and we[-1, 0] < 1e-5
    # 10 N m: saturation active (commanded torque > 10 N m), slower, still converging
    for c in (1, 2):
        assert np.abs(r['u_cmd'][:, c]).max() > 10.0
        assert th[-1, c] < 0.02 and we[-1, c] < 2e-3
        assert th[-1, c] > th[-1, 0]
        assert np.all(np.abs(r['u'][:, c]) <= 10.0 + 1e-12)
    # 1 N m: the inertia estimates diverge and V grows (figure 10), no spin
    for c in (3, 4):
        assert gmax[-1, c] > 100.0
        assert r['V'][-1, c] > 1000 * r['V'][0, c]
        assert we[-1, c] > 1.0
        assert np.all(np.abs(r['u'][:, c]) <= 1.0 + 1e-12)


def test_m2s_estimator_step_refinement_converges():
    """The compensator integrates eq. (37) between control calls (fixed-step RK4, max_step):
    refining max_step changes the closed loop less and less (4th order); at 0.0125 s the result no
    longer changes (< 1e-9 on the state after 20 s with 0.1 s control calls and R_d(t) moving)."""
    finals = []
    for ms in (0.1, 0.05, 0.025, 0.0125):
        law = m2s.M2sLaw(m2s_params(saturation='cutoff', u_max=10.0, max_step=ms))
        r = closed_loop(law, J52, Q_R0_M2S, W0_M2S, 8.0, 0.1, np.full(3, 10.0), max_step=0.02)
        finals.append(np.concatenate([r['q'][-1], r['w'][-1], r['gamma_hat'][-1]]))
    d = [np.abs(finals[i + 1] - finals[i]).max() for i in range(3)]
    assert d[0] > 0
    assert d[1] < d[0] / 8 and d[2] < d[1] / 8
    assert d[2] < 1e-9


@pytest.mark.paper
@pytest.mark.slow
def test_LONG_m2s_vag_low_torque_reaches_the_spin():
    """LONG (9000 steps x 5 runs, ~20 s). Section 7.2-7.3 (figures 11, 13): VAG-C and VAG-S
    (q_max = 10 000, K_Q = 0.001) reach the intermediate-axis spin at 0.01 N m where plain cutoff
    does not; the non-principal spin at 0.02 N m is reached with a steady torque ω_d × Jω_d,
    ‖u‖∞ = 0.0124 N m (paper: "close to the theoretical value"). 0.1 s hold."""
    sats = ['cutoff', 'scaling', 'cutoff', 'cutoff', 'scaling']
    vag = [True, True, False, True, True]
    u_max = np.array([0.01, 0.01, 0.01, 0.02, 0.02])
    wd = np.array([WD_INTERMEDIATE] * 3 + [WD_NONPRINCIPAL] * 2)
    law = m2s.M2sLaw(m2s_params(saturation=sats, vag=vag, u_max=u_max[:, None], max_step=0.1,
                                **{'target.rate': wd.tolist()}))
    r = closed_loop(law, J52, Q_R0_M2S, W0_M2S, 900.0, 0.1, np.repeat(u_max[:, None], 3, 1),
                    every=50)
    th, we = r['theta'][-1], np.linalg.norm(r['w_err'][-1], axis=-1)
    for c in (0, 1, 3, 4):
        assert th[c] < 5e-3 and we[c] < 1e-4, (c, th[c], we[c])
        assert r['q_vag'][-1, c] == 10000.0
    assert th[2] > 0.1 and we[2] > 0.1 and np.abs(r['gamma_hat'][-1, 2]).max() > 10
    for c in (3, 4):
        u = r['u'][-1, c]
        assert_allclose(np.abs(u).max(), 0.01237, rtol=0.02)
        assert_allclose(u, np.cross(WD_NONPRINCIPAL, J52 @ WD_NONPRINCIPAL), atol=5e-4)


@pytest.fixture(scope='module')
def m2s_disturbance():
    """Section 7.5 (figures 16-18): non-principal spin under z_d = -0.1/√3 [1, 1, 1] N m (eq. 68)
    with disturbance estimation (C_d = I, A_d = 0, D = I): unsaturated, VAG-C at 10 and 1 N m.
    60 s with a 0.02 s hold."""
    sats, vag = ['none', 'cutoff', 'cutoff'], [False, True, True]
    u_max = np.array([np.inf, 10.0, 1.0])
    law = m2s.M2sLaw(m2s_params(saturation=sats, vag=vag, u_max=u_max[:, None], max_step=0.02,
                                C_d=np.eye(3).ravel().tolist(),
                                **{'target.rate': WD_NONPRINCIPAL.tolist()}))
    zd = np.broadcast_to(-0.1 / math.sqrt(3.0) * np.ones(3), (3, 3))
    return closed_loop(law, J52, Q_R0_M2S, W0_M2S, 60.0, 0.02, np.repeat(u_max[:, None], 3, 1),
                       dist=zd, every=10)


@pytest.mark.slow
def test_m2s_disturbance_estimate_diverges_at_1_Nm(m2s_disturbance):
    """Unsaturated: the spin is reached with a bounded disturbance estimate (figure 16). VAG-C at
    10 N m: converging at 60 s after a large transient of d̂ (ours: θ = 0.012 rad at 60 s, 1e-3
    at 200 s). VAG-C at 1 N m: d̂ (not slowed by VAG) diverges to ~10 N m against |z_d,i| =
    0.058 N m, the controller fights a "phantom" disturbance and never settles (figures 17-18)."""
    r = m2s_disturbance
    th, we = r['theta'], np.linalg.norm(r['w_err'], axis=-1)
    dinf = np.abs(r['d_hat']).max(axis=-1)
    half = at(r, 30)
    assert th[-1, 0] < 0.01 and we[-1, 0] < 0.01 and dinf[-1, 0] < 0.2  # ours: 2e-3 rad, 0.095 N m
    assert th[-1, 1] < 0.05 and we[-1, 1] < 0.03
    assert np.median(dinf[half:, 2]) > 5.0
    assert np.median(th[half:, 2]) > 1.0 and np.median(we[half:, 2]) > 0.5  # tumbling


class _Recording(dict):
    """A section that records how the law reads it: ``p[key]`` (no fallback) or ``p.get(key, ...)``."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.indexed, self.fetched = set(), set()

    def __getitem__(self, key):
        self.indexed.add(key)
        return super().__getitem__(key)

    def get(self, key, default=None):
        self.fetched.add(key)
        return super().get(key, default)


@pytest.mark.parametrize('schema, law_class', [(M2S_SCHEMA, m2s.M2sLaw), (M2R_SCHEMA, m2r.M2rLaw)],
                         ids=['M2S', 'M2R'])
def test_inertia_free_laws_take_their_defaults_from_the_schema(schema, law_class):
    """The schema is the one source of defaults: the law reads every schema key it uses as
    ``p[key]`` (a section without it is a KeyError, never completed by a default of the law's own)
    and a section validated from the required keys alone gives the law the schema's values."""
    section = schema.validate({'inertia': np.diag(J52).tolist(), 'alpha': 1.0, 'beta': 1.0,
                               'actuator': 'torquers'})
    recorded = _Recording(section)
    law = law_class(recorded)
    assert recorded.indexed <= set(schema.by_name)
    assert not recorded.fetched & set(schema.by_name), 'schema keys read with a fallback of the law'
    for key in recorded.indexed:
        with pytest.raises(KeyError):
            law_class({k: v for k, v in section.items() if k != key})
    d = schema_defaults(schema)
    assert_array_equal(law.a, d['A'])
    assert law.B is None and d['B'] == []
    assert_array_equal(law.u_max, [d['torquers.max_torque']])
    if law_class is m2r.M2rLaw:
        assert (law.f, law.omega_bar) == (d['f'], d['omega_bar'])
        return
    # the two defaults law and schema used to disagree on (issue 17): the schema's hold
    assert law.max_step == d['max_step'] == 0.02
    assert law.saturation == sat.SAT_CODES[d['saturation']] == sat.SAT_CODES['clip']
    assert (law.q_max, law.K_Q, law.t_max, law.phi_max, law.K_omega, law.vag_excess) == (
        d['q_max'], d['K_Q'], d['t_max'], d['phi_max'], d['K_omega'], d['vag_excess'])
    assert (bool(law.vag), law.vag_disturbance, law.extremum) == (d['vag'], d['vag_disturbance'], d['extremum'])
    assert_array_equal(law.gamma0, [*d['J_hat0'], 0.0, 0.0, 0.0])
    assert law.C_d is None and law.A_d is None and law.d_true is None and law.d_hat0.shape == (0,)
    assert_array_equal(law.K1, np.eye(3))
    assert_array_equal(law.Q0, np.eye(6))
    assert_array_equal(law.delta0, law.omega_bar0)  # delta0 = 0: ||w_d||


def test_section_laws_refuse_bad_parameters():
    with pytest.raises(ValueError, match='distinct'):
        m2r.M2rLaw(m2r_params(1.0, A=[1.0, 1.0, 3.0]))
    with pytest.raises(ValueError, match='target.rate'):
        m2r.M2rLaw(m2r_params(1.0, **{'target.rate': [0.0, 0.1, 0.0]}))
    with pytest.raises(ValueError, match='saturation'):
        m2s.M2sLaw(m2s_params(saturation='clamp'))
    with pytest.raises(ValueError, match='max_step'):
        m2s.M2sLaw(m2s_params(max_step=0.0))
    with pytest.raises(ValueError, match='K1'):
        m2s.M2sLaw(m2s_params(K1=[1.0, 2.0]))
    law = m2r.M2rLaw(m2r_params(0.1))
    u, st = law.control(0.0, IDENTITY, np.array([1.0, -1.0, 0.5]))
    assert np.abs(u).max() <= 0.1 and st['theta'] == pytest.approx(np.pi)
    assert law.published_status(st)['mode'] in ('saturated', 'unsaturated')
