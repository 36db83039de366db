#!/usr/bin/env python3
"""How long does ``Environment.sample`` take, for one time and for many, with the IGRF and with the
dipole? And ppigrf's own ``igrf_gc`` for comparison (the reason the IGRF sums are evaluated in
:mod:`adcs_core.environment.magnetic` instead of through it).

Prints, best of ``--repeat`` (default 5) each: ``Environment.sample(t)`` for a scalar ``t`` and for an
array of ``--times`` (default 10 000) times, circular 500 km orbit, conical shadow, IGRF and dipole;
then ``ppigrf.igrf_gc`` for one point and for 1000 and 10 000 points at one date. Not a test (no timing
assertions: the numbers depend on the machine and its load).
"""
from __future__ import annotations

import argparse
import time
from datetime import datetime

import numpy as np
import ppigrf

from adcs_core.environment.environment import build_environment
from adcs_msgs_py.blocks import check_environment, environment_params
from adcs_msgs_py.params import Schema


def best_ms(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n', 1)[0])
    parser.add_argument('--times', type=int, default=10_000)
    parser.add_argument('--repeat', type=int, default=5)
    args = parser.parse_args(argv)
    schema = Schema('benchmark', environment_params(), cross_check=check_environment)
    t_many = np.arange(args.times, dtype=float)
    for model in ('igrf', 'dipole'):
        env = build_environment(schema.validate({'environment.magnetic_model': model,
                                                 'environment.circular.inclination_deg': 51.6}))
        one = best_ms(lambda: env.sample(123.0), args.repeat)
        many = best_ms(lambda: env.sample(t_many), args.repeat)
        print(f'Environment.sample {model:6s}: 1 time {one:8.2f} ms   {args.times} times {many:9.1f} ms '
              f'({1e3 * many / args.times:.1f} us per time)')
    date = datetime(2026, 3, 20, 12)
    for n in (1, 1000, 10_000):
        theta, phi = np.linspace(1, 179, n), np.linspace(-180, 180, n)
        ms = best_ms(lambda: ppigrf.igrf_gc(6878.0, theta, phi, date), args.repeat)
        print(f'ppigrf.igrf_gc        : {n:5d} points {ms:9.1f} ms')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
