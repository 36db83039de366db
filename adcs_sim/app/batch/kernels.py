"""Every compiled (numba) kernel of the packages, compiled into numba's on-disk cache in one call.

numba compiles a kernel at its first call and keeps the machine code beside its module
(``__pycache__/<module>.<function>-<line>.py311.nbi`` + ``.nbc``, or under ``NUMBA_CACHE_DIR``), one
entry per argument types; later processes load it (~0.1 s) as long as the source is unchanged.
:func:`compile_all` makes those first calls, so that neither a run, nor a node at start-up, nor a
test pays a compilation: ``make install`` calls it once, the test suite before its tests (in the
controller of an xdist run, not in each worker). On a warm cache it only loads.

The groups and what compiles them:

* ``plant``: :mod:`adcs_sim.truth.kernel` (RK4 and torque of the plant), through a plant's warm-up;
* ``campaign``: :mod:`adcs_sim.app.batch.fused`'s closed PD loop and :mod:`adcs_sim.app.analysis.metrics_kernel`'s
  first pass with :mod:`adcs_sim.app.analysis.batch_metrics`, through a 2-run campaign of the PD slew;
* ``rare metrics``: :func:`adcs_sim.app.analysis.metrics_kernel.compile_rare_kernels` (what a small campaign
  does not reach), the pairwise sum called alone, and the same kernels on read-only arrays (a run's
  reference or a dispersed parameter given per run is a read-only view: numba compiles those apart);
* ``fused variants``: the closed loop with the law's inertia, reference attitude and rate or the wheel
  limits given per run (read-only views, as :class:`adcs_sim.app.batch.fused.FusedLoop` passes them);
* ``euler``: :func:`adcs_core.euler_kernel.euler_213_rows` (2-1-3 Euler angles of many quaternions);
* ``pd rows``: :mod:`adcs_controllers.laws.pd_kernel`'s row functions called alone (the fused loop
  inlines them; the tests call them from Python).

``python -m adcs_sim.app.batch.kernels`` prints one line per group and the total.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

# The closed loop's arguments that FusedLoop passes as read-only views when a campaign gives them per
# run (np.broadcast_to of an array already of the batch's shape): law inertia, q_ref, w_ref (6, 7, 8)
# and the wheel limits (11); each combination the campaigns and tests reach is its own compilation.
FUSED_READ_ONLY = ((), (6,), (7,), (8,), (11,), (7, 8, 11), (6, 7, 8, 11))


def _plant() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_sim.truth.plant import Plant
    Plant(np.eye(3))


def _campaign_file():
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_sim.app.scenario.files import config_dirs
    for folder in config_dirs():
        if (folder / 'campaigns' / 'pd_slew_30deg.yaml').is_file():
            return folder / 'campaigns' / 'pd_slew_30deg.yaml'
    raise FileNotFoundError('campaigns/pd_slew_30deg.yaml in none of the config folders')


def _campaign() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_sim.app.campaign.plan import Campaign, run_chunk
    campaign = Campaign.load(_campaign_file(), runs=2)
    for chunk in campaign.chunks():
        run_chunk(campaign, chunk)


def _variants(dispatcher, arrays: tuple[int, ...], read_only_sets) -> None:
    """Compile ``dispatcher`` for the argument types it was first called with, the arrays at
    positions ``arrays`` read-only for those in each of ``read_only_sets`` and writable otherwise
    (nothing if it was not called: ``ADCS_FUSED_LOOP=0`` leaves the closed loop out)."""
    if not dispatcher.signatures:
        return
    base = dispatcher.signatures[0]
    for read_only in read_only_sets:
        dispatcher.compile(tuple(t.copy(readonly=i in read_only) if i in arrays else t for i, t in enumerate(base)))


def _rare_metrics() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_sim.app.analysis import metrics_kernel
    metrics_kernel.compile_rare_kernels()
    metrics_kernel.pairwise_sum(np.zeros(2), 0, 2)
    _variants(metrics_kernel.error_quaternions, (1,), [(), (1,)])   # q_ref: a run's own or a read-only view
    _variants(metrics_kernel.first_pass, (1,), [(), (1,)])


def _fused_variants() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_sim.app.batch import fused
    _variants(fused.closed_loop, (6, 7, 8, 11), FUSED_READ_ONLY)


def _euler() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_core.euler_kernel import euler_213_rows
    euler_213_rows(np.array([[0.0, 0.0, 0.0, 1.0]]), np.empty((1, 3)))


def _pd_rows() -> None:
    # lazy: each group's modules, imported inside the group so that its time counts them
    from adcs_controllers.laws import pd_kernel
    q, w, out = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.empty(4)
    pd_kernel.normalize_row(q, 0, out)
    pd_kernel.pd_torque_row(q, w, 0, np.eye(3).reshape(9), 1.0, 1.0, q.copy(), w.copy(), True, np.empty(3))
    pd_kernel.wheel_command_row(np.zeros(3), np.eye(3), np.ones(3), pd_kernel.CLIP, np.zeros(3), 0)


# (name, function): in this order (the campaign compiles what the variants start from)
GROUPS: tuple[tuple[str, Callable[[], None]], ...] = (
    ('plant', _plant), ('campaign', _campaign), ('rare metrics', _rare_metrics),
    ('fused variants', _fused_variants), ('euler', _euler), ('pd rows', _pd_rows))


def compile_all(progress: Callable[[str], None] | None = print) -> dict[str, float]:
    """Compile (or, on a warm cache, load) every kernel; ``{group: seconds}`` plus ``'total'``.
    ``progress`` gets one line per group as it ends and the summary line."""
    times: dict[str, float] = {}
    start = time.perf_counter()
    for name, compile_group in GROUPS:
        t0 = time.perf_counter()
        with np.errstate(all='ignore'):
            compile_group()
        times[name] = time.perf_counter() - t0
        if progress is not None:
            progress(f'  {name}: {times[name]:.1f} s')
    times['total'] = time.perf_counter() - start
    if progress is not None:
        progress(summary(times))
    return times


def summary(times: dict[str, float]) -> str:
    """``adcs_sim kernels: compiled in 41.2 s (plant 9.1 s, ...)``."""
    groups = ', '.join(f'{name} {t:.1f} s' for name, t in times.items() if name != 'total')
    return f'adcs_sim kernels: compiled in {times["total"]:.1f} s ({groups})'


if __name__ == '__main__':
    compile_all()
