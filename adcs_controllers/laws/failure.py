"""A controller or estimator that cannot answer a step (pure; no rclpy): the one error the nodes stop
the run with (exit status 6, :data:`adcs_msgs_py.node.EXIT_FLIGHT_SOFTWARE`) and the batch engine
raises, from the same calls.

The rule: the first time the flight software's own computation fails, not a message it refuses.
Bad messages are rejected (counted) before they reach the law or the filter, and a law refusing
one state is a counted refusal (:class:`~adcs_controllers.laws.base.LawOutputRejected`; the
controller node stops on three in a row: ``FlightSoftwareStop.MAX_REFUSALS_IN_A_ROW``), so what
raises here is the law's, the allocation's or the filter's arithmetic on valid inputs, or an
estimate that is not finite. Nothing is published for that step, so on the lockstep graph every
later step would wait out ``lockstep.timeout`` (a filter whose covariance broke raises on every
step after: a 3000-step run took hours), and a filter that raised mid-step (propagated, not
updated) has a state nobody should fly on.
"""
from __future__ import annotations

from typing import Callable, TypeVar

import numpy as np

NS_PER_S = 1_000_000_000
T = TypeVar('T')


class FlightSoftwareError(RuntimeError):
    """``node`` could not answer the step at ``t_ns``: the message names the node, the time and the
    error. ``runs``: with a batch axis, the indices of the runs it concerns (None: all of them, a
    raise of the batch's computation; rerun a run alone to tell)."""

    def __init__(self, node: str, t_ns: int, error: str, runs: np.ndarray | None = None) -> None:
        self.node, self.t_ns, self.error, self.runs = node, t_ns, error, runs
        super().__init__(f'flight software failed: {node} could not answer the step at '
                         f't = {t_ns / NS_PER_S:g} s: {error}')


def answer(node: str, t_ns: int, compute: Callable[[], T], refusals: tuple[type[Exception], ...] = ()) -> T:
    """``compute()``, or :class:`FlightSoftwareError` for anything it raises except ``refusals``
    (re-raised as they are: a refused state is counted by the node, not a failure)."""
    try:
        with np.errstate(all='ignore'):   # a non-finite result is checked by the caller
            return compute()
    except refusals:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever the computation raised is the reason
        raise FlightSoftwareError(node, t_ns, f'{type(exc).__name__}: {exc}') from exc


ESTIMATE_FIELDS = {'q': 1, 'w': 1, 'bias': 1, 'cov': 2, 'rate_cov': 2}   # trailing (non-batch) axes


def nonfinite_estimate(est) -> tuple[str, np.ndarray] | None:
    """What is not finite in an :class:`~adcs_msgs_py.measurements.Estimate` and where (a boolean of
    the batch shape: the runs concerned), or None."""
    bad, where = [], False
    for name, axes in ESTIMATE_FIELDS.items():
        value = np.asarray(getattr(est, name), dtype=float)
        rows = ~np.isfinite(value).all(axis=tuple(range(-axes, 0)))
        if rows.any():
            bad.append(name)
            where = where | rows
    return (f'the estimate is not finite ({", ".join(bad)})', np.asarray(where)) if bad else None


def estimate_step(node: str, estimator, m):
    """``estimator.step(m)`` (an estimator family's object), or :class:`FlightSoftwareError` when it
    raises or its estimate is not finite (in any run of a batch): the node's and the batch engine's call."""
    est, status = answer(node, m.t_ns, lambda: estimator.step(m))
    problem = nonfinite_estimate(est)
    if problem is not None:
        raise FlightSoftwareError(node, m.t_ns, problem[0], np.flatnonzero(problem[1]) if problem[1].ndim else None)
    return est, status
