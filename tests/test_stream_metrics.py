"""adcs-run's streamed end-of-run analysis (adcs_sim.app.analysis.stream_metrics.analyse_bag) gives exactly
run_metrics(RunData.from_bag(bag)): on every committed bag, on bags of other writers, truncated
bags, bags with missing topics, namespaced and noisy runs, under any chunk boundaries; bags it
cannot stream (stamps out of order, scenario after the data) go through the in-memory path. And
its memory does not grow with the run like RunData's (tracemalloc, nothing timed). No ROS.
"""
from __future__ import annotations

import gc
import json
import math
import tracemalloc

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import StoragePlugin
from support.bags import (
    DIAG,
    ODOM,
    QOS,
    REFERENCE,
    SYN,
    WRITERS,
    diag,
    odom,
    ser,
    truncated_copy,
    write,
    write_ours,
    write_rosbags,
)
from support.paths import ROOT

from adcs_sim.app.analysis.metrics import (
    RunData,
    first_entry_time,
    integrated_norm,
    integrated_square,
    jsonable_metrics,
    run_metrics,
    settling_time,
)
from adcs_sim.app.analysis.stream_metrics import AttitudeStream, BandTrack, TorqueStream, analyse_bag
from adcs_sim.bag.reader import read_metadata, read_raw
from adcs_sim.bag.writer import BagWriter

COMMITTED = sorted(p.parent.name for p in (ROOT / 'bags').glob('*/bag'))
FUZZ = settings(derandomize=True, max_examples=60, deadline=None, database=None)


def text(metrics: dict) -> str:
    """Metrics as metrics.json holds them (every float's repr, key order): equal text = equal bits."""
    return json.dumps(jsonable_metrics(metrics))


def same_as_in_memory(bag, tol_deg=0.5, eigen_tol_deg=None, namespace=None, **options):
    """analyse_bag equals the in-memory path bit for bit (metrics, intruders, namespace)."""
    run = RunData.from_bag(bag, namespace)
    got = analyse_bag(bag, tol_deg, eigen_tol_deg, namespace, **options)
    assert text(got.metrics) == text(run_metrics(run, tol_deg, eigen_tol_deg))
    assert got.intrusions == run.intrusions and got.namespace == run.namespace
    return got


# --- every committed bag -------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize('name', COMMITTED)
def test_committed_bags_streamed_bit_for_bit(name):
    bag = ROOT / 'bags' / name / 'bag'
    got = same_as_in_memory(bag)
    assert got.streamed, got.reason
    assert text(got.metrics) == json.dumps(json.loads((bag.parent / 'metrics.json').read_text()))
    # other bands, and a batch per MCAP chunk: the trackers carry their state across batches
    assert same_as_in_memory(bag, 1.0, 0.2, batch_bytes=1).streamed


def test_committed_bags_cover_every_metric():
    keys = set()
    for name in COMMITTED:
        keys |= set(json.loads((ROOT / 'bags' / name / 'metrics.json').read_text()))
    for key in ('first_fault_time_s', 'integrated_torque_after_fault_Nms', 'thruster_firings',
                'pointing_settling_0.01deg_s', 'peak_wheel_speed_rad_s'):
        assert key in keys


# --- other writers, truncation, missing topics, namespaces -------------------------------------

@pytest.mark.parametrize('kind', WRITERS)
def test_other_writers(tmp_path, kind):
    bag = write(kind, tmp_path / 'bag', SYN.messages())
    assert same_as_in_memory(bag, batch_bytes=2000).streamed


def test_truncated_bags(tmp_path):
    streamed = 0
    for fraction in np.linspace(0.05, 0.98, 12):
        bag = truncated_copy(tmp_path, fraction)
        try:
            expected = RunData.from_bag(bag)
        except ValueError as exc:
            with pytest.raises(ValueError) as got:
                analyse_bag(bag)
            assert str(got.value) == str(exc)
            continue
        assert expected.truncated
        streamed += same_as_in_memory(bag, batch_bytes=1).streamed
    assert streamed >= 8


@pytest.mark.parametrize('which', [('state',), ('state', 'torque'), ('state', 'wheels', 'status')])
def test_missing_topics(tmp_path, which):
    bag = write_rosbags(tmp_path / 'bag', SYN.messages(which), StoragePlugin.MCAP)
    assert same_as_in_memory(bag).streamed


def test_no_state_is_the_same_error(tmp_path):
    bag = write_rosbags(tmp_path / 'bag', SYN.messages(('torque', 'wheels')), StoragePlugin.MCAP)
    with pytest.raises(ValueError) as expected:
        RunData.from_bag(bag)
    with pytest.raises(ValueError) as got:
        analyse_bag(bag)
    assert str(got.value) == str(expected.value)


def test_truth_state_and_namespaces(tmp_path):
    noisy = [(topic, ty, t, ser(odom(t, [0.0, 0.0, 0.6, 0.8], [0.0, 0.0, 0.0]), ODOM)) if topic == '/state'
             else (topic, ty, t, d) for topic, ty, t, d in SYN.messages()]
    truth = [('/truth/state', ty, t, d) for _, ty, t, d in SYN.messages(('state',))]
    bag = write_rosbags(tmp_path / 'noisy', truth + noisy, StoragePlugin.MCAP)
    assert same_as_in_memory(bag).streamed
    sat1 = SYN.messages(prefix='/sat1/')
    sat2 = [('/sat2/state', ty, t, d) for topic, ty, t, d in noisy if topic == '/state']
    bag = write_rosbags(tmp_path / 'ns', sat2 + sat1, StoragePlugin.MCAP)
    assert same_as_in_memory(bag).namespace == '/sat1/'
    assert same_as_in_memory(bag, namespace='sat2').namespace == '/sat2/'


def test_missed_steps_and_faults(tmp_path):
    """Missed-step gaps (the median step from the kept stamps) and the settling after a fault,
    which the committed bags have with the fault after the last exit; here also before it."""
    extra = []
    for k, t in enumerate((10, 11, 12, 50, 51), start=1):
        extra.append(('/dynamics/status', DIAG, t * 10**9, ser(diag(t * 10**9, 'dynamics', {'missed_steps': str(k)}),
                                                                DIAG)))
    for t_fault in (5, 120, 290):
        faults = [('/faults', DIAG, t_fault * 10**9, ser(diag(t_fault * 10**9, 'wheel', {}, level=2), DIAG))]
        bag = write_ours(tmp_path / f'bag{t_fault}', SYN.messages() + extra + faults)
        got = same_as_in_memory(bag, 2.0, batch_bytes=1)
        assert got.streamed and got.metrics['missed_step_gaps'] == 2
        assert got.metrics['first_fault_time_s'] == t_fault


# --- what cannot be streamed -----------------------------------------------------------------

def test_stamps_out_of_order_fall_back_to_the_in_memory_path(tmp_path):
    messages = SYN.messages()
    states = [i for i, m in enumerate(messages) if m[0] == '/state']
    a, b = states[100], states[101]
    messages[a], messages[b] = messages[b], messages[a]
    got = same_as_in_memory(write_rosbags(tmp_path / 'bag', messages, StoragePlugin.MCAP))
    assert not got.streamed and 'out of file order' in got.reason


def _with_scenario(path, messages, first: bool):
    scenario = yaml.safe_dump({'pd_controller': {'ros__parameters': {'target': {'attitude': [0.0, 0.0, 0.6, 0.8]}}},
                               'pointer': {'ros__parameters': {'sigma': [1.0, 0.0, 0.0], 'tau': [0.0, 1.0, 0.0]}}})
    writer = BagWriter(path, chunk_size=4096, metadata={'scenario': scenario} if first else {})
    for topic, type_name, t_ns, data in messages:
        writer.add_topic(topic, type_name, QOS)
        writer.write(topic, data, t_ns)
    if not first:
        writer._writer.add_metadata('scenario', {'text': scenario})
    writer.close()
    return path


def test_scenario_before_the_data_is_streamed_after_it_is_not(tmp_path):
    got = same_as_in_memory(_with_scenario(tmp_path / 'first', SYN.messages(), True))
    assert got.streamed and 'final_pointing_error_deg' in got.metrics
    got = same_as_in_memory(_with_scenario(tmp_path / 'last', SYN.messages(), False), batch_bytes=1)
    assert not got.streamed and 'scenario' in got.reason and 'final_pointing_error_deg' in got.metrics


# --- any chunk boundaries --------------------------------------------------------------------

errors = st.lists(st.one_of(st.floats(0.0, 2.0), st.just(math.nan), st.just(math.inf)), min_size=0, max_size=40)


@FUZZ
@given(e=errors, cuts=st.lists(st.integers(0, 40), max_size=6), tol=st.sampled_from([0.5, 1.0, 0.0]))
def test_band_track_equals_settling_and_first_entry(e, cuts, tol):
    e = np.array(e, dtype=float)
    t = np.arange(e.size) * 0.1 + 3.0
    track = BandTrack(tol)
    for a, b in _pieces(cuts, e.size):
        track.add(t[a:b], e[a:b])
    assert text({'x': track.settling()}) == text({'x': settling_time(t, e, tol)})
    if e.size:
        assert text({'x': track.first_entry()}) == text({'x': first_entry_time(t, e, tol)})


def _pieces(cuts, n):
    edges = sorted({0, n, *(c for c in cuts if c <= n)})
    return list(zip(edges[:-1], edges[1:]))


RUNS = {name: RunData.from_bag(ROOT / 'bags' / name / 'bag') for name in ('pointing_controller_a', 'uosat12_gsmn')}


@FUZZ
@given(name=st.sampled_from(sorted(RUNS)), cuts=st.lists(st.integers(0, 3000), max_size=8),
       u_cuts=st.lists(st.integers(0, 3000), max_size=8))
def test_streams_under_any_chunk_boundaries(name, cuts, u_cuts):
    run = RUNS[name]
    expected = run_metrics(run)
    att = AttitudeStream('/state', run.q_ref, run.pointing, 0.5, 0.5)
    stamp_ns = np.round(run.t * 1e9).astype(np.int64)
    for a, b in _pieces(cuts, run.t.size):
        att.add(run.t[a:b], stamp_ns[a:b], run.q[a:b])
    got = {**att.metrics(0.5, 0.5), **(att.pointing_metrics() if run.pointing is not None else {})}
    assert text(got) == text({k: expected[k] for k in got})
    torque = TorqueStream('/actuators/torque')
    u_ns = np.round(run.t_u * 1e9).astype(np.int64)
    for a, b in _pieces(u_cuts, run.t_u.size):
        torque.add(run.t_u[a:b], u_ns[a:b], run.u[a:b])
    got = torque.defined_values(run.t_end)   # the torque metrics of metric_defs.DEFINED
    assert set(got) == {'integrated_torque_Nms', 'control_energy_N2m2s', 'peak_torque_Nm'}
    assert text(got) == text({k: expected[k] for k in got})
    assert text({'s': [got['integrated_torque_Nms'], got['control_energy_N2m2s']]}) == \
        text({'s': [integrated_norm(run.t_u, run.u, run.t_end), integrated_square(run.t_u, run.u, run.t_end)]})


# --- memory ----------------------------------------------------------------------------------

def repeated_bag(path, times: int):
    """The reference recording ``times`` times end to end (stamps shifted by whole seconds)."""
    messages = list(read_raw(REFERENCE))
    span = (max(t for *_, t, _ in messages) // 10**9) + 1
    writer = BagWriter(path, chunk_size=65536, metadata={'scenario': read_metadata(REFERENCE)['scenario']})
    for topic, type_name, _, _ in messages:
        writer.add_topic(topic, type_name, QOS)
    for k in range(times):
        for topic, type_name, t_ns, data in messages:
            cdr = bytearray(data)
            order = '<' if cdr[1] == 1 else '>'
            sec = np.frombuffer(cdr, order + 'i4', 1, 4)[0] + k * span
            cdr[4:8] = np.array([sec], order + 'i4').tobytes()
            writer.write(topic, bytes(cdr), t_ns + k * span * 10**9)
    writer.close()
    return path


def traced_peak(fn) -> float:
    """Peak bytes Python and numpy allocate during ``fn()`` (tracemalloc)."""
    gc.collect()
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_streamed_memory_does_not_grow_with_the_run(tmp_path):
    """Ten times the steps: the in-memory path's peak grows by hundreds of bytes a step, the
    streamed one's by the few tens it keeps (the torque terms and stamps). Its batches are made
    small here (256 KiB of storage data, adcs-run's are 4 MiB) so that both bags are many batches:
    the batch is a constant the per-step growth would otherwise include."""
    small, big = repeated_bag(tmp_path / 'small', 3), repeated_bag(tmp_path / 'big', 30)
    steps = 27 * (RunData.from_bag(REFERENCE).t.size)
    run_metrics(RunData.from_bag(small))   # (once before measuring: the lazy imports, e.g. scipy's)
    streamed = (traced_peak(lambda: analyse_bag(big, batch_bytes=256 << 10))
                - traced_peak(lambda: analyse_bag(small, batch_bytes=256 << 10)))
    in_memory = (traced_peak(lambda: run_metrics(RunData.from_bag(big)))
                 - traced_peak(lambda: run_metrics(RunData.from_bag(small))))
    bound = 100 * steps
    assert streamed < bound < in_memory, (streamed / steps, in_memory / steps)
    assert text(analyse_bag(big).metrics) == text(run_metrics(RunData.from_bag(big)))
