"""Attitude sensor models of the truth model: gyro, star tracker, sun sensor, magnetometer (numpy, no ROS).

Each model turns the true state (and, for the vector sensors, the inertial reference vectors of the
environment, given as inputs) into a :class:`adcs_msgs_py.measurements.Reading` per step, with a
leading batch axis when it was built with one seed per run. Seeding follows
:class:`adcs_sim.truth.sensors.MeasurementModel`: run ``i`` has its own generator, here seeded
``[seed[i], stream]`` (numpy ``SeedSequence`` entropy) with a stream number per sensor, and draws the
same count of normals every step whatever the faults, outages or update rate, so a run reads the same
numbers alone on the graph, inside any batch, and with or without the other sensors fitted. Every
operation is element-wise per run (:mod:`adcs_core.attitude`'s fixed-order products), so a run's
readings are the same bit for bit in any batch.

Models and equations: docs/determination_sensors.md.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from adcs_core.attitude import (
    cross,
    dot,
    matvec,
    quat_conjugate,
    quat_multiply,
    rotate_to_body,
    rotate_to_inertial,
    rotation_vector,
    unit,
)
from adcs_msgs_py.measurements import Reading

GYRO_AXES = ('x', 'y', 'z')
_IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def run_generators(seed, stream: int) -> tuple[list[np.random.Generator], bool]:
    """One generator per run (``seed`` an int, or one int >= 0 per run), and whether batched."""
    seeds = np.asarray(seed)
    rngs = [np.random.default_rng([int(s), stream]) for s in seeds.reshape(-1)]
    return rngs, seeds.ndim > 0


def _normals(rngs, n: int) -> np.ndarray:
    """(runs, n) standard normals, run by run (each run's stream alone)."""
    return np.stack([rng.standard_normal(n) for rng in rngs])


def _runs(a, n_runs: int, tail: tuple[int, ...]) -> np.ndarray:
    """``a`` as a (runs, *tail) float array (a shared value broadcast, a per-run one kept)."""
    return np.broadcast_to(np.asarray(a, dtype=float), (n_runs,) + tail).copy()


def rotation_quaternion(phi: np.ndarray) -> np.ndarray:
    """``exp(φ/2)`` = ``[sin(|φ|/2) φ/|φ|, cos(|φ|/2)]`` (..., 4) of rotation vectors ``φ`` (..., 3);
    ``sin(a/2)/a = sinc(a/2π)/2`` is exact at 0."""
    a = np.sqrt(dot(phi, phi))
    s = 0.5 * np.sinc(a / (2.0 * math.pi))
    return np.concatenate([s[..., None] * phi, np.cos(0.5 * a)[..., None]], axis=-1)


def sensor_frame(boresight) -> np.ndarray:
    """Columns ``[x_s, y_s, z_s]`` (3, 3) of a sensor frame in body axes with ``z_s`` the unit
    boresight and ``x_s`` perpendicular to it in the plane of the body x axis (the body y axis when
    the boresight is along x)."""
    z = np.asarray(boresight, dtype=float)
    z = z / np.linalg.norm(z)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - np.dot(ref, z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


class _Model:
    """Shared plumbing: per-run generators, output shaping, and what the suite
    (:class:`adcs_sim.truth.sensor_suite.SensorSuite`) calls: :meth:`read` a step's reading from the
    true state and the environment, :meth:`follow_fault` one of its fault targets. ``ENVIRONMENT``: the
    :class:`~adcs_sim.truth.sensor_suite.SensorEnvironment` fields its reading cannot do without (a
    model with any needs ``environment.enabled``)."""

    ENVIRONMENT: tuple[str, ...] = ()

    def __init__(self, seed, stream: int) -> None:
        self.rngs, self.batched = run_generators(seed, stream)
        self.n_runs = len(self.rngs)
        self.failed = False

    def read(self, k: int, q, w, env) -> Reading:
        """The reading at step ``k`` of true attitude ``q`` and rate ``w`` in the environment ``env``."""
        raise NotImplementedError

    def follow_fault(self, target: str, fault) -> None:
        """A fault snapshot's entry for one of its targets (``adcs_msgs_py.sensor_interfaces``):
        ``failed`` until another mode."""
        self.failed = fault.mode == 'failed'

    def _batch(self, a, width: int) -> np.ndarray:
        a = np.asarray(a, dtype=float)
        return np.broadcast_to(a, (self.n_runs, width)) if a.ndim == 1 else a

    def _reading(self, value, cov, valid) -> Reading:
        valid = np.asarray(valid, dtype=bool)
        if not self.batched:
            return Reading(value[0], cov[0], valid[0])
        return Reading(value, cov, valid)


class Gyro(_Model):
    """Three-axis rate-integrating gyro, the discrete Farrenkopf model (Crassidis & Junkins, *Optimal
    Estimation of Dynamic Systems*, 2nd ed., CRC 2012, ch. 7, the gyro measurement model used to
    simulate the attitude Kalman filter; equation numbers not checked):

    ``ω̃_k = (1 + s) ∘ ω̄_k + ½ (β_k + β_{k+1}) + m_k + b_f + (σ_v²/Δt + σ_u² Δt/12)^½ N_v``,
    ``β_{k+1} = β_k + σ_u Δt^½ N_u``, ``β_0`` = the constant bias,

    the average over the step of ``ω + β + η_v`` (``β̇ = η_u``): ``σ_v`` the angle random walk
    (rad/√s), ``σ_u`` the rate random walk (rad/s^1.5), ``s`` the scale-factor errors. The rate
    term ``ω̄_k`` is the body rate over the step that ends at ``t_k``, as a rate-integrating gyro
    with coning compensation outputs it (a strapdown unit's angle increment over its sample
    period): the rotation vector of ``q(t_{k−1})* ⊗ q(t_k)`` over ``Δt``, the constant rate that
    takes the attitude of ``t_{k−1}`` to that of ``t_k`` exactly, whatever the rate did within the
    step. So the MEKF (:mod:`adcs_controllers.estimators.mekf`) propagating ``[t_{k−1}, t_k]`` with
    the sample of ``t_k`` (``gyro.propagation: increment``) propagates the true attitude exactly but
    for the noise and bias it models. At the first step (no step before it) ``ω̄_0`` is the true
    rate of ``t_0``. Optional bias instability as a first-order Gauss-Markov
    ``m_{k+1} = φ m_k + σ_m (1 − φ²)^½ N_m``, ``φ = exp(−Δt/τ)``, ``m_0 = 0``; ``b_f`` the fault
    bias (a bias jump). The output is clipped to ``±max_rate`` per axis (saturation); a stuck axis
    repeats its reading. The reported covariance is that of the white part,
    ``(σ_v²/Δt + σ_u² Δt/12) I``. Draws per step and run: ``N_v`` (3), ``N_u`` (3), then ``N_m`` (3)
    when the Markov term is on.
    """

    STREAM = 1

    def __init__(self, seed, period: float, arw: float = 0.0, rrw: float = 0.0, bias=(0.0, 0.0, 0.0),
                 scale_factor=(0.0, 0.0, 0.0), max_rate: float = math.inf, markov_std: float = 0.0,
                 markov_time: float = math.inf) -> None:
        super().__init__(seed, self.STREAM)
        self.dt = float(period)
        self.sigma_white = math.sqrt(arw ** 2 / self.dt + rrw ** 2 * self.dt / 12.0)
        self.sigma_walk = rrw * math.sqrt(self.dt)
        self.variance = self.sigma_white ** 2
        self.beta = _runs(bias, self.n_runs, (3,))          # β_k, rad/s
        self.scale = _runs(scale_factor, self.n_runs, (3,))
        self.max_rate = float(max_rate)
        self.markov_on = markov_std > 0.0
        self.phi = math.exp(-self.dt / markov_time) if self.markov_on else 0.0
        self.markov_drive = markov_std * math.sqrt(1.0 - self.phi ** 2) if self.markov_on else 0.0
        self.markov = np.zeros((self.n_runs, 3))
        self.fault_bias = np.zeros(3)
        self.stuck = np.zeros(3, dtype=bool)
        self._freeze = np.zeros(3, dtype=bool)   # axes stuck at this step: hold what they read now
        self.stuck_value = np.zeros((self.n_runs, 3))
        self.true_bias = self.beta.copy()           # the bias in the last reading (½(β_k+β_k+1) + m_k + b_f)
        self.cov = np.broadcast_to(self.variance * np.eye(3), (self.n_runs, 3, 3))
        self.q_last = None                          # the attitude of the previous reading (runs, 4)

    def apply_fault(self, axis: int, mode: str, value: float = 0.0) -> None:
        """``bias``: the axis reads ``value`` rad/s more; ``stuck``: it repeats this step's reading;
        ``recovered`` / ``nominal``: back to the model."""
        self.fault_bias[axis] = float(value) if mode == 'bias' else 0.0
        if mode == 'stuck' and not self.stuck[axis]:
            self._freeze[axis] = True
        self.stuck[axis] = mode == 'stuck'

    def read(self, k: int, q, w, env) -> Reading:
        """The reading of step ``k`` (one a step, in order): of the mean rate over the step that
        ends here (class docstring), the true rate ``w`` at the first."""
        q = self._batch(q, 4)
        mean = w if self.q_last is None else rotation_vector(quat_multiply(quat_conjugate(self.q_last), q)) / self.dt
        self.q_last = q.copy()
        return self.measure(mean)

    def follow_fault(self, target: str, fault) -> None:
        self.apply_fault(GYRO_AXES.index(target.split('.', 1)[1]), fault.mode, fault.value)

    def measure(self, w) -> Reading:
        """The reading of the body rate ``w`` (3,) or (runs, 3) over this step (:meth:`read` gives
        the step's mean rate)."""
        w = self._batch(w, 3)
        n = _normals(self.rngs, 9 if self.markov_on else 6)
        beta_next = self.beta + self.sigma_walk * n[:, 3:6]
        self.true_bias = 0.5 * (self.beta + beta_next) + self.markov + self.fault_bias
        out = (1.0 + self.scale) * w + self.true_bias + self.sigma_white * n[:, :3]
        out = np.clip(out, -self.max_rate, self.max_rate)
        self.stuck_value[:, self._freeze] = out[:, self._freeze]
        self._freeze[:] = False
        out[:, self.stuck] = self.stuck_value[:, self.stuck]
        self.beta = beta_next
        if self.markov_on:
            self.markov = self.phi * self.markov + self.markov_drive * n[:, 6:9]
        return self._reading(out, self.cov, np.ones(self.n_runs, dtype=bool))


class StarTracker(_Model):
    """Star tracker: the attitude of ``latency_steps`` steps ago rotated by a small random rotation
    whose sensor-frame components are ``σ_c N₁, σ_c N₂`` (cross-boresight) and ``σ_a N₃`` (about the
    boresight): ``q̃_k = q(t_{k−L}) ⊗ exp(R_bs δθ_s / 2)``, covariance ``R_bs diag(σ_c², σ_c², σ_a²)
    R_bsᵀ`` in body axes (``R_bs`` :func:`sensor_frame`).

    With no measurement the reading is canonical, as its message reads back: the identity quaternion
    and a zero covariance.

    Valid at step ``k`` only when ``k`` is a multiple of ``every`` (the update rate), ``k >= L`` (the
    first image is not out yet), the tracker is not failed (a fault from its step on), and it was
    not blinded when the image was taken: the boresight in inertial axes ``b = R(q) b_body`` within
    ``sun_exclusion`` of the Sun direction, or within ``earth_exclusion + ρ`` of the nadir (``ρ`` the
    Earth's angular radius, 0 if not given: the angle is then from the nadir). With no Sun or nadir
    direction given there is no exclusion. Latency is exact: the image's attitude and blinding are
    those computed at step ``k − L`` (kept in a history of ``L + 1`` steps), so ``latency`` is a whole
    number of control periods. Draws per step and run: ``N₁, N₂, N₃``, every step.
    """

    STREAM = 2

    def __init__(self, seed, boresight=(0.0, 0.0, 1.0), cross_std: float = 0.0, about_std: float = 0.0,
                 every: int = 1, latency_steps: int = 0, sun_exclusion: float = 0.0,
                 earth_exclusion: float = 0.0) -> None:
        super().__init__(seed, self.STREAM)
        self.frame = sensor_frame(boresight)
        self.boresight = self.frame[:, 2].copy()
        self.std = np.array([cross_std, cross_std, about_std], dtype=float)
        cov = self.frame @ np.diag(self.std ** 2) @ self.frame.T
        self.cov = np.broadcast_to(0.5 * (cov + cov.T), (self.n_runs, 3, 3))
        self.every = int(every)
        self.latency = int(latency_steps)
        self.sun_exclusion = float(sun_exclusion)
        self.earth_exclusion = float(earth_exclusion)
        self.history: deque = deque(maxlen=self.latency + 1)   # (q, blinded) of steps k - L .. k
        self._last_k: int | None = None

    def blinded(self, q: np.ndarray, sun=None, nadir=None, earth_radius=None) -> np.ndarray:
        """(runs,) whether the boresight at attitude ``q`` (runs, 4) is within an exclusion cone."""
        b = rotate_to_inertial(q, np.broadcast_to(self.boresight, q.shape[:-1] + (3,)))
        out = np.zeros(q.shape[0], dtype=bool)
        if sun is not None and self.sun_exclusion > 0.0:
            out |= dot(b, self._batch(sun, 3)) > math.cos(self.sun_exclusion)
        if nadir is not None and self.earth_exclusion > 0.0:
            rho = 0.0 if earth_radius is None else np.asarray(earth_radius, dtype=float)
            cone = np.minimum(self.earth_exclusion + rho, math.pi)
            out |= dot(b, self._batch(nadir, 3)) > np.cos(cone)
        return out

    def read(self, k: int, q, w, env) -> Reading:
        return self.measure(k, q, env.sun, env.nadir, env.earth_angular_radius)

    def measure(self, k: int, q, sun=None, nadir=None, earth_radius=None) -> Reading:
        """The reading at step ``k`` (called once per step, in order) of true attitude ``q``."""
        if self._last_k is not None and k != self._last_k + 1:
            raise ValueError(f'star tracker: step {k} after step {self._last_k} (one call per step, in order)')
        self._last_k = k
        q = self._batch(q, 4)
        n = _normals(self.rngs, 3)
        self.history.append((q.copy(), self.blinded(q, sun, nadir, earth_radius)))
        q_seen, blinded = self.history[0]
        due = k % self.every == 0 and k >= self.latency and not self.failed
        dtheta = matvec(self.frame, self.std * n)
        valid = np.logical_and(due, ~blinded)
        value = np.where(valid[:, None], quat_multiply(q_seen, rotation_quaternion(dtheta)), _IDENTITY)
        return self._reading(value, np.where(valid[:, None, None], self.cov, 0.0), valid)


class SunSensor(_Model):
    """Sun vector sensor: the unit Sun direction in body axes ``s = R(q)ᵀ s_I`` turned by a small
    rotation ``v = σ (n − (n·s) s)`` perpendicular to it (``n`` three normals):
    ``s̃ = s cos|v| + (v × s) sin|v|/|v|``, a unit vector whose error has covariance ``σ² (I − s sᵀ)``
    to first order (the QUEST measurement model). Valid when the illuminated fraction exceeds
    ``min_illumination`` (0: not in umbra), the Sun is within ``fov`` of the boresight and the sensor
    has not failed; otherwise the value is the zero vector (what the message carries). The covariance is
    reported as zeros (the message type has none; estimators use their own parameters).
    """

    STREAM = 3
    ENVIRONMENT = ('sun', 'illumination')

    def __init__(self, seed, std: float = 0.0, boresight=(0.0, 0.0, 1.0), fov: float = math.pi,
                 min_illumination: float = 0.0) -> None:
        super().__init__(seed, self.STREAM)
        self.std = float(std)
        self.boresight = unit(np.asarray(boresight, dtype=float))
        self.cos_fov = math.cos(fov)
        self.min_illumination = float(min_illumination)
        self.cov = np.zeros((self.n_runs, 3, 3))

    def read(self, k: int, q, w, env) -> Reading:
        return self.measure(q, env.sun, env.illumination)

    def measure(self, q, sun, illumination) -> Reading:
        q = self._batch(q, 4)
        n = _normals(self.rngs, 3)
        s = unit(rotate_to_body(q, self._batch(sun, 3)))
        v = self.std * (n - dot(n, s)[:, None] * s)
        a = np.sqrt(dot(v, v))
        turned = np.cos(a)[:, None] * s + np.sinc(a / math.pi)[:, None] * cross(v, s)
        lit = np.broadcast_to(np.asarray(illumination, dtype=float), (self.n_runs,)) > self.min_illumination
        valid = lit & (dot(s, np.broadcast_to(self.boresight, s.shape)) >= self.cos_fov) & (not self.failed)
        return self._reading(np.where(valid[:, None], unit(turned), 0.0), self.cov, valid)


class Magnetometer(_Model):
    """Three-axis magnetometer: ``b̃ = R(q)ᵀ B_I + b + σ N`` (T, body axes), covariance ``σ² I``;
    valid unless failed (then a zero covariance, as the message reads back). Draws per step and run:
    ``N`` (3)."""

    STREAM = 4
    ENVIRONMENT = ('field',)

    def __init__(self, seed, std: float = 0.0, bias=(0.0, 0.0, 0.0)) -> None:
        super().__init__(seed, self.STREAM)
        self.std = float(std)
        self.bias = _runs(bias, self.n_runs, (3,))
        self.cov = np.broadcast_to(self.std ** 2 * np.eye(3), (self.n_runs, 3, 3))

    def read(self, k: int, q, w, env) -> Reading:
        return self.measure(q, env.field)

    def measure(self, q, field) -> Reading:
        q = self._batch(q, 4)
        n = _normals(self.rngs, 3)
        b = rotate_to_body(q, self._batch(field, 3)) + self.bias + self.std * n
        return self._reading(b, self.cov if not self.failed else np.zeros_like(self.cov),
                             np.full(self.n_runs, not self.failed))


def _solve3(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A⁻¹ b`` for (runs, 3, 3) symmetric ``A`` by the adjugate (element-wise per run, fixed order),
    and ``det A``; rows with ``det A = 0`` give zeros."""
    c0 = cross(A[:, 1], A[:, 2])
    c1 = cross(A[:, 2], A[:, 0])
    c2 = cross(A[:, 0], A[:, 1])
    det = dot(A[:, 0], c0)
    x = c0 * b[:, 0:1] + c1 * b[:, 1:2] + c2 * b[:, 2:3]   # adj(A) b for symmetric A
    safe = np.where(det == 0.0, 1.0, det)
    return np.where((det == 0.0)[:, None], 0.0, x / safe[:, None]), det


class CoarseSunSensors(_Model):
    """An assembly of cosine photodiodes (coarse sun sensors) with unit normals ``n_i`` (body axes):
    each reads ``I_i = f max(0, n_i·s) + σ N_i`` clipped at 0 (``f`` the illuminated fraction; 0 when
    the Sun is beyond the detector's ``fov`` from its normal), in units of the full-Sun signal. The
    assembly's sun vector is the least-squares solution over the detectors that see the Sun,
    ``ŝ = unit((Σ n_i n_iᵀ)⁻¹ Σ I_i n_i)``; valid when at least three detectors spanning 3-D see the
    Sun (``det Σ n_i n_iᵀ > 1e-6``), the fraction exceeds ``min_illumination`` and it has not failed
    (else the zero vector). Covariance reported as zeros, as :class:`SunSensor`. Draws per step and
    run: one normal per detector."""

    STREAM = 3   # the sun sensor's stream: one sun sensor is fitted, of either kind
    ENVIRONMENT = ('sun', 'illumination')

    def __init__(self, seed, normals, std: float = 0.0, fov: float = 0.5 * math.pi,
                 min_illumination: float = 0.0) -> None:
        super().__init__(seed, self.STREAM)
        n = np.asarray(normals, dtype=float).reshape(-1, 3)
        self.normals = n / np.linalg.norm(n, axis=-1, keepdims=True)
        self.std = float(std)
        self.cos_fov = math.cos(fov)
        self.min_illumination = float(min_illumination)
        self.cov = np.zeros((self.n_runs, 3, 3))

    def read(self, k: int, q, w, env) -> Reading:
        return self.measure(q, env.sun, env.illumination)

    def measure(self, q, sun, illumination) -> Reading:
        q = self._batch(q, 4)
        noise = _normals(self.rngs, len(self.normals))
        s = unit(rotate_to_body(q, self._batch(sun, 3)))
        frac = np.broadcast_to(np.asarray(illumination, dtype=float), (self.n_runs,))
        A, b = np.zeros((self.n_runs, 3, 3)), np.zeros((self.n_runs, 3))
        for i, n_i in enumerate(self.normals):          # fixed order over the detectors
            c = dot(s, np.broadcast_to(n_i, s.shape))
            sees = (c > 0.0) & (c >= self.cos_fov)
            signal = np.maximum(np.where(sees, frac * c, 0.0) + self.std * noise[:, i], 0.0)
            w = sees.astype(float)
            A = A + w[:, None, None] * np.outer(n_i, n_i)
            b = b + (w * signal)[:, None] * n_i
        x, det = _solve3(A, b)
        norm = np.sqrt(dot(x, x))
        valid = (det > 1e-6) & (norm > 0.0) & (frac > self.min_illumination) & (not self.failed)
        value = np.where(valid[:, None], x / np.where(norm > 0.0, norm, 1.0)[:, None], 0.0)
        return self._reading(value, self.cov, valid)


class FineSunSensor(_Model):
    """Fine (two-axis) sun sensor: it measures the two angles of the Sun direction in its own frame
    (``R_bs`` :func:`sensor_frame` of the boresight, ``s_s = R_bsᵀ R(q)ᵀ s_I``),
    ``α = atan2(s_x, s_z)``, ``β = atan2(s_y, s_z)`` (the angles of the two slit or quadrant detector
    axes: Wertz (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978, §6.1, two-axis
    sun sensors; Markley & Crassidis, *Fundamentals of Spacecraft Attitude Determination and Control*,
    Springer 2014, ch. 4, sun sensors; section numbers not checked), each with its own white noise:
    ``α̃ = α + σ N₁``, ``β̃ = β + σ N₂``. The reading is the unit vector of the measured angles,
    ``s̃ = R_bs unit(sin α̃ cos β̃, cos α̃ sin β̃, cos α̃ cos β̃)`` (= ``unit(tan α̃, tan β̃, 1)``).

    Noise on the angles, not on the unit vector, because the angles are what the detector outputs,
    each from its own axis and electronics. To first order the error of ``s̃`` is ``σ (∂s/∂α N₁ +
    ∂s/∂β N₂)``: ``σ²(I − s sᵀ)`` on the boresight (the QUEST measurement model the MEKF's vector update
    assumes, Markley & Crassidis 2014 ch. 6), and within a half-cone ``θ ≤ 45°`` each of the two
    sensitivities lies in ``[σ cos θ, σ]``: the filter's σ is exact on the boresight and conservative
    off it.

    Valid when the illuminated fraction exceeds ``min_illumination`` (0: not in umbra), the Sun is
    within the half-cone ``fov`` (< 90°) of the boresight and the sensor has not failed; otherwise the
    zero vector (what its message, ``sensors/fine_sun``, a Vector3Stamped as the sun sensor's, carries).
    Covariance reported as zeros (the message has none). Draws per step and run: ``N₁, N₂``.
    """

    STREAM = 5
    ENVIRONMENT = ('sun', 'illumination')

    def __init__(self, seed, std: float = 0.0, boresight=(0.0, 0.0, 1.0), fov: float = math.radians(60.0),
                 min_illumination: float = 0.0) -> None:
        super().__init__(seed, self.STREAM)
        if not 0.0 < fov < 0.5 * math.pi:
            raise ValueError(f'fine sun sensor: the field of view half angle must be in (0, 90) deg, got '
                             f'{math.degrees(fov)}')
        self.std = float(std)
        self.frame = sensor_frame(boresight)
        self.cos_fov = math.cos(fov)
        self.min_illumination = float(min_illumination)
        self.cov = np.zeros((self.n_runs, 3, 3))

    def angles(self, s_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The true angles ``(α, β)`` (runs,) of unit Sun directions ``s_body`` (runs, 3), rad."""
        s = matvec(self.frame.T, s_body)
        return np.arctan2(s[:, 0], s[:, 2]), np.arctan2(s[:, 1], s[:, 2])

    def read(self, k: int, q, w, env) -> Reading:
        return self.measure(q, env.sun, env.illumination)

    def measure(self, q, sun, illumination) -> Reading:
        q = self._batch(q, 4)
        n = _normals(self.rngs, 2)
        s = unit(rotate_to_body(q, self._batch(sun, 3)))
        alpha, beta = self.angles(s)
        a, b = alpha + self.std * n[:, 0], beta + self.std * n[:, 1]
        seen = np.stack([np.sin(a) * np.cos(b), np.cos(a) * np.sin(b), np.cos(a) * np.cos(b)], axis=-1)
        turned = matvec(self.frame, seen)
        lit = np.broadcast_to(np.asarray(illumination, dtype=float), (self.n_runs,)) > self.min_illumination
        inside = dot(s, np.broadcast_to(self.frame[:, 2], s.shape)) >= self.cos_fov
        valid = lit & inside & (not self.failed)
        return self._reading(np.where(valid[:, None], unit(turned), 0.0), self.cov, valid)
