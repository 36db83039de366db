"""The applied-torque metrics defined once (adcs_sim.app.analysis.metric_defs: IntegratedTorque, ControlEnergy,
PeakTorque): closed forms, the formulas every path used before (numpy's norm, square sum and max of
the whole run, the zero-order hold to the run's end) bit for bit, and any chunking or merge equal to
the whole run."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_sim.app.analysis.metric_defs import DEFINED, ControlEnergy, IntegratedTorque, PeakTorque

TORQUE = [m for m in DEFINED if m.needs == ('torque',)]


def value(metric, t, u, t_end, cuts=()):
    """The metric of one run (u (N, 3) at t) fed in the pieces between ``cuts``."""
    state = metric.init({'runs': 1})
    edges = [0, *sorted(set(c for c in cuts if 0 < c < len(t))), len(t)]
    for a, b in zip(edges[:-1], edges[1:]):
        state = metric.update(state, {'t_s': t[a:b], 'torque': u[None, a:b]})
    return metric.finish(state, t_end)[0]


def reference(t, u, t_end):
    """The formulas of analysis.run_metrics before the definitions (numpy on the whole run)."""
    zoh = np.diff(np.append(t, max(t_end, t[-1])))
    return {'integrated_torque_Nms': float(np.sum(np.linalg.norm(u, axis=-1) * zoh)),
            'control_energy_N2m2s': float(np.sum(np.sum(u ** 2, axis=-1) * zoh)),
            'peak_torque_Nm': np.abs(u).max(axis=0).tolist()}


def bits(v):
    return repr(np.asarray(v, dtype=float).tolist())


def test_the_run_metrics_order():
    assert [m.name for m in TORQUE] == ['integrated_torque_Nms', 'control_energy_N2m2s', 'peak_torque_Nm']


def test_closed_form_of_a_held_torque():
    # (1, 0, 0) for 1 s then (3, 4, 0) held to t_end = 3 s: ∫‖u‖ = 1 + 5·2, ∫uᵀu = 1 + 25·2
    t, u = np.array([0.0, 1.0]), np.array([[1.0, 0, 0], [3.0, 4.0, 0]])
    assert value(IntegratedTorque(), t, u, 3.0) == 11.0
    assert value(ControlEnergy(), t, u, 3.0) == 51.0
    assert value(PeakTorque(), t, u, 3.0).tolist() == [3.0, 4.0, 0.0]
    # a run ending before its last torque sample holds it for nothing (zoh_durations)
    assert value(IntegratedTorque(), t, u, 0.5) == 1.0


def test_no_samples_is_nan():
    t, u = np.zeros(0), np.zeros((0, 3))
    for m in TORQUE:
        assert np.isnan(value(m, t, u, 10.0)).all()
    assert PeakTorque().finish(PeakTorque().init({'runs': 4})).shape == (4, 3)


@pytest.mark.filterwarnings('ignore:overflow encountered:RuntimeWarning')   # the 1e300 samples
@settings(derandomize=True, max_examples=40, deadline=None)
@given(n=st.integers(1, 700), seed=st.integers(0, 2 ** 32 - 1),
       cuts=st.lists(st.integers(0, 700), max_size=6), nan=st.booleans())
def test_any_chunking_equals_the_whole_run_formulas(n, seed, cuts, nan):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 0.2, n))
    u = rng.normal(0.0, 1e-3, (n, 3)) * rng.choice([1.0, -0.0, 1e-300, 1e300], (n, 3), p=[0.97, 0.01, 0.01, 0.01])
    if nan:
        u[rng.integers(n), rng.integers(3)] = math.nan
    t_end = float(t[-1] + rng.uniform(0.0, 0.5))
    expected = reference(t, u, t_end)
    for m in TORQUE:
        assert bits(value(m, t, u, t_end, cuts)) == bits(expected[m.name]), m.name


@settings(derandomize=True, max_examples=25, deadline=None)
@given(n=st.integers(2, 400), split=st.integers(1, 399), seed=st.integers(0, 2 ** 32 - 1))
def test_merge_of_two_spans_equals_the_whole(n, split, seed):
    split = min(split, n - 1)
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 0.2, n))
    u = rng.normal(0.0, 1.0, (3, n, 3))          # three runs at once
    for m in TORQUE:
        whole = m.finish(m.update(m.init({'runs': 3}), {'t_s': t, 'torque': u}), t[-1] + 0.1)
        a = m.update(m.init({'runs': 3}), {'t_s': t[:split], 'torque': u[:, :split]})
        b = m.update(m.init({'runs': 3}), {'t_s': t[split:], 'torque': u[:, split:]})
        merged = m.finish(m.merge(a, b), t[-1] + 0.1)
        assert bits(merged) == bits(whole), m.name
        for r in range(3):   # a batch's row is that run alone
            assert bits(whole[r]) == bits(value(m, t, u[r], t[-1] + 0.1)), m.name
