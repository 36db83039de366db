"""The batch engine's fused closed loop: whole runs of the PD family in one compiled call (numba).

:meth:`adcs_sim.app.batch.engine.BatchSimulation.run` advances every run one control step at a time in
Python: each step measures, calls the law, allocates, packs the commands for the compiled plant
(:mod:`adcs_sim.truth.kernel`) and records, a few dozen numpy calls per step whatever the batch
size. For the commonest campaign (seed 004's PD benchmark: PD law, reaction wheels with
minimum-norm allocation and saturation, perfect state feedback) :func:`plan` builds instead one
compiled loop that runs every control step of a run, the runs in parallel (``prange``):

    q_m = quat_normalize(q)                       (what the controller does to its input)
    u   = pd_torque(q_m, w, ...)                  (:func:`adcs_controllers.laws.pd_kernel.pd_torque_row`)
    tau = saturate(M u, limit)                    (:func:`~adcs_controllers.laws.pd_kernel.wheel_command_row`)
    u_b = control_torque(t_k, x, tau)             (:func:`adcs_sim.truth.kernel.control_torque_row`)
    x   = RK4 over [t_k, t_k+1] holding tau       (:func:`adcs_sim.truth.kernel.rk4_period`)

and records ``q``, ``w``, ``u_b`` and the wheel speeds as the general path does, stopping a run at
its own step count or at its first non-finite state or torque. The law and actuation kernels
live beside their law (flight software) and the plant's beside the plant (truth model); only this
application module calls both. Every kernel does numpy's operations in numpy's order, compiled
without fastmath, so the rows are the same bits as the general path's (``tests/test_fused_loop.py``;
``benchmarks/montecarlo_speed.py`` compares the campaign's rows of the three paths).

It applies (:func:`plan` returns None otherwise, and the general path runs) to a batch with a
``pd_controller`` section on wheels, the plant on the compiled kernel with wheels and no thrusters,
no environment torque, no noise, sensors, estimator or fault schedule, and no ``progress`` /
``observe`` callback. ``ADCS_FUSED_LOOP=0`` (or :data:`ENABLED` = False) turns it off.
"""
from __future__ import annotations

import functools
import os

import numba
import numpy as np
from numba import njit, prange

from adcs_core import compile_log  # noqa: F401 - a compilation prints one line (kernel, types, seconds)
from adcs_controllers.laws.allocation import WheelActuation
from adcs_controllers.laws.pd import PdLaw
from adcs_controllers.laws.pd_kernel import CLIP, SCALE, normalize_row, pd_torque_row, wheel_command_row
from adcs_sim.truth import kernel
from adcs_sim.truth.kernel import WHEELS, WORK_SIZE, control_torque_row, kernel_rows, rk4_period, stage_times

ENABLED = os.environ.get('ADCS_FUSED_LOOP', '1') != '0'
NS_PER_S = 1_000_000_000


@njit(parallel=True, cache=True, error_model='numpy', nogil=True)
def closed_loop(x0, n_steps, t_k, times, h, law, inertia, q_ref, w_ref, shortest, alloc, limit, mode, cw,
                params, cmds, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr, env,
                sw, hq, hw, hu, hs, x_end, done, failed):
    """Every run r from x0[r] for n_steps[r] control steps (or to its first non-finite step):
    step i at t_k[i], RK4 stage times times[i] of step h. ``law[r]`` = (kp, kd); the wheel
    commands go to cmds[r][cw:], their speed-mode flags (0: torque mode) after them. Records into
    hq, hw, hu, hs (wheel speeds: the state at sw), NaN after the run's last step (they need not be
    filled before); x_end, done, failed per run."""
    n_runs, n_states = x0.shape
    width = max(3, counts.max())
    n_wheels = alloc.shape[0]
    for r in prange(n_runs):
        p, c = params[r], cmds[r].copy()
        xr = x0[r].copy()
        k = np.empty((4, n_states))
        xs = np.empty(n_states)
        wk = np.empty(WORK_SIZE)
        aux = np.empty((max(1, kinds.size), width))
        qm, u = np.empty(4), np.empty(3)
        steps, bad = 0, False
        for i in range(n_steps[r]):
            normalize_row(xr, 0, qm)
            pd_torque_row(qm, xr, 4, inertia[r], law[r, 0], law[r, 1], q_ref[r], w_ref[r], shortest, u)
            wheel_command_row(u, alloc, limit[r], mode, c, cw)
            for j in range(n_wheels):
                c[cw + n_wheels + j] = 0.0
            ub = hu[r, i]
            control_torque_row(t_k[i], xr, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags,
                               thr, wk, aux, ub, 0)
            rk4_period(xr, k, xs, times[i], h, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail,
                       flags, env, False, env, 0.0, False, thr, wk, aux)
            finite = True
            for e in range(n_states):
                finite = finite and np.isfinite(xr[e])
            for e in range(3):
                finite = finite and np.isfinite(ub[e])
            for e in range(4):
                hq[r, i + 1, e] = xr[e]
            for e in range(3):
                hw[r, i + 1, e] = xr[4 + e]
            for j in range(hs.shape[2]):
                hs[r, i + 1, j] = xr[sw + j]
            steps = i + 1
            if not finite:
                bad = True
                break
        done[r], failed[r] = steps, bad
        for e in range(n_states):
            x_end[r, e] = xr[e]
        for i in range(steps, hu.shape[1]):   # no sample after the run's end (the history is np.empty)
            for e in range(3):
                hu[r, i, e] = np.nan
            for e in range(4):
                hq[r, i + 1, e] = np.nan
            for e in range(3):
                hw[r, i + 1, e] = np.nan
            for j in range(hs.shape[2]):
                hs[r, i + 1, j] = np.nan


@functools.lru_cache(maxsize=8)
def _grid(period_ns: int, K: int, max_step: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The control steps' times t_k (K,), their RK4 stage times (K, n, 3) and step h, as the general
    path computes them step by step; kept for the next chunk of a campaign (read, never written)."""
    period = period_ns / NS_PER_S
    t_k = np.array([(k * period_ns) / NS_PER_S for k in range(K)])
    grids = [stage_times(t, period, max_step) for t in t_k]
    return t_k, (np.stack([g[0] for g in grids]) if K else np.zeros((0, 1, 3))), (grids[0][1] if K else period)


class FusedLoop:
    """A batch's arguments of :func:`closed_loop` (built by :func:`plan`)."""

    def __init__(self, sim, plant_args: tuple) -> None:
        """``plant_args``: the kernel's packed plant arguments (``KernelPlan._inputs(...)[1]``)."""
        N, law, act, plant = sim.n_runs, sim.law, sim.actuation, sim.plant
        n = len(act.wheel_names)

        def as_rows(value, shape: tuple) -> np.ndarray:   # one row per run, contiguous and writable
            return kernel_rows(np.broadcast_to(np.asarray(value, dtype=float), (N,) + shape))
        self.law = np.stack([as_rows(law.kp, ()), as_rows(law.kd, ())], axis=1)
        self.inertia = as_rows(law.inertia, (3, 3)).reshape(N, 9)
        self.q_ref, self.w_ref = as_rows(law.q_ref, (4,)), as_rows(law.w_ref, (3,))
        self.alloc = np.ascontiguousarray(act.allocation, dtype=float)
        self.limit = as_rows(act.limit, (n,))
        self.mode = CLIP if act.saturation == 'clip' else SCALE
        self.plant_args = plant_args
        wheel_index = [a.name for a in plant.kernel.actuators].index(sim.wheels.name)
        self.cw = int(self.plant_args[5][wheel_index])
        self.sw = plant.slices[sim.wheels.name].start
        self.t_k, self.times, self.h = _grid(int(sim.period_ns), int(sim.n_steps.max()), float(sim.max_step))

    def run(self, sim, x0: np.ndarray, hist: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Simulate into ``hist`` (sim._history's arrays); (done steps, failed, final states) per run."""
        N = x0.shape[0]
        x_end = np.empty_like(x0)
        done, failed = np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.bool_)
        threads = numba.config.NUMBA_NUM_THREADS if N >= kernel.PARALLEL_MIN_RUNS else 1
        if numba.get_num_threads() != threads:
            numba.set_num_threads(threads)
        closed_loop(np.ascontiguousarray(x0), sim.n_steps, self.t_k, self.times, self.h, self.law, self.inertia,
                    self.q_ref, self.w_ref, bool(sim.law.shortest_path), self.alloc, self.limit, self.mode,
                    self.cw, *self.plant_args, np.zeros((1, 3, 3)), self.sw, hist['q'], hist['w'], hist['u'],
                    hist['speed'], x_end, done, failed)
        return done, failed, x_end


def plan(sim, x0: np.ndarray, progress=None, observe=None) -> FusedLoop | None:
    """The fused loop of batch ``sim`` (a :class:`~adcs_sim.app.batch.engine.BatchSimulation`) from states
    ``x0``, or None when it does not apply (module docstring): the general path runs then."""
    plant, act = sim.plant, sim.actuation
    if not ENABLED or progress is not None or observe is not None or type(sim.law) is not PdLaw:
        return None
    if not isinstance(act, WheelActuation) or sim.wheels is None or sim.thrusters is not None \
            or plant.kernel is None:
        return None
    if sim.estimator is not None or sim.feedback != 'state' or sim.measurement.active or sim.sensors is not None:
        return None
    if sim.fault_schedule or plant.disturbance is not None or plant.gravity_gradient:
        return None
    if list(act.wheel_names) != list(sim.wheels.names) or np.ndim(act.allocation) != 2 \
            or np.ndim(sim.law.inertia) not in (2, 3) or act.saturation not in ('clip', 'scale'):
        return None
    inputs = plant.kernel._inputs(plant, x0, plant.zero_commands()) if WHEELS in plant.kernel.kinds else None
    if inputs is None:
        return None
    return FusedLoop(sim, inputs[1])
