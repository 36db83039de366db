"""The controller-status figure's timeline of text values (adcs_sim/app/report/status_figure.py):
one lane per value, named with its share of the run, so that a mode a law holds for one step
at a time among another (the GSMN's low_gain between zero_torque steps) stays visible instead
of being painted over by the value around it."""
from __future__ import annotations

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from adcs_sim.app.report.status_figure import _timelines


def _chattering(n: int = 1000):
    """``mode`` 'pd' for the first 100 s, then 'low_gain' one step in ten, 'zero_torque' otherwise;
    ``phase`` 'a' then 'b' at 100 s. Samples at 0, 1, ..., n - 1 s."""
    t = np.arange(n, dtype=float)
    mode = np.where(t < 100, 'pd', np.where(t % 10 == 0, 'low_gain', 'zero_torque')).astype(object)
    phase = np.where(t < 100, 'a', 'b').astype(object)
    return {'mode': (t, mode), 'phase': (t, phase)}


def _draw():
    ax = Figure().subplots()
    _timelines(ax, _chattering(), ['mode', 'phase'])
    return ax


def test_each_value_has_its_own_lane_named_with_its_share():
    ax = _draw()
    labels = [label.get_text() for label in ax.get_yticklabels()]
    assert labels == ['mode = pd  (10 %, 1×)', 'mode = low_gain  (9 %, 90×)', 'mode = zero_torque  (81 %, 90×)',
                      'phase = a  (10 %, 1×)', 'phase = b  (90 %, 1×)']
    ticks = list(ax.get_yticks())
    assert ticks == sorted(ticks, reverse=True)      # top to bottom in the order above


def test_a_value_held_one_step_at_a_time_is_drawn_in_its_own_lane():
    ax = _draw()
    bars = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert [len(c.get_paths()) for c in bars] == [1, 90, 90, 1, 1]
    low_gain = bars[1].get_paths()
    lanes = {round(float(np.mean(p.vertices[:, 1]))) for p in low_gain}
    assert lanes == {3}                              # the low_gain lane only (5 lanes: 4, 3, 2, 1, 0)
    assert all(np.ptp(p.vertices[:, 0]) == 1.0 for p in low_gain)   # each one step (1 s) wide
    assert bars[1].get_linewidth()[0] > 0            # an edge: a one-step span stays drawn at any width


def test_keys_are_separated():
    ax = _draw()
    assert [line.get_ydata()[0] for line in ax.get_lines()] == [1.5]   # between mode's lanes and phase's
