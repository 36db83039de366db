"""The bag writer's memory does not grow with the recording (issue 18: the recorder's RSS grew
93 -> 124 MiB over a 230 MB bag in a long run), and what it writes is unchanged by how it keeps
its chunk indexes. tracemalloc, nothing timed; no ROS.

The growth came from the mcap ``Writer``'s list of ``ChunkIndex`` objects (one per chunk, with a
dict of one offset per channel: ~2 KiB with 20 channels), kept for the summary written at close.
:class:`~adcs_sim.bag.writer.SpilledChunkIndexes` keeps them serialised in an unlinked temporary
file instead.
"""
from __future__ import annotations

import gc
import tracemalloc

from mcap.reader import make_reader
import pytest
from support.bags import ODOM, QOS, odom, ser

from adcs_sim.bag import writer as bag_writer
from adcs_sim.bag.reader import read_raw
from adcs_sim.bag.storage import mcap_file
from adcs_sim.bag.writer import BagWriter, SpilledChunkIndexes

TOPICS = [f'/topic_{i:02d}' for i in range(20)]   # as many channels as a full graph's bag
STEP_NS = 100_000_000


def messages():
    """One serialised Odometry per step (the content does not matter here, its size does)."""
    return [ser(odom(k * STEP_NS, (0.0, 0.0, 0.0, 1.0), (1e-3 * k, 0.0, 0.0)), ODOM) for k in range(4)]


def record_steps(writer: BagWriter, first: int, steps: int, data, flush_every: int = 2) -> None:
    """``steps`` steps of one message on each topic, the chunk closed every ``flush_every`` steps
    (the recorder's flush every half wall second, at a rate where that is a few steps)."""
    for k in range(first, first + steps):
        for topic in TOPICS:
            writer.write(topic, data[k % len(data)], k * STEP_NS)
        if k % flush_every == 0:
            writer.flush()


def open_writer(path) -> BagWriter:
    writer = BagWriter(path, chunk_size=1 << 20)
    for topic in TOPICS:
        writer.add_topic(topic, ODOM, QOS)
    return writer


def retained_growth(path, steps: int, extra: int, flush_every: int = 1) -> tuple[int, int]:
    """Bytes the writer still holds (tracemalloc: traced now, not peak) after ``steps + extra``
    steps minus after ``steps``; and the number of chunks those ``extra`` steps wrote."""
    data = messages()
    writer = open_writer(path)
    record_steps(writer, 0, steps, data, flush_every)   # warm: the writer's buffers, first chunks
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        chunks = _chunk_count(writer)
        record_steps(writer, steps, extra, data, flush_every)
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - before
        chunks = _chunk_count(writer) - chunks
    finally:
        tracemalloc.stop()
    writer.close()
    return grown, chunks


def _chunk_count(writer: BagWriter) -> int:
    return writer._writer._Writer__statistics.chunk_count


@pytest.mark.slow
def test_the_writer_does_not_grow_with_the_chunks_it_writes(tmp_path, monkeypatch):
    """1 000 more chunks (20 channels, one step each): the writer keeps a few bytes a chunk at most
    with its chunk indexes spilled to disk, against the ~2 KiB a chunk of the mcap writer's own list."""
    spilled, chunks = retained_growth(tmp_path / 'spilled', 100, 1000)
    monkeypatch.setattr(bag_writer, 'spill_chunk_indexes', lambda w: None)
    listed, listed_chunks = retained_growth(tmp_path / 'listed', 100, 1000)
    assert chunks == listed_chunks == 1000
    bound = 16 * chunks   # 16 bytes a chunk: nothing kept per chunk (allocator noise only)
    print(f"retained a chunk: spilled {spilled / chunks:.1f} B, listed {listed / chunks:.1f} B")
    assert spilled < bound < listed, (spilled / chunks, listed / chunks)
    assert listed / chunks > 1000   # what the bound catches: the list's ~2 KiB a chunk


def test_spilled_indexes_write_the_same_file(tmp_path, monkeypatch):
    """Byte for byte the same .mcap (summary included) as with the mcap writer's own list, and a
    summary every reader uses: the chunk indexes locate every message."""
    data = messages()
    paths = {}
    for name, spill in (('spilled', True), ('listed', False)):
        if not spill:
            monkeypatch.setattr(bag_writer, 'spill_chunk_indexes', lambda w: None)
        writer = open_writer(tmp_path / name / 'bag')   # same folder name: same file name inside
        record_steps(writer, 0, 500, data, flush_every=3)
        writer.close()
        paths[name] = mcap_file(tmp_path / name / 'bag')
    assert paths['spilled'].read_bytes() == paths['listed'].read_bytes()
    with open(paths['spilled'], 'rb') as f:
        summary = make_reader(f).get_summary()
        assert len(summary.chunk_indexes) == 168   # a flush every 3 steps from k = 0, and the close
        f.seek(0)
        assert sum(1 for _ in make_reader(f).iter_messages()) == 500 * len(TOPICS)   # read through the index
    assert sum(1 for _ in read_raw(tmp_path / 'spilled' / 'bag')) == 500 * len(TOPICS)


def test_spilled_indexes_come_back_in_blocks_in_order(tmp_path):
    """Records split over several read blocks come back whole and in order (the summary is their
    concatenation), and the file can be appended to after an iteration."""
    class Index:
        def __init__(self, k):
            self.k = k

        def write(self, builder):
            builder.write(bytes([self.k % 251]) * (1 + self.k % 37))

    spilled = SpilledChunkIndexes(block=64)
    expected = b''
    for k in range(300):
        spilled.append(Index(k))
        expected += bytes([k % 251]) * (1 + k % 37)
        if k == 150:
            assert b''.join(r.data for r in spilled) == expected
    assert len(spilled) == 300
    assert b''.join(r.data for r in spilled) == expected
    spilled.close()


def test_the_recorder_writer_spills_its_chunk_indexes(tmp_path):
    """The mcap version installed still has the private list the writer replaces (if a new mcap
    renamed it, the writer would silently keep the growing list: this says so)."""
    writer = open_writer(tmp_path / 'bag')
    assert isinstance(writer._chunk_indexes, SpilledChunkIndexes)
    writer.close()
