"""Issue #31, class "Tracebacks instead of one line": a full disk (ENOSPC, or EDQUOT for a quota).

The recorder counted the first failed write as a bad message, then raised out of its flush timer
and out of closing the bag (two tracebacks). Now a write error stops the recording cleanly: the
bag writer writes nothing more and lets go of its file and lock, the bag is readable up to the
failure (a truncated bag, which ``adcs-analyze`` and ``adcs-bag-repair`` handle), the recorder
exits with its own status and one line naming the bag and the error, and ``adcs-run`` stops the
graph and says the disk is full and where the bag is.

Without a real full disk: a file that takes ``room`` bytes and fails after, in-process (the bag
writer and the recorder node). With one: ``adcs-run`` on a tmpfs that another process fills mid-run,
where the test may mount one (root with CAP_SYS_ADMIN); skipped elsewhere.
"""
from __future__ import annotations

import contextlib
import errno
import functools
import io
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import pytest
import rclpy
from hypothesis import example, given, settings
from hypothesis import strategies as st
from rclpy.duration import Duration
from support.bags import states_on_disk
from support.paths import ROOT
from support.processes import alive, children
from support.scenarios import make_scenario

import adcs_sim.bag.writer as bag_writer
from adcs_msgs_py import topics
from adcs_msgs_py.conversions import clock_msg, state_to_msg
from adcs_msgs_py.node import EXIT_DISK_FULL, main_for
from adcs_sim.app.analysis.analyze import main as analyze_main
from adcs_sim.app.analysis.repair import main as repair_main
from adcs_sim.bag.lock import bag_writer as writer_of
from adcs_sim.bag.reader import is_complete, read_metadata, read_raw
from adcs_sim.bag.writer import BagWriteError, BagWriter
from adcs_sim.nodes import recorder

COMMITTED = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'
MESSAGES = list(read_raw(COMMITTED))
METADATA = read_metadata(COMMITTED)


class SmallDisk:
    """A file on a disk with ``room`` bytes left: a write that does not fit writes what fits and
    fails with ``err`` (as write(2) then does), and so does every write after it."""

    def __init__(self, path, room: int, err: int) -> None:
        self.file = open(path, 'wb', buffering=0)   # noqa: SIM115 - closed by close()
        self.room, self.err = room, err

    def write(self, data) -> int:
        data = bytes(data)
        fits = data[:max(self.room, 0)]
        self.file.write(fits)
        self.room -= len(fits)
        if len(fits) < len(data):
            raise OSError(self.err, os.strerror(self.err))
        return len(data)

    def tell(self) -> int:
        return self.file.tell()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.file.close()


@contextlib.contextmanager
def small_disk(room: int, err: int = errno.ENOSPC):
    """Bag writers in this block write their MCAP file to a :class:`SmallDisk`."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bag_writer, 'open', lambda path, mode: SmallDisk(path, room, err), raising=False)
        yield


def run_tool(main, *args: str) -> tuple[int, list[str], list[str]]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return code, out.getvalue().splitlines(), err.getvalue().splitlines()


def check_readable_prefix(bag: Path, recorded: list) -> int:
    """The bag holds the first messages of ``recorded`` (topic, type, log time, data), intact and in
    order; how many. Both tools take it as a truncated bag: analysed with one warning line (or refused
    in one line when no state precedes the cut), repaired into a complete bag (or refused, untouched,
    when nothing is intact)."""
    got = [(topic, t, bytes(data)) for topic, _, t, data in read_raw(bag)]
    assert got == [(topic, t, bytes(data)) for topic, _, t, data in recorded[:len(got)]]
    code, _, err = run_tool(analyze_main, str(bag), '--json', '--no-report')
    assert len(err) == 1 and (code == 0 and 'warning' in err[0] or code == 1 and 'state' in err[0]), err
    code, out, err = run_tool(repair_main, str(bag))
    assert code == 0 and 'repaired' in out[0] and is_complete(bag) if got else code == 1 and len(err) == 1
    return len(got)


def write_all(writer: BagWriter) -> None:
    """The committed recording, in the recorder's pattern (a flush every 50 messages), then closed."""
    for i, (topic, type_name, t, data) in enumerate(MESSAGES):
        writer.add_topic(topic, type_name, [])
        writer.write(topic, data, log_time_ns=t)
        if i % 50 == 49:
            writer.flush()
    writer.close()


@functools.cache
def full_size() -> int:
    """Bytes of the MCAP file :func:`write_all` makes on a disk with room."""
    with tempfile.TemporaryDirectory() as folder:
        writer = BagWriter(Path(folder) / 'bag', chunk_size=4096, metadata=METADATA)
        write_all(writer)
        return writer.mcap_path.stat().st_size


@settings(derandomize=True, max_examples=10, deadline=None)
@given(per_mille=st.integers(0, 1010), err=st.sampled_from([errno.ENOSPC, errno.EDQUOT]))
@example(per_mille=0, err=errno.ENOSPC)          # not even the header fits
@example(per_mille=950, err=errno.EDQUOT)        # the data fits, the summary does not
@example(per_mille=1010, err=errno.ENOSPC)       # it all fits
def test_a_full_disk_stops_the_bag_writer_and_leaves_a_truncated_bag(tmp_path_factory, per_mille, err):
    """A disk with room for ``per_mille`` thousandths of the bag fills at its start, amid the
    messages or in the summary."""
    bag = tmp_path_factory.mktemp('disk') / 'bag'
    failed, started, room = None, False, full_size() * per_mille // 1000
    with small_disk(room, err):
        try:
            writer = BagWriter(bag, chunk_size=4096, metadata=METADATA)
        except BagWriteError as exc:       # not even the header fits
            failed = exc
        else:
            started = True
            try:
                write_all(writer)
            except BagWriteError as exc:
                failed = exc
                size = writer.mcap_path.stat().st_size
                with pytest.raises(BagWriteError) as again:          # nothing more is written
                    writer.write(MESSAGES[0][0], MESSAGES[0][3])
                assert again.value is exc and writer.mcap_path.stat().st_size == size
                writer.close()                                        # lets go, raises nothing
    assert writer_of(bag) is None and sorted(p.name for p in bag.iterdir()) in (
        ['bag_0.mcap'], ['bag_0.mcap', 'metadata.yaml'])             # no lock, no temporary file left
    if failed is None:
        assert is_complete(bag)
        return
    assert failed.errno == err and failed.disk_full
    assert str(failed) == f'cannot write the bag {bag}: {os.strerror(err)}'
    if started:                                                       # past the header: a truncated bag
        check_readable_prefix(bag, MESSAGES)


def _publish_until(stop: threading.Event) -> None:
    """State + /clock for k = 0, 1, ... until ``stop`` (or the recorder is gone), waiting for the
    recorder's acknowledgements every 20 steps (the publishers keep more): it receives every message
    in order."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node('disk_full_publisher', context=ctx)
        clock, state = (node.create_publisher(topics.TOPICS[name].msg_type, name, topics.TOPICS[name].qos)
                        for name in (topics.CLOCK, topics.STATE))
        while not stop.is_set() and not (state.get_subscription_count() and clock.get_subscription_count()):
            stop.wait(0.01)
        k = 0
        while not stop.is_set() and state.get_subscription_count():
            for _ in range(20):
                state.publish(state_to_msg(k * 100_000_000, [0.0, 0.0, 0.0, 1.0], [1e-3 * k, 0.0, 0.0]))
                clock.publish(clock_msg(k * 100_000_000))
                k += 1
            state.wait_for_all_acked(Duration(seconds=1))
    finally:
        rclpy.try_shutdown(context=ctx)


def test_the_recorder_stops_on_a_full_disk_with_one_line(tmp_path, ros_domain, capfd):
    bag = tmp_path / 'bag'
    stop = threading.Event()
    publisher = threading.Thread(target=_publish_until, args=(stop,))
    guard = threading.Timer(120, recorder.STOP_REQUESTED.set)   # a hang becomes a failure below
    publisher.start()
    guard.start()
    try:
        with small_disk(20_000):
            status = main_for(recorder.RecorderNode, ['recorder', '--ros-args', '-p', f'output:={bag}',
                                                      '-p', 'chunk_size:=2048', '-p', 'flush_period:=0.05'],
                              handle_signals=False)
    finally:
        guard.cancel()
        stop.set()
        publisher.join()
        stopped_by_guard = recorder.STOP_REQUESTED.is_set()
        recorder.STOP_REQUESTED.clear()
    assert not stopped_by_guard, 'the recorder did not stop on the full disk'
    out, err = capfd.readouterr()
    lines = [line for line in (out + err).splitlines() if 'error' in line.lower()]
    assert status == EXIT_DISK_FULL, (status, out, err)
    assert lines == [f'[recorder] error: disk full: cannot write the bag {bag}: No space left on device; '
                     f'recording stopped, the bag is readable up to there (adcs-bag-repair completes it)']
    assert 'Traceback' not in err and 'rejected' not in err, err
    states = [(topic, ty, t, data) for topic, ty, t, data in read_raw(bag) if topic == '/state']
    assert states and [t for _, _, t, _ in states] == [k * 100_000_000 for k in range(len(states))]
    check_readable_prefix(bag, list(read_raw(bag)))


@contextlib.contextmanager
def tmpfs(path: Path, size: str):
    """A tmpfs of ``size`` mounted at ``path`` (skips the test where one cannot be mounted)."""
    path.mkdir()
    if os.geteuid() != 0:
        pytest.skip('mounting a tmpfs needs root')
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={size}', 'tmpfs', str(path)],
                             capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs here: {mounted.stderr.strip()}')
    try:
        yield path
    finally:
        subprocess.run(['umount', '-l', str(path)], check=True)


def test_adcs_run_on_a_full_disk_stops_the_graph_and_says_where_the_bag_is(tmp_path, spawn):
    """The disk has room for the whole bag when the run starts (adcs-run checks that), then another
    process takes all of it but 64 KiB mid-run."""
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': 20000.0}})   # ~30 MB by adcs-run's estimate
    with tmpfs(tmp_path / 'disk', '64m') as disk:
        out, bag = disk / 'run', disk / 'run' / 'bag'
        proc = spawn([sys.executable, '-m', 'adcs_sim.app.graph.runner', str(scenario), '--out', str(out),
                      '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
        nodes, filled = {}, False
        while proc.poll() is None:     # note the nodes while the run goes, to check none is left
            nodes.update(children(proc.pid))
            spawn.adopt(nodes)
            if not filled and states_on_disk(bag) >= 2:
                with open(disk / 'filler', 'wb') as f:
                    os.posix_fallocate(f.fileno(), 0, shutil.disk_usage(disk).free - 64 * 1024)
                filled = True
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=0.2)
        stdout, stderr = proc.communicate(timeout=120)
        assert proc.returncode == 1 and filled, (stdout, stderr)
        assert stderr.splitlines() == [
            f'adcs-run: error: disk full: cannot write the bag {bag}: No space left on device; recording '
            f'stopped, the bag is readable up to there (adcs-bag-repair completes it); graph stopped, bag kept '
            f'in {bag} (every step up to it)']
        assert not [pid for pid in nodes if alive(pid)]
        assert not (out / 'metrics.json').exists() and states_on_disk(bag) > 0
        code, _, err = run_tool(analyze_main, str(bag), '--json', '--no-report')
        assert code == 0 and len(err) == 1 and 'truncated at byte' in err[0], err
