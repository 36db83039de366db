"""The estimator's own truth model, for tests (not product code, not the truth model of adcs_sim.truth):
M runs of a rigid body turning at a constant body rate (closed-form attitude), a Farrenkopf gyro with
the exact discrete variances, a star tracker of white small-rotation noise and unit-vector sensors,
giving contract :class:`~adcs_msgs_py.measurements.Measurements` with a leading batch axis (M,) or,
with ``batch=False``, of one run.

Discrete gyro (Crassidis & Junkins, *Optimal Estimation of Dynamic Systems*, 2nd ed., §7.2), the
sample stamped ``t_k`` covering ``[t_k, t_k+1]`` (the interval the estimator propagates with it):
``β_{k+1} = β_k + σ_u √Δt n_u``, ``ω_meas,k = ω + (β_k + β_{k+1})/2 + √(σ_v²/Δt + σ_u² Δt/12) n_v``.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.estimators import mekf
from adcs_core.attitude import quat_conjugate, quat_multiply, rotate_to_body
from adcs_msgs_py.measurements import Measurements, Reading

NS_PER_S = 1_000_000_000

# The filter tests' scenario (tests/test_estimators_mekf.py, tests/test_estimator_families.py):
DT, STAR_EVERY, STEPS = 0.1, 10, 3000          # 10 Hz gyro, 1 Hz star tracker, 300 s
SIGMA_V, SIGMA_U = 1e-5, 1e-7                   # ARW rad/√s, RRW rad/s^1.5
SIGMA_ST = 1e-4                                 # star tracker, rad per axis (~20 arcsec)
OMEGA = np.array([0.02, -0.01, 0.015])          # rad/s, ~1.5 deg/s
SIGMA_ATT0 = np.radians(10.0) / np.sqrt(3.0)    # 10 deg RMS initial attitude error
SIGMA_BIAS0 = np.radians(0.1)                   # 0.1 deg/s per axis
RUNS = 100


class Truth:
    """``M`` runs; ``step()`` returns the Measurements stamped ``t_k`` and advances to ``k + 1``.
    ``q_true``, ``beta``: the truth at the current step (before ``step()``: that of the step
    ``step()`` will measure)."""

    def __init__(self, M: int, seed: int, dt: float, omega, sigma_v: float, sigma_u: float,
                 sigma_st: float = 1e-4, star_every: int = 1, outage=(), q0=None, beta0=None,
                 refs=None, sigma_vec: float = 1e-3, sensors=('gyro', 'star_tracker'), batch: bool = True):
        self.rng = np.random.default_rng(seed)
        self.M, self.dt, self.omega = M, dt, np.asarray(omega, dtype=float)
        self.sigma_v, self.sigma_u, self.sigma_st, self.sigma_vec = sigma_v, sigma_u, sigma_st, sigma_vec
        self.star_every, self.outage, self.sensors, self.batch = star_every, set(outage), sensors, batch
        self.q0 = np.broadcast_to(np.array([0.0, 0.0, 0.0, 1.0]) if q0 is None else q0, (M, 4)).copy()
        self.beta = np.zeros((M, 3)) if beta0 is None else np.broadcast_to(beta0, (M, 3)).copy()
        self.refs = (np.array([[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]]) if refs is None else np.asarray(refs))
        self.k = 0

    @property
    def q_true(self) -> np.ndarray:
        """q(t_k) = q0 ⊗ exp(ω t_k / 2): exact for a constant body rate."""
        return quat_multiply(self.q0, mekf.rotation_quaternion(np.broadcast_to(self.omega * self.k * self.dt,
                                                                                (self.M, 3))))

    def _reading(self, value, cov, valid) -> Reading:
        valid = np.broadcast_to(np.asarray(valid, dtype=bool), (self.M,))
        if not self.batch:
            return Reading(value[0], cov, np.bool_(valid[0]))
        return Reading(value, cov, valid.copy())

    def step(self) -> Measurements:
        M, dt, rng = self.M, self.dt, self.rng
        q = self.q_true
        beta_next = self.beta + self.sigma_u * np.sqrt(dt) * rng.normal(size=(M, 3))
        s_g = np.sqrt(self.sigma_v ** 2 / dt + self.sigma_u ** 2 * dt / 12.0)
        gyro = self.omega + 0.5 * (self.beta + beta_next) + s_g * rng.normal(size=(M, 3))
        out = {'gyro': self._reading(gyro, s_g ** 2 * np.eye(3), True)}
        due = self.k % self.star_every == 0 and self.k not in self.outage
        if 'star_tracker' in self.sensors:
            q_meas = quat_multiply(q, mekf.rotation_quaternion(self.sigma_st * rng.normal(size=(M, 3))))
            out['star_tracker'] = self._reading(q_meas, self.sigma_st ** 2 * np.eye(3), due)
        for i, name in enumerate(('sun', 'magnetometer')):
            if name in self.sensors:
                b = rotate_to_body(q, self.refs[i])
                b = rotate_to_body(mekf.rotation_quaternion(self.sigma_vec * rng.normal(size=(M, 3))), b)
                out[name] = self._reading(b, np.zeros((3, 3)), due)
        m = Measurements(self.k * round(dt * NS_PER_S), **out)
        self.beta = beta_next
        self.k += 1
        return m


def perturbed(q_true: np.ndarray, dtheta: np.ndarray) -> np.ndarray:
    """The estimate q with ``q_true = q ⊗ δq(δθ)``: an initial error of ``δθ`` (body axes)."""
    return quat_multiply(q_true, quat_conjugate(mekf.rotation_quaternion(dtheta)))


class StateSensors:
    """A sensor source for the batch engine (``sensors(k, t_ns, q, w) -> Measurements``) on the plant's
    true state: per run ``i`` its own generator seeded ``seeds[i]``; gyro = ω(t_k) + β_k + white noise
    of σ_v/√Δt (β a random walk of σ_u, from ``bias0``), star tracker = q(t_k) ⊗ exp(σ_st n / 2) every
    step; ``true_bias`` is β_k of the last step measured."""

    def __init__(self, seeds, dt: float, sigma_v: float, sigma_u: float, sigma_st: float, bias0) -> None:
        self.rngs = [np.random.default_rng(int(s)) for s in seeds]
        self.dt, self.sigma_v, self.sigma_u, self.sigma_st = dt, sigma_v, sigma_u, sigma_st
        self.beta = np.broadcast_to(np.asarray(bias0, dtype=float), (len(self.rngs), 3)).copy()
        self.true_bias = None

    def __call__(self, k: int, t_ns: int, q: np.ndarray, w: np.ndarray) -> Measurements:
        draws = np.stack([rng.normal(size=(3, 3)) for rng in self.rngs])   # (N, [gyro, bias, star], 3)
        self.true_bias = self.beta.copy()
        gyro = w + self.beta + self.sigma_v / np.sqrt(self.dt) * draws[:, 0]
        self.beta = self.beta + self.sigma_u * np.sqrt(self.dt) * draws[:, 1]
        q_meas = quat_multiply(q, mekf.rotation_quaternion(self.sigma_st * draws[:, 2]))
        valid = np.ones(len(self.rngs), dtype=bool)
        return Measurements(t_ns, gyro=Reading(gyro, np.zeros((3, 3)), valid),
                            star_tracker=Reading(q_meas, self.sigma_st ** 2 * np.eye(3), valid.copy()))
