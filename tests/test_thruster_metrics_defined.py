"""The thruster metrics defined once (adcs_sim.app.analysis.metric_defs_thrusters): a closed form, the
whole-run formulas every path used before (the last impulse row summed, the count of positive
on-times, the sum of the whole (samples, thrusters) array) bit for bit under any chunking and merge,
a batch row equal to that run alone, and no values without thrusters."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_sim.app.analysis import metric_defs_attitude as mda
from adcs_sim.app.analysis.metric_defs_thrusters import THRUSTERS


def fed(metric, t, on, impulse, cuts=()):
    state = metric.init({'runs': on.shape[0]})
    edges = [0, *sorted(set(c for c in cuts if 0 < c < len(t))), len(t)]
    for a, b in zip(edges[:-1], edges[1:]):
        state = metric.update(state, {'t_s': t[a:b], 'thruster_on_time': on[:, a:b],
                                      'thruster_impulse': impulse[:, a:b]})
    return metric.finish(state)


def reference(on, impulse):
    """analysis.metrics.thruster_metrics as written before its definition (one run)."""
    return {'thruster_impulse_Ns': float(impulse[-1].sum()),
            'thruster_firings': int(np.count_nonzero(on > 0.0)),
            'thruster_on_time_s': float(on.sum())}


def test_closed_form_and_counts_stay_integers():
    t = np.array([0.0, 0.1, 0.2])
    on = np.array([[[0.05, 0.0], [0.0, 0.0], [0.1, 0.02]]])
    impulse = np.array([[[0.5, 0.0], [0.5, 0.0], [1.5, 0.25]]])
    got = mda.listed(mda.values_of(THRUSTERS, {'runs': 1}, {'t_s': t, 'thruster_on_time': on,
                                                            'thruster_impulse': impulse}))
    assert got == {'thruster_impulse_Ns': 1.75, 'thruster_firings': 3, 'thruster_on_time_s': 0.05 + 0.1 + 0.02}
    assert type(got['thruster_firings']) is int


def test_no_thrusters_no_values():
    for shape in ((1, 0, 2), (1, 5, 0)):
        t = np.zeros(shape[1])
        assert mda.values_of(THRUSTERS, {'runs': 1}, {'t_s': t, 'thruster_on_time': np.zeros(shape),
                                                       'thruster_impulse': np.zeros(shape)}) == {}


@settings(derandomize=True, max_examples=30, deadline=None)
@given(n=st.integers(1, 400), k=st.integers(1, 4), seed=st.integers(0, 2 ** 32 - 1),
       cuts=st.lists(st.integers(0, 400), max_size=5), split=st.integers(1, 399))
def test_any_chunking_and_merge_equal_the_whole_run_formulas(n, k, seed, cuts, split):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    on = rng.uniform(0.0, 0.1, (3, n, k)) * (rng.random((3, n, k)) < 0.3)
    impulse = np.cumsum(on * 2.0, axis=1)
    for m in THRUSTERS:
        whole = fed(m, t, on, impulse)
        for r in range(3):
            assert repr(fed(m, t, on[r:r + 1], impulse[r:r + 1], cuts)[0].tolist()) == \
                repr(reference(on[r], impulse[r])[m.name]), m.name
        if n > 1:
            s = min(split, n - 1)
            a = m.update(m.init({'runs': 3}), {'t_s': t[:s], 'thruster_on_time': on[:, :s],
                                               'thruster_impulse': impulse[:, :s]})
            b = m.update(m.init({'runs': 3}), {'t_s': t[s:], 'thruster_on_time': on[:, s:],
                                               'thruster_impulse': impulse[:, s:]})
            assert repr(m.finish(m.merge(a, b)).tolist()) == repr(whole.tolist()), m.name
