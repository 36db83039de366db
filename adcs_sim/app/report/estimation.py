"""The estimation figures of one run (:func:`estimation_figure`) and of a Monte Carlo batch
(:func:`consistency_figure`): errors per body axis with the filter's ±3σ, NEES and NIS with their 95 %
χ² bounds. :class:`matplotlib.figure.Figure` only (no pyplot); the numbers come from
:mod:`adcs_sim.app.analysis.estimation`. A report calls these and saves the figure (:func:`save`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from adcs_msgs_py import names
from adcs_sim.app.analysis.estimation import (
    NIS_DOF,
    EstimationSeries,
    chi2_bounds,
    estimation_errors,
    estimation_metrics,
    nees,
    series_from_bag,
)

AXES = 'xyz'
COLORS = ('C0', 'C1', 'C2')
ARCSEC = np.degrees(1.0) * 3600.0   # rad -> arcsec


def _band(ax, t, err, sigma, scale: float, unit: str, title: str) -> None:
    """One quantity, per axis: the error and its ±3σ envelope (same colour, dashed)."""
    for i, axis in enumerate(AXES):
        ax.plot(t, scale * err[:, i], color=COLORS[i], linewidth=1.0, label=f'{axis}')
        ax.plot(t, 3 * scale * sigma[:, i], color=COLORS[i], linewidth=0.8, linestyle='--')
        ax.plot(t, -3 * scale * sigma[:, i], color=COLORS[i], linewidth=0.8, linestyle='--')
    ax.set_ylabel(unit)
    ax.set_title(title + ' (dashed: ±3σ of the filter)', fontsize=9, loc='left')
    ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8)   # beside the panel, not over the data
    ax.grid(True, alpha=0.3)


def _zoom(ax, values: np.ndarray, t: np.ndarray, settle_s: float) -> None:
    """Scale the y axis to what follows the acquisition (``settle_s``), where the interest is."""
    keep = (t >= settle_s)[:, None] & np.isfinite(values)
    if keep.any():
        m = 1.2 * np.abs(values[np.broadcast_to(keep, values.shape)]).max()
        if m > 0:
            ax.set_ylim(-m, m)


def _chi2_panel(ax, t, values, dof: int, label: str, runs: int = 1) -> None:
    lo, hi = chi2_bounds(dof, runs)
    ok = np.isfinite(values)
    ax.semilogy(t[ok], values[ok], '.', markersize=2, color='C0', label=label)
    ax.axhline(lo, color='k', linestyle='--', linewidth=0.8)
    ax.axhline(hi, color='k', linestyle='--', linewidth=0.8, label=f'95 % χ²({dof}) bounds'
               + (f', mean of {runs}' if runs > 1 else ''))
    inside = ((values[ok] >= lo) & (values[ok] <= hi)).mean() if ok.any() else float('nan')
    if ok.any():   # a few tiny values (a first update) must not squash the band
        ax.set_ylim(max(float(values[ok].min()), lo / 30.0) / 1.5, max(float(values[ok].max()), hi) * 1.5)
    ax.set_title(f'{label}: {100 * inside:.1f} % of the steps inside', fontsize=9, loc='left')
    ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.grid(True, alpha=0.3, which='both')


def estimation_figure(s: EstimationSeries, settle_s: float = 0.0, title: str = '') -> Figure:
    """Attitude error (arcsec), rate error and, with the true bias, bias error (deg/h) per body axis
    with ±3σ; the NEES and each sensor's NIS with their single-run 95 % χ² bounds. The error panels'
    y axes are scaled to the part after ``settle_s`` (the acquisition stays visible at the left)."""
    e = estimation_errors(s)
    sensors = [k for k, v in sorted(s.nis.items()) if np.isfinite(v).any()]
    rows = 3 + ('bias' in e and 'sigma_bias' in e) + len(sensors)
    fig = Figure(figsize=(10.0, 0.9 + 2.3 * rows), layout='constrained')
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    _band(axes[0], s.t, e['attitude'], e['sigma_attitude'], ARCSEC, 'arcsec', 'attitude error δθ (body axes)')
    _zoom(axes[0], ARCSEC * 3 * e['sigma_attitude'], s.t, settle_s)
    _band(axes[1], s.t, e['rate'], e['sigma_rate'], np.degrees(1.0) * 3600, 'deg/h', 'rate error ω̂ − ω')
    _zoom(axes[1], np.degrees(1.0) * 3600 * 3 * e['sigma_rate'], s.t, settle_s)
    row = 2
    if 'bias' in e and 'sigma_bias' in e:
        _band(axes[row], s.t, e['bias'], e['sigma_bias'], np.degrees(1.0) * 3600, 'deg/h', 'bias error β − β̂')
        _zoom(axes[row], np.degrees(1.0) * 3600 * 3 * e['sigma_bias'], s.t, settle_s)
        row += 1
    value, dof = nees(s)
    _chi2_panel(axes[row], s.t, value, dof, f'NEES ({"attitude, " if dof == 3 else ""}{dof} dof)')
    for sensor in sensors:
        row += 1
        _chi2_panel(axes[row], s.t, s.nis[sensor], NIS_DOF.get(sensor, 3), f'NIS {sensor}')
    axes[-1].set_xlabel('t (s)')
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def consistency_figure(consistency: dict, t: np.ndarray, runs: int, title: str = '') -> Figure:
    """The run-averaged NEES of a batch (:func:`adcs_sim.app.analysis.estimation.batch_consistency`) against
    the 95 % bounds of the mean of ``runs`` runs."""
    fig = Figure(figsize=(10.0, 3.4), layout='constrained')
    ax = fig.subplots()
    mean = consistency['nees']
    _chi2_panel(ax, t[:mean.size], mean, consistency['nees_dof'], f'mean NEES of {runs} runs', runs)
    ax.set_yscale('linear')
    lo, hi = consistency['nees_bounds']
    ax.set_ylim(0, max(2 * hi, float(np.nanpercentile(mean, 99)) * 1.1))
    ax.set_xlabel('t (s)')
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def save(fig: Figure, path: Path) -> list[Path]:
    """``path`` with .png and .svg."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = [path.with_suffix('.png'), path.with_suffix('.svg')]
    for p in out:
        fig.savefig(p, dpi=110)
    return out


# --- the report's estimation section (registered with adcs_sim.app.report.single_run) -------------

def estimation_lines(report) -> list[str]:
    """The section of a run with an estimator (``estimate/state`` in the bag): the estimation error
    against the truth with the filter's ±3σ, NEES and NIS with their χ² bounds, and their numbers.
    Nothing for a run without an estimate."""
    data = report.run.data
    if not any(t.endswith(names.ESTIMATE_STATE) for t, n in data.topic_counts.items() if n):
        return []
    try:
        s = series_from_bag(report.run.path)
    except ValueError as exc:
        return ['## Estimation', '', f'Skipped: {exc}.', '']
    metrics = estimation_metrics(s)
    lines = ['## Estimation', '',
             'The estimate (`estimate/state`, what a controller with `feedback: estimate` flies on) against '
             'the truth (`truth/state`): errors per body axis with the filter\'s own ±3σ, and its consistency '
             '(NEES of the attitude, NIS of each sensor) inside their 95 % χ² bounds '
             '(docs/determination.md). The numbers cover the whole run, the acquisition included.', '',
             '| quantity | value |', '| --- | --- |']
    lines += [f'| `{k}` | {v:.6g} |' for k, v in metrics.items()]
    # the y axes scaled to what follows the first tenth of the run (the acquisition stays visible at the left)
    fig = estimation_figure(s, settle_s=0.1 * float(s.t[-1]), title=f'{report.run.name}: estimation error and consistency')
    save(fig, report.out / 'estimation')
    return lines + ['', '![Estimation error and consistency](estimation.png)', '',
                    'Estimation error with ±3σ of the filter\'s covariance, NEES and NIS with their 95 % bounds '
                    '([SVG](estimation.svg))', '']
