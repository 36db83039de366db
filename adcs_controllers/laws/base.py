"""What every section-bound law object shares (pure; no rclpy)."""
from __future__ import annotations

import numpy as np

from adcs_core.inertia import inertia_matrix


class SectionLaw:
    """A law bound to a validated controller section: the controller's inertia model and the
    regulation target (values may carry a batch axis). Subclasses read their gains and implement
    ``control(t, q, w) -> (torque (..., 3), status)``; the node and the batch engine call it.

    ``mode_names`` maps the integer ``status['mode']`` codes to the names the node publishes.
    ``output`` says what ``control`` returns: ``'torque'`` (body torque, N m) or
    ``'wheel_momentum'`` (the wheels' commanded angular momentum in body axes, N m s, which the
    actuation turns into wheel speed commands).
    """

    mode_names: dict[int, str] = {}
    output: str = 'torque'

    def __init__(self, p: dict) -> None:
        self.inertia = inertia_matrix(p['inertia'])
        q_ref = np.asarray(p['target.attitude'], dtype=float)
        self.q_ref = q_ref / np.linalg.norm(q_ref, axis=-1, keepdims=True)
        self.w_ref = np.asarray(p['target.rate'], dtype=float)
        self.shortest_path = bool(p.get('shortest_path', False))

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        raise NotImplementedError

    def on_wheels(self, axes: np.ndarray, available: np.ndarray) -> str | None:
        """The usable wheels changed (a fault): ``axes`` (n, 3) unit spin axes, ``available`` (n,)
        bool. A law that depends on which wheels remain adapts here and returns a note for the
        log; most laws do not care (allocation alone follows the wheels)."""
        return None

    def published_status(self, status: dict) -> dict:
        """One run's status as the node publishes it: mode codes as names, arrays as floats,
        3-vectors as ``key_x``, ``key_y``, ``key_z``."""
        out = {}
        for key, value in status.items():
            if key == 'mode' and np.ndim(value) == 0 and not isinstance(value, str) and self.mode_names:
                out[key] = self.mode_names.get(int(value), str(int(value)))
            elif isinstance(value, np.ndarray) and value.ndim == 0:
                out[key] = float(value)
            elif isinstance(value, np.ndarray) and value.shape == (3,):
                out.update({f'{key}_{c}': float(v) for c, v in zip('xyz', value)})
            else:
                out[key] = value
        return out


class LawOutputRejected(ValueError):
    """A law produced a non-finite output: the controller node refuses to publish it."""


def checked_output(law: str, value: np.ndarray) -> np.ndarray:
    """``value`` if every entry is finite, else :class:`LawOutputRejected` with the reason.

    The controller node's last line of defence: validation lets only finite states with unit
    quaternions through and every law is fuzzed to stay finite on them (tests/test_fuzz.py), but
    a NaN must never reach the wheels if a law misbehaves anyway (the step is then counted as
    rejected and the dynamics node's missed-step policy applies)."""
    if not np.all(np.isfinite(value)):
        raise LawOutputRejected(f'{law}: non-finite output {np.asarray(value).tolist()} refused')
    return value


def checked_control(law: SectionLaw, name: str, t: float, q: np.ndarray, w: np.ndarray, *extra):
    """``law.control(t, q, w, *extra)`` with its output checked (:func:`checked_output`); a law that
    refuses the state (``ValueError``, e.g. infeasible geometry) is reported the same way, so the
    node can count the step as rejected with the reason instead of crashing or publishing NaN."""
    try:
        with np.errstate(all='ignore'):   # a non-finite result is refused below, with a reason
            value, status = law.control(t, q, w, *extra)
    except LawOutputRejected:
        raise
    except (ValueError, FloatingPointError, ZeroDivisionError, np.linalg.LinAlgError) as exc:
        raise LawOutputRejected(f'{name}: the law refused the state: {exc}') from None
    return checked_output(name, value), status
