"""Reconfiguration on a wheel failure: a three-wheel law until a wheel is lost, then a two-wheel law.

Seed 000, section VI.A: "the satellite is first controlled with all three wheels to an off-pointing
attitude ... before being controlled by two wheels only (the 2 wheel mode is activated at time
t0 = 500 sec)". :class:`TwoWheelReconfiguration` is that controller as one law object (pure; the
node and the batch engine call it like any law):

* phase ``three_wheel``: the quaternion PD of seed 004 eq. (13) (:class:`~adcs_controllers.laws.pd.PdLaw`,
  shortest path) with its own gains and target (the off-pointing attitude of the manoeuvre);
* phase ``two_wheel``: a seed 000 law (:mod:`adcs_controllers.laws.underactuated`), entered when the
  usable wheels (:meth:`on_wheels`, called by the node when the fault topic changes them) are two
  whose axes span the plane normal to a body axis; that axis becomes the law's unactuated axis;
* back to ``three_wheel`` when the usable axes span space again (a wheel ``recovered``);
* phase ``unsupported`` when what is left is neither (one wheel, or two not normal to a body
  axis): the PD keeps running over what is left (minimum-norm allocation) and the node warns —
  no law of seed 000 applies there.

Without a three-wheel law (``three_wheel.enabled: false``) the two-wheel law runs from the start:
the paper's "plain" case.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.base import SectionLaw
from adcs_controllers.laws.pd import PdLaw
from adcs_controllers.laws.underactuated import unactuated_body_axis

THREE_WHEEL, TWO_WHEEL, UNSUPPORTED = 'three_wheel', 'two_wheel', 'unsupported'
PHASE_CODES = {THREE_WHEEL: 3, TWO_WHEEL: 2, UNSUPPORTED: 0}   # phase_index: the wheels the phase's law uses


def pd_section(p) -> dict:
    """The ``three_wheel.*`` parameters of a two-wheel controller section (typed) as a PD law's
    section: the phase holds its attitude at rest, flipping q the short way."""
    phase = p.three_wheel
    return {'inertia': p.inertia, 'kp': phase.kp, 'kd': phase.kd,
            'target.attitude': phase.target.attitude, 'target.rate': [0.0, 0.0, 0.0],
            'shortest_path': True}


class TwoWheelReconfiguration:
    """``nominal`` (three-wheel law, or None) until two wheels are left, then ``two_wheel``.

    Duck-types a :class:`~adcs_controllers.laws.base.SectionLaw`: ``control``, ``output``,
    ``published_status``, ``on_wheels``, ``q_ref`` (the two-wheel law's target: where the run ends).
    The status gains ``phase``.
    """

    def __init__(self, nominal, two_wheel) -> None:
        self.nominal = nominal
        self.two_wheel = two_wheel
        self.phase = THREE_WHEEL if nominal is not None else TWO_WHEEL
        self.inertia = two_wheel.inertia
        self.q_ref = two_wheel.q_ref
        self.w_ref = two_wheel.w_ref

    @classmethod
    def factory(cls, two_wheel_cls):
        """A law builder for the registry: section dict -> this law around ``two_wheel_cls``."""
        def build(p) -> 'TwoWheelReconfiguration':
            p = two_wheel_cls.section(p)
            nominal = PdLaw(pd_section(p)) if p.three_wheel.enabled else None
            return cls(nominal, two_wheel_cls(p))
        build.__name__ = f'{two_wheel_cls.__name__}WithReconfiguration'
        build.__doc__ = f'{two_wheel_cls.__name__}, after a three-wheel PD phase if configured.'
        return build

    @property
    def active(self):
        return self.two_wheel if self.phase == TWO_WHEEL else self.nominal

    @property
    def output(self) -> str:
        return self.active.output

    @property
    def mode_names(self) -> dict:
        return self.active.mode_names

    def on_wheels(self, axes: np.ndarray, available: np.ndarray) -> str | None:
        """Choose the phase for the usable wheels; returns a note when it changes, else None."""
        available = np.asarray(available, dtype=bool)
        axis = unactuated_body_axis(axes, available)
        spans = available.any() and np.linalg.matrix_rank(np.asarray(axes)[available]) == 3
        if self.nominal is None:
            phase = TWO_WHEEL
        elif spans:
            phase = THREE_WHEEL
        else:
            phase = TWO_WHEEL if axis is not None else UNSUPPORTED
        note = self.two_wheel.follow_axis(axis)
        notes = [note] if note else []
        if phase != self.phase:
            notes.insert(0, f'phase {self.phase} -> {phase}' + (
                ' (no seed 000 law for these wheels: three-wheel PD over what is left)'
                if phase == UNSUPPORTED else ''))
            self.phase = phase
        return '; '.join(notes) or None

    def control(self, t, q, w):
        value, status = self.active.control(t, q, w)
        status['phase'] = self.phase
        return value, status

    def published_status(self, status: dict) -> dict:
        return self.active.published_status(status)

    def mode_codes(self) -> dict[str, dict[str, int]]:
        return {**self.active.mode_codes(), 'phase': PHASE_CODES}

    with_mode_index = SectionLaw.with_mode_index   # the one implementation, on these codes
