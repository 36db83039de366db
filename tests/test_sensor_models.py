"""The truth-side sensor models (adcs_sim/truth/sensor_models.py, sensor_suite.py) against their
closed forms: noise statistics within chi-square bounds, the gyro's Allan deviation (slope -1/2 from
the angle random walk, +1/2 from the rate random walk, and the values sigma_v^2/tau + sigma_u^2 tau/3
the discrete Farrenkopf model reproduces exactly), the bias random walk's variance growth, saturation,
scale factor, the Gauss-Markov bias, the star tracker's exclusion cones, update pattern and exact
latency, the sun sensor's eclipse and field of view, the magnetometer, sensor faults at their step, and
a batch equal to the loop of its runs bit for bit. Every test is seeded: the bounds are those of the
model (99.9 % chi-square), the draws fixed, so a failure is a modelling error, not bad luck."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.stats import chi2

from adcs_core.attitude import quat_conjugate, quat_multiply, quat_normalize, rotate_to_body, rotation_from_quaternion
from adcs_core.faults import FaultState
from adcs_msgs_py import conversions_determination as cd
from adcs_sim.truth.sensor_models import (
    CoarseSunSensors,
    Gyro,
    Magnetometer,
    StarTracker,
    SunSensor,
    rotation_quaternion,
    sensor_frame,
)
from adcs_sim.truth.sensor_suite import SensorEnvironment, SensorSuite

P = 1e-3  # two-sided chi-square bound probability


def chi2_ok(sum_sq_over_var: float, dof: int) -> bool:
    return chi2.ppf(P / 2, dof) <= sum_sq_over_var <= chi2.ppf(1 - P / 2, dof)


def rotvec(q):
    """Rotation vector of unit quaternions (..., 4) (exact, w >= 0 taken)."""
    q = np.where(q[..., 3:] < 0, -q, q)
    v = q[..., :3]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    return 2.0 * np.arctan2(s, q[..., 3:]) * np.where(s > 0, v / np.where(s > 0, s, 1.0), 0.0)


def random_quaternions(rng, n):
    return quat_normalize(rng.normal(size=(n, 4)))


def gyro_series(gyro, n_runs, K, w=None):
    w = np.zeros((n_runs, 3)) if w is None else w
    return np.stack([gyro.measure(w).value for _ in range(K)], axis=1)   # (N, K, 3)


# --- gyro ---------------------------------------------------------------------------------------

def test_gyro_white_noise_matches_the_reported_covariance():
    """sigma_v^2/dt + sigma_u^2 dt/12: the reading minus the model's own bias is white with the
    variance the Reading reports (chi-square over 3 axes x samples)."""
    dt, arw, rrw, N, K = 0.25, 2e-4, 3e-6, 8, 2000
    gyro = Gyro(np.arange(N), dt, arw=arw, rrw=rrw, bias=[1e-3, -2e-3, 0.0])
    res, cov = [], None
    for _ in range(K):
        r = gyro.measure(np.zeros((N, 3)))
        res.append(r.value - gyro.true_bias)
        cov = r.cov
    res = np.stack(res)
    var = arw ** 2 / dt + rrw ** 2 * dt / 12
    assert_allclose(cov, np.broadcast_to(var * np.eye(3), (N, 3, 3)), rtol=1e-15)
    assert chi2_ok(float(np.sum(res ** 2) / var), res.size)
    # uncorrelated between axes and steps
    flat = res.reshape(-1, 3)
    assert np.abs(np.corrcoef(flat.T)[np.triu_indices(3, 1)]).max() < 4 / math.sqrt(flat.shape[0])
    lag = np.mean(res[1:] * res[:-1]) / var
    assert abs(lag) < 4 / math.sqrt(res[1:].size)


def _allan_variance(y, dt, m):
    """Overlapping Allan variance of rate series ``y`` (..., K) at tau = m dt."""
    th = np.concatenate([np.zeros(y.shape[:-1] + (1,)), np.cumsum(y, axis=-1) * dt], axis=-1)
    d = th[..., 2 * m:] - 2 * th[..., m:-m] + th[..., :-2 * m]
    return float(np.mean(d ** 2) / (2 * (m * dt) ** 2))


@pytest.mark.parametrize('arw, rrw, slope', [(1e-3, 0.0, -0.5), (0.0, 1e-5, 0.5)])
def test_gyro_allan_deviation(arw, rrw, slope):
    """ADEV(tau) = sqrt(sigma_v^2/tau + sigma_u^2 tau/3): within 5 % at each tau (the estimator's
    spread over 96 series of 4096 samples is ~1-2 %), log-log slope -1/2 (ARW) / +1/2 (RRW)."""
    N, K, dt = 32, 4096, 0.5
    out = gyro_series(Gyro(np.arange(N), dt, arw=arw, rrw=rrw), N, K)
    y = np.moveaxis(out, -1, 1).reshape(N * 3, K)
    ms = np.array([1, 4, 16, 64])
    adev = np.array([math.sqrt(_allan_variance(y, dt, m)) for m in ms])
    expected = np.sqrt(arw ** 2 / (ms * dt) + rrw ** 2 * ms * dt / 3)
    assert_allclose(adev, expected, rtol=0.05)
    fitted = np.polyfit(np.log(ms * dt), np.log(adev), 1)[0]
    assert fitted == pytest.approx(slope, abs=0.03)


def test_gyro_bias_random_walk_grows_linearly():
    """beta_k - beta_0 ~ N(0, sigma_u^2 k dt): chi-square at three times over 400 runs x 3 axes."""
    N, dt, rrw, b0 = 400, 2.0, 1e-5, np.array([1e-3, 0.0, -1e-3])
    gyro = Gyro(np.arange(N), dt, rrw=rrw, bias=b0)
    for k in range(1, 201):
        gyro.measure(np.zeros((N, 3)))
        if k in (50, 100, 200):
            d = gyro.beta - b0
            assert chi2_ok(float(np.sum(d ** 2) / (rrw ** 2 * k * dt)), d.size), k


def test_gyro_markov_bias_variance():
    """m_k ~ N(0, sigma_m^2 (1 - phi^(2k))), phi = exp(-dt/tau), from m_0 = 0."""
    N, dt, tau, sm = 600, 1.0, 20.0, 1e-4
    gyro = Gyro(np.arange(N), dt, markov_std=sm, markov_time=tau)
    phi = math.exp(-dt / tau)
    for k in range(1, 61):
        gyro.measure(np.zeros((N, 3)))
        if k in (5, 60):
            var = sm ** 2 * (1 - phi ** (2 * k))
            assert chi2_ok(float(np.sum(gyro.markov ** 2) / var), gyro.markov.size), k


def test_gyro_saturation_scale_factor_and_zero_rate():
    w = np.array([[3.0, -5.0, 0.2], [0.0, 0.0, 0.0]])
    gyro = Gyro([1, 2], 1.0, scale_factor=[1e-3, -2e-3, 0.5], max_rate=1.0)
    r = gyro.measure(w)
    assert_array_equal(r.value[0], [1.0, -1.0, 0.2 * 1.5])   # clipped to +-max_rate, scale factor
    assert_array_equal(r.value[1], np.zeros(3))              # zero rate, no noise: exactly zero
    assert r.valid.all() and np.isfinite(r.cov).all()


# --- star tracker --------------------------------------------------------------------------------

def test_star_tracker_noise_in_the_sensor_frame():
    """Cross-boresight sigma_c on the two axes across the boresight, sigma_a about it; the reported
    covariance is R diag(sigma_c^2, sigma_c^2, sigma_a^2) R^T (body axes)."""
    N, K, sc, sa = 20, 500, 2e-5, 3e-4
    boresight = [1.0, 2.0, -0.5]
    st = StarTracker(np.arange(N), boresight, cross_std=sc, about_std=sa)
    q = random_quaternions(np.random.default_rng(0), N)
    errs = []
    for k in range(K):
        r = st.measure(k, q)
        errs.append(rotvec(quat_multiply(quat_conjugate(q), r.value)))
    frame = sensor_frame(boresight)
    assert_allclose(frame[:, 2], np.array(boresight) / np.linalg.norm(boresight), rtol=1e-15)
    assert_allclose(frame.T @ frame, np.eye(3), atol=1e-15)
    e_s = np.stack(errs) @ frame          # sensor-frame components
    for axis, sigma in enumerate((sc, sc, sa)):
        assert chi2_ok(float(np.sum(e_s[..., axis] ** 2) / sigma ** 2), N * K), axis
    assert_allclose(r.cov[0], frame @ np.diag([sc ** 2, sc ** 2, sa ** 2]) @ frame.T, rtol=1e-12, atol=1e-24)


def test_rotation_quaternion_is_exact():
    phi = np.array([[0.0, 0.0, 0.0], [1e-9, 0.0, 0.0], [0.3, -0.2, 0.1], [0.0, math.pi, 0.0]])
    q = rotation_quaternion(phi)
    assert_allclose(np.linalg.norm(q, axis=-1), 1.0, rtol=1e-15)
    assert_allclose(rotvec(q), phi, atol=1e-15)


@pytest.mark.parametrize('exclusion_deg', [10.0, 45.0, 120.0])
def test_star_tracker_sun_exclusion_cone(exclusion_deg):
    """Valid iff the angle between the inertial boresight R(q) b and the Sun exceeds the exclusion
    angle: Sun placed at exclusion +- 1e-6 rad from the boresight, for random attitudes."""
    rng = np.random.default_rng(1)
    N = 16
    b_body = np.array([0.0, 0.6, 0.8])
    st = StarTracker(np.arange(N), b_body, sun_exclusion=math.radians(exclusion_deg))
    q = random_quaternions(rng, N)
    b = np.einsum('nij,j->ni', rotation_from_quaternion(q), b_body)
    perp = np.cross(b, rng.normal(size=(N, 3)))
    perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
    delta = np.where(np.arange(N) % 2 == 0, 1e-6, -1e-6)
    angle = math.radians(exclusion_deg) + delta
    sun = np.cos(angle)[:, None] * b + np.sin(angle)[:, None] * perp
    r = st.measure(0, q, sun=sun)
    assert_array_equal(r.valid, delta > 0)
    assert StarTracker(np.arange(N), b_body).measure(0, q, sun=sun).valid.all()   # no cone: no outage


def test_star_tracker_earth_exclusion_from_the_limb():
    """Earth: outage iff the boresight is within earth_exclusion + rho of the nadir (rho the Earth's
    angular radius; from the nadir when not given)."""
    excl, rho = math.radians(20.0), math.radians(64.0)
    alpha = np.array([excl + rho - 1e-6, excl + rho + 1e-6, excl - 1e-6, excl + 1e-6])
    nadir = np.stack([np.sin(alpha), np.zeros(4), np.cos(alpha)], axis=-1)   # boresight +z, q identity
    q = np.tile([0.0, 0.0, 0.0, 1.0], (4, 1))
    st = StarTracker(np.arange(4), earth_exclusion=excl)
    assert_array_equal(st.measure(0, q, nadir=nadir, earth_radius=np.full(4, rho)).valid,
                       [False, True, False, False])
    st = StarTracker(np.arange(4), earth_exclusion=excl)
    assert_array_equal(st.measure(0, q, nadir=nadir).valid, [True, True, False, True])


def test_star_tracker_update_pattern_and_exact_latency():
    """Valid on steps k % every == 0 and k >= L; the reading at k is the attitude at k - L rotated
    by that step's noise, bit for bit the reading a latency-free tracker gives of q_{k-L}."""
    rng = np.random.default_rng(2)
    K, L, every = 30, 4, 3
    qs = random_quaternions(rng, K)
    late = StarTracker(5, cross_std=1e-4, about_std=1e-3, every=every, latency_steps=L)
    now = StarTracker(5, cross_std=1e-4, about_std=1e-3, every=every)
    for k in range(K):
        r = late.measure(k, qs[k])
        ref = now.measure(k, qs[max(k - L, 0)])
        assert bool(r.valid) == (k % every == 0 and k >= L), k
        if k >= L:
            assert_array_equal(r.value, ref.value)
    noiseless = StarTracker(0, latency_steps=L)
    for k in range(K):
        r = noiseless.measure(k, qs[k])
        if k >= L:
            assert_array_equal(r.value, qs[k - L])
    with pytest.raises(ValueError, match='one call per step'):
        noiseless.measure(K + 1, qs[0])


# --- sun sensor and magnetometer ----------------------------------------------------------------

def test_sun_sensor_noise_eclipse_and_field_of_view():
    rng = np.random.default_rng(3)
    N, K, sigma = 10, 400, 1e-3
    q = random_quaternions(rng, N)
    sun = rng.normal(size=(N, 3))
    sun /= np.linalg.norm(sun, axis=-1, keepdims=True)
    sensor = SunSensor(np.arange(N), sigma, fov=math.pi)
    s_true = rotate_to_body(q, sun)
    err = []
    for _ in range(K):
        r = sensor.measure(q, sun, np.ones(N))
        assert r.valid.all()
        assert_allclose(np.linalg.norm(r.value, axis=-1), 1.0, rtol=1e-15)
        err.append(r.value - s_true)
    err = np.stack(err)
    along = np.einsum('kni,ni->kn', err, s_true)
    assert np.abs(along).max() < 10 * sigma ** 2       # second order along s
    assert chi2_ok(float(np.sum(err ** 2) / sigma ** 2), 2 * N * K)   # two perpendicular axes
    # eclipse: umbra (0) gives no reading and the zero vector; penumbra above the threshold reads
    illum = np.array([0.0, 0.2, 0.6, 1.0] + [1.0] * (N - 4))
    r = SunSensor(np.arange(N), sigma, min_illumination=0.5).measure(q, sun, illum)
    assert_array_equal(r.valid[:4], [False, False, True, True])
    assert_array_equal(r.value[:2], np.zeros((2, 3)))
    # field of view: Sun at fov +- 1e-6 from the boresight (+z, identity attitude)
    fov = math.radians(60.0)
    a = np.array([fov - 1e-6, fov + 1e-6])
    sun2 = np.stack([np.sin(a), np.zeros(2), np.cos(a)], axis=-1)
    r = SunSensor([1, 2], 0.0, fov=fov).measure(np.tile([0.0, 0, 0, 1], (2, 1)), sun2, np.ones(2))
    assert_array_equal(r.valid, [True, False])


def test_magnetometer_noise_and_bias():
    rng = np.random.default_rng(4)
    N, K, sigma, bias = 10, 300, 5e-8, np.array([1e-7, -2e-7, 3e-7])
    q = random_quaternions(rng, N)
    field = rng.normal(scale=3e-5, size=(N, 3))
    mag = Magnetometer(np.arange(N), sigma, bias)
    res = np.stack([mag.measure(q, field).value for _ in range(K)]) - rotate_to_body(q, field) - bias
    assert chi2_ok(float(np.sum(res ** 2) / sigma ** 2), res.size)
    assert_allclose(mag.cov[0], sigma ** 2 * np.eye(3), rtol=1e-15)


# --- the suite: batch == loop, faults at their step -----------------------------------------------

def _suite(seed, period_ns=500_000_000):
    dt = period_ns / 1e9
    return SensorSuite(period_ns,
                       Gyro(seed, dt, arw=1e-4, rrw=1e-6, bias=[1e-3, 0, -1e-3], scale_factor=[1e-4, 0, 0],
                            max_rate=0.5, markov_std=1e-5, markov_time=100.0),
                       StarTracker(seed, [0, 1, 1], 1e-5, 1e-4, every=2, latency_steps=1,
                                   sun_exclusion=math.radians(30), earth_exclusion=math.radians(10)),
                       SunSensor(seed, 1e-3, fov=math.radians(80), min_illumination=0.1),
                       Magnetometer(seed, 1e-7, [1e-7, 0, 0]))


def _env_series(rng, K, N):
    sun = rng.normal(size=(K, N, 3))
    nadir = rng.normal(size=(K, N, 3))
    return [SensorEnvironment(sun=sun[k] / np.linalg.norm(sun[k], axis=-1, keepdims=True),
                              illumination=rng.uniform(size=N),
                              nadir=nadir[k] / np.linalg.norm(nadir[k], axis=-1, keepdims=True),
                              earth_angular_radius=np.full(N, 1.0), field=rng.normal(scale=3e-5, size=(N, 3)))
            for k in range(K)]


def test_a_batch_equals_the_loop_of_its_runs_bit_for_bit():
    rng = np.random.default_rng(5)
    N, K = 5, 25
    seeds = np.array([3, 1, 4, 1, 5])
    q = random_quaternions(rng, K * N).reshape(K, N, 4)
    w = rng.normal(scale=0.3, size=(K, N, 3))
    env = _env_series(rng, K, N)
    batch = _suite(seeds)
    alone = [_suite(int(s)) for s in seeds]
    for k in range(K):
        m = batch.measure(k, 0.5 * k, q[k], w[k], env[k])
        assert m.t_ns == k * 500_000_000 and m.fitted() == ('gyro', 'star_tracker', 'sun', 'magnetometer')
        for i, suite in enumerate(alone):
            e = env[k]
            one = suite.measure(k, 0.5 * k, q[k, i], w[k, i], SensorEnvironment(
                e.sun[i], e.illumination[i], e.nadir[i], e.earth_angular_radius[i], e.field[i]))
            for name in m.fitted():
                a, b = getattr(one, name), getattr(m, name)
                assert_array_equal(a.value, b.value[i], err_msg=f'{name} k={k} run {i}')
                assert_array_equal(a.cov, b.cov[i])
                assert a.valid == b.valid[i]


def test_the_streams_do_not_depend_on_which_sensors_are_fitted():
    """Each sensor draws its own stream: the gyro reads the same with or without a star tracker."""
    w = np.full(3, 0.01)
    both = SensorSuite(10**9, Gyro(9, 1.0, arw=1e-3), StarTracker(9, cross_std=1e-4))
    gyro_only = SensorSuite(10**9, Gyro(9, 1.0, arw=1e-3))
    for k in range(5):
        a = both.measure(k, k, np.array([0, 0, 0, 1.0]), w).gyro.value
        assert_array_equal(a, gyro_only.measure(k, k, np.array([0, 0, 0, 1.0]), w).gyro.value)


def test_sensor_faults_act_from_their_step():
    """A fault applied at step k changes the readings from step k on, and nothing before; the noise
    streams are untouched (after recovery the readings are the unfaulted ones again)."""
    rng = np.random.default_rng(6)
    K, kf, kr = 12, 4, 8
    qs = random_quaternions(rng, K)
    ws = rng.normal(scale=0.05, size=(K, 3))
    env = [SensorEnvironment(field=rng.normal(scale=3e-5, size=3)) for _ in range(K)]
    ref, faulty = _suite_no_sun(), _suite_no_sun()
    for k in range(K):
        if k == kf:
            faulty.apply_faults({'star_tracker': FaultState('failed'), 'magnetometer': FaultState('failed'),
                                 'gyro.x': FaultState('bias', 0.01), 'gyro.z': FaultState('stuck')})
        if k == kr:
            faulty.apply_faults({n: FaultState('recovered') for n in ('star_tracker', 'magnetometer',
                                                                      'gyro.x', 'gyro.z')})
        a, b = ref.measure(k, k, qs[k], ws[k], env[k]), faulty.measure(k, k, qs[k], ws[k], env[k])
        if k < kf or k >= kr:
            for name in a.fitted():
                assert_array_equal(getattr(a, name).value, getattr(b, name).value, err_msg=f'{name} {k}')
                assert getattr(a, name).valid == getattr(b, name).valid
            continue
        assert not b.star_tracker.valid and not b.magnetometer.valid
        assert b.gyro.value[0] - a.gyro.value[0] == pytest.approx(0.01, abs=1e-15)
        assert b.gyro.value[1] == a.gyro.value[1]
        if k == kf:
            stuck = a.gyro.value[2]
        assert b.gyro.value[2] == stuck


def _suite_no_sun():
    return SensorSuite(10**9, Gyro(2, 1.0, arw=1e-4, rrw=1e-6), StarTracker(2, cross_std=1e-5, about_std=1e-4),
                       None, Magnetometer(2, 1e-7))


def test_vector_sensors_need_the_environment():
    suite = SensorSuite(10**9, sun=SunSensor(0, 1e-3))
    with pytest.raises(ValueError, match='Sun direction'):
        suite.measure(0, 0.0, np.array([0, 0, 0, 1.0]), np.zeros(3))
    suite = SensorSuite(10**9, magnetometer=Magnetometer(0, 1e-7))
    with pytest.raises(ValueError, match='magnetic field'):
        suite.measure(0, 0.0, np.array([0, 0, 0, 1.0]), np.zeros(3))


def test_readings_survive_their_messages():
    """What an estimator on the graph reads back (``*_from_msg(*_to_msg(r))``) is the model's reading:
    value and valid bit for bit, valid or not (canonical 'no measurement'); the star tracker's
    covariance to rounding (rotated to the inertial axes and back), the others' exactly."""
    rng = np.random.default_rng(7)
    q = random_quaternions(rng, 1)[0]
    sun = np.array([0.0, 0.6, 0.8])
    env = SensorEnvironment(sun=sun, illumination=np.float64(1.0), field=np.array([2e-5, -1e-5, 3e-5]))
    for failed in (False, True):
        suite = _suite(3)
        suite.star_tracker.latency = 0
        suite.star_tracker.history = type(suite.star_tracker.history)(maxlen=1)
        suite.apply_faults({n: FaultState('failed' if failed else 'recovered')
                            for n in ('star_tracker', 'sun', 'magnetometer')})
        m = suite.measure(0, 0.0, q, np.array([0.01, -0.02, 0.03]), env)
        pairs = {'gyro': (cd.imu_to_msg, cd.imu_from_msg), 'star_tracker': (cd.star_tracker_to_msg,
                 cd.star_tracker_from_msg), 'sun': (cd.sun_to_msg, cd.sun_from_msg),
                 'magnetometer': (cd.magnetometer_to_msg, cd.magnetometer_from_msg)}
        for name, (to_msg, from_msg) in pairs.items():
            r = getattr(m, name)
            t_ns, back = from_msg(to_msg(m.t_ns, r))
            assert t_ns == m.t_ns and bool(back.valid) == bool(r.valid), name
            assert bool(r.valid) == (name == 'gyro' or not failed), name
            assert_array_equal(back.value, r.value, err_msg=name)
            if name == 'star_tracker':
                assert_allclose(back.cov, r.cov, rtol=0, atol=1e-12 * np.abs(r.cov).max(initial=1e-300))
            elif name != 'sun':
                assert_array_equal(back.cov, r.cov, err_msg=name)


CUBE = [1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1]


def test_coarse_sun_sensors_least_squares_sun_vector():
    """Six cosine detectors on the cube faces: noiseless, the three lit faces give the Sun exactly
    (whatever the illuminated fraction); a Sun along an axis lights one face only (no reading); the
    noisy error is sigma per axis perpendicular to the Sun (chi-square), zero along it to first order."""
    rng = np.random.default_rng(8)
    N = 12
    q = random_quaternions(rng, N)
    sun = rng.normal(size=(N, 3))
    sun /= np.linalg.norm(sun, axis=-1, keepdims=True)
    s_true = rotate_to_body(q, sun)
    r = CoarseSunSensors(np.arange(N), CUBE).measure(q, sun, np.full(N, 0.3))
    assert r.valid.all()
    assert_allclose(r.value, s_true, atol=2e-15)
    axis = CoarseSunSensors(0, CUBE).measure(np.array([0, 0, 0, 1.0]), np.array([1.0, 0, 0]), 1.0)
    assert not axis.valid and not np.any(axis.value)
    assert not CoarseSunSensors(0, CUBE).measure(q[0], sun[0], 0.0).valid     # umbra
    sigma, K = 1e-4, 300
    css = CoarseSunSensors(np.arange(N), CUBE, std=sigma)
    err = np.stack([css.measure(q, sun, np.ones(N)).value - s_true for _ in range(K)])
    assert chi2_ok(float(np.sum(err ** 2) / sigma ** 2), 2 * N * K)
    assert np.abs(np.einsum('kni,ni->kn', err, s_true)).max() < 50 * sigma ** 2
    # a run of the batch equals the run alone, bit for bit
    for i in (0, 5):
        alone = CoarseSunSensors(i, CUBE, std=sigma)
        batch = CoarseSunSensors(np.arange(N), CUBE, std=sigma)
        for _ in range(3):
            assert_array_equal(alone.measure(q[i], sun[i], 1.0).value, batch.measure(q, sun, np.ones(N)).value[i])
