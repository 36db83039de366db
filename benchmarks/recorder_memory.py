#!/usr/bin/env python3
"""The recorder node's resident memory over a long recording, in minutes instead of hours.

Issue 18: in the 24 h run (benchmarks/long_run_memory.py) the recorder's RSS grew 93 -> 124 MiB
while its bag grew 50 -> 230 MB. What grows with a recording is the number of chunks the bag is
written in (the recorder closes its chunk every ``flush_period``, 0.5 wall s, and at
``chunk_size``). This benchmark records the same kind of traffic with many more chunks a minute:
a publisher process (this script, one rclpy node) sends ``nav_msgs/Odometry`` on 20 topics of the
graph at full speed (acknowledged every 50 messages, as the lockstep nodes pace the recorder),
into ``python -m adcs_sim.nodes.recorder`` with ``flush_period`` 0.01 s and ``chunk_size`` 4096 B. The recorder's VmRSS is
sampled from /proc every ``--sample`` s; printed: RSS and chunks written at a quarter, half and the
end, and the growth per 1000 chunks over the second half (after the allocator's warm-up).

``--compare TREE`` (e.g. /tmp/s9_base) runs the recorder of that checkout (``PYTHONPATH``) the same
way, alternated with this tree's.

``--probe DIR`` runs the recorder under ``benchmarks/recorder_probe.py`` (samples from inside the
process: glibc's heap in use and free, mmapped, Python's tracemalloc with ``--probe-tracemalloc``,
the recorder's tables) and prints its backlog, the messages sent and not yet taken, which DDS
holds for it. What it showed (issue 18, session 10): the growth was that backlog, native memory
(Python's traced total flat), kept by Fast DDS at its high-water mark; the recorder's readers
are now bounded (``adcs_sim/nodes/recorder_fastdds.xml``). ``--recorder-env KEY=VALUE`` (e.g.
``MALLOC_ARENA_MAX=2``, ``FASTRTPS_DEFAULT_PROFILES_FILE=...``) and ``--topics N`` vary the set-up.

``--writer`` measures the bag writer alone instead, in a lean process of its own (no ROS): RssAnon
after every 7000 chunks of 7 messages, with its chunk indexes spilled to a temporary file (the
default) and kept as the mcap Writer's list of objects (before issue 18's fix), one after the other.

    .venv/bin/python benchmarks/recorder_memory.py [--seconds 60] [--compare /tmp/s9_base] [--writer]
        [--probe DIR [--probe-tracemalloc 3] [--trim]] [--topics 20] [--domains 220 229]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TOPICS = ['state', 'truth/state', 'estimate/state', 'reference', *[f'bench/odom_{i:02d}' for i in range(16)]]


def rss_mib(pid: int, field: str = 'VmRSS') -> float | None:
    """VmRSS (or RssAnon, RssFile, RssShmem) of ``pid`` in MiB."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith(f'{field}:'):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def rss_parts(pid: int) -> str:
    return ', '.join(f'{f} {rss_mib(pid, f):.1f}' for f in ('RssAnon', 'RssFile', 'RssShmem'))


def record(tree: Path, seconds: float, sample: float, tmp: Path, env: dict, flush_period: float = 0.01,
           chunk_size: int = 4096, n_topics: int = len(TOPICS), probe: dict | None = None):
    """One recording of ``seconds`` by the recorder of ``tree``: [(t, RSS MiB, messages sent)] and
    the bag folder. ``probe``: environment of benchmarks/recorder_probe.py, which then runs the
    recorder (its memory sampled from inside)."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.duration import Duration

    from adcs_msgs_py import topics
    from adcs_sim.nodes.recorder import READY_LINE
    out = tmp / 'bag'
    renv = {**env, 'PYTHONPATH': str(tree)}
    command = [sys.executable, *([str(ROOT / 'benchmarks' / 'recorder_probe.py')] if probe is not None else
                                 ['-m', 'adcs_sim.nodes.recorder'])]
    renv.update(probe or {})
    proc = subprocess.Popen([*command, '--ros-args', '-p', f'output:={out}',
                             '-p', f'flush_period:={flush_period!r}', '-p', f'chunk_size:={chunk_size}'], cwd=tree, env=renv, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    context = Context()
    rclpy.init(context=context, domain_id=int(env['ROS_DOMAIN_ID']))
    node = rclpy.create_node('bench_publisher', context=context)
    pubs = [node.create_publisher(Odometry, name, topics.QOS_LOCKSTEP) for name in TOPICS[:n_topics]]
    samples = []
    try:
        assert proc.stdout.readline().strip() == READY_LINE
        deadline = time.monotonic() + 30
        while not all(p.get_subscription_count() for p in pubs[:4]):   # the graph topics it subscribes at start
            assert time.monotonic() < deadline, 'recorder never subscribed'
            time.sleep(0.05)   # (a benchmark: the graph cache fills in DDS' threads)
        msg = Odometry()
        msg.child_frame_id = 'body'
        sent, t0 = 0, time.monotonic()
        next_sample = t0
        while time.monotonic() - t0 < seconds:
            k = sent // len(pubs)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * 100_000_000, 1_000_000_000)
            msg.pose.pose.orientation.w = 1.0 - 1e-9 * k
            for pub in pubs:
                pub.publish(msg)
            sent += len(pubs)
            if k % 50 == 0:
                for pub in pubs:
                    pub.wait_for_all_acked(Duration(seconds=5))
            if time.monotonic() >= next_sample:
                samples.append((time.monotonic() - t0, rss_mib(proc.pid), sent))
                next_sample += sample
                if len(samples) in (2, int(seconds / sample)):
                    print(f'  recorder at {samples[-1][0]:.0f} s: {rss_parts(proc.pid)} MiB', flush=True)
        for pub in pubs:
            pub.wait_for_all_acked(Duration(seconds=5))
        samples.append((time.monotonic() - t0, rss_mib(proc.pid), sent))
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        proc.send_signal(2)
        proc.wait(60)
    return samples, out, t0


WRITER_CHILD = r'''
import os, sys, tempfile
from pathlib import Path
from adcs_sim.bag import writer as bw
if sys.argv[1] == 'listed':
    bw.spill_chunk_indexes = lambda w: None
def rss():
    return int([l for l in open('/proc/self/status') if l.startswith('RssAnon')][0].split()[1]) / 1024
data = [os.urandom(200) + bytes(500) for _ in range(4)]
with tempfile.TemporaryDirectory() as tmp:
    w = bw.BagWriter(Path(tmp) / 'bag', chunk_size=4096)
    topics = [f'/t{i}' for i in range(20)]
    for t in topics:
        w.add_topic(t, 'nav_msgs/msg/Odometry', [{'history': 'keep_last', 'depth': 10}])
    k, out = 0, []
    for block in range(5):
        for _ in range(6000):
            for t in topics[:7]:
                w.write(t, data[k % 4], k * 100_000_000)
            k += 1
        out.append(f'{w._writer._Writer__statistics.chunk_count} {rss():.1f}')
    w.close()
print(' / '.join(out))
'''


def writer_only() -> None:
    for mode in ('spilled', 'listed'):
        out = subprocess.run([sys.executable, '-c', WRITER_CHILD, mode], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.strip()
        print(f'writer alone, chunk indexes {mode:<7}: (chunks RssAnon MiB) {out}', flush=True)


def describe(label: str, samples, bag: Path) -> None:
    from mcap.reader import make_reader
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        summary = make_reader(f).get_summary()
    chunks = len(summary.chunk_indexes)
    n = len(samples)
    q, h = samples[n // 4], samples[n // 2]
    end = samples[-1]
    msgs = end[2]
    per_chunk_s = end[0] / max(chunks, 1)
    second_half_chunks = (end[0] - h[0]) / per_chunk_s
    growth = (end[1] - h[1]) / max(second_half_chunks, 1) * 1000 * 1024
    per_message = (end[1] - h[1]) * 2**20 / max(end[2] - h[2], 1)
    size = sum(p.stat().st_size for p in bag.iterdir()) / 2**20
    print(f'{label:<9}: {msgs} messages, {chunks} chunks in {end[0]:.0f} s, bag {size:.1f} MiB; '
          f'recorder RSS {q[1]:.1f} MiB at 1/4, {h[1]:.1f} at 1/2, {end[1]:.1f} at the end: '
          f'+{growth:.0f} KiB per 1000 chunks ({per_message:.0f} B per message) over the second half', flush=True)


def probe_env(args, name: str) -> dict | None:
    if args.probe is None:
        return None
    args.probe.mkdir(parents=True, exist_ok=True)
    out = args.probe / f'{name}.jsonl'
    out.unlink(missing_ok=True)
    return {'ADCS_PROBE_OUT': str(out.resolve()), 'ADCS_PROBE_PERIOD': str(args.sample * 2),
            'ADCS_PROBE_DIFF_AT': str(args.seconds / 2), 'ADCS_PROBE_TRIM': '1' if args.trim else '0',
            **({'ADCS_PROBE_TRACEMALLOC': str(args.probe_tracemalloc)} if args.probe_tracemalloc else {})}


def describe_probe(path: Path, sent, t0: float) -> None:
    """The probe's samples at a quarter, half and the end of the publishing (MiB): what grew, native
    or Python, and how many messages the recorder had not taken yet (sent - received: what DDS holds
    for it; the publisher's samples interpolated at the probe's time)."""
    import json

    import numpy as np
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    samples = [r for r in rows if 'chunks' in r and not r.get('exit') and r['mono'] - t0 <= sent[-1][0]]
    mib = 1 / 2**20
    # messages sent before the recorder had discovered their topic never reach it: what it took in
    # the end (after its drain) tells how many
    lost = sent[-1][2] - next(r['received'] for r in rows if r.get('exit'))
    times, counts = [s[0] for s in sent], [s[2] for s in sent]
    for r in samples:
        r['backlog'] = int(np.interp(r['mono'] - t0, times, counts, left=0)) - r['received'] - lost
    print('    backlog (messages sent, not yet taken) over the recording: '
          + ' '.join(str(r['backlog']) for r in samples))
    for r in (samples[len(samples) // 4], samples[len(samples) // 2], samples[-1]):
        traced = f', Python traced {r["traced"] * mib:.1f}' if r.get('traced') is not None else ''
        trimmed = f' ({r["anon_after_trim_kib"] / 1024:.1f} after malloc_trim)' if 'anon_after_trim_kib' in r else ''
        print(f'    t {r["t"]:6.1f} s, {r["chunks"]:6d} chunks: RssAnon {r["anon_kib"] / 1024:.1f}{trimmed}, '
              f'malloc in use {r["heap_used"] * mib:.1f} + mmapped {r["mmapped"] * mib:.1f}, free in heaps '
              f'{r["heap_free"] * mib:.1f}, {r["maps"]} maps, {r["threads"]} threads{traced}', flush=True)
    for r in rows:
        for line in r.get('diff', ()):
            print(f'    {line}')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--sample', type=float, default=1.0)
    ap.add_argument('--repeat', type=int, default=1)
    ap.add_argument('--compare', type=Path, metavar='TREE')
    ap.add_argument('--flush-period', type=float, default=0.01, help="the recorder's (s; default 0.01)")
    ap.add_argument('--chunk-size', type=int, default=4096, help="the recorder's (bytes; default 4096)")
    ap.add_argument('--writer', action='store_true', help='the bag writer alone (no ROS), spilled vs listed')
    ap.add_argument('--topics', type=int, default=len(TOPICS), help=f'how many of the {len(TOPICS)} topics to publish')
    ap.add_argument('--domains', type=int, nargs=2, default=(100, 232), metavar=('LO', 'HI'),
                    help='ROS domain ids to lease one from')
    ap.add_argument('--probe', type=Path, metavar='DIR', help='run the recorder under benchmarks/recorder_probe.py, '
                    'its samples in DIR (one JSON-lines file a recording)')
    ap.add_argument('--probe-tracemalloc', type=int, default=0, metavar='FRAMES',
                    help='with --probe: trace Python allocations (FRAMES deep), diff from the half to the end')
    ap.add_argument('--trim', action='store_true', help="with --probe: malloc_trim(0) after each sample")
    ap.add_argument('--recorder-env', action='append', default=[], metavar='KEY=VALUE',
                    help="set in the recorder's environment (e.g. MALLOC_ARENA_MAX=2)")
    args = ap.parse_args()
    if args.writer:
        writer_only()
        return 0
    from adcs_msgs_py.node import network_hygiene_defaults
    from adcs_sim.app.graph.domains import DomainLease
    network_hygiene_defaults()   # our Fast DDS profile: 10 ms heartbeats (the acknowledgement waits)
    lease = DomainLease(*args.domains)
    env = {**lease.env(), **dict(kv.split('=', 1) for kv in args.recorder_env)}
    os.environ.update({k: env[k] for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')})
    trees = {'this': ROOT, **({'compared': args.compare.resolve()} if args.compare else {})}
    print(f'ROS_DOMAIN_ID={lease.domain_id}; load average {" ".join(f"{x:.2f}" for x in os.getloadavg())}')
    try:
        for i in range(args.repeat):
            for label, tree in trees.items():
                with tempfile.TemporaryDirectory(prefix='recorder_memory_') as tmp:
                    probe = probe_env(args, f'{i + 1}_{label}')
                    samples, bag, t0 = record(tree, args.seconds, args.sample, Path(tmp), env, args.flush_period,
                                          args.chunk_size, args.topics, probe)
                    describe(f'[{i + 1}] {label}', samples, bag)
                    if probe is not None:
                        describe_probe(Path(probe['ADCS_PROBE_OUT']), samples, t0)
    finally:
        lease.release()
    return 0


if __name__ == '__main__':
    sys.exit(main())
