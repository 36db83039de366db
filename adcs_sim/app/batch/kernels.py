"""Every compiled (numba) kernel of the packages, compiled into numba's on-disk cache ahead of use.

numba compiles a kernel for the argument types of its first call and keeps the machine code beside
its module (``__pycache__/<module>.<function>-<line>.py311.nbi`` + ``.nbc``, or under
``NUMBA_CACHE_DIR``), one entry per argument types; a later process loads it (~0.1 s) as long as the
source is unchanged. :data:`SPECIALISATIONS` lists, for each kernel called from Python, the one
argument-type signature the code calls it with (the callers pass float64, C-contiguous, writable
arrays: :func:`adcs_sim.truth.kernel.kernel_rows`), and :func:`compile_all` compiles exactly those,
so that neither a run, nor a node at start-up, nor a test pays a compilation
(``tests/test_kernel_specialisations.py`` checks that the runs call nothing else). Who calls it:

* ``make install`` (``python -m adcs_sim.app.batch.kernels``); ``make run`` compiles what a graph run
  and its report use (:data:`RUN_KERNELS`, ``--run``: ~33 of the 132 CPU seconds) before its run and
  the others (``--not-run``) after it, once its result is on the screen;
* building the package (``pip install .``: ``setup.py``'s ``build_py`` compiles the built copy, so
  the wheel carries the cache: the first ``adcs-run`` after ``pip install`` compiles nothing on the
  machine that built it);
* the test suite, before its tests (in the controller of an xdist run, not in each worker).

The kernels are independent: they are compiled in ``jobs`` processes at once (numba compiles one
function at a time in a process), the longest first. Each compilation prints one line on stderr
(:mod:`adcs_core.compile_log`): kernel, argument types, seconds; on a warm cache nothing compiles and
only the summary is printed.
"""
from __future__ import annotations

import argparse
import importlib
import os
import subprocess
import sys
import time
from collections.abc import Callable

# Argument types, one letter group each: f float64, i int64, b bool; F1/F2/F3 float64 arrays of 1-3
# dimensions, I1/I2 int64 arrays, B1 bool arrays, all C-contiguous and writable.
MODULE = 'adcs_sim.app.batch.kernels'   # what the compiling processes run (python -m)
_CODES = {'f': ('float64', ()), 'i': ('int64', ()), 'b': ('boolean', ()),
          'F1': ('float64', 1), 'F2': ('float64', 2), 'F3': ('float64', 3),
          'I1': ('int64', 1), 'I2': ('int64', 2), 'B1': ('boolean', 1)}
_PLANT = 'F2 F2 I1 I1 I1 I1 I1 F2 F1 B1 B1 B1'   # params cmds kinds soff poff coff counts axes bias stuck avail flags

# (kernel, argument types, CPU seconds of its compilation measured on the 2-core machine under load, 131.7 s
# for all twelve). The seconds only share the work between the processes.
SPECIALISATIONS: tuple[tuple[str, str, float], ...] = (
    ('adcs_sim.app.batch.fused.closed_loop',
     f'F2 I1 F1 F3 f F2 F2 F2 F2 b F2 F2 i i {_PLANT} F1 F3 i F3 F3 F3 F3 F2 I1 B1', 50.2),
    ('adcs_sim.truth.kernel.rk4_runs', f'F2 F2 F2 f {_PLANT} F3 b F3 f b F1', 26.7),
    ('adcs_sim.app.analysis.metrics_kernel.first_pass', 'F3 F2 F3 F3 F1 F1 f F1 I2 F2 F2 F2', 41.4),
    ('adcs_sim.app.analysis.metrics_kernel.second_pass', 'F2 F1 f F2', 0.9),
    ('adcs_sim.app.analysis.metrics_kernel.error_quaternions', 'F3 F2 F3 F2', 0.8),
    ('adcs_core.euler_kernel.euler_213_rows', 'F2 F2', 1.2),
    ('adcs_sim.truth.kernel.torque_runs', f'F2 F2 f {_PLANT} F1', 4.6),
    ('adcs_sim.app.analysis.metrics_kernel.eigen_columns', 'F2 I2 F1 f F2', 0.2),
    ('adcs_sim.app.analysis.metrics_kernel.pairwise_sum', 'F1 i i', 1.4),
    # the law's row kernels, inlined into the fused loop; compiled alone for the tests that call them
    ('adcs_controllers.laws.pd_kernel.normalize_row', 'F1 i F1', 0.2),
    ('adcs_controllers.laws.pd_kernel.pd_torque_row', 'F1 F1 i F1 f f F1 F1 b F1', 0.6),
    ('adcs_controllers.laws.pd_kernel.wheel_command_row', 'F1 F2 F1 i F1 i', 0.4),
)


# What a graph run and its report use (the dynamics node's plant, the report's Euler angles): `make run`
# compiles these before the run and the others after it (`make install` all of them at once).
RUN_KERNELS = ('adcs_sim.truth.kernel.rk4_runs', 'adcs_sim.truth.kernel.torque_runs',
               'adcs_core.euler_kernel.euler_213_rows')


def argument_types(codes: str) -> tuple:
    """numba's types of ``codes`` (``'F2 f b'``: a 2-D float64 C array, a float64, a bool)."""
    # lazy: numba (0.4-0.7 s) only where kernels are compiled or checked
    from numba import types
    out = []
    for code in codes.split():
        dtype, ndim = _CODES[code]
        scalar = getattr(types, dtype)
        out.append(scalar if ndim == () else types.Array(scalar, ndim, 'C'))
    return tuple(out)


def dispatcher(kernel: str):
    """The numba dispatcher ``module.function``."""
    module, name = kernel.rsplit('.', 1)
    return getattr(importlib.import_module(module), name)


def compile_here(kernels: list[str]) -> None:
    """Compile (or load from the cache) ``kernels`` in this process, for their listed types."""
    listed = {name: codes for name, codes, _ in SPECIALISATIONS}
    for kernel in kernels:
        dispatcher(kernel).compile(argument_types(listed[kernel]))


def plan(jobs: int, kernels: list[str] | None = None) -> list[list[str]]:
    """``kernels`` (default: all listed) split into ``jobs`` lists of about equal compilation time
    (longest first, each to the least loaded list)."""
    bins: list[tuple[float, list[str]]] = [(0.0, []) for _ in range(max(1, jobs))]
    chosen = [s for s in SPECIALISATIONS if kernels is None or s[0] in kernels]
    for name, _, seconds in sorted(chosen, key=lambda s: -s[2]):
        load, names = min(bins, key=lambda b: b[0])
        bins[bins.index((load, names))] = (load + seconds, names + [name])
    return [names for _, names in bins if names]


def default_jobs() -> int:
    """Processes compiling at once: one per core, at most two (numba's compilation is one thread)."""
    return max(1, min(2, os.cpu_count() or 1))


def compile_all(progress: Callable[[str], None] | None = print, jobs: int | None = None,
                kernels: list[str] | None = None) -> dict[str, float]:
    """Compile (or, on a warm cache, load) ``kernels`` (default: every listed one) in ``jobs``
    processes (default: :func:`default_jobs`; 1: in this process); ``{'total': seconds}``. Each
    compilation prints its line on stderr as it ends; ``progress`` gets the summary line."""
    jobs = default_jobs() if jobs is None else jobs
    kernels = [name for name, _, _ in SPECIALISATIONS] if kernels is None else kernels
    start = time.perf_counter()
    if jobs <= 1:
        compile_here(kernels)
    else:
        children = [subprocess.Popen([sys.executable, '-m', MODULE, '--jobs', '1', '--only', ','.join(names)])
                    for names in plan(jobs, kernels)]
        failed = [child.args[-1].replace(',', ', ') for child in children if child.wait() != 0]
        if failed:
            raise RuntimeError(f'kernels: compiling {"; ".join(failed)} failed (the error is printed above)')
    times = {'total': time.perf_counter() - start, 'kernels': len(kernels)}
    if progress is not None:
        progress(summary(times))
    return times


def summary(times: dict[str, float]) -> str:
    """``adcs_sim kernels: 12 compiled or loaded in 41.2 s``."""
    return f'adcs_sim kernels: {times.get("kernels", len(SPECIALISATIONS))} compiled or loaded in {times["total"]:.1f} s'


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='python -m adcs_sim.app.batch.kernels', description=__doc__.splitlines()[0])
    parser.add_argument('--jobs', type=int, default=None, help='processes compiling at once (default: cores, at most 2)')
    parser.add_argument('--only', default=None, help='comma-separated kernels (module.function) instead of all')
    parser.add_argument('--run', action='store_true', help="only what a graph run and its report use (RUN_KERNELS)")
    parser.add_argument('--not-run', action='store_true', help='all but those')
    args = parser.parse_args(argv)
    listed = [name for name, _, _ in SPECIALISATIONS]
    if args.only is not None:
        unknown = sorted(set(args.only.split(',')) - set(listed))
        if unknown:
            print(f'kernels: --only: not a listed kernel: {", ".join(unknown)}', file=sys.stderr)
            return 2
        compile_here(args.only.split(','))
        return 0
    chosen = [name for name in listed if not (args.run or args.not_run) or (name in RUN_KERNELS) == args.run]
    compile_all(jobs=args.jobs, kernels=chosen)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
