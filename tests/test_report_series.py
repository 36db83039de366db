"""The report's controller-status series, read column by column
(:func:`adcs_sim.app.analysis.status_records.key_texts`), equal what the record-by-record reading gave
(the references below are the report's code before issue #18's report work): ``status_series``,
``held_text`` and ``status_array``, for any mix of status names, layouts, batches and texts
(hostile ones included), and on committed bags of every kind."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_sim.app.report.kinds import held_text
from adcs_sim.app.report.lead import status_array
from adcs_sim.app.report.loading import load_run, status_series
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.app.analysis.status_records import WIDE, StatusRecords, status_column, status_keys

BAGS = Path(__file__).resolve().parents[1] / 'bags'


def ref_status_series(records) -> dict:
    several = len({name for _, name, _ in records}) > 1
    raw: dict = {}
    for t, name, values in records:
        for key, value in values.items():
            ts, vs = raw.setdefault(f'{name}/{key}' if several else key, ([], []))
            ts.append(t)
            vs.append(value)
    out = {}
    for key, (ts, vs) in raw.items():
        try:
            arr = np.array(vs, dtype=float)
        except ValueError:
            arr = np.array(vs, dtype=object)
        out[key] = (np.array(ts, dtype=float), arr)
    return out


def ref_held_text(records, t, key):
    rows = [(s, v[key]) for s, _, v in records if key in v]
    if not rows:
        return None
    ts = np.array([s for s, _ in rows])
    vs = np.array([str(v) for _, v in rows], dtype=object)
    return vs[np.clip(np.searchsorted(ts, t, side='right') - 1, 0, ts.size - 1)]


def ref_status_array(records, keys):
    rows = [(t, [v.get(k) for k in keys]) for t, _, v in records if all(k in v for k in keys)]
    if not rows:
        return None
    try:
        return np.array([t for t, _ in rows]), np.array([r for _, r in rows], dtype=float)
    except ValueError:
        return None


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal shape, dtype and values, bit for bit (NaN included)."""
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype == object:
        return a.tolist() == b.tolist()
    return a.tobytes() == b.tobytes()


def check_series(records) -> None:
    """Every series the report derives from ``records`` equals the record-by-record reading."""
    run = RunData(t=np.array([-2.0, 0.0, 1.0, 2.0, 3.0]), q=np.zeros((5, 4)), w=np.zeros((5, 3)),
                  controller_status=records)
    got, ref = status_series(run), ref_status_series(records)
    assert list(got) == list(ref)
    for key in ref:
        assert _same_array(got[key][0], ref[key][0]) and _same_array(got[key][1], ref[key][1]), key
    for key in ('mode', 'V', 'phase', 'é', 'absent'):
        a, b = held_text(run, key), ref_held_text(records, run.t, key)
        assert (a is None and b is None) or _same_array(a, b), key
    for keys in (['V'], ['u_x', 'V'], ['mode'], ['absent'], ['V', 'absent']):
        a, b = status_array(run, keys), ref_status_array(records, keys)
        assert (a is None) == (b is None), keys
        if a is not None:
            assert _same_array(a[0], b[0]) and _same_array(a[1], b[1]), keys


numbers = st.sampled_from(['0', '-0.0', '1e-05', '2.5', 'nan', '-inf', '1_0', ' 3 '])
texts = st.one_of(numbers, st.sampled_from(['pd', '', 'x' * (WIDE + 1), 'a\0', 'é', '🛰']), st.text(max_size=20))
keys = st.sampled_from(['mode', 'V', 'u_x', 'phase', 'é'])
status = st.tuples(st.just(0), st.sampled_from(['pd_controller', 'minnorm_controller']), st.just(''), st.just(''),
                   st.dictionaries(keys, st.one_of(numbers, numbers, texts), max_size=4))
batch = st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.0, 2.5, -1.0, 1e9]), st.lists(status, max_size=3)), max_size=8)


@settings(max_examples=150, derandomize=True, deadline=None)
@given(st.lists(batch, max_size=4))
@pytest.mark.slow
def test_columns_give_the_series_of_the_records(raw):
    batches = [(np.array([s for s, _ in b], dtype=float), [m for _, m in b]) for b in raw]
    records = StatusRecords()
    for stamps, messages in batches:
        records.add(stamps, messages)
    records.freeze()
    as_list = list(records)
    check_series(records)
    check_series(as_list)    # a plain list of records (RunData built by hand) gives the same
    assert status_keys(records) == status_keys(as_list)
    for name, key in status_keys(as_list) + [(None, 'V'), (None, 'mode'), (None, 'absent')]:
        a, b = status_column(records, key, name), status_column(as_list, key, name)
        assert a[0].tolist() == b[0].tolist() and a[1].tolist() == b[1].tolist()
        assert [v.decode('utf-8', 'surrogatepass') if isinstance(v, bytes) else v for v in a[2].tolist()] == b[2].tolist()


@pytest.mark.parametrize('name', ['uosat12_gsmn', 'm2s_intermediate_vagc_0p01', 'pointing_controller_a',
                                  'microsat_gsmn_slew'])
def test_committed_bags_series_unchanged(name):
    run = load_run(BAGS / name / 'bag').data
    records = list(run.controller_status)
    got, ref = status_series(run), ref_status_series(records)
    assert list(got) == list(ref)
    assert all(_same_array(got[k][0], ref[k][0]) and _same_array(got[k][1], ref[k][1]) for k in ref)
    for key in ('phase', 'mode'):
        a, b = held_text(run, key), ref_held_text(records, run.t, key)
        assert (a is None and b is None) or _same_array(a, b), key
    for keys in (['theta'], ['w_err_x', 'w_err_y', 'w_err_z']):
        a, b = status_array(run, keys), ref_status_array(records, keys)
        assert (a is None) == (b is None)
        if a is not None:
            assert _same_array(a[0], b[0]) and _same_array(a[1], b[1])
