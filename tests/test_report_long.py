"""A long run's report streamed (adcs_sim.app.report.long_run, issue #18: a day at 10 Hz in <= 300 MB):
two passes over the bag, never the whole run in memory, and the same report byte for byte.

* the envelope built chunk by chunk (:class:`~adcs_sim.app.report.envelope.EnvelopeStream`) is
  :func:`~adcs_sim.app.report.envelope.kept_indices` of the whole arrays (NaN, infinities, ties,
  one sample, chunks splitting a column, columns at chunk edges);
* the derived series computed per chunk (errors to the reference, 2-1-3 angles, log masks, scaled
  torques) are the whole-array computation's, bit for bit;
* with the limits lowered (a run of a few hundred samples is "long"), the streamed report of
  synthetic and committed bags is the in-memory report: every PNG, SVG and report.md byte for
  byte; runs the streaming does not cover are read in memory (the same report as before);
* a damaged or truncated long bag fails, or is recovered, exactly as the in-memory reading does.
"""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.report_runs import RUNS
from support.report_runs import write_bag as write_synthetic

from adcs_sim.app.analysis.metrics import attitude_errors
from adcs_sim.app.report import envelope, long_run, single_run
from adcs_sim.app.report.envelope import EnvelopeStream, kept_indices, log_positive
from adcs_sim.app.report.loading import BagError, load_run
from adcs_sim.app.analysis.run_data import RunData, TooLong

BAGS = Path(__file__).resolve().parents[1] / 'bags'


def streamed_indices(t: np.ndarray, ys: list, cuts, columns: int, many: bool = False) -> np.ndarray:
    """kept_indices of ``ys`` fed to an EnvelopeStream in the chunks ``cuts`` delimit (``many``: all
    series in one call)."""
    env = EnvelopeStream(t[0], t[-1] - t[0], columns)
    bounds = [0, *sorted(set(cuts)), t.size]
    for a, b in zip(bounds[:-1], bounds[1:]):
        column = env.column(t[a:b])
        env.ends(column, a)
        if many:
            env.add_many(list(range(len(ys))), column, a, np.column_stack([y[a:b] for y in ys]))
        else:
            for j, y in enumerate(ys):
                env.add(j, column, a, y[a:b])
    return env.indices()


values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1.0, -1.0, np.nan]))


@settings(max_examples=400, derandomize=True, deadline=None)
@given(st.data())
@pytest.mark.slow
def test_streamed_envelope_is_the_whole_arrays_envelope(data):
    n = data.draw(st.integers(1, 120), label='n')
    columns = data.draw(st.integers(1, 24), label='columns')
    steps = data.draw(st.lists(st.sampled_from([0.0, 0.1, 0.25, 1.0, 7.5]), min_size=n, max_size=n))
    t = np.cumsum(steps) + data.draw(st.sampled_from([0.0, -3.0, 1e6]))   # ties, one sample, span 0
    ys = [np.array(data.draw(st.lists(values, min_size=n, max_size=n))) for _ in range(data.draw(st.integers(1, 3)))]
    cuts = data.draw(st.lists(st.integers(1, max(1, n - 1)), max_size=10)) if n > 1 else []
    many = data.draw(st.booleans(), label='many')
    assert np.array_equal(streamed_indices(t, ys, cuts, columns, many), kept_indices(t, *ys, columns=columns))


def test_streamed_envelope_of_a_day():
    """A day at 10 Hz in chunks of a few thousand samples (each splitting some column), with NaN
    runs across chunk and column edges: the envelope of the whole arrays, at the report's columns."""
    rng = np.random.default_rng(18)
    n = 864_001
    t = np.arange(n) * 0.1
    y = np.exp(-t / 20_000) * np.sin(t / 300) + 0.01 * rng.standard_normal(n)
    y[rng.integers(0, n, 50)] = np.nan
    y[4000:4500] = np.nan
    z = np.round(np.cos(t / 5000), 2)         # long runs of equal values: first of the ties kept
    cuts = np.cumsum(rng.integers(1, 9000, 400))
    cuts = cuts[cuts < n]
    assert np.array_equal(streamed_indices(t, [y, z], cuts, envelope.COLUMNS, many=True), kept_indices(t, y, z))


def test_derived_series_per_chunk_are_the_whole_arrays():
    """What the second pass computes per chunk (long_run._SecondPass._state) is the figures'
    computation on the whole arrays, bit for bit: near gimbal lock and sign flips included."""
    rng = np.random.default_rng(7)
    n = 20_000
    q = rng.standard_normal((n, 4))
    q[::7] = [np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]          # θ1 = 90°: gimbal lock
    q[::11, 3] *= -1.0
    q /= np.linalg.norm(q, axis=1)[:, None]
    target = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    u = rng.standard_normal((n, 3)) * 1e-3

    def derived(q, u):
        q_ref = np.broadcast_to(target, (q.shape[0], 4)).copy()
        qe, eigen, euler = attitude_errors(SimpleNamespace(q=q), q_ref)
        phase = qe * np.where(qe[:, 3:4] < 0, -1.0, 1.0)
        return [qe, eigen, euler, log_positive(eigen), log_positive(np.abs(euler)), np.abs(euler).max(axis=1),
                phase, 1e3 * u, 1.0 * u]

    whole = derived(q, u)
    cuts = [0, 1, 2, 3, 517, 4096, 4097, 13_333, n]
    parts = [derived(q[a:b], u[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
    for i, array in enumerate(whole):
        assert np.concatenate([p[i] for p in parts]).tobytes() == array.tobytes(), i


@pytest.fixture
def small_limits(monkeypatch):
    """A run of a few hundred samples is long; batches of a few kilobytes (many chunks a column)."""
    monkeypatch.setattr(envelope, 'MAX_POINTS', 60)
    monkeypatch.setattr(envelope, 'COLUMNS', 16)
    monkeypatch.setattr(long_run, 'BATCH_BYTES', 4096)


# matplotlib names an SVG clip path by a hash that, for some artists, includes a transform's id():
# a memory address, so two renders of one figure can differ there and nowhere else (seen in full runs)
_CLIP_ID = re.compile(rb'(?<=id=")p[0-9a-f]{10}(?=")|(?<=url\(#)p[0-9a-f]{10}(?=\))')


def _content(path: Path) -> bytes:
    """A report file's bytes; an SVG's clip-path ids numbered in their order of appearance."""
    data = path.read_bytes()
    if path.suffix != '.svg':
        return data
    ids: dict[bytes, bytes] = {}
    return _CLIP_ID.sub(lambda m: ids.setdefault(m.group(0), b'clip%d' % len(ids)), data)


def same_reports(a: Path, b: Path) -> list[str]:
    """Files that differ between two report folders (all of them if the names differ)."""
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    return [n for n in names if _content(a / n) != _content(b / n)]


def streamed_and_whole(bag: Path, out: Path):
    """(streamed run, whole run) of ``bag`` and their reports' differing files."""
    with matplotlib.rc_context({'svg.hashsalt': 'test_report_long'}):
        whole = load_run(bag, stream=False)
        single_run.write_report(whole, out / 'whole')
        streamed = load_run(bag)
        single_run.write_report(streamed, out / 'streamed')
    return streamed, whole, same_reports(out / 'whole', out / 'streamed')


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(RUNS))
def test_streamed_report_of_a_synthetic_run_is_the_whole_runs(name, tmp_path, small_limits):
    """Faults (stars on the phase portrait), a mode switch (a text timeline), missed steps."""
    bag = write_synthetic(tmp_path / name / 'bag', **RUNS[name])
    streamed, whole, differ = streamed_and_whole(bag, tmp_path)
    assert streamed.long is not None and whole.long is None
    assert streamed.data.t.size < whole.data.t.size and streamed.samples == whole.samples == whole.data.t.size
    assert streamed.metrics() == whole.metrics()
    assert differ == []
    assert streamed.metrics(1.0, 0.25) == whole.metrics(1.0, 0.25)   # streamed again at other tolerances


@pytest.mark.slow
def test_streamed_report_of_a_committed_regulation_run(tmp_path, monkeypatch):
    """The GSMN slew (regulation: its lead figures, settling times and table from the stream)."""
    monkeypatch.setattr(envelope, 'MAX_POINTS', 1500)
    monkeypatch.setattr(envelope, 'COLUMNS', 128)
    monkeypatch.setattr(long_run, 'BATCH_BYTES', 64 << 10)
    streamed, whole, differ = streamed_and_whole(BAGS / 'microsat_gsmn_slew' / 'bag', tmp_path)
    assert streamed.long is not None and streamed.data.t.size < whole.data.t.size
    assert differ == []


@pytest.mark.parametrize('name, why', [('uosat12_gsmn', 'actuators'), ('pointing_controller_a', 'pointing'),
                                       ('m2s_intermediate_vagc_0p01', 'spin')])
def test_what_is_not_streamed_is_read_whole(name, why, small_limits):
    bag = BAGS / name / 'bag'
    with pytest.raises(long_run.Unstreamable, match=why):
        long_run.load_long(bag)
    run = load_run(bag)
    assert run.long is None and run.data.t.size == run.samples > envelope.MAX_POINTS


def test_a_short_run_is_read_whole_as_before():
    run = load_run(BAGS / 'microsat_pd_slew' / 'bag')
    assert run.long is None
    with pytest.raises(TooLong):
        RunData.from_bag(BAGS / 'microsat_pd_slew' / 'bag', max_samples=100)


def _outcome(bag: Path, stream: bool):
    try:
        run = load_run(bag, stream=stream)
    except BagError as exc:
        return 'error', str(exc)
    return 'read', run.samples, run.message_count, run.data.problem, run.complete, run.metrics()


@pytest.mark.slow
def test_damaged_long_bags_fail_or_recover_as_in_memory(tmp_path, small_limits):
    """Truncations and flipped bytes of a long bag: the same one-line error, or the same salvage
    (messages, problem, metrics), streamed or read whole."""
    good = write_synthetic(tmp_path / 'good' / 'bag', **RUNS['run_b'])
    raw = next(good.glob('*.mcap')).read_bytes()
    cases = [('cut', k) for k in (9, 200, len(raw) // 3, len(raw) // 2, len(raw) - 40, len(raw) - 1)]
    cases += [('flip', k) for k in (20, 500, len(raw) // 4, len(raw) // 2 + 7, len(raw) - 100, len(raw) - 10)]
    seen = set()
    for how, k in cases:
        bag = tmp_path / f'{how}{k}' / 'bag'
        bag.mkdir(parents=True)
        data = raw[:k] if how == 'cut' else raw[:k] + bytes([raw[k] ^ 0x5A]) + raw[k + 1:]
        (bag / 'bag_0.mcap').write_bytes(data)
        whole, streamed = _outcome(bag, False), _outcome(bag, True)
        assert streamed == whole, (how, k)
        seen.add(whole[0])
    assert seen == {'error', 'read'}


def test_a_status_text_changing_too_often_is_read_whole(tmp_path, small_limits, monkeypatch):
    """Each change of a status text keeps two records: past MAX_TEXT_CHANGES the run is read whole."""
    bag = write_synthetic(tmp_path / 'run' / 'bag', **RUNS['run_b'])
    assert load_run(bag).long is not None                # one change of `mode`: streamed
    monkeypatch.setattr(long_run, 'MAX_TEXT_CHANGES', 0)
    with pytest.raises(long_run.Unstreamable, match='changes'):
        long_run.load_long(bag)
    run = load_run(bag)
    assert run.long is None and run.data.t.size == run.samples
