"""One line on stderr for every numba compilation of the packages' kernels: which kernel, for which
argument types, how long.

numba compiles a ``cache=True`` kernel only when its on-disk cache holds no machine code for the
argument types of a call (``make install`` and ``pip install`` fill it: :mod:`adcs_sim.app.batch.kernels`);
a compilation takes seconds to minutes and used to happen silently. Every kernel module imports this
module, which registers a listener of numba's ``numba:compile`` event (sent on a cache miss only, not
when machine code is loaded from the cache), so that a compilation is never silent, wherever it
happens: at install, in a test, or at run time::

    numba: compiled adcs_sim.truth.kernel.rk4_runs(f8[2d C], f8[2d C], ...) in 21.4 s (CPU 20.9 s)

:data:`COMPILED` keeps ``(kernel, types, seconds)`` of each compilation of this process (the test
that nothing compiles at run time reads it). ``ADCS_COMPILE_LOG=0`` silences the lines.
"""
from __future__ import annotations

import os
import sys
import time

from numba.core import event, types

PACKAGES = ('adcs_core.', 'adcs_msgs_py.', 'adcs_controllers.', 'adcs_sim.')
COMPILED: list[tuple[str, str, float]] = []   # (kernel, argument types, wall seconds), in order
PRINT = os.environ.get('ADCS_COMPILE_LOG', '1') != '0'


def type_text(t) -> str:
    """``f8[2d C]`` for a C-contiguous 2-D float64 array (``ro`` if read-only), numba's name otherwise."""
    if isinstance(t, types.Array):
        dtype = {'float64': 'f8', 'int64': 'i8', 'bool': 'b1'}.get(str(t.dtype), str(t.dtype))
        return f'{dtype}[{t.ndim}d {t.layout}{"" if t.mutable else " ro"}]'
    return str(t)


def kernel_name(dispatcher) -> str:
    """``module.function`` of a numba dispatcher."""
    func = dispatcher.py_func
    return f'{func.__module__}.{func.__qualname__}'


class CompileLog(event.Listener):
    """Times each compilation of the packages' kernels and prints it when it ends (nested ones too:
    a kernel that calls another compiles the callee first, inside its own time)."""

    def __init__(self) -> None:
        self._started: list[tuple[float, float]] = []

    def on_start(self, ev) -> None:
        self._started.append((time.perf_counter(), time.process_time()))

    def on_end(self, ev) -> None:
        wall0, cpu0 = self._started.pop()
        name = kernel_name(ev.data['dispatcher'])
        if not name.startswith(PACKAGES):
            return
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        args = ', '.join(type_text(t) for t in ev.data['args'])
        COMPILED.append((name, args, wall))
        if PRINT:
            print(f'numba: compiled {name}({args}) in {wall:.1f} s (CPU {cpu:.1f} s)', file=sys.stderr, flush=True)


LISTENER = CompileLog()
event.register('numba:compile', LISTENER)
