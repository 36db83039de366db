"""Where ``adcs-montecarlo`` runs a campaign's chunks by default (``--scheduler auto``): in its own
process, or on a Dask ``LocalCluster`` when the cluster saves more than it costs.

A ``LocalCluster`` costs :data:`CLUSTER_START_S` before its first result: the scheduler and the
worker processes start, each worker imports the packages and loads the compiled kernels. It then
runs the chunks on ``workers`` processes at once. How long a run takes differs by orders of
magnitude between campaigns (a PD slew on the fused loop: ~1 ms; a run of the general path with
sensors and an estimator: ~1 s), so it is measured, not guessed: the first chunk runs in this
process, timed, and :func:`choose` compares, for the chunks left,

* in this process: ``per_run_s * runs_left``;
* on the cluster: ``CLUSTER_START_S + per_run_s * runs_left / min(workers, chunks_left)``
  (a chunk is the unit of work: two chunks keep at most two workers busy);

and takes the cluster only if it finishes sooner. The rows do not depend on the choice (each run
has its own random stream and the rows are sorted by run index).
"""
from __future__ import annotations

# Seconds from LocalCluster(...) to the result of a one-run chunk, that run's own time taken off (2
# workers, the kernels' cache warm), measured by `benchmarks/montecarlo_speed.py --end-to-end` on the
# 2-core machine: 2.66 s at a load of ~1.5, 4.79 s at a load of 6-7 (the cluster's processes then wait
# for the cores too).
CLUSTER_START_S = 2.7


def choose(per_run_s: float, chunk_sizes: list[int], workers: int, start_s: float = CLUSTER_START_S) -> str:
    """``'local'`` (a LocalCluster of ``workers`` processes) or ``'none'`` (this process) for the
    chunks of ``chunk_sizes`` still to run, a run costing ``per_run_s`` seconds (module docstring)."""
    if per_run_s < 0 or workers < 1 or start_s < 0:
        raise ValueError(f'choose: per_run_s {per_run_s}, workers {workers}, start_s {start_s}: none may be negative '
                         'and workers must be at least 1')
    runs = sum(chunk_sizes)
    parallel = min(workers, len(chunk_sizes))
    if parallel <= 1:
        return 'none'
    here = per_run_s * runs
    on_cluster = start_s + per_run_s * runs / parallel
    return 'local' if on_cluster < here else 'none'
