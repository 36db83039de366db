"""The run metrics (adcs_sim.app.analysis.metrics) against signals whose answers are known in closed form.

No ROS, no bags: numpy arrays in, numbers out. Tolerances are tied to the sampling (linear
interpolation of a smooth crossing is off by at most max|e''| dt^2 / (8 |e'|) to leading order).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from adcs_sim.app.analysis.metrics import (
    RunData,
    first_entry_time,
    integrated_norm,
    integrated_square,
    run_metrics,
    settling_time,
    settling_times,
    zoh_durations,
)

# --- exponential decay: settling to tol at tau * ln(e0 / tol) ------------------------------------

E0, TAU, TOL = 30.0, 50.0, 0.5
T_EXP = TAU * math.log(E0 / TOL)


def exp_bound(h: float) -> float:
    """Largest lag of the interpolated crossing of a sampled e0 exp(-t/tau) behind the true one.

    On a sample interval [a, a+h] the chord of the convex exponential lies above it by at most
    max e'' h^2 / 8 = e(a) h^2 / (8 tau^2), and the chord falls at (e(a) - e(a+h)) / h.
    """
    return h ** 3 / (8 * TAU ** 2 * -math.expm1(-h / TAU))


@pytest.mark.parametrize('dt', [2.0, 1.0, 0.25])
@pytest.mark.parametrize('phase', [0.0, 0.37, 0.81])
def test_exponential_settling_within_interpolation_bound(dt, phase):
    t = (np.arange(int(400 / dt)) + phase) * dt
    ts = settling_time(t, E0 * np.exp(-t / TAU), TOL)
    # The chord of a convex decreasing function crosses later than the function: never early.
    assert 0.0 <= ts - T_EXP <= exp_bound(dt) * (1 + 1e-9)


def test_exponential_settling_converges_at_second_order_and_is_exact_when_fine():
    errors = []
    for dt in (2.0, 1.0, 0.5):
        k = np.arange(-int(T_EXP / dt), int(200 / dt))
        t = T_EXP + (k + 0.5) * dt                 # the crossing in mid-interval for all three
        errors.append(settling_time(t, E0 * np.exp(-t / TAU), TOL) - T_EXP)
    assert 3.0 < errors[0] / errors[1] < 5.0 and 3.0 < errors[1] / errors[2] < 5.0
    t = np.arange(0.0, 400.0, 1e-3)
    assert settling_time(t, E0 * np.exp(-t / TAU), TOL) == pytest.approx(T_EXP, abs=1e-8)


def test_exponential_first_entry_equals_settling_when_monotone():
    t = np.arange(0.0, 400.0, 0.5)
    e = E0 * np.exp(-t / TAU)
    assert first_entry_time(t, e, TOL) == settling_time(t, e, TOL)


# --- damped oscillator: last exit vs first entry --------------------------------------------------

ZETA, WN, THETA0, BAND = 0.15, 0.5, 10.0, 0.5
WD = WN * math.sqrt(1 - ZETA ** 2)


def theta(t):
    """Free response of theta'' + 2 zeta wn theta' + wn^2 theta = 0 from (theta0, 0)."""
    return THETA0 * np.exp(-ZETA * WN * t) * (np.cos(WD * t) + ZETA * WN / WD * np.sin(WD * t))


def dtheta(t):
    return -THETA0 * WN ** 2 / WD * np.exp(-ZETA * WN * t) * np.sin(WD * t)


def band_crossings() -> list[float]:
    """Every root of |theta| = BAND, by brentq on the continuous closed form.

    After t_env the envelope theta0 exp(-zeta wn t) / sqrt(1 - zeta^2) is below the band.
    """
    t_env = math.log(THETA0 / (BAND * math.sqrt(1 - ZETA ** 2))) / (ZETA * WN)
    grid = np.linspace(0.0, t_env + 1.0, 200_001)   # 4e-4 s apart: far finer than any lobe
    g = np.abs(theta(grid)) - BAND
    idx = np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:]))
    f = lambda x: abs(theta(x)) - BAND  # noqa: E731
    return [brentq(f, grid[i], grid[i + 1], xtol=1e-13) for i in idx]


@pytest.mark.parametrize('dt', [0.05, 0.01])
@pytest.mark.parametrize('phase', [0.0, 0.29, 0.73])
def test_damped_oscillator_last_exit_and_first_entry(dt, phase):
    roots = band_crossings()
    t_first, t_last = roots[0], roots[-1]
    assert len(roots) > 6  # it overshoots out of the band several times before staying in
    t = (np.arange(int(80 / dt)) + phase) * dt
    e = np.abs(theta(t))
    # Leading-order bound of linear interpolation at a crossing t*: max|e''| dt^2 / (8 |e'(t*)|).
    second = lambda x: np.abs(-2 * ZETA * WN * dtheta(x) - WN ** 2 * theta(x))  # noqa: E731
    for got, exact in ((settling_time(t, e, BAND), t_last), (first_entry_time(t, e, BAND), t_first)):
        near = np.linspace(exact - dt, exact + dt, 101)
        bound = second(near).max() * dt ** 2 / (8 * abs(dtheta(exact)))
        assert abs(got - exact) <= 1.05 * bound + 1e-12, (got, exact, bound)
        assert abs(got - exact) < dt
    assert settling_time(t, e, BAND) - first_entry_time(t, e, BAND) > 4 * math.pi / WD


def test_overshoot_first_entry_vs_settling_hand_computed():
    t = np.arange(7.0)
    e = np.array([5.0, 3.0, 1.0, 0.2, 0.8, 0.3, 0.1])
    assert first_entry_time(t, e, 0.5) == pytest.approx(2.0 + 0.5 / 0.8)   # 1 -> 0.2 crosses 0.5
    assert settling_time(t, e, 0.5) == pytest.approx(4.0 + 0.3 / 0.5)      # 0.8 -> 0.3: last exit


# --- edge cases -----------------------------------------------------------------------------

def test_never_settles_always_inside_and_empty():
    t = np.arange(5.0, 15.0)
    assert settling_time(t, np.linspace(3, 1, t.size), 0.5) == math.inf       # ends outside
    assert settling_time(t, np.r_[np.zeros(9), 1.0], 0.5) == math.inf         # leaves at the end
    assert first_entry_time(t, np.ones(t.size), 0.5) == math.inf
    assert settling_time(t, np.full(t.size, 0.1), 0.5) == 5.0                  # t0, not 0
    assert first_entry_time(t, np.full(t.size, 0.1), 0.5) == 5.0
    assert settling_time(t, np.r_[0.6, np.full(t.size - 1, 0.5)], 0.5) == 6.0  # == tol is inside
    assert math.isnan(settling_time(np.zeros(0), np.zeros(0), 0.5))


def test_nan_counts_as_outside():
    t = np.arange(6.0)
    assert settling_time(t, [1.0, 0.1, math.nan, 0.1, 0.1, 0.1], 0.5) == 3.0
    assert settling_time(t, [0.1] * 5 + [math.nan], 0.5) == math.inf
    assert first_entry_time(t, [math.nan, 0.1, 0.1, 0.1, 0.1, 0.1], 0.5) == 1.0


# --- zero-order-hold integrals ---------------------------------------------------------------

U = np.array([0.01, -0.02, 0.005])


def bang_off_bang(t):
    """+U on [0, 30), 0 on [30, 70), -U on [70, 100): |u| integrates to 60 |U| over [0, 100]."""
    return np.where((t < 30)[:, None], U, np.where((t >= 70)[:, None], -U, 0.0))


@pytest.mark.parametrize('dt', [1.0, 0.5, 0.1])
def test_bang_off_bang_zoh_integrals_exact(dt):
    t = np.arange(0.0, 100.0, dt)
    t = t[t < 100.0 - 1e-9]
    u = bang_off_bang(t)
    norm = np.linalg.norm(U)
    assert integrated_norm(t, u, 100.0) == pytest.approx(60 * norm, rel=1e-12)
    assert integrated_square(t, u, 100.0) == pytest.approx(60 * norm ** 2, rel=1e-12)


def test_zoh_irregular_samples_and_hold_to_the_end():
    rng = np.random.default_rng(4)
    t = np.sort(np.r_[0.0, 30.0, 70.0, rng.uniform(0, 99, 200)])
    u = bang_off_bang(t)
    norm = np.linalg.norm(U)
    assert integrated_norm(t, u, 100.0) == pytest.approx(60 * norm, rel=1e-12)
    # Each sample holds to the next one and the last to t_end (not backwards to the previous).
    d = zoh_durations(np.array([0.0, 1.0, 3.0]), 10.0)
    np.testing.assert_array_equal(d, [1.0, 2.0, 7.0])
    assert integrated_norm(np.array([0.0, 1.0]), np.array([[1.0, 0, 0], [3.0, 4.0, 0]]), 3.0) == 11.0
    assert integrated_square(np.array([0.0, 1.0]), np.array([[1.0, 0, 0], [3.0, 4.0, 0]]), 3.0) == 51.0


# --- through RunData and run_metrics ---------------------------------------------------------

AMPL_DEG = np.array([20.0, -15.0, 8.0])   # 2-1-3 sequence order: about y, then x, then z
TAUS = np.array([10.0, 25.0, 40.0])


def euler_run(dt: float = 0.05, q_ref=None) -> RunData:
    """Attitude built from 2-1-3 Euler angles decaying exponentially (distinct per axis)."""
    t = np.arange(0.0, 200.0 + dt / 2, dt)
    angles = np.radians(AMPL_DEG)[None, :] * np.exp(-t[:, None] / TAUS[None, :])
    qe = Rotation.from_euler('YXZ', angles)
    ref = Rotation.identity() if q_ref is None else Rotation.from_quat(q_ref)
    q = (ref * qe).as_quat()                 # q = q_ref ⊗ q_e, scalar last
    run = RunData(t=t, q=q, w=np.zeros((t.size, 3)))
    if q_ref is not None:
        run.q_ref = np.asarray(q_ref, dtype=float)
    return run


@pytest.mark.parametrize('q_ref', [None, Rotation.from_rotvec([0.3, -1.0, 2.0]).as_quat()])
def test_per_axis_euler_settling_of_synthetic_attitude(q_ref):
    dt, tol = 0.05, 0.5
    metrics = run_metrics(euler_run(dt, q_ref), tol)
    expected = TAUS * np.log(np.abs(AMPL_DEG) / tol)     # y: 36.9 s, x: 85.0 s, z: 110.9 s
    bound = dt ** 2 / (8 * TAUS.min()) * 1.01 + 1e-9
    per_axis = np.array(metrics['settling_euler213_per_axis_s'])
    np.testing.assert_allclose(per_axis, expected, atol=bound)
    # All three axes inside at once: the last of the three.
    assert metrics['settling_euler213_0.5deg_s'] == pytest.approx(expected.max(), abs=bound)


def test_eigenaxis_settling_of_single_axis_rotation():
    t = np.arange(0.0, 150.0, 0.1)
    angle = np.radians(12.0) * np.exp(-t / 20.0)
    q = Rotation.from_rotvec(np.outer(angle, [0.6, 0.0, -0.8])).as_quat()
    metrics = run_metrics(RunData(t=t, q=q, w=np.zeros((t.size, 3))), 1.0, eigen_tol_deg=0.25)
    assert metrics['settling_eigenaxis_0.25deg_s'] == pytest.approx(20.0 * math.log(12.0 / 0.25), abs=1e-3)
    assert metrics['final_eigenaxis_error_deg'] == pytest.approx(12.0 * math.exp(-t[-1] / 20.0), rel=1e-9)


def test_settling_times_several_tolerances_agree_with_run_metrics():
    run = euler_run()
    table = settling_times(run, (0.5, 1.0))
    for tol in (0.5, 1.0):
        m = run_metrics(run, tol)
        assert table[tol]['euler213'] == m[f'settling_euler213_{tol:g}deg_s']
        assert table[tol]['eigenaxis'] == m[f'settling_eigenaxis_{tol:g}deg_s']
        assert table[tol]['euler213_per_axis'] == m['settling_euler213_per_axis_s']
    np.testing.assert_allclose(table[1.0]['euler213_per_axis'], TAUS * np.log(np.abs(AMPL_DEG)), atol=1e-3)


def test_peaks_integrals_and_missed_steps_through_run_metrics():
    t = np.arange(0.0, 100.5, 0.5)
    t_u = t[:-1]
    u = bang_off_bang(t_u)
    u[10] = [0.03, 0.0, -0.04]                    # the peaks: one sample, signed
    speed = np.column_stack([np.sin(t), -3.5 * np.exp(-((t - 40) / 5) ** 2), np.full(t.size, 2.0)])
    run = RunData(t=t, q=np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1)), w=np.zeros((t.size, 3)),
                  t_u=t_u, u=u, t_wheels=t, wheel_names=['a', 'b', 'c'], wheel_speed=speed,
                  wheel_torque=np.zeros_like(speed), missed_steps=3)
    m = run_metrics(run)
    assert m['peak_torque_Nm'] == [0.03, 0.02, 0.04]
    assert m['peak_wheel_speed_rad_s'] == 3.5
    norm = np.linalg.norm(U)
    assert m['integrated_torque_Nms'] == pytest.approx(60 * norm - 0.5 * norm + 0.5 * 0.05, rel=1e-12)
    assert m['control_energy_N2m2s'] == pytest.approx(60 * norm ** 2 - 0.5 * norm ** 2 + 0.5 * 0.0025, rel=1e-12)
    assert m['missed_steps'] == 3 and m['duration_s'] == 100.0
    assert m['settling_eigenaxis_0.5deg_s'] == 0.0 and m['final_eigenaxis_error_deg'] == 0.0
    # No torque or wheel samples: NaN, not an error.
    bare = run_metrics(RunData(t=t, q=run.q, w=run.w))
    assert math.isnan(bare['integrated_torque_Nms']) and math.isnan(bare['peak_wheel_speed_rad_s'])
