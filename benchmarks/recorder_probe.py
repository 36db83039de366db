#!/usr/bin/env python3
"""The recorder node with a memory probe beside it (issue 18: where does its RSS go?).

Runs ``adcs_sim.nodes.recorder`` (of whatever tree is first on ``PYTHONPATH``) in this process,
with a thread that appends one line of JSON to ``ADCS_PROBE_OUT`` every ``ADCS_PROBE_PERIOD``
seconds: RSS (anonymous), glibc's ``mallinfo2`` (bytes in use, free inside the heaps, mmapped),
the number of mappings, Python's tracemalloc total when ``ADCS_PROBE_TRACEMALLOC`` is set (and
its top growth between the first sample after ``ADCS_PROBE_DIFF_AT`` seconds and the exit), and
the sizes of what the recorder keeps (subscriptions, topics, reject and vetting tables).
``ADCS_PROBE_TRIM=1`` calls ``malloc_trim(0)`` after each sample and records the RSS after it.
Used by ``benchmarks/recorder_memory.py --probe``; not part of the product.

    PYTHONPATH=TREE python benchmarks/recorder_probe.py --ros-args -p output:=...
"""
from __future__ import annotations

import atexit
import ctypes
import gc
import json
import os
import sys
import threading
import time
import tracemalloc


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        'arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks', 'fordblks',
        'keepcost')]


LIBC = ctypes.CDLL('libc.so.6')
LIBC.mallinfo2.restype = _Mallinfo2
NODE: list = []   # the RecorderNode, once built


def rss_kib(field: str = 'RssAnon') -> int:
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith(field + ':'):
                return int(line.split()[1])
    return -1


def recorder_state() -> dict:
    if not NODE:
        return {}
    node = NODE[0]
    bag, vetting = node.bag, node.vetting
    stats = bag._writer._Writer__statistics
    return {'received': node.received, 'subs': len(node.subs), 'skipped': len(node.skipped),
            'topics': len(bag.topics), 'rejects': len(node.rejects.counts), 'chunks': stats.chunk_count,
            'channel_counts': len(stats.channel_message_counts),
            'vetting': [len(vetting.vetted), len(vetting.matched), len(vetting.intruders), len(vetting.refused)],
            'chunk_builder_indices': len(bag._writer._Writer__chunk_builder.message_indices)}


def sample(t0: float, trim: bool) -> dict:
    m = LIBC.mallinfo2()
    with open('/proc/self/maps') as f:
        maps = sum(1 for _ in f)
    row = {'t': round(time.monotonic() - t0, 2), 'mono': time.monotonic(), 'anon_kib': rss_kib(),
           'heap_used': m.uordblks, 'heap_free': m.fordblks, 'heap_arena': m.arena, 'mmapped': m.hblkhd, 'maps': maps,
           'threads': threading.active_count(), 'traced': tracemalloc.get_traced_memory()[0]
           if tracemalloc.is_tracing() else None, **recorder_state()}
    if trim:
        LIBC.malloc_trim(0)
        row['anon_after_trim_kib'] = rss_kib()
    return row


def probe(out: str, period: float, diff_at: float, trim: bool) -> None:
    t0 = time.monotonic()
    first = None
    with open(out, 'a') as f:
        def write(row):
            f.write(json.dumps(row) + '\n')
            f.flush()

        def at_exit():
            write({**sample(t0, False), 'exit': True})
            if first is not None:
                gc.collect()
                stats = tracemalloc.take_snapshot().compare_to(first, 'lineno')
                write({'diff': [str(s) for s in stats[:15]]})
        atexit.register(at_exit)
        while True:
            time.sleep(period)   # a sampler's period, not a synchronisation
            write(sample(t0, trim))
            if tracemalloc.is_tracing() and first is None and time.monotonic() - t0 >= diff_at:
                gc.collect()
                first = tracemalloc.take_snapshot()


def main() -> None:
    if os.environ.get('ADCS_PROBE_TRACEMALLOC'):
        tracemalloc.start(int(os.environ['ADCS_PROBE_TRACEMALLOC']))
    from adcs_sim.nodes import recorder
    init = recorder.RecorderNode.__init__

    def capture(self, *args, **kwargs):
        NODE.append(self)
        init(self, *args, **kwargs)
    recorder.RecorderNode.__init__ = capture
    threading.Thread(target=probe, daemon=True, args=(
        os.environ['ADCS_PROBE_OUT'], float(os.environ.get('ADCS_PROBE_PERIOD', '2')),
        float(os.environ.get('ADCS_PROBE_DIFF_AT', '1e9')), os.environ.get('ADCS_PROBE_TRIM') == '1')).start()
    sys.argv[0] = 'recorder'
    recorder.main()


if __name__ == '__main__':
    main()
