"""Attitude sensors: seeded star-tracker and gyro errors on the true state (numpy, no ROS).

The dynamics node publishes the measured state on ``state`` and the truth on ``truth/state``;
the batch engine applies the very same model to each run of a batch.
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import quat_multiply, quat_normalize


class MeasurementModel:
    """Star tracker: the true attitude rotated by a small random rotation (``attitude_std`` rad per
    axis, 1 sigma); gyro: the true rate plus a constant bias and white noise (``rate_std`` rad/s).

    ``seed`` is an int, or one int per run of a batch (shape ``(N,)``): run ``i`` draws from its
    own generator seeded ``seed[i]``, in the same order as a single run would (attitude then rate
    each step), so a run measures the same noise alone on the graph and inside any batch.
    """

    def __init__(self, seed, attitude_std: float, rate_std: float, gyro_bias) -> None:
        seeds = np.asarray(seed)
        self.batched = seeds.ndim > 0
        self.rngs = [np.random.default_rng(int(s)) for s in seeds.reshape(-1)]
        self.attitude_std = float(attitude_std)
        self.rate_std = float(rate_std)
        self.gyro_bias = np.asarray(gyro_bias, dtype=float)
        self.active = self.attitude_std > 0 or self.rate_std > 0 or bool(np.any(self.gyro_bias))

    def _draw(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """One step's (attitude error rotation vector, gyro noise) of one run, in that order."""
        dtheta = rng.normal(0.0, self.attitude_std, 3) if self.attitude_std > 0 else np.zeros(3)
        dw = rng.normal(0.0, self.rate_std, 3) if self.rate_std > 0 else np.zeros(3)
        return dtheta, dw

    def measure(self, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured (q, w) of true (q, w): shapes (4,), (3,) or, batched, (N, 4), (N, 3)."""
        if not self.active:
            return q, w
        draws = [self._draw(rng) for rng in self.rngs]
        dtheta = np.stack([d for d, _ in draws])
        dw = np.stack([d for _, d in draws])
        if not self.batched:
            dtheta, dw = dtheta[0], dw[0]
        dq = quat_normalize(np.concatenate([0.5 * dtheta, np.ones(dtheta.shape[:-1] + (1,))], axis=-1))
        return quat_normalize(quat_multiply(q, dq)), w + self.gyro_bias + dw
