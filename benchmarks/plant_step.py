#!/usr/bin/env python3
"""The plant alone: µs per RK4 step of a body with three wheels, and the batch kernel's throughput.

Issue 18's plant benchmark. The body is the showcase's (``config/uosat12_gsmn.yaml``: UoSAT-12's
inertia, three wheels on the principal axes, 20 mN m, 5000 rpm), wheels in torque mode with
constant commands. Measured in one run, alternating, ``--repeat`` times (medians; the machine is
shared, read the ratios):

(a) **kernel**: ``Plant.step`` (the compiled kernel, :mod:`adcs_sim.truth.kernel`) as the dynamics
    node calls it, one 1 s control period of four 0.25 s RK4 steps per call (so each call also
    pays the Python side: packing commands, dispatch);
(b) **kernel, long call**: one call of ``--steps`` RK4 steps (the compiled loop alone);
(c) **numpy**: ``Plant.step_numpy``, the previous array code, called as (a);
(d) **scalar Python**: the same RK4 and derivative on plain floats (:func:`scalar_step`), called as
    (a): the alternative the issue names for the single run;
(e) **batch**: the kernel on ``--runs`` runs (default 1000) at once, runs·steps/s, against the
    numpy batch path on the same runs.

Every path is checked to give the kernel's numbers bit for bit. ``--basilisk`` also times
Basilisk 2.12.1 (``bsk``, installed into a throwaway venv under /tmp on first use,
:mod:`bsk_support`) on the same body + 3 wheels RK4 step in the same run and prints
``ratio = Basilisk µs / ours``; it says so when Basilisk cannot be installed or run.
JAX was not tried (a 100 MB jaxlib download; XLA's CPU backend contracts multiply-adds into FMA by
default, so the bit-for-bit requirement would need extra flags to check).
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bsk_support import basilisk_python, run_child  # noqa: E402

from adcs_sim.truth.plant import Plant, ReactionWheels, WheelCommand  # noqa: E402

INERTIA = (40.45, 42.09, 42.36)
SPIN, LIMIT, MAX_SPEED = 0.01, 0.02, 523.6
COMMAND = np.array([0.01, -0.005, 0.002])
PERIOD, H = 1.0, 0.25


def make_plant(batch: int = 0) -> tuple[Plant, np.ndarray, dict]:
    J = np.diag(INERTIA) if not batch else np.diag(INERTIA) * (1.0 + 0.01 * np.arange(batch))[:, None, None]
    wheels = ReactionWheels(['rw_x', 'rw_y', 'rw_z'], np.eye(3), [SPIN] * 3, [LIMIT] * 3, [MAX_SPEED] * 3)
    plant = Plant(J, [wheels])
    x = plant.initial_state([0.2236068, 0.2236068, 0.2236068, 0.9219544], [0.01, -0.02, 0.03])
    if batch:
        x = np.array(np.broadcast_to(x, (batch, plant.n_states)))
    value = COMMAND if not batch else np.broadcast_to(COMMAND, (batch, 3))
    return plant, x, {'wheels': WheelCommand(value, np.zeros(3, dtype=bool))}


# --- the scalar alternative: plain Python floats, the numpy code's operation order -----------

def _derivative(x: list, Js: list, Jinv: list, tau_cmd: list) -> list:
    q0, q1, q2, q3, w0, w1, w2 = x[:7]
    speed = x[7:10]
    H = [Js[0] * w0 + Js[1] * w1 + Js[2] * w2, Js[3] * w0 + Js[4] * w1 + Js[5] * w2,
         Js[6] * w0 + Js[7] * w1 + Js[8] * w2]
    tau_w = []
    for j in range(3):
        tau = min(max(tau_cmd[j], -LIMIT), LIMIT)
        if abs(speed[j]) >= MAX_SPEED and tau * speed[j] > 0.0:
            tau = 0.0
        tau_w.append(tau * 1.0)
    w = (w0, w1, w2)
    hm = [SPIN * (speed[i] + w[i]) for i in range(3)]  # axes = identity: only the diagonal terms
    H = [H[i] + (((1.0 if i == 0 else 0.0) * hm[0] + (1.0 if i == 1 else 0.0) * hm[1]) +
                 (1.0 if i == 2 else 0.0) * hm[2]) for i in range(3)]
    ta = [-(((1.0 if i == 0 else 0.0) * tau_w[0] + (1.0 if i == 1 else 0.0) * tau_w[1]) +
            (1.0 if i == 2 else 0.0) * tau_w[2]) for i in range(3)]
    tau = [0.0 + ta[i] for i in range(3)]
    c = (w1 * H[2] - w2 * H[1], w2 * H[0] - w0 * H[2], w0 * H[1] - w1 * H[0])
    r = [tau[i] - c[i] for i in range(3)]
    wd = [(Jinv[3 * i] * r[0] + Jinv[3 * i + 1] * r[1]) + Jinv[3 * i + 2] * r[2] for i in range(3)]
    cq = (w1 * q2 - w2 * q1, w2 * q0 - w0 * q2, w0 * q1 - w1 * q0)
    dq = [0.5 * (q3 * w[i] - cq[i]) for i in range(3)] + [-0.5 * ((w0 * q0 + w1 * q1) + w2 * q2)]
    accel = [tau_w[j] / SPIN - (((1.0 if j == 0 else 0.0) * wd[0] + (1.0 if j == 1 else 0.0) * wd[1]) +
                                (1.0 if j == 2 else 0.0) * wd[2]) for j in range(3)]
    return dq + wd + accel + list(speed)


def scalar_step(x: list, Js: list, Jinv: list, tau_cmd: list, period: float, max_step: float) -> list:
    n = max(1, math.ceil(period / max_step - 1e-9))
    h = period / n
    half, sixth, third = 0.5 * h, h / 6.0, h / 3.0
    for _ in range(n):
        k1 = _derivative(x, Js, Jinv, tau_cmd)
        k2 = _derivative([a + half * b for a, b in zip(x, k1)], Js, Jinv, tau_cmd)
        k3 = _derivative([a + half * b for a, b in zip(x, k2)], Js, Jinv, tau_cmd)
        k4 = _derivative([a + h * b for a, b in zip(x, k3)], Js, Jinv, tau_cmd)
        x = [(a + sixth * (b1 + b4)) + third * (b2 + b3) for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)]
        norm = math.sqrt(((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]) + x[3] * x[3])
        x[:4] = [v / norm for v in x[:4]]
    return x


def scalar_inputs(plant: Plant) -> tuple[list, list]:
    return [float(v) for v in plant.inertia_struct.ravel()], [float(v) for v in plant.body_inertia_inverse().ravel()]


# --- timing ------------------------------------------------------------------------------------

def _per_call(fn, calls: int) -> float:
    """Seconds per call of ``fn`` over ``calls`` calls."""
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t0) / calls


def single_run(calls: int, steps: int) -> dict[str, float]:
    """µs per RK4 step of each single-run path (one timing each)."""
    plant, x, cmd = make_plant()
    Js, Jinv = scalar_inputs(plant)
    n_sub = round(PERIOD / H)
    tau = [float(v) for v in COMMAND]
    return {
        'kernel': 1e6 * _per_call(lambda: plant.step(0.0, x, cmd, PERIOD, H), calls) / n_sub,
        'kernel_long': 1e6 * _per_call(lambda: plant.step(0.0, x, cmd, steps * H, H), 3) / steps,
        'numpy': 1e6 * _per_call(lambda: plant.step_numpy(0.0, x, cmd, PERIOD, H), max(1, calls // 10)) / n_sub,
        'scalar': 1e6 * _per_call(lambda: scalar_step(list(x), Js, Jinv, tau, PERIOD, H), max(1, calls // 10)) / n_sub,
    }


def batch_rate(runs: int, calls: int, numpy_path: bool) -> float:
    """runs·steps/s of the batch kernel (or the numpy batch path) on ``runs`` runs."""
    plant, x, cmd = make_plant(runs)
    step = plant.step_numpy if numpy_path else plant.step
    per_call = _per_call(lambda: step(0.0, x, cmd, PERIOD, H), calls)
    return runs * round(PERIOD / H) / per_call


def check_bits(runs: int) -> bool:
    plant, x, cmd = make_plant()
    Js, Jinv = scalar_inputs(plant)
    a = plant.step(0.0, x, cmd, 10.0, H)
    same = np.array_equal(a, plant.step_numpy(0.0, x, cmd, 10.0, H))
    same &= np.array_equal(a, scalar_step(list(x), Js, Jinv, [float(v) for v in COMMAND], 10.0, H))
    bp, bx, bc = make_plant(runs)
    return bool(same and np.array_equal(bp.step(0.0, bx, bc, PERIOD, H), bp.step_numpy(0.0, bx, bc, PERIOD, H)))


def basilisk(steps: int) -> tuple[float | None, str]:
    python, why = basilisk_python()
    if python is None:
        return None, why
    answer, why = run_child(python, 'bsk_plant_step.py', {'h': H, 'steps': steps, 'inertia': INERTIA})
    return (answer['us_per_step'], '') if answer else (None, why)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--calls', type=int, default=2000, help='timed calls per single-run path')
    parser.add_argument('--steps', type=int, default=40000, help='RK4 steps of the long kernel call')
    parser.add_argument('--runs', type=int, default=1000, help='runs of the batch')
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--basilisk', action='store_true', help='also time bsk 2.12.1 (throwaway venv)')
    args = parser.parse_args()
    t0 = time.perf_counter()
    if not check_bits(args.runs):
        print('MISMATCH: the kernel, numpy and scalar paths differ', file=sys.stderr)
        return 1
    print(f'first kernel calls (cache load or compilation) and bit checks: {time.perf_counter() - t0:.2f} s; '
          'kernel == numpy == scalar Python, bit for bit')
    rows: dict[str, list[float]] = {}
    for _ in range(args.repeat):
        for key, value in single_run(args.calls, args.steps).items():
            rows.setdefault(key, []).append(value)
        rows.setdefault('batch', []).append(batch_rate(args.runs, 20, False))
        rows.setdefault('batch_numpy', []).append(batch_rate(args.runs, 3, True))
        if args.basilisk and rows.get('basilisk') != []:
            us, why = basilisk(args.steps)
            rows.setdefault('basilisk', []).extend([us] if us is not None else [])
            if us is None:
                print(f'Basilisk: not measured ({why})')
    med = {k: statistics.median(v) for k, v in rows.items() if v}
    report(med, args)
    return 0


def report(med: dict, args) -> None:
    print(f'body + 3 wheels, RK4 h = {H} s, single run; medians of {args.repeat} (µs per RK4 step):')
    rows = [('(a) kernel, 1 s period per call (as the dynamics node)', med['kernel'], ''),
            (f'(b) kernel, {args.steps} steps in one call', med['kernel_long'], ''),
            ('(c) numpy (previous code), as (a)', med['numpy'], f"(c)/(a) = {med['numpy'] / med['kernel']:.1f}"),
            ('(d) scalar Python floats, as (a)', med['scalar'], f"(d)/(a) = {med['scalar'] / med['kernel']:.1f}")]
    if 'basilisk' in med:
        rows.append(('Basilisk 2.12.1, same body + 3 wheels, RK4', med['basilisk'],
                     f"Basilisk/(a) = {med['basilisk'] / med['kernel']:.2f}, Basilisk/(b) = "
                     f"{med['basilisk'] / med['kernel_long']:.1f}  (target >= 1)"))
    for label, value, note in rows:
        print(f'  {label:<56}{value:9.2f}   {note}')
    print(f"(e) batch of {args.runs} runs: kernel {med['batch']:.3g} runs·steps/s, numpy "
          f"{med['batch_numpy']:.3g} runs·steps/s, ratio {med['batch'] / med['batch_numpy']:.1f}")


if __name__ == '__main__':
    sys.exit(main())
