"""``adcs-montecarlo <campaign.yaml> [--runs N] [--out DIR] [--scheduler ADDR]``: run a Monte Carlo
campaign on the batch engine, in this process or scaled out with Dask, and write its results,
summary and histograms.

The campaign (:mod:`adcs_sim.app.campaign.plan`) is checked whole before anything runs, split into chunks
of ``chunk_size`` runs, and each chunk is simulated as one batch (:mod:`adcs_sim.app.batch.engine`) by a Dask
worker, or in this process when a cluster would cost more than it saves: by default (``--scheduler
auto``) the first chunk runs in this process, timed, and the rest here or on a ``LocalCluster`` on
loopback using every core, whichever is expected to finish sooner (:mod:`adcs_sim.app.campaign.scheduling`);
``--scheduler local`` forces the cluster, ``--scheduler none`` this process, ``--scheduler
tcp://host:port`` any running Dask scheduler. The results do not depend on the split nor on the scheduler.

Output folder (``--out``, default ``runs/<campaign>-<timestamp>``, numbered if taken):

* ``results.csv`` — one row per run: index, status (``ok``, ``failed``: diverged, ``violated``:
  outside the campaign's ``requirements``), reason, dispersed inputs, metrics;
* ``results.parquet`` — the same table, columnar (pyarrow; typed columns: ``run`` int64, ``status``
  and ``reason`` strings, inputs and metrics float64, integer inputs int64): a 100 000-run table
  loads in a fraction of a second (``benchmarks/parquet_load.py``); read it with
  :func:`read_results`, ``pyarrow.parquet.read_table`` or ``pandas.read_parquet``;
* ``summary.json`` / ``summary.md`` — per metric: count, mean, std, min, percentiles (5, 50, 95),
  max, and the runs that failed or violated a requirement with their inputs;
* ``replay/run_<i>.yaml`` — for each of those runs, a complete scenario file: replay it alone on
  the ROS graph with ``adcs-run replay/run_<i>.yaml`` (``--export-run I`` writes any run's);
* ``figures/hist_<metric>.png|svg`` — histograms; ``campaign.yaml`` — a copy of the campaign;
* with the campaign's ``series_every``: ``series.npz`` (``t``, ``error_deg`` (runs, samples),
  ``runs``) and ``figures/error_all_runs.png``, every run's error on a log scale (seed 003's
  Figure 3 for a pointing campaign);
* with ``--paired-with DIR`` (another campaign's output over the same draws, e.g. another law):
  ``paired.md`` / ``paired.json``, the run-by-run relative change of every metric.

The output folder is checked before any run (:mod:`adcs_sim.app.outputs`): absent or empty,
writable, not a file or a FIFO, not holding the campaign, its scenario or ``--paired-with``. An
existing campaign output is replaced only with ``--overwrite``, and only if it holds nothing but
what this tool writes (:func:`is_campaign_output`); its files are removed once the runs are done,
before the new ones are written. ``--export-run`` never replaces a file. ``--scheduler ADDR`` is
checked before any run: malformed, refused at once; no answer within ``CONNECT_TIMEOUT_S`` (5 s),
refused in one line.

Exit status: 0 done (even with failed runs: they are results), 2 bad campaign, output or scheduler
(nothing ran).
"""
from __future__ import annotations

import argparse
import csv
import json
import logging
import math
import os
import re
import shutil
import socket
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from adcs_msgs_py.help_text import command_parser
from adcs_msgs_py.params_file import one_line_warnings
from adcs_sim.app.campaign import scheduling
from adcs_sim.app.campaign.plan import Campaign, CampaignError, run_chunk
from adcs_sim.app.outputs import OutputError, check_file, check_folder, fresh_folder

PERCENTILES = (5, 50, 95)
MAX_WORKERS = 4 * (os.cpu_count() or 1)   # LocalCluster processes: more only thrash


# --- execution ---------------------------------------------------------------------------------

def execute(campaign: Campaign, scheduler: str = 'auto', workers: int | None = None,
            progress: bool = True) -> list[dict]:
    """Run every chunk of the campaign; rows sorted by run index.

    ``scheduler``: ``auto`` (the first chunk here, timed, then the rest here or on a LocalCluster,
    whichever :func:`adcs_sim.app.campaign.scheduling.choose` expects to finish sooner), ``local`` (a
    Dask LocalCluster on 127.0.0.1 with ``workers`` processes, default one per core), ``none`` (in
    this process, no Dask) or a scheduler address.
    """
    # lazy: tqdm, and Dask (1.2 s) only for a scheduler other than none
    from tqdm import tqdm
    chunks = campaign.chunks()
    bar = tqdm(total=campaign.runs, unit='run', disable=not progress, dynamic_ncols=True)
    rows: list[dict] = []
    try:
        if scheduler == 'auto':
            t0 = time.perf_counter()
            rows += run_chunk(campaign, chunks[0])
            bar.update(len(chunks[0]))
            per_run, chunks = (time.perf_counter() - t0) / len(chunks[0]), chunks[1:]
            scheduler = scheduling.choose(per_run, [len(c) for c in chunks], workers or os.cpu_count() or 1)
        if scheduler == 'none':
            for chunk in chunks:
                rows += run_chunk(campaign, chunk)
                bar.update(len(chunk))
        else:
            rows += _on_dask(campaign, chunks, scheduler, workers, bar)
    finally:
        bar.close()
    rows.sort(key=lambda r: r['run'])
    return rows


def _on_dask(campaign: Campaign, chunks: list, scheduler: str, workers: int | None, bar) -> list[dict]:
    """The rows of ``chunks`` run by Dask: a LocalCluster (``scheduler`` 'local') or a scheduler's address."""
    # lazy: Dask (1.2 s) only for a scheduler other than none
    from dask.distributed import Client, LocalCluster, as_completed
    if scheduler == 'local':
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               host='127.0.0.1', dashboard_address=None,
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        cluster, client = None, _connect(Client, scheduler)
    rows: list[dict] = []
    try:
        futures = client.map(run_chunk, [campaign] * len(chunks), chunks, pure=False)
        for future in as_completed(futures):
            done = future.result()
            rows += done
            bar.update(len(done))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return rows


# Seconds to connect to a scheduler given by address (Dask's own default is 30 s, then two
# tracebacks): a scheduler on a reachable host answers in milliseconds; 5 s leaves room for a
# loaded machine or a remote host, and is what a user waits for a wrong address.
CONNECT_TIMEOUT_S = 5.0
SCHEDULER_ADDRESS = re.compile(r'(?:(?P<protocol>tcp|tls)://)?(?P<host>[A-Za-z0-9._-]+|\[[0-9A-Fa-f:.]+\])'
                               r':(?P<port>[0-9]{1,5})')


def scheduler_endpoint(address: str) -> tuple[str, int]:
    """(host, port) of a Dask scheduler address ``[tcp://|tls://]host:port``; CampaignError
    naming it otherwise (before anything is read or run)."""
    match = SCHEDULER_ADDRESS.fullmatch(address)
    if match is None or not 1 <= int(match['port']) <= 65535:
        raise CampaignError(f"--scheduler {address!r}: not 'auto', 'local', 'none' nor a scheduler address "
                            'tcp://host:port (port 1..65535)')
    return match['host'].strip('[]'), int(match['port'])


def check_scheduler(address: str) -> None:
    """A Dask scheduler answers at ``address`` within CONNECT_TIMEOUT_S, else CampaignError in
    one line (checked before any run). A ``tcp://`` scheduler speaks first (its handshake, a
    msgpack map naming ``compression``): a server that accepts and stays silent is refused here,
    since the Dask client's own handshake read has no timeout (it waited forever). ``tls://``:
    the connection only (TLS waits for the client)."""
    if address in ('auto', 'local', 'none'):
        return
    host, port = scheduler_endpoint(address)
    why = None
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S) as conn:
            if not address.startswith('tls://'):   # the socket keeps create_connection's timeout
                first = conn.recv(256)
                why = None if b'compression' in first else (
                    'it closed the connection' if not first else 'what answered is not a Dask scheduler')
    except TimeoutError:
        why = 'nothing answered'
    except OSError as exc:
        why = exc.strerror or str(exc)
    if why is not None:
        raise CampaignError(f'--scheduler {address}: no Dask scheduler answered within {CONNECT_TIMEOUT_S:g} s: '
                            f'{why}')


def _connect(client_type, address: str):
    """A Dask client of the scheduler at ``address``; CampaignError in one line if no Dask
    scheduler answers there within CONNECT_TIMEOUT_S. Any error is that: a server of another
    kind makes the client fail in any way (seen: a 3 EiB allocation from the frame size it read)."""
    scheduler_endpoint(address)
    try:
        return client_type(address, timeout=CONNECT_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - whatever answered is not a usable scheduler
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CampaignError(f'--scheduler {address}: no Dask scheduler answered within '
                            f'{CONNECT_TIMEOUT_S:g} s ({first[:200]})') from None


# --- results ---------------------------------------------------------------------------------

def _input_columns(rows: list[dict]) -> list[str]:
    cols = []
    for key, value in rows[0]['inputs'].items():
        cols += [f'{key}[{j}]' for j in range(len(value))] if isinstance(value, list) else [key]
    return cols


def _input_values(inputs: dict) -> list:
    out = []
    for value in inputs.values():
        out += value if isinstance(value, list) else [value]
    return out


def write_results_csv(rows: list[dict], path: Path) -> None:
    metrics = list(rows[0]['metrics'])
    with open(path, 'w', newline='', encoding='utf-8') as f:
        writer = csv.writer(f)
        writer.writerow(['run', 'status', 'reason', *_input_columns(rows), *metrics])
        for r in rows:
            writer.writerow([r['run'], r['status'], r['reason'], *map(repr, _input_values(r['inputs'])),
                             *(repr(r['metrics'][m]) for m in metrics)])


def results_table(rows: list[dict]) -> pa.Table:
    """The rows of ``results.csv`` as a typed Arrow table (same columns, same order, same values:
    CSV's ``repr`` of a float64 reads back to the same float64)."""
    metrics = list(rows[0]['metrics'])
    inputs = list(zip(*(_input_values(r['inputs']) for r in rows))) if rows[0]['inputs'] else []
    columns: dict[str, pa.Array] = {
        'run': pa.array([r['run'] for r in rows], pa.int64()),
        'status': pa.array([r['status'] for r in rows], pa.string()),
        'reason': pa.array([r['reason'] for r in rows], pa.string()),
    }
    for name, values in zip(_input_columns(rows), inputs):
        integer = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values)
        columns[name] = pa.array([int(v) if integer else float(v) for v in values],
                                 pa.int64() if integer else pa.float64())
    for m in metrics:
        columns[m] = pa.array([float(r['metrics'][m]) for r in rows], pa.float64())
    return pa.table(columns)


def write_results_parquet(rows: list[dict], path: Path) -> None:
    pq.write_table(results_table(rows), path, compression='zstd')


def read_results(folder: str | Path) -> pa.Table:
    """A campaign output folder's results: ``results.parquet``, or ``results.csv`` if it has none
    (an output of an older version), as an Arrow table (``.to_pandas()`` with pandas)."""
    folder = Path(folder)
    if (folder / 'results.parquet').exists():
        return pq.read_table(folder / 'results.parquet')
    return pacsv.read_csv(folder / 'results.csv')


def summarize(campaign: Campaign, rows: list[dict]) -> dict:
    """Statistics per metric over the runs that did not fail (finite values; ``inf`` counted)."""
    ok = [r for r in rows if r['status'] != 'failed']
    stats = {}
    for m in campaign.metrics:
        values = np.array([r['metrics'][m] for r in ok], dtype=float)
        finite = values[np.isfinite(values)]
        entry = {'runs': int(values.size), 'finite': int(finite.size),
                 'infinite': int(np.isinf(values).sum())}
        if finite.size:
            entry.update({'mean': float(finite.mean()), 'std': float(finite.std(ddof=1)) if finite.size > 1 else 0.0,
                          'min': float(finite.min()), 'max': float(finite.max())})
            entry.update({f'p{p}': float(np.percentile(finite, p)) for p in PERCENTILES})
        stats[m] = entry
    counts = {s: sum(r['status'] == s for r in rows) for s in ('ok', 'failed', 'violated')}
    return {
        'campaign': str(campaign.path), 'scenario': str(campaign.scenario_path), 'runs': len(rows),
        'seed': campaign.seed, 'chunk_size': campaign.chunk_size, 'tolerance_deg': campaign.tol_deg,
        'dispersions': {d.target: {'distribution': d.distribution,
                                   **{k: np.asarray(v).tolist() for k, v in d.args.items()},
                                   **({'link': [f'{s}.{k}' for s, k in d.links]} if d.links else {})}
                        for d in campaign.dispersions},
        'requirements': campaign.requirements, 'counts': counts, 'metrics': stats,
        'not_ok': [{'run': r['run'], 'status': r['status'], 'reason': r['reason'], 'inputs': r['inputs'],
                    'replay': f'replay/run_{r["run"]}.yaml'} for r in rows if r['status'] != 'ok'],
    }


def _fmt(v) -> str:
    return f'{v:.6g}' if isinstance(v, float) else str(v)


def summary_markdown(summary: dict) -> str:
    lines = [f'# Monte Carlo campaign `{Path(summary["campaign"]).name}`', '',
             f'Scenario `{Path(summary["scenario"]).name}`, {summary["runs"]} runs, seed {summary["seed"]}, '
             f'settling band {summary["tolerance_deg"]:g} deg. '
             + ', '.join(f'{n} {s}' for s, n in summary['counts'].items()) + '.', '',
             '## Dispersions', '']
    for target, spec in summary['dispersions'].items():
        args = ', '.join(f'{k} = {v}' for k, v in spec.items() if k != 'distribution')
        lines.append(f'- `{target}`: {spec["distribution"]}' + (f' ({args})' if args else ''))
    if summary['requirements']:
        lines += ['', '## Requirements', '']
        lines += [f'- `{m}`: ' + ', '.join(f'{k} {v:g}' for k, v in b.items())
                  for m, b in summary['requirements'].items()]
    cols = ['mean', 'std', 'min', *(f'p{p}' for p in PERCENTILES), 'max']
    lines += ['', '## Metrics (runs that did not fail)', '',
              '| metric | finite | inf | ' + ' | '.join(cols) + ' |',
              '| --- | ---: | ---: | ' + ' | '.join('---:' for _ in cols) + ' |']
    for m, s in summary['metrics'].items():
        lines.append(f'| `{m}` | {s["finite"]} | {s["infinite"]} | '
                     + ' | '.join(_fmt(s.get(c, math.nan)) for c in cols) + ' |')
    lines += ['', '## Failed runs and requirement violations', '']
    if not summary['not_ok']:
        lines.append('None.')
    for r in summary['not_ok']:
        lines.append(f'- run {r["run"]} ({r["status"]}): {r["reason"]}; replay `{r["replay"]}`; inputs '
                     + ', '.join(f'`{k}` = {v}' for k, v in r['inputs'].items()))
    return '\n'.join(lines) + '\n'


def write_histograms(campaign: Campaign, rows: list[dict], out: Path) -> list[Path]:
    # lazy: matplotlib (1.3 s): only when figures are written
    from matplotlib.figure import Figure

    from adcs_sim.app.report.figures import save_figure
    from adcs_sim.app.report.markdown import metric_label
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for m in campaign.metrics:
        values = np.array([r['metrics'][m] for r in rows if r['status'] != 'failed'], dtype=float)
        finite = values[np.isfinite(values)]
        if not finite.size:
            continue
        fig = Figure(figsize=(6.0, 3.4), layout='constrained')
        ax = fig.subplots()
        ax.hist(finite, bins=min(50, max(10, int(math.sqrt(finite.size)))), color='tab:blue', alpha=0.8)
        for p, style in zip(PERCENTILES, (':', '--', ':')):
            ax.axvline(np.percentile(finite, p), color='k', linestyle=style, linewidth=1,
                       label=f'p{p} = {np.percentile(finite, p):.4g}')
        bound = campaign.requirements.get(m, {})
        for k, v in bound.items():
            ax.axvline(v, color='tab:red', linewidth=1.5, label=f'requirement {k} {v:g}')
        ax.set_xlabel(metric_label(m))   # a readable name and unit; the column's key in the title
        ax.set_ylabel('runs')
        extra = f', {values.size - finite.size} not finite' if values.size > finite.size else ''
        ax.set_title(f'{finite.size} runs{extra} (column {m})', fontsize='medium')
        ax.grid(True, alpha=0.35)
        ax.legend(fontsize='small')
        safe = m.replace('[', '_').replace(']', '')
        paths += save_figure(fig, out, f'hist_{safe}')
    return paths


def write_outputs(campaign: Campaign, rows: list[dict], out: Path, figures: bool = True) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(campaign.path, out / 'campaign.yaml')
    write_results_csv(rows, out / 'results.csv')
    write_results_parquet(rows, out / 'results.parquet')
    summary = summarize(campaign, rows)
    (out / 'summary.json').write_text(json.dumps(summary, indent=2, default=_json_default) + '\n')
    (out / 'summary.md').write_text(summary_markdown(summary))
    replay = out / 'replay'
    for r in summary['not_ok']:
        replay.mkdir(exist_ok=True)
        (replay / f'run_{r["run"]}.yaml').write_text(campaign.scenario_text(r['run']))
    if figures:
        write_histograms(campaign, rows, out / 'figures')
    if rows and 'series' in rows[0]:
        write_series(rows, out, figures)
    return summary


def write_series(rows: list[dict], out: Path, figure: bool = True) -> list[Path]:
    """``series.npz`` of every run's error series, and the figure of all of them on a log scale."""
    longest = max(rows, key=lambda r: r['series']['t'].size)['series']
    t = longest['t']
    err = np.full((len(rows), t.size), np.nan, dtype=np.float32)
    for i, r in enumerate(rows):
        e = r['series']['error_deg']
        err[i, :e.size] = e
    np.savez_compressed(out / 'series.npz', t=t, error_deg=err, runs=np.array([r['run'] for r in rows]))
    if not figure or not t.size:   # no run has a series (every one failed before its first step)
        return []
    # lazy: matplotlib (1.3 s): only when figures are written
    from matplotlib.figure import Figure

    from adcs_sim.app.report.figures import DPI
    kind = longest['kind']
    fig = Figure(figsize=(6.4, 4.0), layout='constrained')
    ax = fig.subplots()
    floor = np.float32(1e-6)
    for e in err:
        ax.semilogy(t, np.maximum(e, floor), color='tab:blue', linewidth=0.4, alpha=0.15)
    for band in (1.0, 0.1, 0.01):
        ax.axhline(band, color='k', linestyle=':', linewidth=0.8)
    ax.set_xlabel('time (s)')
    ax.set_ylabel(f'{kind} error (deg)')
    ax.set_title(f'{kind} error of all {len(rows)} runs', fontsize='medium')
    ax.set_xlim(t[0], t[-1])
    ax.set_ylim(max(floor, np.nanmin(err[:, -1]) / 3) if np.isfinite(np.nanmin(err[:, -1])) else floor, 200)
    ax.grid(True, which='both', alpha=0.3)
    # PNG only: an SVG of a thousand curves is megabytes
    path = out / 'figures' / 'error_all_runs.png'
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    return [path]


def paired_comparison(rows: list[dict], other_csv: Path, metrics: list[str]) -> dict:
    """Run-by-run comparison with another campaign's ``results.csv`` over the same draws.

    Runs are matched by index; every input column the two share must be equal (same seed and
    dispersions: the same spacecraft and slew), else ValueError. Per metric: the relative change
    ``(ours - theirs) / theirs`` over the runs where both are finite and neither failed — its
    mean, percentiles and the fraction of runs where ours is lower.
    """
    with open(other_csv, newline='', encoding='utf-8') as f:
        theirs = {int(r['run']): r for r in csv.DictReader(f)}
    columns = _input_columns(rows)
    shared = [c for c in columns if c in next(iter(theirs.values()), {})]
    if not shared:
        raise ValueError(f'{other_csv}: no dispersed input in common: not a paired campaign')
    changes: dict[str, list[float]] = {m: [] for m in metrics}
    paired = 0
    for r in rows:
        t = theirs.get(r['run'])
        if t is None or r['status'] == 'failed' or t['status'] == 'failed':
            continue
        ours_inputs = dict(zip(columns, _input_values(r['inputs'])))
        if any(float(t[c]) != ours_inputs[c] for c in shared):
            raise ValueError(f'run {r["run"]}: inputs differ from {other_csv} ({shared}): not the same draws')
        paired += 1
        for m in metrics:
            if m in t:
                a, b = r['metrics'][m], float(t[m])
                if math.isfinite(a) and math.isfinite(b) and b != 0:
                    changes[m].append((a - b) / b)
    out = {'other': str(other_csv), 'paired_runs': paired, 'shared_inputs': shared, 'relative_change': {}}
    for m, values in changes.items():
        v = np.array(values)
        if v.size:
            out['relative_change'][m] = {
                'runs': int(v.size), 'mean': float(v.mean()), 'lower_fraction': float((v < 0).mean()),
                **{f'p{p}': float(np.percentile(v, p)) for p in PERCENTILES},
                'min': float(v.min()), 'max': float(v.max())}
    return out


def paired_markdown(paired: dict, name: str) -> str:
    lines = [f'# Run-by-run comparison: `{name}` vs `{paired["other"]}`', '',
             f'{paired["paired_runs"]} runs paired by index, same inputs: '
             + ', '.join(f'`{c}`' for c in paired['shared_inputs']) + '.', '',
             'Relative change (ours − theirs) / theirs, in %; "lower" = runs where ours is lower.', '',
             '| metric | runs | lower | mean | p5 | p50 | p95 | min | max |',
             '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
    for m, s in paired['relative_change'].items():
        pct = ' | '.join(f'{100 * s[k]:+.1f}' for k in ('mean', 'p5', 'p50', 'p95', 'min', 'max'))
        lines.append(f'| `{m}` | {s["runs"]} | {100 * s["lower_fraction"]:.1f} % | {pct} |')
    return '\n'.join(lines) + '\n'


def _json_default(v):
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    raise TypeError(f'not JSON serialisable: {v!r}')


# --- CLI -------------------------------------------------------------------------------------

# What write_outputs (and --paired-with) write: a folder holding only these is a campaign output
# of this tool, the one kind of folder --overwrite replaces.
CAMPAIGN_FILES = frozenset({'campaign.yaml', 'results.csv', 'results.parquet', 'summary.json', 'summary.md',
                            'series.npz', 'paired.json', 'paired.md'})
CAMPAIGN_FOLDERS = {'replay': re.compile(r'run_[0-9]+\.yaml'),
                    'figures': re.compile(r'(hist_.+|error_all_runs)\.(png|svg)')}


def _plain_file(entry: os.DirEntry) -> bool:
    return entry.is_file(follow_symlinks=False)


def is_campaign_output(folder: Path) -> bool:
    """A campaign output of this tool: ``campaign.yaml`` and ``summary.json``, and nothing but
    the files :func:`write_outputs` writes (``replay/run_<i>.yaml``, ``figures/hist_*``...); no
    symlink, no other file or folder."""
    names = set()
    with os.scandir(folder) as entries:
        for entry in entries:
            names.add(entry.name)
            pattern = CAMPAIGN_FOLDERS.get(entry.name)
            if pattern is not None and entry.is_dir(follow_symlinks=False):
                with os.scandir(entry.path) as inner:
                    if not all(_plain_file(e) and pattern.fullmatch(e.name) for e in inner):
                        return False
            elif entry.name not in CAMPAIGN_FILES or not _plain_file(entry):
                return False
    return {'campaign.yaml', 'summary.json'} <= names


def clear_campaign_output(folder: Path) -> None:
    """Remove an old campaign's outputs (:func:`is_campaign_output` checked again first), so
    the new campaign's are never mixed with them."""
    if not folder.is_dir() or next(folder.iterdir(), None) is None:
        return
    if not is_campaign_output(folder):
        raise CampaignError(f'--out {folder}: no longer only a campaign output: not replaced')
    for entry in list(folder.iterdir()):
        if entry.is_dir():
            for inner in entry.iterdir():
                inner.unlink()
            entry.rmdir()
        else:
            entry.unlink()


def _check_outputs(args, campaign: Campaign, out: Path) -> None:
    """Every output of this invocation usable, before any run (OutputError otherwise)."""
    inputs = [campaign.path, campaign.scenario_path, args.paired_with]
    if args.export_run is not None:
        check_file(out, inputs)   # an export never replaces a file
    else:
        check_folder(out, inputs, owned=is_campaign_output if args.overwrite else None)


@one_line_warnings('adcs-montecarlo')   # a scenario section written twice, named once per line
def _parser() -> argparse.ArgumentParser:
    parser = command_parser('adcs-montecarlo', __doc__)
    parser.add_argument('campaign', help='campaign YAML file, or the name of a shipped one (e.g. pd_slew_30deg)')
    parser.add_argument('--runs', type=int, default=None, help='number of runs (overrides the file)')
    parser.add_argument('--out', type=Path, default=None, help='output folder (default runs/<campaign>-<time>, numbered if taken)')
    parser.add_argument('--scheduler', default='auto',
                        help="'auto' (default: the first chunk in this process, timed, then the rest here "
                             "or on a LocalCluster, whichever is expected to finish sooner), 'local' (Dask "
                             "LocalCluster on loopback), 'none' (no Dask), or a Dask scheduler address "
                             'tcp://host:port')
    parser.add_argument('--workers', type=int, default=None, help='LocalCluster worker processes (default: cores)')
    parser.add_argument('--export-run', type=int, default=None, metavar='I',
                        help='only write the scenario file of run I (to --out, default run_I.yaml) and exit')
    parser.add_argument('--paired-with', type=Path, default=None, metavar='DIR',
                        help="another campaign's output folder over the same draws: write paired.md/json, "
                             'the run-by-run relative change of every metric')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace --out if it is the output of an earlier campaign (only then: a folder '
                             'holding anything else is refused); its files are removed before the new ones')
    parser.add_argument('--no-figures', action='store_true', help='skip the histograms')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    return parser


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.runs is not None and args.runs < 1:
            raise CampaignError(f'--runs: must be at least 1, got {args.runs}')
        if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
            raise CampaignError(f'--workers: must be in 1..{MAX_WORKERS} (4 per core), got {args.workers}')
        if args.scheduler not in ('auto', 'local', 'none'):
            scheduler_endpoint(args.scheduler)
        campaign = Campaign.load(args.campaign, args.runs)
        if args.export_run is not None and not 0 <= args.export_run < campaign.runs:
            raise CampaignError(f'--export-run: run {args.export_run} is not in 0..{campaign.runs - 1}')
        if args.paired_with is not None and not (args.paired_with / 'results.csv').is_file():
            raise CampaignError(f'--paired-with: no results.csv in {args.paired_with}')
        if args.export_run is not None:
            out = args.out or Path(f'run_{args.export_run}.yaml')
        else:
            out = args.out or fresh_folder(Path(args.campaign).stem)
        _check_outputs(args, campaign, out)
        if args.export_run is not None:
            out.write_text(campaign.scenario_text(args.export_run))
            print(f'adcs-montecarlo: run {args.export_run} written to {out} (replay: adcs-run {out})')
            return 0
        check_scheduler(args.scheduler)
        rows = execute(campaign, args.scheduler, args.workers, progress=not args.quiet)
        if args.overwrite:
            clear_campaign_output(out)
    except (CampaignError, OutputError) as exc:
        print(f'adcs-montecarlo: {"--out " if isinstance(exc, OutputError) else ""}{exc}', file=sys.stderr)
        return 2
    summary = write_outputs(campaign, rows, out, figures=not args.no_figures)
    print(summary_markdown(summary))
    if args.paired_with is not None:
        try:
            paired = paired_comparison(rows, args.paired_with / 'results.csv', campaign.metrics)
        except ValueError as exc:
            print(f'adcs-montecarlo: --paired-with: {exc}', file=sys.stderr)
            return 1
        (out / 'paired.json').write_text(json.dumps(paired, indent=2) + '\n')
        text = paired_markdown(paired, campaign.path.name)
        (out / 'paired.md').write_text(text)
        print(text)
    print(f'adcs-montecarlo: results in {out}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
