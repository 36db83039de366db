"""StatusRecords (adcs_sim.app.analysis.status_records): the controller status of a run, stored compactly,
reads back as exactly the list of ``(t, name, {key: value})`` the analysis used to build: in
stamp order, reading order on ties, every text as it was (hostile ones included), for any mix of
layouts and batches. Memory: a fraction of the tuples-and-dicts form (issue #18)."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_sim.app.analysis.status_records import WIDE, StatusRecords


def reference(batches) -> list:
    """What RunData built before: every status of every message, stably sorted by the message stamp."""
    rows = [(stamp, s[1], s[4]) for stamps, messages in batches for stamp, statuses in zip(stamps.tolist(), messages)
            for s in statuses]
    rows.sort(key=lambda r: r[0])
    return rows


def records(batches) -> StatusRecords:
    out = StatusRecords()
    for stamps, messages in batches:
        out.add(stamps, messages)
    return out.freeze()


texts = st.one_of(st.sampled_from(['0', '-0.0', '1e-05', 'pd', 'rw_x,rw_y', '', 'x' * (WIDE + 1), 'a\0', '\0',
                                   'é', '🛰', 'nan']), st.text(max_size=80))
keys = st.sampled_from(['mode', 'V', 'u_x', 'phase', 'é'])
status = st.tuples(st.just(0), st.sampled_from(['pd_controller', 'minnorm_controller']), st.just(''), st.just(''),
                   st.dictionaries(keys, texts, max_size=4))
message = st.lists(status, min_size=0, max_size=3)
batch = st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.0, 2.5, -1.0, 1e9]), message), max_size=8)


@settings(max_examples=150, derandomize=True, deadline=None)
@given(st.lists(batch, max_size=4))
@pytest.mark.slow
def test_reads_back_as_the_sorted_list_of_tuples(raw):
    batches = [(np.array([s for s, _ in b], dtype=float), [m for _, m in b]) for b in raw]
    ref, got = reference(batches), records(batches)
    assert got == ref and list(got) == ref and len(got) == len(ref)
    if ref:
        assert got[0] == ref[0] and got[-1] == ref[-1] and got[-len(ref)] == ref[0]
        assert got[1:3] == ref[1:3]


def test_index_out_of_range_and_empty():
    empty = StatusRecords().freeze()
    assert len(empty) == 0 and list(empty) == [] and empty == [] and not empty
    one = records([(np.array([1.0]), [[(0, 'pd', '', '', {'mode': 'a'})]])])
    assert one[0] == (1.0, 'pd', {'mode': 'a'}) and one[-1] == one[0]
    for bad in (1, -2):
        try:
            one[bad]
        except IndexError:
            continue
        raise AssertionError(f'index {bad} did not raise')


def test_a_day_of_statuses_costs_a_fraction_of_the_tuples():
    """20 000 steps of a PD-like status (5 keys of float texts): the compact form takes under a fifth
    of the memory of the list of tuples and dicts it replaces."""
    rng = np.random.default_rng(3)
    n = 20_000
    values = rng.normal(size=(n, 3)).tolist()
    stamps = np.arange(n, dtype=float)
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    messages = [[(0, 'pd_controller', '', '', {'mode': 'pd', 'u_x': repr(x), 'u_y': repr(y), 'u_z': repr(z),
                                                'rejected_messages': '0'})] for x, y, z in values]
    as_list = reference([(stamps, messages)])   # what RunData kept: these tuples and the decoded dicts
    list_bytes = tracemalloc.get_traced_memory()[0] - base
    base = tracemalloc.get_traced_memory()[0]
    compact = records([(stamps, messages)])
    compact_bytes = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    assert compact == as_list
    print(f"status records: {list_bytes / n:.0f} B/step as tuples, {compact_bytes / n:.0f} B/step compact")
    assert compact_bytes < list_bytes / 5, (compact_bytes, list_bytes)
