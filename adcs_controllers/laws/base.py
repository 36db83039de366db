"""What every section-bound law object shares (pure; no rclpy)."""
from __future__ import annotations

import dataclasses

import numpy as np

from adcs_core.inertia import inertia_matrix
from adcs_msgs_py.blocks import check_unit_quaternion
from adcs_msgs_py.params import Param
from adcs_msgs_py.sections import Section, as_section


def target_params() -> list[Param]:
    """The regulation target (every law with a target attitude has them)."""
    return [
        Param('target.attitude', 'double_array', default=[0.0, 0.0, 0.0, 1.0], length=4,
              check=check_unit_quaternion, batch=True, doc='commanded attitude [x, y, z, w]'),
        Param('target.rate', 'double_array', default=[0.0, 0.0, 0.0], length=3, batch=True,
              doc='commanded rate (rad/s)'),
    ]


TARGET_PARAMS = tuple(target_params())

# The sign convention of the attitude error (the laws of seed 004 and seed 000 have it).
SHORTEST_PATH = Param('shortest_path', 'bool', default=False,
                      doc='flip q when q4 < 0 (not in seed 004, whose laws are applied as printed by default)')


def shortest_path_param(doc: str) -> Param:
    """:data:`SHORTEST_PATH` with another description (its default stays declared once)."""
    return dataclasses.replace(SHORTEST_PATH, doc=doc)


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
    # The optional parameters the law reads: the very Param objects its schema lists, so that a law
    # built from a plain dict (a test, a script) gets the schema's default (:meth:`section`).
    params: tuple[Param, ...] = TARGET_PARAMS
    targeted: bool = True   # the section has ``target.*`` (the pointing laws point an axis instead)

    @classmethod
    def section(cls, p: dict | Section) -> Section:
        """``p`` as a typed section: as it is when the family built it from the schema
        (:func:`adcs_msgs_py.sections.section`), or a plain ``{dotted.name: value}`` dict with the
        schema defaults of :attr:`params` it lacks."""
        return as_section(p, cls.params)

    def __init__(self, p: dict | Section) -> None:
        p = self.section(p)
        self.inertia = inertia_matrix(p.inertia)
        if not self.targeted:   # no target attitude: the identity, at rest
            self.q_ref, self.w_ref = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)
            return
        q_ref = np.asarray(p.target.attitude, dtype=float)
        self.q_ref = q_ref / np.linalg.norm(q_ref, axis=-1, keepdims=True)
        self.w_ref = np.asarray(p.target.rate, dtype=float)

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        raise NotImplementedError

    def on_wheels(self, axes: np.ndarray, available: np.ndarray) -> str | None:
        """The usable wheels changed (a fault): ``axes`` (n, 3) unit spin axes, ``available`` (n,)
        bool. A law that depends on which wheels remain adapts here and returns a note for the
        log; most laws do not care (allocation alone follows the wheels)."""
        return None

    def mode_codes(self) -> dict[str, dict[str, int]]:
        """The number of each mode name the law publishes, by status key: ``mode`` from
        :attr:`mode_names` (a law with more mode keys, such as ``phase``, adds its own)."""
        return {'mode': {name: code for code, name in self.mode_names.items()}}

    def with_mode_index(self, published: dict) -> dict:
        """``published`` (:meth:`published_status`) with ``<key>_index``, the mode's number
        (:meth:`mode_codes`), right after each mode key whose name the law numbers: status values
        travel as text, and a viewer plots a value that parses as a number (PlotJuggler's ROS 2
        parser, Lichtblick's Plot panel), not a name."""
        codes, out = self.mode_codes(), {}
        for key, value in published.items():
            out[key] = value
            code = codes.get(key, {}).get(value) if isinstance(value, str) else None
            if code is not None:
                out[f'{key}_index'] = code
        return out

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
