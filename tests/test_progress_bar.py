"""The runner's progress bar in simulated seconds (:class:`adcs_sim.app.graph.processes.SimTimeBar`):
a completed run ends at 100 %, though the last ``/clock`` tick the runner saw was a few steps
short of the end; an interrupted run stays where it stopped."""
from __future__ import annotations

import io

import pytest

from adcs_sim.app.graph.processes import SimTimeBar


def _bar(duration: float) -> tuple[SimTimeBar, io.StringIO]:
    out = io.StringIO()
    return SimTimeBar(duration, enabled=True, file=out), out


def _last_percent(out: io.StringIO) -> str:
    shown = out.getvalue().replace('\r', '\n').strip().splitlines()[-1]
    return shown.split('%', 1)[0].strip()


@pytest.mark.parametrize('duration, last_tick', [(600.0, 588.0), (10_000.0, 9_800.0), (0.3, 0.1), (120.0, 0.0)])
def test_a_completed_run_ends_at_100_percent(duration, last_tick):
    bar, out = _bar(duration)
    bar.advance(last_tick)             # the last tick the runner saw: ~98 % of the run
    bar.complete()
    bar.close()
    assert bar.bar.n == duration and bar.sim_time == duration
    assert _last_percent(out) == '100'


def test_an_interrupted_run_stays_where_it_stopped():
    bar, out = _bar(600.0)
    bar.advance(300.0)
    bar.close()
    assert bar.bar.n == 300.0
    assert _last_percent(out) == '50'


def test_the_bar_never_moves_back():
    bar, _ = _bar(100.0)
    bar.advance(40.0)
    bar.advance(10.0)                  # a late, older tick
    assert bar.sim_time == 40.0 and bar.bar.n == 40.0
    bar.close()


def test_a_disabled_bar_still_counts_and_completes():
    bar = SimTimeBar(100.0, enabled=False)
    bar.advance(42.0)
    bar.complete()
    assert bar.sim_time == 100.0
    bar.close()
