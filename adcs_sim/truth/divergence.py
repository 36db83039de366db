"""A plant state that is no longer finite: what is not, for the one message the dynamics node and
the batch engine both give when they stop such a run (the run cannot go on: every later state
would be NaN, and the controllers refuse NaN states)."""
from __future__ import annotations

import math

import numpy as np


def nonfinite_cause(plant, x: np.ndarray, torque: np.ndarray | None = None) -> str | None:
    """``None`` if state ``x`` (and the applied ``torque``) are finite, else what is not, e.g.
    ``'body rate, wheels state'``. ``x`` is one run's state vector. Called every step by the
    dynamics node: a finite sum says every entry is finite (a NaN or an infinity never sums to
    a finite number; a sum of finite entries that overflows only takes the long way), in ~1 µs
    with Python floats (no numpy overflow warning); the parts are named only when it is not."""
    if math.isfinite(sum(np.ravel(x).tolist()) + (0.0 if torque is None else sum(np.ravel(torque).tolist()))):
        return None
    parts = {'attitude quaternion': x[:4], 'body rate': x[4:7]}
    parts.update({f'{name} state': x[s] for name, s in plant.slices.items()})
    if torque is not None:
        parts['applied torque'] = torque
    bad = [name for name, values in parts.items() if not np.isfinite(values).all()]
    return ', '.join(bad) or None
