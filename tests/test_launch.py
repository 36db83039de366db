"""``python -m adcs_sim.app.graph.launch <module>`` (how adcs-run starts its nodes) ends as
``python -m <module>`` would: same arguments seen, same exit status, output flushed, a traceback
and status 1 for an uncaught exception, death by SIGINT for an uncaught KeyboardInterrupt; only
the interpreter's teardown after ``main`` is skipped. And a node so started leaves no DDS
shared-memory segment behind in /dev/shm (its participant is deleted with the node)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from support.processes import shm_segments

ROOT = Path(__file__).resolve().parents[1]

MODULES = {
    'prints_args': '''
        import sys
        print('args', sys.argv[1:], end='')   # no newline, no flush: launch must flush it
        sys.stderr.write('to stderr')
        if __name__ == '__main__':
            raise SystemExit(int(sys.argv[-1]))
    ''',
    'returns': '''
        print('ran as', __name__)
    ''',
    'raises': '''
        raise ValueError('broken node')
    ''',
    'interrupted': '''
        raise KeyboardInterrupt
    ''',
    'exits_with_text': '''
        raise SystemExit('a message')
    ''',
}


@pytest.fixture(scope='module')
def modules(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp('launched')
    for name, text in MODULES.items():
        (folder / f'{name}.py').write_text(textwrap.dedent(text))
    return folder


def launch(folder: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join([str(folder), str(ROOT)])}
    return subprocess.run([sys.executable, '-m', 'adcs_sim.app.graph.launch', *args], env=env, capture_output=True,
                          text=True, timeout=60)


def plain(folder: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join([str(folder), str(ROOT)])}
    return subprocess.run([sys.executable, '-m', *args], env=env, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize('args', [('prints_args', '--ros-args', '-p', 'x:=1', '3'), ('prints_args', '0'),
                                  ('returns',), ('raises',), ('interrupted',), ('exits_with_text',)])
def test_launch_ends_as_python_m_would(modules, args):
    launched, direct = launch(modules, *args), plain(modules, *args)
    assert launched.returncode == direct.returncode
    assert launched.stdout == direct.stdout
    if direct.returncode == 0 or args[0] == 'prints_args':
        assert launched.stderr == direct.stderr
    else:   # the same traceback's last line (the frames differ: runpy's own)
        assert launched.stderr.strip().splitlines()[-1] == direct.stderr.strip().splitlines()[-1]


def test_codes_and_signals(modules):
    assert launch(modules, 'prints_args', '3').returncode == 3
    assert launch(modules, 'raises').returncode == 1
    assert launch(modules, 'interrupted').returncode == -signal.SIGINT
    assert launch(modules, 'exits_with_text').returncode == 1
    assert launch(modules).returncode == 2   # no module: usage


def test_a_launched_node_leaves_no_shared_memory_behind(tmp_path, ros_domain):
    """A recorder started through launch, stopped by SIGINT: its bag is closed and no Fast DDS
    segment of its own is left in /dev/shm (the participant was deleted before the fast exit)."""
    env = ros_domain.env()
    proc = subprocess.Popen([sys.executable, '-m', 'adcs_sim.app.graph.launch', 'adcs_sim.nodes.recorder', '--ros-args',
                             '-p', f'output:={tmp_path / "bag"}'], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=ROOT)
    try:
        assert proc.stdout.readline().strip() == 'recorder: ready'
        own = shm_segments(proc.pid)   # no peer on this domain: every segment mapped is its own
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, out
    assert (tmp_path / 'bag' / 'metadata.yaml').exists()
    assert own   # (Fast DDS' shared memory transport was in use)
    left = {seg for seg in own if seg.exists()}
    assert not left, left
