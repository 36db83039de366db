"""The thruster metrics defined once, on the protocol of :mod:`adcs_sim.app.analysis.metric_defs`.

They read ``thrusters/state`` (the thrusters named in its last message), each chunk with its stamps
``t_s`` and, per run, sample and thruster: ``'thruster_on_time'`` (the ``velocity`` field: the
on-time commanded for the period, s) and ``'thruster_impulse'`` (``position``: the impulse
delivered so far, N·s), (runs, samples, n).

* :class:`ThrusterImpulse` ``thruster_impulse_Ns``: the impulse of the last sample summed over the
  thrusters (N·s);
* :class:`ThrusterFirings` ``thruster_firings``: thruster-periods with a non-zero on-time (a count);
* :class:`ThrusterOnTime` ``thruster_on_time_s``: every on-time summed (s): the terms are kept and
  summed once in ``finish``, over each run's samples × thrusters in order (numpy's pairwise sum of
  the flattened array, the order the whole run always had).

None (left out of a run's metrics) without on-time samples: a run without thrusters. The campaign's
batch engine does not give them (its runs' ``run_data`` carries no thruster series).
"""
from __future__ import annotations

import numpy as np

from adcs_sim.app.analysis.metric_defs import Metric


class _Thrusters(Metric):
    """A thruster metric: ``reduce`` a chunk of its series ``needs[0]`` (runs, samples, thrusters) to a
    value, ``combine`` two spans' values in time order; no value without thruster samples."""

    def init(self, context: dict):
        return {'runs': context['runs'], 'value': None}

    def merge(self, a, b):
        if a['value'] is None or b['value'] is None:
            return b if a['value'] is None else a
        return {'runs': a['runs'], 'value': self.combine(a['value'], b['value'])}

    def update(self, state, chunk: dict):
        """The chunk's value of its series (``reduce``) folded into the state (``combine``); a chunk
        without thruster samples leaves it as it is."""
        values = np.asarray(chunk[self.needs[0]], dtype=float)
        if values.shape[1] and values.shape[2]:
            value = self.reduce(values)
            state['value'] = value if state['value'] is None else self.combine(state['value'], value)
        return state


class ThrusterImpulse(_Thrusters):
    name, unit, needs = 'thruster_impulse_Ns', 'N·s', ('thruster_impulse',)
    note = 'total thruster impulse Σ∫F dt at the end (N·s)'

    @staticmethod
    def reduce(impulse):
        return impulse[:, -1].copy()

    @staticmethod
    def combine(a, b):
        return b

    def finish(self, state, t_end_s: float | None = None):
        return None if state['value'] is None else state['value'].sum(axis=-1)


class ThrusterFirings(_Thrusters):
    name, unit, needs = 'thruster_firings', '', ('thruster_on_time',)
    note = 'thruster-periods with a non-zero on-time'

    @staticmethod
    def reduce(on):
        return np.count_nonzero(on > 0.0, axis=(1, 2))

    @staticmethod
    def combine(a, b):
        return a + b

    def finish(self, state, t_end_s: float | None = None):
        return state['value']


class ThrusterOnTime(_Thrusters):
    name, unit, needs = 'thruster_on_time_s', 's', ('thruster_on_time',)
    note = 'total thruster on-time, all thrusters (s)'

    @staticmethod
    def reduce(on):
        return [on]

    @staticmethod
    def combine(a, b):
        return [*a, *b]

    def finish(self, state, t_end_s: float | None = None):
        if state['value'] is None:
            return None
        on = np.concatenate(state['value'], axis=1)
        return np.array([row.sum() for row in on])   # each run's (samples, n), flattened: its pairwise sum


THRUSTERS: tuple[Metric, ...] = (ThrusterImpulse(), ThrusterFirings(), ThrusterOnTime())
