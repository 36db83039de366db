"""Compiled RK4 kernel of :class:`adcs_sim.truth.plant.Plant` (numba; no ROS).

One code path for the single run (a graph's dynamics node, ``adcs-run``) and the batch engine: the
plant's fixed-step RK4 over one zero-order-hold period, for every run of a batch, written as scalar
loops and compiled by numba. The batch axis stays: runs are independent iterations of a ``prange``
loop (all threads for a large batch, one thread otherwise; one compiled function).

Bit for bit the numpy plant
---------------------------
Every operation is the numpy code's, in the numpy code's order (:mod:`adcs_sim.truth.plant`):
``matvec`` sums its terms left to right from the first product, ``cross`` is
``a[1] b[2] - a[2] b[1], ...``, numpy's sums over 3 or 4 components are sequential (checked on
batches of 1 and 1000), ``np.minimum`` / ``np.maximum`` / ``np.clip`` propagate NaN, ``np.sign``
is 0 at 0 and NaN at NaN, boolean factors multiply as 0.0 / 1.0. numba compiles without
``fastmath`` (no reassociation, no FMA contraction: LLVM only fuses multiply-adds flagged
``contract``, which numba sets only under fastmath) and with ``error_model='numpy'`` (a division by
zero gives inf/NaN as numpy does instead of raising). What numpy computes with transcendental
functions stays numpy's: the disturbance ``c + A sin(f t + phi)`` is evaluated by
:class:`~adcs_sim.truth.plant.Disturbance` at each stage time before the call, and the orbit
position (``math.sin``/``math.cos`` of Python floats) likewise; the kernel only does + - * / and
sqrt, which IEEE 754 rounds exactly. ``tests/test_plant_kernel.py`` compares the two paths bit for
bit; the reproduction tests compare every committed bag with its batch run.

Checked on the development machine (x86-64 with FMA, AVX2, AVX-512; numba 0.68.1, llvmlite 0.50.0):
the compiled kernels' assembly holds no FMA instruction and their LLVM IR no fast-math flag and no
``llvm.fma`` / ``llvm.fmuladd`` (``inspect_asm`` / ``inspect_llvm`` of a fresh compilation).

Compilation is cached (``cache=True``: next to this file, or under ``NUMBA_CACHE_DIR``), so a
node's start-up loads machine code instead of compiling it.

Data layout (built by :class:`KernelPlan`, one row per run): ``params[r]`` = body inertia inverse
(9), ``J_s`` (9), ``J`` (9), then per actuator its block; ``cmds[r]`` per actuator its command.
Actuators are kinds ``WHEELS``, ``TORQUERS``, ``THRUSTERS`` in the plant's order (the sums over
actuators are in that order too).
"""
from __future__ import annotations

import math
import os

import numba
import numpy as np
from numba import njit, prange

from adcs_core import compile_log  # noqa: F401 - a compilation prints one line (kernel, types, seconds)
from adcs_sim.truth.kernel_kinds import THRUSTERS, TORQUERS, WHEELS

# ADCS_PLANT_KERNEL=0 builds plants without the kernel (numpy path; same numbers, for comparison).
ENABLED = os.environ.get('ADCS_PLANT_KERNEL', '1') != '0'
_JIT = dict(cache=True, error_model='numpy', nogil=True)
_INNER = dict(_JIT, inline='always')  # inlined into the RK4 loop: no call or array refcount traffic


@njit(**_INNER)
def _max(a, b):
    """np.maximum: NaN if either is NaN."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@njit(**_INNER)
def _min(a, b):
    """np.minimum: NaN if either is NaN."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


@njit(**_INNER)
def _sign(a):
    if a > 0.0:
        return 1.0
    if a < 0.0:
        return -1.0
    if a == 0.0:
        return 0.0
    return a


# Work buffer of one run (no array views in the loop: each would cost reference counting):
# H, tau, actuator torque, actuator momentum, cross products, then the gravity gradient's temporaries.
_H, _TAU, _TA, _HM, _CW, _GT, _GC, _GJC, _GV, _WORK = 0, 3, 6, 9, 12, 15, 18, 21, 24, 27
WORK_SIZE = _WORK  # the length of a run's work buffer (callers of rk4_period, control_torque_row)


@njit(**_INNER)
def _matvec3(M, o, v, vo, out, oo):
    """out[oo:oo+3] = M v for the 3 x 3 matrix row-major at M[o:o+9], v at v[vo:vo+3] (matvec's order)."""
    for i in range(3):
        out[oo + i] = (M[o + 3 * i] * v[vo] + M[o + 3 * i + 1] * v[vo + 1]) + M[o + 3 * i + 2] * v[vo + 2]


@njit(**_INNER)
def _cross(a, ao, b, bo, out, oo):
    c0 = a[ao + 1] * b[bo + 2] - a[ao + 2] * b[bo + 1]
    c1 = a[ao + 2] * b[bo] - a[ao] * b[bo + 2]
    c2 = a[ao] * b[bo + 1] - a[ao + 1] * b[bo]
    out[oo], out[oo + 1], out[oo + 2] = c0, c1, c2


@njit(**_INNER)
def _gravity_gradient(p, x, pos, i, ts, factor, wk):
    """Orbit.gravity_gradient into wk[_TA]: c = rotate_to_body(q, v) with v = -position (negated
    by the caller), then factor * c x (J c)."""
    for j in range(3):
        wk[_GV + j] = pos[i, ts, j]
    _cross(wk, _GV, x, 0, wk, _GT)
    for j in range(3):
        wk[_GT + j] = 2.0 * wk[_GT + j]
    _cross(wk, _GT, x, 0, wk, _GC)
    for j in range(3):
        wk[_GC + j] = (wk[_GV + j] + x[3] * wk[_GT + j]) + wk[_GC + j]
    _matvec3(p, 18, wk, _GC, wk, _GJC)
    _cross(wk, _GC, wk, _GJC, wk, _TA)
    for j in range(3):
        wk[_TA + j] = factor * wk[_TA + j]


@njit(**_INNER)
def _wheel_torque(x, s, p, o, c, oc, n, axes, bias, stuck, avail, flags, aux, a, wk):
    """ReactionWheels.torque: motor (+ friction) torque per wheel in aux[a], body torque in wk[_TA]."""
    faulty, friction, limited = flags[0], flags[1], flags[2]
    for j in range(n):
        speed = x[s + j]
        value = c[oc + j]
        if c[oc + n + j] != 0.0:
            value = (p[o + j] * p[o + 5 * n + j]) * (value - speed)
        lim = p[o + n + j]
        tau = _min(_max(value, -lim), lim)
        if faulty:
            tau = tau + bias[j]
        if limited and abs(speed) >= p[o + 2 * n + j] and tau * speed > 0.0:
            tau = 0.0
        if faulty and stuck[j]:
            tau = 0.0
        tau = tau * (1.0 if avail[j] else 0.0)
        if friction:
            tau = tau + ((-p[o + 3 * n + j]) * speed - p[o + 4 * n + j] * _sign(speed))
            if faulty and stuck[j]:
                tau = 0.0
        aux[a, j] = tau
    for i in range(3):
        acc = axes[0, i] * aux[a, 0]
        for j in range(1, n):
            acc = acc + axes[j, i] * aux[a, j]
        wk[_TA + i] = -acc


@njit(**_INNER)
def _wheel_momentum(x, s, p, o, n, axes, wk):
    """ReactionWheels.momentum into wk[_HM]."""
    for i in range(3):
        acc = 0.0
        for j in range(n):
            absolute = x[s + j] + ((axes[j, 0] * x[4] + axes[j, 1] * x[5]) + axes[j, 2] * x[6])
            term = axes[j, i] * (absolute * p[o + j])
            acc = term if j == 0 else acc + term
        wk[_HM + i] = acc


@njit(**_INNER)
def _thruster_torque(t, p, o, c, oc, m, thr, aux, a, wk):
    """Thrusters.torque: forces (lit x max force) in aux[a], body torque T f in wk[_TA]."""
    start, period, tol = thr[0], thr[1], thr[2]
    rel = t - start
    for k in range(m):
        on = c[oc + k]
        lit = (rel >= -tol) and ((rel < on) or ((on >= period) and (rel <= period + tol)))
        aux[a, k] = (1.0 if lit else 0.0) * p[o + 3 * m + k]
    for i in range(3):
        acc = p[o + i * m] * aux[a, 0]
        for k in range(1, m):
            acc = acc + p[o + i * m + k] * aux[a, k]
        wk[_TA + i] = acc


@njit(**_INNER)
def _actuators(t, x, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr, wk, aux):
    """The actuator loop of Plant.derivative: H += momentum, tau += torque, in the plant's order."""
    for a in range(kinds.size):
        kind, s, o, oc, n = kinds[a], soff[a], poff[a], coff[a], counts[a]
        if kind == WHEELS:
            _wheel_momentum(x, s, p, o, n, axes, wk)
            _wheel_torque(x, s, p, o, c, oc, n, axes, bias, stuck, avail, flags, aux, a, wk)
        else:
            for i in range(3):
                wk[_HM + i] = 0.0
            if kind == TORQUERS:
                for i in range(3):
                    wk[_TA + i] = _min(_max(c[oc + i], -p[o + i]), p[o + i])
            else:
                _thruster_torque(t, p, o, c, oc, n, thr, aux, a, wk)
        for i in range(3):
            wk[_H + i] = wk[_H + i] + wk[_HM + i]
            wk[_TAU + i] = wk[_TAU + i] + wk[_TA + i]


@njit(**_INNER)
def _derivative(t, x, k, stage, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags,
                env, env_on, pos, i_step, ts, gg_factor, gg_on, thr, wk, aux):
    """Plant.derivative of one run at time t into k[stage] (env/pos[i_step, ts]: this stage's
    disturbance and orbit position)."""
    _matvec3(p, 9, x, 4, wk, _H)
    for i in range(3):
        wk[_TAU + i] = 0.0
    if env_on:
        for i in range(3):
            wk[_TAU + i] = wk[_TAU + i] + env[i_step, ts, i]
    if gg_on:
        _gravity_gradient(p, x, pos, i_step, ts, gg_factor, wk)
        for i in range(3):
            wk[_TAU + i] = wk[_TAU + i] + wk[_TA + i]
    _actuators(t, x, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr, wk, aux)
    _cross(x, 4, wk, _H, wk, _CW)
    for i in range(3):
        wk[_CW + i] = wk[_TAU + i] - wk[_CW + i]
    for i in range(3):  # wdot = matvec(body inertia inverse, tau - w x H)
        k[stage, 4 + i] = (p[3 * i] * wk[_CW] + p[3 * i + 1] * wk[_CW + 1]) + p[3 * i + 2] * wk[_CW + 2]
    _cross(x, 4, x, 0, wk, _CW)
    for i in range(3):
        k[stage, i] = 0.5 * (x[3] * x[4 + i] - wk[_CW + i])
    k[stage, 3] = -0.5 * ((x[4] * x[0] + x[5] * x[1]) + x[6] * x[2])
    for a in range(kinds.size):
        kind, s, o, n = kinds[a], soff[a], poff[a], counts[a]
        if kind == WHEELS:
            for j in range(n):
                wdot = (axes[j, 0] * k[stage, 4] + axes[j, 1] * k[stage, 5]) + axes[j, 2] * k[stage, 6]
                accel = aux[a, j] / p[o + j] - wdot
                if flags[0] and stuck[j]:
                    accel = 0.0
                k[stage, s + j] = accel
                k[stage, s + n + j] = x[s + j]
        elif kind == THRUSTERS:
            for j in range(n):
                k[stage, s + j] = aux[a, j]


@njit(**_INNER)
def rk4_period(xr, k, xs, times, h, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags,
               env, env_on, pos, gg_factor, gg_on, thr, wk, aux):
    """Plant.step of one run's state xr (updated in place): len(times) RK4 steps of h, stage times
    times[i] = (t_i, t_i + h/2, t_i + h), quaternion renormalised after each (k (4, n_states), xs
    (n_states,): work arrays). Also the fused closed loop's (:mod:`adcs_sim.app.batch.fused`)."""
    n_states = xr.size
    half, sixth, third = 0.5 * h, h / 6.0, h / 3.0
    for i in range(times.shape[0]):
        for stage in range(4):
            ts = 0 if stage == 0 else (1 if stage < 3 else 2)
            if stage == 0:
                for e in range(n_states):
                    xs[e] = xr[e]
            else:
                step = half if stage < 3 else h
                for e in range(n_states):
                    xs[e] = xr[e] + step * k[stage - 1, e]
            _derivative(times[i, ts], xs, k, stage, p, c, kinds, soff, poff, coff, counts, axes, bias,
                        stuck, avail, flags, env, env_on, pos, i, ts, gg_factor, gg_on, thr, wk, aux)
        for e in range(n_states):
            xr[e] = (xr[e] + sixth * (k[0, e] + k[3, e])) + third * (k[1, e] + k[2, e])
        norm = np.sqrt(((xr[0] * xr[0] + xr[1] * xr[1]) + xr[2] * xr[2]) + xr[3] * xr[3])
        for e in range(4):
            xr[e] = xr[e] / norm


def _rk4_runs(x, out, times, h, params, cmds, kinds, soff, poff, coff, counts, axes, bias, stuck, avail,
              flags, env, env_on, pos, gg_factor, gg_on, thr):
    """Plant.step for every run r (rows of x): :func:`rk4_period` of each."""
    n_runs, n_states = x.shape
    width = max(3, counts.max()) if counts.size else 3
    for r in prange(n_runs):
        p, c = params[r], cmds[r]
        xr = x[r].copy()
        k = np.empty((4, n_states))
        xs = np.empty(n_states)
        wk = np.empty(_WORK)
        aux = np.empty((max(1, kinds.size), width))
        rk4_period(xr, k, xs, times, h, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags,
                   env, env_on, pos, gg_factor, gg_on, thr, wk, aux)
        for e in range(n_states):
            out[r, e] = xr[e]


@njit(**_INNER)
def control_torque_row(t, x, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr, wk, aux,
                       out, oo):
    """Plant.control_torque of one run into out[oo:oo+3] (the sum from 0.0 in the plant's order)."""
    for i in range(_WORK):
        wk[i] = 0.0
    _actuators(t, x, p, c, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr, wk, aux)
    for i in range(3):
        out[oo + i] = wk[_TAU + i]


@njit(**_JIT)
def torque_runs(x, out, t, params, cmds, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr):
    """Plant.control_torque for every run: the actuators' body torque at (t, x) under the commands
    (the sum from 0.0 in the plant's order, no environment torque)."""
    width = max(3, counts.max()) if counts.size else 3
    wk = np.zeros(_WORK)
    aux = np.empty((max(1, kinds.size), width))
    for r in range(x.shape[0]):
        control_torque_row(t, x[r], params[r], cmds[r], kinds, soff, poff, coff, counts, axes, bias, stuck, avail,
                           flags, thr, wk, aux, out[r], 0)


# The RK4 loop is compiled once, as a parallel (prange) loop, and run on one thread or on all of
# them per call. Compiled without parallel=True the same source ran 3-5x slower per step (measured
# 2.0 against 0.36 µs per RK4 step, body + 3 wheels, one thread each: the serial compilation kept
# array reference counting in the loop).
rk4_runs = njit(parallel=True, **_JIT)(_rk4_runs)
# Item dimensions of each kind's parameter arrays, in KernelPlan._param_arrays' order.
_ITEM_NDIMS = {WHEELS: (1,) * 6, TORQUERS: (1,), THRUSTERS: (2, 1)}

# A call runs on all threads only with enough work (runs x RK4 steps): waking the worker threads
# costs more, on a loaded 2-core machine, than a 125-run chunk's step (measured: a 250-run campaign
# 2.9 s on one thread against 5-19 s threaded, benchmarks/montecarlo_speed.py).
PARALLEL_MIN_RUNS = 256
PARALLEL_MIN_WORK = 8192


def kernel_rows(a) -> np.ndarray:
    """``a`` as the one array type the compiled kernels are specialised for: float64, C-contiguous,
    writable. A read-only view (``np.broadcast_to`` of a per-run value) is copied: numba would compile
    a kernel once more for it (minutes), the copy costs microseconds and holds the same bits."""
    return np.require(a, np.float64, ('C', 'W'))


def stage_times(t: float, period: float, max_step: float) -> tuple[np.ndarray, float]:
    """Plant.step's grid: ``ceil(period / max_step)`` steps of ``h``; times (n, 3) as it computes
    them (``t + i h``, ``+ h/2``, ``+ h``)."""
    n = max(1, math.ceil(period / max_step - 1e-9))
    h = period / n
    if n <= 16:  # a control period's few steps: Python floats are cheaper than array calls
        half = 0.5 * h
        return np.array([(ti, ti + half, ti + h) for ti in (t + i * h for i in range(n))]), h
    ti = t + np.arange(n) * h  # t + (i h), each rounded as the Python expression
    return np.stack([ti, ti + 0.5 * h, ti + h], axis=1), h


class KernelPlan:
    """What the kernel needs of a plant: its actuators' kinds and offsets; parameters packed per
    batch shape (cached while the plant's parameter arrays are the same objects), commands and
    fault state read at every call. :meth:`of` gives None for a plant the kernel cannot step (an
    actuator without ``kernel_kind``, two actuators of one kind): it keeps the numpy path."""

    def __init__(self, plant) -> None:
        self.actuators = list(plant.actuators)
        self.kinds = np.array([a.kernel_kind for a in self.actuators], dtype=np.int64)
        self.soff = np.array([plant.slices[a.name].start for a in self.actuators], dtype=np.int64)
        self.counts = np.array([0 if k == TORQUERS else a.count for a, k in zip(self.actuators, self.kinds)],
                               dtype=np.int64)
        self.wheels = next((a for a, k in zip(self.actuators, self.kinds) if k == WHEELS), None)
        self.thrusters = next((a for a, k in zip(self.actuators, self.kinds) if k == THRUSTERS), None)
        self._cache_key: tuple = ()
        self._packed = None
        self._no_environment = np.zeros((0, 3, 3))
        self._last = None  # (x, commands, their values, _inputs of them): control_torque's, for step

    @classmethod
    def of(cls, plant) -> 'KernelPlan | None':
        kinds = [getattr(a, 'kernel_kind', None) for a in plant.actuators]
        if not ENABLED or None in kinds or len(set(kinds)) != len(kinds):
            return None
        if plant.disturbance is not None and plant.disturbance.batched:   # one environment for every run
            return None
        if plant.gravity_gradient and not hasattr(plant.orbit, 'mean_motion'):   # an SGP4 orbit: numpy's
            return None
        return cls(plant)

    def warm(self, plant) -> None:
        """One step and one torque of the plant at rest with zero commands: loads (or, on a cold
        cache, compiles) the machine code, so a node pays it at start-up rather than in its first step."""
        x = plant.initial_state(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
        commands = plant.zero_commands()
        with np.errstate(all='ignore'):
            self.step(plant, 0.0, x, commands, 1.0, 1.0)
            self.control_torque(plant, 0.0, x, commands)

    def _param_arrays(self, plant) -> list:
        arrays = [plant.body_inertia_inverse(), plant.inertia_struct, plant.inertia]
        for a, kind in zip(self.actuators, self.kinds):
            if kind == WHEELS:
                arrays += [a.spin_inertia, a._limit, a.max_speed, a.viscous, a.coulomb, a.speed_gain]
            elif kind == TORQUERS:
                arrays.append(a.max_torque)
            else:
                arrays += [a.torque_matrix, a.max_force]
        return arrays

    def _params(self, plant, batch: tuple) -> tuple[np.ndarray, np.ndarray] | None:
        arrays = self._param_arrays(plant)
        key = (batch, *arrays)
        old = self._cache_key
        if len(key) == len(old) and key[0] == old[0] and all(a is b for a, b in zip(key[1:], old[1:])):
            return self._packed
        self._packed = None
        self._cache_key = key
        n_runs = math.prod(batch)
        rows = [_rows(arr, batch, 2, n_runs) for arr in arrays[:3]]
        poff, at, i = [], 27, 3
        for kind in self.kinds:
            poff.append(at)
            for item_ndim in _ITEM_NDIMS[int(kind)]:
                rows.append(_rows(arrays[i], batch, item_ndim, n_runs))
                at += rows[-1].shape[1] if rows[-1] is not None else 0
                i += 1
        if any(r is None for r in rows):
            return None
        self._packed = (np.ascontiguousarray(np.concatenate(rows, axis=1)), np.array(poff, dtype=np.int64))
        return self._packed

    def _commands(self, commands: dict, batch: tuple, n_runs: int):
        parts, coff, at, thr = [], [], 0, np.array([0.0, math.inf, 0.0])
        for a, kind in zip(self.actuators, self.kinds):
            cmd = commands[a.name]
            coff.append(at)
            if kind == WHEELS:
                parts += [_rows(cmd.value, batch, 1, n_runs), _rows(cmd.speed_mode, batch, 1, n_runs)]
            elif kind == TORQUERS:
                parts.append(_rows(cmd, batch, 1, n_runs))
            else:
                parts.append(_rows(cmd.on_time, batch, 1, n_runs))
                period = cmd.period
                thr = np.array([cmd.start, period, 1e-9 * period if math.isfinite(period) else 0.0])
            if any(p is None for p in parts):
                return None
            at += sum(p.shape[1] for p in parts[len(parts) - (2 if kind == WHEELS else 1):])
        cmds = np.concatenate(parts, axis=1) if parts else np.zeros((n_runs, 1))
        return np.ascontiguousarray(cmds, dtype=float), np.array(coff, dtype=np.int64), thr

    def _environment(self, plant, times: np.ndarray):
        shape = times.shape + (3,)
        if plant.disturbance is None and not plant.gravity_gradient:
            if self._no_environment.shape != shape:  # read only by the kernel: one zero array is enough
                self._no_environment = np.zeros(shape)
            return self._no_environment, self._no_environment, 0.0
        env, pos, factor = np.zeros(shape), np.zeros(shape), 0.0
        if plant.disturbance is not None:
            for i, s in np.ndindex(times.shape):
                env[i, s] = plant.disturbance.torque(times[i, s])
        if plant.gravity_gradient:
            orbit = plant.orbit
            factor = 3.0 * orbit.mean_motion ** 2
            for i, s in np.ndindex(times.shape):
                pos[i, s] = -orbit.position_unit(times[i, s])
        return env, pos, factor

    def _wheel_state(self):
        w = self.wheels
        if w is None:
            return np.zeros((1, 3)), np.zeros(1), np.zeros(1, dtype=np.bool_), np.ones(1, dtype=np.bool_), \
                np.zeros(3, dtype=np.bool_)
        if w.bias.ndim != 1 or w.stuck.ndim != 1 or w.available.ndim != 1:
            return None
        flags = np.array([w._faulty, w._has_friction, w._speed_limited], dtype=np.bool_)
        return (w.axes, np.asarray(w.bias, dtype=float), np.asarray(w.stuck, dtype=np.bool_),
                np.asarray(w.available, dtype=np.bool_), flags)

    def _inputs(self, plant, x, commands: dict):
        """(runs' states (n_runs, n_states), the shared arguments of both kernels) or None."""
        x = np.asarray(x)
        if x.dtype != np.float64 or x.ndim < 1 or x.shape[-1] != plant.n_states:
            return None
        batch = x.shape[:-1]
        n_runs = math.prod(batch)
        packed, cmd, wheel = self._params(plant, batch), self._commands(commands, batch, n_runs), self._wheel_state()
        if packed is None or cmd is None or wheel is None or n_runs == 0:
            return None
        (params, poff), (cmds, coff, thr) = packed, cmd
        axes, bias, stuck, avail, flags = wheel
        xr = np.ascontiguousarray(x.reshape(n_runs, plant.n_states))
        return xr, (params, cmds, self.kinds, self.soff, poff, coff, self.counts, np.ascontiguousarray(axes),
                    bias, stuck, avail, flags, thr)

    def _inputs_after_torque(self, plant, x, commands: dict):
        """:meth:`_inputs`, taken from the :meth:`control_torque` call just before when it had the same
        state and commands (the same objects: the dynamics node and the batch engine compute a
        period's torque, then step it; commands are replaced, never changed in place): a period's
        inputs are packed once. Used once, then forgotten."""
        last, self._last = self._last, None
        if last is not None and last[0] is x and last[1] is commands and len(last[2]) == len(commands) \
                and all(a is b for a, b in zip(last[2], commands.values())):
            return last[3]
        return self._inputs(plant, x, commands)

    def step(self, plant, t: float, x, commands: dict, period: float, max_step: float) -> np.ndarray | None:
        """Plant.step through the kernel, or None where it cannot (the caller steps with numpy)."""
        inputs = self._inputs_after_torque(plant, x, commands)
        if inputs is None:
            return None
        xr, (params, cmds, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags, thr) = inputs
        times, h = stage_times(t, period, max_step)
        env, pos, factor = self._environment(plant, times)
        out = np.empty_like(xr)
        threaded = len(xr) >= PARALLEL_MIN_RUNS and len(xr) * len(times) >= PARALLEL_MIN_WORK
        threads = numba.config.NUMBA_NUM_THREADS if threaded else 1
        if numba.get_num_threads() != threads:
            numba.set_num_threads(threads)
        rk4_runs(xr, out, times, h, params, cmds, kinds, soff, poff, coff, counts, axes, bias, stuck, avail, flags,
               env, plant.disturbance is not None, pos, factor, bool(plant.gravity_gradient), thr)
        return out.reshape(np.shape(x))

    def control_torque(self, plant, t: float, x, commands: dict) -> np.ndarray | None:
        """Plant.control_torque through the kernel (batch + (3,)), or None where it cannot."""
        inputs = self._inputs(plant, x, commands)
        self._last = (x, commands, tuple(commands.values()), inputs)
        if inputs is None:
            return None
        xr, args = inputs
        out = np.empty((len(xr), 3))
        torque_runs(xr, out, float(t), *args)
        return out.reshape(np.shape(x)[:-1] + (3,))


def _rows(value, batch: tuple, item_ndim: int, n_runs: int) -> np.ndarray | None:
    """``value`` (batch' + item) broadcast to ``batch + item`` as float rows (n_runs, item size);
    None if its batch axes do not broadcast to ``batch`` (the numpy path decides then)."""
    arr = np.asarray(value, dtype=float)
    item = arr.shape[arr.ndim - item_ndim:] if arr.ndim >= item_ndim else None
    if item is None:
        return None
    if arr.shape != batch + item:
        try:
            arr = np.broadcast_to(arr, batch + item)
        except ValueError:
            return None
    return arr.reshape(n_runs, -1)
