"""The attitude and after-fault metrics defined once (adcs_sim.app.analysis.metric_defs_attitude):
closed forms, the whole-series formulas every path used before (the last exit / first entry found
with flatnonzero and interpolated) bit for bit, any chunking and any merge equal to the whole run,
a batch row equal to that run alone, and the fault's time read before or after the samples."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_sim.app.analysis import metric_defs_attitude as mda

SETTLE = mda.SettlingTime('s', 'e', 0.5)
FIRST = mda.FirstEntryTime('f', 'e', 0.5)


def crossing(t0, e0, t1, e1, tol):
    return float(t1) if not math.isfinite(e0) else float(t0 + (e0 - tol) / (e0 - e1) * (t1 - t0))


def settling_reference(t, e, tol):
    """analysis.metrics.settling_time as written before its definition (one run, the whole series)."""
    outside = np.flatnonzero(~(e <= tol))
    if outside.size == 0:
        return float(t[0]) if t.size else math.nan
    i = outside[-1]
    return math.inf if i == e.size - 1 else crossing(t[i], e[i], t[i + 1], e[i + 1], tol)


def first_entry_reference(t, e, tol):
    inside = np.flatnonzero(e <= tol)
    if inside.size == 0:
        return math.inf
    i = inside[0]
    return float(t[0]) if i == 0 else crossing(t[i - 1], e[i - 1], t[i], e[i], tol)


def fed(metric, t, e, cuts=(), runs=1, series='e', extra=(), t_end=None):
    """The metric of ``runs`` runs (e (runs, N)) fed in the pieces between ``cuts``, with the chunks
    ``extra`` (e.g. the faults) first."""
    state = metric.init({'runs': runs})
    for chunk in extra:
        state = metric.update(state, chunk)
    edges = [0, *sorted(set(c for c in cuts if 0 < c < len(t))), len(t)]
    for a, b in zip(edges[:-1], edges[1:]):
        state = metric.update(state, {'t_s': t[a:b], series: e[:, a:b]})
    return metric.finish(state, t_end)


def bits(v):
    return repr(np.asarray(v, dtype=float).tolist())


def test_closed_forms():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    e = np.array([[2.0, 0.0, 1.0, 0.0]])   # in at 0.75 (first entry), out again, in for good at 2.5
    assert fed(SETTLE, t, e)[0] == 2.5
    assert fed(FIRST, t, e)[0] == 0.75
    assert fed(SETTLE, t, np.array([[0.0, 0.1, 0.2, 0.3]]))[0] == 0.0        # always inside: t0
    assert fed(SETTLE, t, np.array([[0.0, 0.1, 0.2, 0.9]]))[0] == math.inf   # ends outside
    assert fed(FIRST, t, np.array([[1.0, 1.0, 1.0, 1.0]]))[0] == math.inf    # never inside
    assert fed(SETTLE, t, np.array([[math.nan, 0.0, 0.0, 0.0]]))[0] == 1.0   # after a NaN: the next stamp
    assert math.isnan(fed(SETTLE, t[:0], np.zeros((1, 0)))[0])              # no samples
    assert fed(FIRST, t[:0], np.zeros((1, 0)))[0] == math.inf


def series(seed, n, runs=1):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 0.2, n))
    e = np.abs(rng.normal(0.0, 0.6, (runs, n))) * np.linspace(2.0, 0.2, n)
    e[rng.random((runs, n)) < 0.02] = math.nan
    e[rng.random((runs, n)) < 0.01] = math.inf
    return t, e


@settings(derandomize=True, max_examples=40, deadline=None)
@given(n=st.integers(1, 300), seed=st.integers(0, 2 ** 32 - 1), cuts=st.lists(st.integers(0, 300), max_size=6))
def test_any_chunking_equals_the_whole_series_formulas(n, seed, cuts):
    t, e = series(seed, n)
    assert bits(fed(SETTLE, t, e, cuts)[0]) == bits(settling_reference(t, e[0], 0.5))
    assert bits(fed(FIRST, t, e, cuts)[0]) == bits(first_entry_reference(t, e[0], 0.5))


@settings(derandomize=True, max_examples=30, deadline=None)
@given(n=st.integers(2, 300), split=st.integers(1, 299), seed=st.integers(0, 2 ** 32 - 1))
def test_merge_of_two_spans_and_batch_rows(n, split, seed):
    split = min(split, n - 1)
    t, e = series(seed, n, runs=4)
    for m in (SETTLE, FIRST):
        whole = fed(m, t, e, runs=4)
        a = m.update(m.init({'runs': 4}), {'t_s': t[:split], 'e': e[:, :split]})
        b = m.update(m.init({'runs': 4}), {'t_s': t[split:], 'e': e[:, split:]})
        assert bits(m.finish(m.merge(a, b))) == bits(whole), m.name
        for r in range(4):   # a batch's row is that run alone
            assert bits(whole[r]) == bits(fed(m, t, e[r:r + 1])[0]), m.name


def test_per_axis_and_the_head_metrics_order():
    t = np.array([0.0, 1.0, 2.0])
    e = np.array([[[1.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]])   # (runs, samples, 3)
    per_axis = mda.SettlingTime('p', 'e', 0.5, per='axis')
    assert fed(per_axis, t, e).tolist() == [[0.5, 0.0, 1.5]]
    assert [m.name for m in mda.head_metrics(0.5, 2.0)] == [
        'duration_s', 'settling_eigenaxis_2deg_s', 'settling_euler213_0.5deg_s', 'settling_euler213_per_axis_s',
        'final_eigenaxis_error_deg']


def faults(*rows):
    return {'faults': np.array(rows, dtype=float).reshape(-1, 2)}


@settings(derandomize=True, max_examples=30, deadline=None)
@given(n=st.integers(2, 200), seed=st.integers(0, 2 ** 32 - 1), cuts=st.lists(st.integers(0, 200), max_size=4),
       at=st.floats(0.0, 1.2), before=st.booleans())
def test_q4_settling_after_a_fault_read_before_or_after_the_samples(n, seed, cuts, at, before):
    t, e = series(seed, n)
    e *= 0.02
    t0 = float(t[0] + at * (t[-1] - t[0]))
    chunk = faults((t0 + 5.0, 2), (t0, 2), (t0 - 1.0, 1))   # the earliest ERROR: t0 (a WARN before it)
    after = t >= t0
    expected = settling_reference(t[after], e[0, after], 0.01) - t0 if after.any() else math.nan
    metric = mda.Q4SettlingAfterFault(0.01)
    state = metric.init({'runs': 1})
    if before:
        state = metric.update(state, chunk)
    edges = [0, *sorted(set(c for c in cuts if 0 < c < n)), n]
    for a, b in zip(edges[:-1], edges[1:]):
        state = metric.update(state, {'t_s': t[a:b], 'q4_error': e[:, a:b]})
    if not before:
        state = metric.update(state, chunk)
    assert bits(metric.finish(state)[0]) == bits(expected)


def test_integral_after_a_fault_is_the_integral_of_the_samples_after_it():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    u = np.array([[[3.0, 4.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]])
    metric = mda.IntegratedTorqueAfterFault()
    got = fed(metric, t, u, series='torque', extra=[faults((1.5, 2))], t_end=5.0)
    assert got.tolist() == [2.0 + 2.0]   # ‖u‖ = 2 on [2, 3], 1 on [3, 5]
    assert fed(metric, t, u, series='torque', extra=[faults((1.5, 1))], t_end=5.0) is None   # a WARN: no fault
    assert fed(metric, t[:0], u[:, :0], series='torque', extra=[faults((1.5, 2))], t_end=5.0) is None


def test_no_fault_no_values():
    for m in mda.fault_metrics_defs():
        assert m.finish(m.update(m.init({'runs': 2}), faults())) is None, m.name
    assert mda.FirstFaultTime().finish(mda.FirstFaultTime().update(
        mda.FirstFaultTime().init({'runs': 2}), faults((3.0, 2), (1.0, 3)))).tolist() == [1.0, 1.0]
