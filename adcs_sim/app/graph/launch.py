"""``python -m adcs_sim.app.graph.launch <module> [args ...]``: run a node executable's module as
``python -m <module> [args ...]`` does, then end the process at once.

How ``adcs-run`` starts its nodes (:meth:`adcs_sim.app.graph.processes.Graph.start`). A node has shut down
when its ``main`` returns (:func:`adcs_msgs_py.node.main_for`: the node destroyed, which deletes
its DDS participant and removes its shared-memory segments from ``/dev/shm``, its files closed -
the recorder's bag and ``metadata.yaml`` included - and the context shut down). What the
interpreter would still do then is tear down the libraries: Fast DDS' static objects join their
threads and sleep (0.45-0.9 s measured per process, after the last ``atexit`` handler, 2 cores,
2026-12-02), and the runner waits for each node's exit in turn at the end of a run. So once
``main`` has returned (or raised), this flushes stdout/stderr and calls ``os._exit`` with the
status the interpreter would have given: ``SystemExit``'s code; 1 and the traceback for an
uncaught exception; a KeyboardInterrupt ends the process by SIGINT as Python does.
"""
from __future__ import annotations

import os
import runpy
import signal
import sys
import traceback


def exit_status(code) -> int:
    """The process status of ``SystemExit(code)``, as the interpreter computes it."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code & 0xFF
    print(code, file=sys.stderr)
    return 1


def run(module: str) -> int:
    """Run ``module`` as ``__main__`` (``sys.argv`` as ``-m`` sets it); its exit status."""
    try:
        runpy.run_module(module, run_name='__main__', alter_sys=True)
    except SystemExit as exc:
        return exit_status(exc.code)
    except KeyboardInterrupt:
        traceback.print_exc()
        return -signal.SIGINT
    except BaseException:  # noqa: BLE001 - reported as the interpreter would, status 1
        traceback.print_exc()
        return 1
    return 0


def main() -> None:
    if len(sys.argv) < 2:
        print('usage: python -m adcs_sim.app.graph.launch <module> [args ...]', file=sys.stderr)
        raise SystemExit(2)
    module = sys.argv[1]
    sys.argv = [sys.argv[0], *sys.argv[2:]]
    status = run(module)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if status < 0:   # killed by a signal, as an uncaught KeyboardInterrupt ends a Python process
        signal.signal(-status, signal.SIG_DFL)
        os.kill(os.getpid(), -status)
    os._exit(status)


if __name__ == '__main__':
    main()
