#!/usr/bin/env python3
"""How long does a 100 000-run campaign's results table take to load, Parquet against CSV?

Builds ``--runs`` (default 100 000) synthetic result rows shaped like a real campaign's (the PD
slew's dispersions: 4 attitude + 3 inertia + 1 gain inputs, and every metric column of
:func:`adcs_sim.app.campaign.plan.metric_names`, with some failed runs carrying ``inf``/NaN metrics
and a reason), writes them with the campaign's own writers (``results.csv`` and
``results.parquet``, :mod:`adcs_sim.app.campaign.montecarlo`) into a temporary folder, checks that both
files hold the same values, then times, best of ``--repeat`` (default 3):

* **parquet**: ``pyarrow.parquet.read_table`` (what :func:`adcs_sim.app.campaign.montecarlo.read_results`
  does), and ``.to_pandas()`` where pandas is installed;
* **csv (pyarrow)**: ``pyarrow.csv.read_csv`` of the CSV;
* **csv (python)**: ``csv.DictReader`` + ``float()`` of every cell (what a script without pyarrow does).

Prints the times and the file sizes. Not a test (timings depend on the machine).
"""
from __future__ import annotations

import argparse
import csv
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from adcs_sim.app.campaign.plan import metric_names
from adcs_sim.app.campaign.montecarlo import write_results_csv, write_results_parquet


def synthetic_rows(n: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    metrics = metric_names(0.5)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    inertia = np.array([12.0, 14.0, 10.0]) + rng.normal(scale=[0.6, 0.7, 0.5], size=(n, 3))
    kd = rng.uniform(0.04, 0.06, size=n)
    values = rng.lognormal(mean=0.0, sigma=1.0, size=(n, len(metrics)))
    failed = rng.random(n) < 0.01
    rows = []
    for i in range(n):
        m = dict(zip(metrics, values[i].tolist()))
        if failed[i]:
            m = {k: (math.inf if j % 2 else math.nan) for j, k in enumerate(m)}
        rows.append({'run': i, 'status': 'failed' if failed[i] else 'ok',
                     'reason': f'non-finite state or torque at t = {i % 600} s' if failed[i] else '',
                     'inputs': {'dynamics.initial.attitude': q[i].tolist(), 'dynamics.inertia': inertia[i].tolist(),
                                'pd_controller.kd': float(kd[i])},
                     'metrics': m})
    return rows


def best_of(repeat: int, fn) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def python_csv(path: Path) -> list[dict]:
    with open(path, newline='', encoding='utf-8') as f:
        return [{k: (v if k in ('status', 'reason') else float(v)) for k, v in r.items()} for r in csv.DictReader(f)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=100_000)
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args(argv)
    rows = synthetic_rows(args.runs)
    with tempfile.TemporaryDirectory(prefix='parquet_load_') as tmp:
        csv_path, pq_path = Path(tmp) / 'results.csv', Path(tmp) / 'results.parquet'
        write_results_csv(rows, csv_path)
        write_results_parquet(rows, pq_path)
        t_pq, table = best_of(args.repeat, lambda: pq.read_table(pq_path))
        t_pacsv, from_csv = best_of(args.repeat, lambda: pacsv.read_csv(csv_path))
        t_py, _ = best_of(1, lambda: python_csv(csv_path))
        assert table.num_rows == from_csv.num_rows == args.runs
        assert table.column_names == from_csv.column_names
        for name in table.column_names:   # the same values in both files (NaN where NaN)
            if name in ('status', 'reason'):    # pyarrow.csv reads an empty string as null
                assert table[name].to_pylist() == [v or '' for v in from_csv[name].to_pylist()], name
                continue
            a, b = table[name].to_numpy(), from_csv[name].to_numpy()
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == 'f'), name
        print(f'{args.runs} runs x {table.num_columns} columns: parquet {pq_path.stat().st_size / 1e6:.1f} MB, '
              f'csv {csv_path.stat().st_size / 1e6:.1f} MB')
        print(f'parquet  pyarrow.parquet.read_table  {t_pq:.3f} s')
        try:
            import pandas  # noqa: F401  (optional: timed only where installed)
            t_pd, _ = best_of(args.repeat, lambda: pq.read_table(pq_path).to_pandas())
            print(f'parquet  read_table().to_pandas()    {t_pd:.3f} s')
        except ImportError:
            print('parquet  to_pandas: pandas not installed')
        print(f'csv      pyarrow.csv.read_csv          {t_pacsv:.3f} s')
        print(f'csv      csv.DictReader + float()      {t_py:.3f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
