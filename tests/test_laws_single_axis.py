"""Seed 003's single-axis pointing with two wheels and non-zero momentum
(adcs_controllers.laws.single_axis): geometry (eq. 6-16), controller A (eq. 18-22, LQR) and
controller B (eq. 24-33), checked on the pure plant. No ROS; ~15 s in total.

Closed loops (section 5): J = diag(10, 8, 9) kg m² (total, wheels locked), wheels on ê1, ê2 with
J_w = 0.0077 kg m², torque mode, motor torque limit 20 mN m, the ê3 wheel failed (absent: h3 = 0),
H0 = 0.85 N m s, λ = 5°, α = 45°, K_p = 0.25, K_Ψ = 0.1, K_h = 0.1; LQR Q = diag(0.1, 100, 100,
100, 1), R = diag(100, 100); ε_ω = 0.01 rad/s, ε_Φ = 1°. The paper does not give σ̂'s azimuth η:
we take η = 0 (σ̂ in the ê1-ê3 plane). Inertial frame = F_I of eq. 6: H = (0, 0, H0), τ̂ = (cos α,
0, sin α). Control period 1 s (zero-order hold; not given by the paper), RK4 at 1 s.

Initial momentum split: ALL of H0 in the body, wheels at rest (ω0 = J⁻¹ R(q0)ᵀ H). The text says
that during stage 1 "the angular velocity ω is controlled and decreased towards zero, while the
angular momentum is loaded into the two active reaction wheels" (section 3) and that step 1
"reduces the residual angular speed" (section 1): the wheels start unloaded. (Any other split
needs ω3 = H3/J3 anyway, since the failed wheel holds nothing.)
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from adcs_controllers.laws import single_axis as sa
from adcs_core.attitude import cross, pointing_error, rotate_to_body, rotate_to_inertial
from adcs_sim.truth.plant import Plant, ReactionWheels, WheelCommand

J = np.diag([10.0, 8.0, 9.0])
JW = 0.0077
H0 = 0.85
LAM, ALPHA = np.deg2rad(5.0), np.deg2rad(45.0)
SIGMA = np.array([np.cos(LAM), 0.0, np.sin(LAM)])          # η = 0 (not given by the paper)
TAU = np.array([np.cos(ALPHA), 0.0, np.sin(ALPHA)])
H_N = np.array([0.0, 0.0, H0])
P = dict(inertia=[10.0, 8.0, 9.0], sigma=SIGMA.tolist(), tau=TAU.tolist(), K_p=0.25, K_h=0.1,
         K_Psi=0.1)
MAX_TORQUE = 0.02
PERIOD = 1.0


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_geometry(rng, n):
    sigma = unit(rng.normal(size=(n, 3)))
    tau = unit(rng.normal(size=(n, 3)))
    H = rng.normal(size=(n, 3)) * rng.uniform(0.1, 2.0, size=(n, 1))
    lam, _ = sa.body_axis_angles(sigma)
    alpha = sa.elevation(tau, H)
    feasible = np.abs(alpha) < np.pi / 2 - np.abs(lam) - 1e-9
    return sigma, tau, H, feasible


# --- geometry: eq. 6-16 ----------------------------------------------------------------------------

def test_final_attitudes_point_sigma_at_tau_at_rest_with_all_momentum_in_the_wheels():
    """For random feasible (σ̂, τ̂, H), both attitudes of eq. (16): R(q_f) σ̂ = τ̂; at rest the
    body-axes momentum is all in the wheels, H_B = h_f = H0 (sin Φ_f, cos Φ_f, 0) (h3 = 0);
    Θ_f = π/2 and (Ψ_f, Φ_f) are read back by the 3-1-3 extraction."""
    sigma, tau, H, ok = random_geometry(np.random.default_rng(0), 3000)
    assert 0.5 < ok.mean() < 0.95          # both feasible and infeasible draws occur
    sigma, tau, H = sigma[ok], tau[ok], H[ok]
    q_f, psi_f, phi_f = sa.final_attitudes(sigma, tau, H)
    assert q_f.shape == (len(H), 2, 4)
    s_inertial = rotate_to_inertial(q_f, sigma[:, None, :])
    assert_allclose(s_inertial, np.broadcast_to(tau[:, None, :], s_inertial.shape), atol=1e-12)
    H_body = rotate_to_body(q_f, H[:, None, :])
    h_f = sa.target_momentum(phi_f, np.linalg.norm(H, axis=-1)[:, None])
    assert_allclose(H_body, h_f, atol=1e-12)
    assert np.abs(H_body[..., 2]).max() < 1e-12
    frame = sa.inertial_frame(H, tau)
    for k in range(2):
        psi, theta, phi = sa.attitude_angles(q_f[:, k], frame)
        assert_allclose(sa.wrap(psi - psi_f[:, k]), 0.0, atol=1e-12)
        assert_allclose(theta, np.pi / 2, atol=1e-12)
        assert_allclose(sa.wrap(phi - phi_f[:, k]), 0.0, atol=1e-12)
        assert pointing_error(q_f[:, k], sigma, tau).max() < 1e-7
    # the two solutions are different attitudes
    assert np.all(np.abs(np.sum(q_f[:, 0] * q_f[:, 1], axis=-1)) < 1 - 1e-9)


@pytest.mark.paper
def test_paper_case_eq13_eq15():
    """λ = 5°, α = 45°, η = 0: sin Ψ* = sin 5°/cos 45° (Ψ* = 7.0801°), Φ* = atan2(sin α,
    cos α cos Ψ*) = 45.2193°; second solution (180° - Ψ*, 180° - Φ*)."""
    psi, phi = sa.final_angles(LAM, 0.0, ALPHA)
    assert_allclose(np.degrees(psi), [7.080101, 180 - 7.080101], atol=1e-5)
    assert_allclose(np.degrees(phi), [45.219281, 180 - 45.219281], atol=1e-5)
    # the inertial frame of eq. 6 for H = H0 ô3, τ̂ = (cos α, 0, sin α) is the identity
    assert_allclose(sa.inertial_frame(H_N, TAU), np.eye(3), atol=1e-15)
    assert_allclose(sa.elevation(TAU, H_N), ALPHA, atol=1e-15)


def test_infeasible_requests_are_refused_with_the_condition_and_numbers():
    sigma, tau, H, ok = random_geometry(np.random.default_rng(1), 500)
    bad = (~ok) & (np.abs(sa.elevation(tau, H)) > np.pi / 2 - np.abs(sa.body_axis_angles(sigma)[0]) + 1e-6)
    assert bad.sum() > 20
    for i in np.flatnonzero(bad)[:20]:
        with pytest.raises(ValueError, match=r'infeasible.*\|alpha\| <= pi/2 - \|lambda\|.*deg'):
            sa.final_attitudes(sigma[i], tau[i], H[i])
    with pytest.raises(ValueError, match='runs'):
        sa.final_attitudes(sigma, tau, H)
    # λ = 50°, α = 45°: 45 > 90 - 50
    with pytest.raises(ValueError, match=r'\|alpha\| = 45 deg > 90 - \|lambda\| = 40 deg'):
        sa.final_angles(np.deg2rad(50.0), 0.0, ALPHA)
    sa.final_angles(np.deg2rad(45.0), 0.0, ALPHA)   # the boundary is feasible
    steep = dict(P, sigma=[np.cos(0.9), 0.0, np.sin(0.9)])
    for cls in (sa.PointingALaw, sa.PointingBLaw):
        with pytest.raises(ValueError, match='infeasible'):
            cls(dict(steep, H=H_N.tolist()))             # H given: refused at construction
        law = cls(steep)                                 # H measured: refused at the first call
        with pytest.raises(ValueError, match='infeasible'):
            law.control(0.0, np.array([0, 0, 0, 1.0]), np.array([0, 0, H0 / 9]), np.zeros(3))


def test_dcm_313_matches_scipy_and_euler_rates_eq8():
    rng = np.random.default_rng(2)
    n = 200
    psi, phi = rng.uniform(-np.pi, np.pi, (2, n))
    theta = rng.uniform(0.1, np.pi - 0.1, n)
    T = sa.dcm_313(psi, theta, phi)
    R = Rotation.from_euler('ZXZ', np.stack([psi, theta, phi], axis=-1)).as_matrix()
    assert_allclose(np.swapaxes(T, -1, -2), R, atol=1e-14)   # T_BI = body <- inertial
    back = sa.euler_313(T)
    for a, b in zip(back, (psi, theta, phi)):
        assert_allclose(sa.wrap(a - b), 0.0, atol=1e-12)
    # eq. 8: angle rates along the motion, by central differences on the quaternion kinematics
    q = Rotation.from_matrix(np.swapaxes(T, -1, -2)).as_quat()
    w = rng.normal(size=(n, 3)) * 0.05
    dt = 1e-5
    frame = np.broadcast_to(np.eye(3), (n, 3, 3))
    qp = (Rotation.from_quat(q) * Rotation.from_rotvec(w * dt)).as_quat()
    qm = (Rotation.from_quat(q) * Rotation.from_rotvec(-w * dt)).as_quat()
    ap, am = sa.attitude_angles(qp, frame), sa.attitude_angles(qm, frame)
    fd = [sa.wrap(a - b) / (2 * dt) for a, b in zip(ap, am)]
    for got, want in zip(sa.euler_rates_313(theta, phi, w), fd):
        assert_allclose(got, want, rtol=1e-6, atol=1e-9)


# --- controller A: eq. 18 linearisation, LQR, eq. 20-22 --------------------------------------------

def _reduced_model(x, u, phi_f, psi_f, state):
    """Nonlinear d/dt of (e_Ψ, ω, e_h1|2) (eq. 4, 5, 8) at a state near rest (Θ, Φ from momentum
    conservation), for the finite-difference check of eq. 18."""
    h_f = sa.target_momentum(phi_f, H0)
    w = x[1:4]
    e_h = np.zeros(3)
    i, j = (0, 1) if state == 'h1' else (1, 0)
    e_h[i] = x[4]
    # the other wheel component from |J w + h| = H0 (the branch near h_f)
    a = J @ w + h_f + e_h
    a[j] = np.sign(h_f[j]) * np.sqrt(H0 ** 2 - a[i] ** 2 - a[2] ** 2)
    h = a - J @ w
    h[2] = 0.0
    Hb = J @ w + h
    theta = np.arccos(Hb[2] / H0)
    phi = np.arctan2(Hb[0], Hb[1])
    dpsi, _, _ = sa.euler_rates_313(theta, phi, w)
    u3 = np.array([u[0], u[1], 0.0])
    dw = np.linalg.solve(J, u3 - np.cross(w, Hb))
    return np.concatenate([[dpsi], dw, [-u3[i]]])


@pytest.mark.parametrize('state', ['h1', 'h2'])
def test_linearisation_eq18_matches_finite_differences(state):
    """A, B of eq. (18) (with ``-ω x h_f = h_f x ω``) equal the Jacobian of the nonlinear model."""
    psi, phi = sa.final_angles(LAM, 0.0, ALPHA)
    h_f = sa.target_momentum(phi[0], H0)
    A, B = sa.linearisation(J, h_f, state)
    x0, u0, eps = np.zeros(5), np.zeros(2), 1e-7
    A_fd = np.stack([(_reduced_model(x0 + eps * e, u0, phi[0], psi[0], state)
                      - _reduced_model(x0 - eps * e, u0, phi[0], psi[0], state)) / (2 * eps)
                     for e in np.eye(5)], axis=1)
    B_fd = np.stack([(_reduced_model(x0, u0 + eps * e, phi[0], psi[0], state)
                      - _reduced_model(x0, u0 - eps * e, phi[0], psi[0], state)) / (2 * eps)
                     for e in np.eye(2)], axis=1)
    assert_allclose(A, A_fd, atol=1e-7)
    assert_allclose(B, B_fd, atol=1e-7)


def test_lqr_gain_and_dual_state_choice():
    """K = R⁻¹BᵀP solves the ARE, A - BK is Hurwitz; at Φ_f = ±π/2 (h_f2 = 0) the e_h1 model is
    uncontrollable (rank 4) and the dual e_h2 model (the 'auto' choice) is controllable."""
    psi, phi = sa.final_angles(LAM, 0.0, ALPHA)
    for phi_f in (phi[0], phi[1], 0.3, -2.0):
        h_f = sa.target_momentum(phi_f, H0)
        for state in ('h1', 'h2'):
            K = sa.lqr_gain(J, h_f, momentum_state=state)
            A, B = sa.linearisation(J, h_f, state)
            assert np.linalg.eigvals(A - B @ K).real.max() < -0.02
    for phi_f in (np.pi / 2, -np.pi / 2):
        h_f = sa.target_momentum(phi_f, H0)

        def rank(state):
            A, B = sa.linearisation(J, h_f, state)
            C = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(5)])
            return np.linalg.matrix_rank(C, tol=1e-9)
        assert rank('h1') == 4 and rank('h2') == 5
        assert sa.momentum_state_choice(phi_f) == 2
    assert sa.momentum_state_choice(0.2) == 1
    with pytest.raises(ValueError):
        sa.momentum_state_choice(0.2, 'h3')


def test_stage1_eq22_sign_makes_eq21_negative():
    """dV/dt = (ω - K_h e_h)ᵀu (eq. 21, V = ½ωᵀJω + ½K_h e_hᵀe_h). With u = -K_p(ω - K_h e_h),
    u3 = 0 (our reading) it is <= 0 on random states; the printed u = +K_p(...) makes it >= 0.
    Checked against the exact derivative along eq. 4-5."""
    rng = np.random.default_rng(3)
    n = 5000
    w = rng.normal(size=(n, 3)) * 0.05
    h = rng.normal(size=(n, 3)) * 0.5
    h[:, 2] = 0.0
    h_f = sa.target_momentum(rng.uniform(-np.pi, np.pi, n), H0)
    u = sa.momentum_stabilisation_torque(w, h, h_f, 0.25, 0.1)
    assert_array_equal(u[:, 2], 0.0)
    dw = np.linalg.solve(J, (u - cross(w, w @ J + h))[..., None])[..., 0]
    vdot = np.sum(w * (dw @ J), axis=-1) + 0.1 * np.sum((h - h_f) * -u, axis=-1)
    assert_allclose(vdot, np.sum((w - 0.1 * (h - h_f)) * u, axis=-1), rtol=1e-9, atol=1e-15)
    assert vdot.max() <= 1e-15
    assert np.sum(-(w - 0.1 * (h - h_f)) * u, axis=-1).min() >= -1e-15   # printed sign: >= 0


def test_controller_b_nominal_lyapunov_eq32():
    """The nominal part (eq. 30) with u of eq. 33: dV_e/dt = -K_Ψ e_Ψ²/sinΘ + (e_ω - K_h e_h)ᵀu
    = -K_Ψ e_Ψ²/sinΘ - K_p |(e_ω - K_h e_h)_{1,2}|² <= 0; and ω = ω_des gives dΨ/dt = -K_Ψ e_Ψ/sinΘ."""
    rng = np.random.default_rng(4)
    n = 3000
    q = Rotation.random(n, random_state=4).as_quat()
    w = rng.normal(size=(n, 3)) * 0.05
    h = np.concatenate([rng.normal(size=(n, 2)) * 0.5, np.zeros((n, 1))], axis=1)
    frame = np.eye(3)
    psi, phi = sa.final_angles(LAM, 0.0, ALPHA)
    u, st = sa.controller_b_torque(q, w, h, frame, SIGMA, TAU, psi[0], phi[0], H0, 0.25, 0.1, 0.1)
    assert_array_equal(u[:, 2], 0.0)
    e_w = w - st['w_des']
    e_h = h - sa.target_momentum(phi[0], H0)
    s = np.sin(st['theta'])
    vdot = -0.1 * st['e_psi'] ** 2 / s + np.sum((e_w - 0.1 * e_h) * u, axis=-1)
    assert_allclose(vdot, -0.1 * st['e_psi'] ** 2 / s
                    - 0.25 * np.sum(((e_w - 0.1 * e_h) ** 2)[:, :2], axis=-1), rtol=1e-9, atol=1e-15)
    dpsi, _, _ = sa.euler_rates_313(st['theta'], st['phi'], st['w_des'])
    assert_allclose(dpsi, -0.1 * st['e_psi'] / s, rtol=1e-9, atol=1e-15)


# --- closed loops through the plant ---------------------------------------------------------------

def make_plant():
    wheels = ReactionWheels(names=['rw_x', 'rw_y'], axes=[[1, 0, 0], [0, 1, 0]],
                            spin_inertia=[JW, JW], max_torque=[MAX_TORQUE] * 2,
                            max_speed=[np.inf] * 2)
    return Plant(J, [wheels])


def initial_states(plant, q0):
    """All momentum in the body, wheels at rest (module docstring)."""
    w0 = rotate_to_body(q0, H_N) / np.diag(J)
    return plant.initial_state(q0, w0)


def wheel_momentum(x):
    h = np.zeros(x.shape[:-1] + (3,))
    h[..., :2] = JW * x[..., 7:9]
    return h


def simulate(law, q0, duration, record_states=False):
    """Closed loop, 1 s ZOH: motor torque command -u (the paper's u = -dh/dt), saturated at
    20 mN m by the wheels. Returns pointing error (deg, (steps + 1, n)), stages, final x."""
    plant = make_plant()
    x = initial_states(plant, q0)
    cmds = plant.zero_commands()
    speed_mode = np.zeros(2, dtype=bool)
    err, stages, states = [], [], []
    for k in range(int(duration / PERIOD)):
        if record_states:
            states.append(x.copy())
        u, st = law.control(k * PERIOD, x[..., :4], x[..., 4:7], wheel_momentum(x))
        err.append(st['pointing_error'])
        stages.append(st['stage'])
        cmds['wheels'] = WheelCommand(-u[..., :2], speed_mode)
        x = plant.step(k * PERIOD, x, cmds, PERIOD, PERIOD)
    _, st = law.control(duration, x[..., :4], x[..., 4:7], wheel_momentum(x))
    err.append(st['pointing_error'])
    return np.degrees(np.array(err)), np.array(stages), x, states, plant


def convergence_times(err, threshold):
    """(first entry, staying below) times (s) to ``err < threshold``; NaN if never / not at end."""
    below = err < threshold
    first = np.where(below.any(0), below.argmax(0) * PERIOD, np.nan)
    above = ~below
    last_above = np.where(above.any(0), len(err) - 1 - above[::-1].argmax(0), -1)
    stay = np.where(below[-1], (last_above + 1) * PERIOD, np.nan)
    return first, stay


@pytest.mark.slow
def test_batch_equals_loop_bit_for_bit_with_stage_state():
    """A batch of closed-loop states fed to one law object gives, run by run, the same bits as a
    fresh law per run (stage switch per run, per-run LQR gains and geometry)."""
    q0 = Rotation.random(4, random_state=11).as_quat()
    for cls in (sa.PointingALaw, sa.PointingBLaw):
        _, stages, _, states, _ = simulate(cls(P), q0, 400.0, record_states=True)
        states = np.array(states)
        if cls is sa.PointingALaw:   # some runs switch inside the window, at different times
            switch = [np.argmax(stages[:, i] == sa.STAGE_LQR) for i in range(4)]
            assert len(set(switch)) > 1 and max(switch) > 0
        batch = cls(P)
        outs = [batch.control(k, s[:, :4], s[:, 4:7], wheel_momentum(s)) for k, s in enumerate(states)]
        for i in range(4):
            single = cls(P)
            for k, s in enumerate(states):
                u, st = single.control(k, s[i, :4], s[i, 4:7], wheel_momentum(s[i]))
                assert_array_equal(u, outs[k][0][i])
                for key in st:
                    assert_array_equal(st[key], outs[k][1][key][i], err_msg=key)


def test_few_initial_attitudes_converge_and_conserve_momentum():
    """Both controllers from singular (Θ = 0, π: H along ±ê3) and generic attitudes: pointing
    below 0.01° by 1500 s, at rest with h = h_f, h3 = 0, inertial H conserved, u3 = 0."""
    q0 = np.array([[0, 0, 0, 1.0], [1.0, 0, 0, 0], [0, 1.0, 0, 0],
                   Rotation.from_rotvec([0.3, -1.0, 2.0]).as_quat()])
    for cls in (sa.PointingALaw, sa.PointingBLaw):
        law = cls(P)
        err, stages, x, _, plant = simulate(law, q0, 1500.0)
        assert np.all(err[-1] < 0.01), (cls.__name__, err[-1])
        assert np.abs(x[:, 4:7]).max() < 1e-5
        g = law._geo
        assert_allclose(wheel_momentum(x), sa.target_momentum(g['phi_f'], g['H0']), atol=1e-5)
        # RK4 truncation at 1 s from ω0 ≈ 0.1 rad/s: up to 1.5e-6 N m s here (4.7e-9 with 0.25 s
        # steps: the 4^4 of a 4th-order method), not a leak
        assert_allclose(plant.inertial_momentum(x), np.broadcast_to(H_N, (4, 3)), atol=5e-6)
        if cls is sa.PointingALaw:
            assert np.all(stages[-1] == sa.STAGE_LQR)


MC_RUNS = 40
MC_SEED = 2024
PAPER_TABLE1_B = {1.0: (603, 98), 0.1: (831, 100), 0.01: (1060, 101)}


@pytest.fixture(scope='module')
def monte_carlo():
    q0 = Rotation.random(MC_RUNS, random_state=MC_SEED).as_quat()
    out = {}
    for name, cls in (('A', sa.PointingALaw), ('B', sa.PointingBLaw)):
        err, stages, x, _, _ = simulate(cls(P), q0, 1500.0)
        out[name] = {thr: convergence_times(err, thr) for thr in PAPER_TABLE1_B}
        out[name]['err'] = err
    return out


@pytest.mark.paper
def test_monte_carlo_all_converge_and_papers_comparison(monte_carlo):
    """Section 5 / Table 1 (40 random initial attitudes, 1500 s): every run of both controllers
    ends below 0.01° and stays; B is faster to 1° (mean first entry and staying), A faster to 0.01°;
    and, the paper's observation, B's spread does not grow with the precision (the tail is
    deterministic): the standard deviations of the times to stay below 0.1° and 0.01° agree within
    three standard errors of a sample standard deviation of n runs, 3 s / sqrt(n - 1) (s / sqrt(2 (n - 1))
    for each, the two taken as independent: conservative, they come from the same runs)."""
    A, B = monte_carlo['A'], monte_carlo['B']
    for r in (A, B):
        for thr in PAPER_TABLE1_B:
            first, stay = r[thr]
            assert np.all(np.isfinite(first)) and np.all(np.isfinite(stay)), thr
    assert np.mean(B[1.0][0]) < np.mean(A[1.0][0]) and np.mean(B[1.0][1]) < np.mean(A[1.0][1])
    assert np.mean(A[0.01][0]) < np.mean(B[0.01][0]) and np.mean(A[0.01][1]) < np.mean(B[0.01][1])
    n = len(B[0.1][1])
    spreads = [np.std(B[thr][1], ddof=1) for thr in (0.1, 0.01)]
    assert abs(spreads[1] - spreads[0]) < 3.0 / np.sqrt(n - 1) * spreads[0], spreads


@pytest.mark.paper
def test_disagreement_controller_b_reaches_table1_bands_faster_than_the_paper(monte_carlo):
    """Against Table 1 (controller B, 1000 runs: 603 ± 98, 831 ± 100, 1060 ± 101 s) ours converges
    about twice as fast (docs/seed003_readings.md R7: the linearised tail decays at 0.0133 /s, the
    paper's at ln 10 / 229 s = 0.0101 /s; no reading found closes the transient's gap). Asserted: our
    mean first entry is below the paper's by more than three standard errors of the difference of the
    two sample means (the paper's std / sqrt(1000) and ours / sqrt(n)), i.e. not a sampling accident
    of our 40 runs."""
    B = monte_carlo['B']
    for thr, (mean, std) in PAPER_TABLE1_B.items():
        ours = np.asarray(B[thr][0])
        se = np.hypot(std / np.sqrt(1000), np.std(ours, ddof=1) / np.sqrt(len(ours)))
        assert np.mean(ours) < mean - 3.0 * se, (thr, np.mean(ours), mean, se)


def test_controller_b_tail_decay_matches_its_linearisation(monte_carlo):
    """The decay of B's pointing error between 0.1° and 0.001° equals the slowest eigenvalue of its
    closed-loop linearisation about the final attitude (0.0133 /s for η = 0; computed here by
    finite differences of the pure law + eq. 4-5), to 15 %; the paper's tail (228 s per decade)
    is 0.0101 /s."""
    psi, phi = sa.final_angles(LAM, 0.0, ALPHA)
    rates = []
    for k in range(2):
        q_f, _, _ = sa.final_attitudes(SIGMA, TAU, H_N)
        h_f = sa.target_momentum(phi[k], H0)

        def f(z):
            q = (Rotation.from_quat(q_f[k]) * Rotation.from_rotvec(z[:3])).as_quat()
            w, h = z[3:6], np.array([z[6], z[7], 0.0])
            u, _ = sa.controller_b_torque(q, w, h, np.eye(3), SIGMA, TAU, psi[k], phi[k], H0,
                                          0.25, 0.1, 0.1)
            return np.concatenate([w, np.linalg.solve(J, u - np.cross(w, J @ w + h)), -u[:2]])
        z0 = np.concatenate([np.zeros(6), h_f[:2]])
        Ajac = np.stack([(f(z0 + 1e-6 * e) - f(z0 - 1e-6 * e)) / 2e-6 for e in np.eye(8)], axis=1)
        ev = np.linalg.eigvals(Ajac)
        ev = ev[np.abs(ev) > 1e-6]
        rates.append(-ev.real.max())
    assert_allclose(rates, 0.01333, rtol=0.01)
    err = monte_carlo['B']['err']
    t01 = convergence_times(err, 0.1)[1]
    t0001 = convergence_times(err, 0.001)[1]
    observed = np.log(100) / (t0001 - t01)
    assert_allclose(np.median(observed), rates[0], rtol=0.15)
    assert np.median(observed) > 1.2 * np.log(10) / 229.0
