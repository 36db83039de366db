#!/usr/bin/env python3
"""The cost of the typed parameter sections (:mod:`adcs_msgs_py.sections`) against the validation
they follow, measured in the same run: for each registered schema, the one-off generation of its
section type (a node does it once at start; a campaign once per process), and the build of one
section from validated values (the node once at start; the batch engine once per chunk of runs)
as a ratio to :meth:`Schema.validate` of the same values (what every node start and every run of a
campaign already pays).

Usage: ``python benchmarks/section_build.py [--repeat N]``.
"""
from __future__ import annotations

import argparse
import time

import yaml

from adcs_msgs_py.params import Param, Schema, flatten
from adcs_msgs_py.sections import _PLANS, section, section_type
from adcs_sim.app.scenario.registry import NODES


def _sections() -> dict[str, dict]:
    """The first section of each registered node in the shipped scenarios."""
    from pathlib import Path
    out: dict[str, dict] = {}
    for path in sorted((Path(__file__).resolve().parents[1] / 'config').glob('*.yaml')):
        for node, body in yaml.safe_load(path.read_text()).items():
            if node in NODES and node not in out:
                out[node] = flatten(body['ros__parameters'])
    return out


def _best(call, repeat: int) -> float:
    best = float('inf')
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeat):
            call()
        best = min(best, (time.perf_counter() - t0) / repeat)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeat', type=int, default=2000)
    args = ap.parse_args()
    print(f'{"section":28s} {"params":>6s} {"type (ms)":>10s} {"validate (us)":>14s} {"section (us)":>13s} '
          f'{"ratio":>6s}')
    total_type = 0.0
    section_type(Schema('warm_up', [Param('a.b', 'double', default=0.0)]))   # first-call costs apart
    for name, given in sorted(_sections().items()):
        schema = NODES[name].schema
        _PLANS.pop(id(schema), None)
        t0 = time.perf_counter()
        section_type(schema)
        generate = time.perf_counter() - t0
        total_type += generate
        values = schema.validate(given)
        v = _best(lambda: schema.validate(given), args.repeat)
        s = _best(lambda: section(schema, values), args.repeat)
        print(f'{name:28s} {len(schema.params):6d} {generate * 1e3:10.2f} {v * 1e6:14.1f} {s * 1e6:13.1f} '
              f'{s / v:6.3f}')
    print(f'all section types generated: {total_type * 1e3:.1f} ms (once per process)')


if __name__ == '__main__':
    main()
