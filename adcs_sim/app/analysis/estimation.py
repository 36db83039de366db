"""Estimation analysis: an estimator's errors against the truth, its 3σ bounds, NEES and NIS with
their χ² bounds, from a bag or a batch result (pure: numpy, scipy; no ROS, no matplotlib).

Conventions (those of :mod:`adcs_controllers.estimators.mekf`): the attitude error is the small
rotation ``δθ`` (body axes) with ``q_true = q̂ ⊗ δq(δθ)``, twice the Gibbs vector of ``q̂* ⊗ q_true``;
the rate error ``ω̂ − ω``; the bias error ``β − β̂``. The attitude covariance is the estimate's
(``estimate/state`` pose covariance rotated back to body axes, :mod:`adcs_msgs_py.conversions_determination`).

* NEES: ``eᵀ P⁻¹ e``; from a bag the attitude part only (3 dof: the bag has no true bias), from a
  batch the full ``[δθ, Δβ]`` (6 dof) when the sensors gave the true bias.
* NIS: the estimator's own (``estimator/status`` ``nis_<sensor>``): χ²(3) for the star tracker, χ²(2)
  for a unit vector (the innovation ``b − b̂`` has no component along ``b̂`` to first order).
* Bounds: for ``M`` runs averaged, the two-sided ``1 − α`` interval of a consistent filter's mean
  NEES/NIS is ``χ²⁻¹(α/2, M d)/M``, ``χ²⁻¹(1 − α/2, M d)/M`` (Bar-Shalom, Li & Kirubarajan 2001, §5.4).

:func:`series_from_bag` and :func:`series_from_batch` give an :class:`EstimationSeries`;
:func:`estimation_errors`, :func:`nees`, :func:`estimation_metrics` work on it;
:func:`batch_consistency` gives the Monte Carlo (run-averaged) consistency of a whole batch.
The figures: :mod:`adcs_sim.app.report.estimation`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammaincinv

from adcs_controllers.estimators.mekf import attitude_error
from adcs_core.attitude import rotation_from_quaternion
from adcs_msgs_py import names
from adcs_msgs_py.sensor_interfaces import NIS_DOF as SENSOR_NIS_DOF
from adcs_sim.bag.reader import read_messages

NIS_DOF = SENSOR_NIS_DOF   # each sensor's declaration (adcs_msgs_py.sensor_interfaces)
CONFIDENCE = 0.95


@dataclass
class EstimationSeries:
    """One run's estimates and truth on the estimate's stamps (seconds, SI units, body axes)."""

    t: np.ndarray                  # (K,) s
    q: np.ndarray                  # (K, 4) estimate
    w: np.ndarray                  # (K, 3)
    att_cov: np.ndarray            # (K, 3, 3) rad², body axes
    rate_cov: np.ndarray           # (K, 3, 3)
    q_true: np.ndarray             # (K, 4)
    w_true: np.ndarray             # (K, 3)
    bias: np.ndarray | None = None        # (K, 3) rad/s, estimated
    bias_true: np.ndarray | None = None   # (K, 3) (batch only)
    cov: np.ndarray | None = None         # (K, 6, 6) full error-state covariance (batch only)
    nis: dict = field(default_factory=dict)   # sensor -> (K,), NaN where not used
    status: dict = field(default_factory=dict)   # estimator/status key -> (K,) numbers


def chi2_bounds(dof: int, runs: int = 1, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The two-sided ``confidence`` interval of the mean of ``runs`` χ²(``dof``) values."""
    a = (1.0 - confidence) / 2.0   # chi2.ppf(q, k) is 2 gammaincinv(k/2, q), bit for bit: scipy.stats
    lo, hi = 2.0 * gammaincinv(dof * runs / 2.0, [a, 1.0 - a]) / runs   # costs 0.8 s to import, every tool
    return float(lo), float(hi)


def fraction_inside(values: np.ndarray, dof: int, runs: int = 1, confidence: float = CONFIDENCE) -> float:
    """Fraction of the finite ``values`` inside :func:`chi2_bounds` (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return float('nan')
    lo, hi = chi2_bounds(dof, runs, confidence)
    return float(((v >= lo) & (v <= hi)).mean())


# --- reading -----------------------------------------------------------------------------------------

def _stamp(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _quat(o) -> np.ndarray:
    return np.array([o.x, o.y, o.z, o.w], dtype=float)


def _vec(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def _status_numbers(msg) -> dict:
    out = {}
    for kv in msg.status[0].values if msg.status else ():
        try:
            out[kv.key] = float(kv.value)
        except ValueError:
            if kv.value in ('True', 'False'):
                out[kv.key] = float(kv.value == 'True')
    return out


def series_from_bag(bag, namespace: str = '/') -> EstimationSeries:
    """The estimate (``estimate/state``), its status (``estimator/status``) and the truth
    (``truth/state``, else ``state``) of a bag, on the estimate's stamps that have a truth sample.
    Raises ValueError when the bag has no estimate."""
    ns = '/' + namespace.strip('/') + '/' if namespace.strip('/') else '/'
    topic = {name: ns + name for name in (names.ESTIMATE_STATE, names.ESTIMATOR_STATUS, names.TRUTH_STATE,
                                          names.STATE)}
    est, status, truth, state = {}, {}, {}, {}
    into = {topic[names.ESTIMATE_STATE]: est, topic[names.ESTIMATOR_STATUS]: status,
            topic[names.TRUTH_STATE]: truth, topic[names.STATE]: state}
    for name, _, msg in read_messages(bag, set(into)):
        into[name][_stamp(msg)] = msg
    truth = truth or state
    stamps = sorted(t for t in est if t in truth)
    if not stamps:
        raise ValueError(f'{bag}: no {names.ESTIMATE_STATE} message with a truth sample of the same stamp')
    q = np.array([_quat(est[t].pose.pose.orientation) for t in stamps])
    R = rotation_from_quaternion(q)
    pose = np.array([np.asarray(est[t].pose.covariance, dtype=float).reshape(6, 6)[3:, 3:] for t in stamps])
    twist = np.array([np.asarray(est[t].twist.covariance, dtype=float).reshape(6, 6)[3:, 3:] for t in stamps])
    values = [_status_numbers(status[t]) if t in status else {} for t in stamps]
    keys = sorted({k for v in values for k in v})
    table = {k: np.array([v.get(k, np.nan) for v in values]) for k in keys}
    bias = np.stack([table[f'bias_{a}'] for a in 'xyz'], axis=-1) if 'bias_x' in table else None
    return EstimationSeries(
        t=np.array(stamps, dtype=float) / 1e9, q=q, w=np.array([_vec(est[t].twist.twist.angular) for t in stamps]),
        att_cov=np.swapaxes(R, -1, -2) @ pose @ R, rate_cov=twist,
        q_true=np.array([_quat(truth[t].pose.pose.orientation) for t in stamps]),
        w_true=np.array([_vec(truth[t].twist.twist.angular) for t in stamps]), bias=bias,
        nis={k[len('nis_'):]: v for k, v in table.items() if k.startswith('nis_')}, status=table)


def series_from_batch(result, i: int) -> EstimationSeries:
    """Run ``i`` of a :class:`~adcs_sim.app.batch.engine.BatchResult` with an estimator section."""
    est = result.estimate
    if est is None:
        raise ValueError('the batch has no estimator section')
    k = int(min(result.n_steps[i], est['q'].shape[1]))
    status = {key: v[i, :k] for key, v in est['status'].items()}
    return EstimationSeries(
        t=result.t[:k], q=est['q'][i, :k], w=est['w'][i, :k], att_cov=est['cov'][i, :k, :3, :3],
        rate_cov=est['rate_cov'][i, :k], q_true=result.q[i, :k], w_true=result.w[i, :k], bias=est['bias'][i, :k],
        bias_true=est['bias_true'][i, :k] if 'bias_true' in est else None, cov=est['cov'][i, :k],
        nis={key[len('nis_'):]: v for key, v in status.items() if key.startswith('nis_')}, status=status)


# --- errors and consistency ----------------------------------------------------------------------------

def _sigma(cov: np.ndarray) -> np.ndarray:
    return np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0.0, None))


def estimation_errors(s: EstimationSeries) -> dict[str, np.ndarray]:
    """``attitude`` (K, 3) rad, ``rate`` (K, 3) rad/s and, with the true bias, ``bias`` (K, 3) rad/s,
    each with its filter 1σ (``sigma_attitude``, ``sigma_rate``, ``sigma_bias``)."""
    out = {'attitude': attitude_error(s.q, s.q_true), 'sigma_attitude': _sigma(s.att_cov),
           'rate': s.w - s.w_true, 'sigma_rate': _sigma(s.rate_cov)}
    if s.bias is not None and s.bias_true is not None:
        out['bias'] = s.bias_true - s.bias
        if s.cov is not None:
            out['sigma_bias'] = _sigma(s.cov[..., 3:, 3:])
    return out


def _quadratic(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``eᵀ P⁻¹ e`` per row; NaN where P is singular (a single-frame estimate's empty bias block)."""
    out = np.full(e.shape[:-1], np.nan)
    ok = np.isfinite(e).all(axis=-1) & (np.linalg.matrix_rank(P) == P.shape[-1])
    if ok.any():
        out[ok] = (e[ok] * np.linalg.solve(P[ok], e[ok][..., None])[..., 0]).sum(axis=-1)
    return out


def nees(s: EstimationSeries) -> tuple[np.ndarray, int]:
    """(NEES per step, its degrees of freedom): 6 with the true bias and the full covariance, else the
    attitude's 3."""
    e = estimation_errors(s)
    if 'bias' in e and s.cov is not None and np.linalg.matrix_rank(s.cov[-1]) == 6:
        return _quadratic(np.concatenate([e['attitude'], e['bias']], axis=-1), s.cov), 6
    return _quadratic(e['attitude'], s.att_cov), 3


def estimation_metrics(s: EstimationSeries, settle_s: float = 0.0) -> dict:
    """Numbers of one run (from ``settle_s`` on, to leave the acquisition out of the statistics):
    RMS, largest and final errors, fraction of attitude errors inside ±3σ, NEES and NIS means and
    the fraction of steps inside their single-run 95 % χ² bounds."""
    e = estimation_errors(s)
    keep = s.t >= settle_s
    att_deg = np.degrees(np.linalg.norm(e['attitude'][keep], axis=-1))
    rate = np.degrees(np.linalg.norm(e['rate'][keep], axis=-1))
    out = {'estimation_attitude_error_rms_deg': float(np.sqrt(np.mean(att_deg ** 2))),
           'estimation_attitude_error_max_deg': float(att_deg.max()),
           'estimation_attitude_error_final_deg': float(att_deg[-1]),
           'estimation_rate_error_rms_deg_s': float(np.sqrt(np.mean(rate ** 2))),
           'estimation_attitude_inside_3sigma': float(
               (np.abs(e['attitude'][keep]) <= 3 * e['sigma_attitude'][keep]).mean())}
    if 'bias' in e:
        out['estimation_bias_error_final_deg_s'] = float(np.degrees(np.linalg.norm(e['bias'][-1])))
    value, dof = nees(s)
    out[f'nees{dof}_mean'] = float(np.nanmean(value[keep]))
    out[f'nees{dof}_inside_95'] = fraction_inside(value[keep], dof)
    for sensor, v in sorted(s.nis.items()):
        v = v[keep]
        if np.isfinite(v).any():
            out[f'nis_{sensor}_mean'] = float(np.nanmean(v))
            out[f'nis_{sensor}_inside_95'] = fraction_inside(v, NIS_DOF.get(sensor, 3))
    return out


def estimation_metric_names(sensors, bias_states: bool = True) -> list[str]:
    """The keys :func:`estimation_metrics` gives for a batch run of an estimator using ``sensors``
    (a Monte Carlo table's estimation columns), from the function itself on a two-step stand-in;
    ``bias_states``: the estimator estimates the gyro bias (the MEKF: a 6-dof NEES), else its
    covariance has no bias block (a single-frame estimator: 3 dof)."""
    one, eye = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1)), np.broadcast_to(np.eye(3) * 1e-6, (2, 3, 3))
    z = np.zeros((2, 3))
    cov = np.eye(6) * 1e-6 if bias_states else np.diag([1e-6] * 3 + [0.0] * 3)
    s = EstimationSeries(t=np.array([0.0, 1.0]), q=one, w=z, att_cov=eye, rate_cov=eye, q_true=one, w_true=z,
                         bias=z, bias_true=z, cov=np.broadcast_to(cov, (2, 6, 6)),
                         nis={name: np.ones(2) for name in sensors if name != 'gyro'})
    return list(estimation_metrics(s))


def batch_consistency(result, confidence: float = CONFIDENCE) -> dict:
    """Monte Carlo consistency of a whole batch (runs of the same length): the run-averaged NEES per
    step against the ``confidence`` bounds of the mean of N runs, and the same for each sensor's NIS
    (over the runs that used it). Returns ``{'nees': (K,), 'nees_dof', 'nees_bounds', 'nees_inside',
    'nees_grand_mean', 'nis_<sensor>_inside', ...}``."""
    series = [series_from_batch(result, i) for i in range(result.n_runs)]
    values = np.array([nees(s)[0] for s in series])
    dof = nees(series[0])[1]
    mean = values.mean(axis=0)
    lo, hi = chi2_bounds(dof, len(series), confidence)
    out = {'nees': mean, 'nees_dof': dof, 'nees_bounds': (lo, hi),
           'nees_inside': float(((mean >= lo) & (mean <= hi)).mean()), 'nees_grand_mean': float(mean.mean())}
    for sensor in series[0].nis:
        nis = np.array([s.nis[sensor] for s in series])
        used = np.isfinite(nis)
        steps = used.any(axis=0)
        if not steps.any():
            continue
        inside = []
        for k in np.flatnonzero(steps):
            m = int(used[:, k].sum())
            lo_k, hi_k = chi2_bounds(NIS_DOF.get(sensor, 3), m, confidence)
            inside.append(lo_k <= nis[used[:, k], k].mean() <= hi_k)
        out[f'nis_{sensor}_inside'] = float(np.mean(inside))
    return out
