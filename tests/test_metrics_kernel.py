"""The compiled campaign metrics (adcs_sim/app/analysis/metrics_kernel.py) are the numpy batch metrics bit for bit.

* :func:`pairwise_sum` is numpy's ``np.sum`` of a row (pairwise summation) for every length up to
  300 and a few long ones, values of mixed magnitude and sign;
* ``_full_run_columns`` (the compiled passes) against ``full_run_columns_numpy`` (the numpy code
  they replace) on random batches whose errors cross the band many times, and the edge cases:
  never settling (the last sample outside), settling at the first sample, leaving the band only at
  the first or the last-but-one sample, always inside, NaN / inf samples, one run, one step, no
  wheels, one target or one per run, a NaN torque or wheel speed; compared by ``repr`` of the
  lists (NaN and inf compare, and -0.0 differs from 0.0);
* real batches: the fused PD campaign's chunk and seed 003's pointing runs.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from adcs_sim.app.batch.engine import BatchResult
from adcs_sim.app.analysis.batch_metrics import _full_run_columns, batch_run_metrics, full_run_columns_numpy
from adcs_sim.app.analysis.metrics_kernel import pairwise_sum


@pytest.mark.parametrize('seed', [0, 1])
def test_pairwise_sum_is_numpys(seed):
    rng = np.random.default_rng(seed)
    for n in [*range(0, 300), 599, 600, 601, 1000, 1024, 4097, 20001]:
        rows = rng.normal(size=(2, n)) * 10.0 ** rng.integers(-12, 12, size=(2, n))
        expected = np.sum(rows, axis=-1)
        for r in range(2):
            got = 0.0 + pairwise_sum(np.ascontiguousarray(rows[r]), 0, n)
            assert repr(got) == repr(float(expected[r])), n


def _quaternions(rng, angle_deg: np.ndarray) -> np.ndarray:
    """Unit quaternions (R, n, 4) rotating by angle_deg about random axes."""
    axis = rng.normal(size=angle_deg.shape + (3,))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    half = np.radians(angle_deg) / 2
    return np.concatenate([axis * np.sin(half)[..., None], np.cos(half)[..., None]], axis=-1)


def _result(q, u, speed, q_ref, wheels=True) -> BatchResult:
    R, n = q.shape[:2]
    return BatchResult(t=np.arange(n, dtype=float) * 0.5, q=q, w=np.zeros((R, n, 3)), u=u,
                       n_steps=np.full(R, n - 1), failure=[None] * R,
                       wheel_names=['a', 'b', 'c'][:speed.shape[-1]] if wheels else [],
                       wheel_speed=speed, q_ref=q_ref)


def _random_batch(rng, R: int, n: int, tol: float) -> BatchResult:
    """Errors scattered around the band, so each run crosses it many times, and the edge cases."""
    angle = tol * np.exp(rng.normal(scale=0.4, size=(R, n))) * np.linspace(3.0, 0.8, n)
    edges = R >= 8 and n >= 4
    if edges:
        angle[0] = tol / 4                            # always inside: settled at t[0]
        angle[1, -1] = 2 * tol                        # the last sample outside: never settles
        angle[2] = tol / 3
        angle[2, 0] = 3 * tol                         # only the first sample outside
        angle[3] = tol / 2
        angle[3, -2] = 5 * tol                        # out only at the last-but-one sample
        angle[4, n // 2:] = tol / 2
        angle[4, n // 2 - 1] = np.inf                 # leaves the band last on an inf sample
        angle[5, -1] = tol                            # exactly on the band
    with np.errstate(invalid='ignore'):
        q = _quaternions(rng, angle)
    if edges:
        q[6, n // 3] = np.nan                         # a NaN sample
        q[7, 1:] *= -1.0                              # the double cover
    q_ref = _quaternions(rng, rng.uniform(0, 1, size=R)) if rng.random() < 0.5 else np.array([0.0, 0.0, 0.0, 1.0])
    u = rng.normal(scale=1e-3, size=(R, n - 1, 3))
    speed = rng.normal(scale=5.0, size=(R, n, 3))
    if edges:
        u[5, n // 2, 1] = np.nan
        speed[6, 0, 2] = np.nan
        u[2] = 0.0
    return _result(q, u, speed, q_ref, wheels=rng.random() < 0.8)


def _same(result, tol: float) -> None:
    rows = np.arange(result.n_runs)
    with np.errstate(all='ignore'):
        got = {k: v.tolist() for k, v in _full_run_columns(result, rows, tol).items()}
        expected = {k: v.tolist() for k, v in full_run_columns_numpy(result, rows, tol).items()}
    assert list(got) == list(expected)
    for key in expected:
        assert repr(got[key]) == repr(expected[key]), key


@pytest.mark.parametrize('seed', range(12))
def test_compiled_columns_equal_the_numpy_columns(seed):
    rng = np.random.default_rng(100 + seed)
    R, n = int(rng.choice([1, 2, 8, 9, 40])), int(rng.choice([2, 3, 9, 130, 601]))
    tol = float(rng.choice([0.5, 1.0, 0.05]))
    _same(_random_batch(rng, R, n, tol), tol)


def test_compiled_columns_on_the_edge_cases_of_a_long_batch():
    rng = np.random.default_rng(7)
    _same(_random_batch(rng, 16, 601, 0.5), 0.5)
    one = _random_batch(rng, 1, 2, 0.5)   # one run, one step
    _same(one, 0.5)


def test_no_wheels_and_per_run_targets():
    rng = np.random.default_rng(8)
    batch = _random_batch(rng, 9, 40, 0.5)
    batch.q_ref = _quaternions(rng, rng.uniform(0, 20, size=9))
    _same(batch, 0.5)
    batch.wheel_names, batch.wheel_speed = [], np.zeros((0, 0, 0))
    _same(batch, 0.5)


def test_a_real_fused_chunk_and_pointing_runs(tmp_path):
    """The PD campaign's first 60 runs (fused loop) and seed 003's pointing runs: the compiled
    columns are the numpy ones, and batch_run_metrics is still run_metrics run by run."""
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.campaign.plan import Campaign
    c = Campaign.load('config/campaigns/pd_slew_30deg.yaml', runs=60)
    indices = list(range(60))
    result = BatchSimulation(c.batch_sections(indices, c.draws(indices)), 60).run()
    _same(result, 0.5)
    assert repr(batch_run_metrics(result)[:5]) == repr([result.metrics(j) for j in range(5)])
    p = Campaign.load('config/campaigns/pointing_table1.yaml', runs=4)
    indices = list(range(4))
    sim = BatchSimulation(p.batch_sections(indices, p.draws(indices)), 4)
    sim.n_steps[:] = min(int(sim.n_steps.max()), 300)
    pointing = sim.run()
    _same(pointing, 1.0)
    assert repr(batch_run_metrics(pointing, 1.0)) == repr([pointing.metrics(j, 1.0) for j in range(4)])
    assert math.isfinite(pointing.q[0, -1, 0])


def _euler_batch(rng, angles_deg: np.ndarray) -> BatchResult:
    """Attitudes (R, n) from 2-1-3 Euler angles (deg, sequence order y, x, z), the target identity."""
    from scipy.spatial.transform import Rotation
    R, n = angles_deg.shape[:2]
    q = Rotation.from_euler('YXZ', angles_deg.reshape(-1, 3), degrees=True).as_quat().reshape(R, n, 4)
    q *= rng.choice([-1.0, 1.0], size=(R, n, 1))              # either sign of the double cover
    return _result(q, rng.normal(size=(R, n - 1, 3)), rng.normal(size=(R, n, 3)), np.array([0.0, 0.0, 0.0, 1.0]))


@pytest.mark.parametrize('tol', [0.5, 0.01, 1e-9, 44.9, 45.0, 60.0])
def test_euler_angles_on_the_band_and_near_gimbal_lock(tol):
    """Angles a few ulp from the band (where the compiled pass cannot tell without computing them),
    pitch near +-90 deg (gimbal lock: the kernel's other branches), angles past 90 and 180 deg."""
    rng = np.random.default_rng(int(tol * 1000) % 2**32)
    R, n = 12, 50
    near = tol * (1.0 + rng.choice([-1, 1], size=(R, n, 3)) * 10.0 ** rng.uniform(-16, -8, size=(R, n, 3)))
    angles = near * rng.choice([-1.0, 1.0], size=(R, n, 3))
    pick = rng.random(size=(R, n, 3))
    angles = np.where(pick < 0.2, rng.uniform(-tol, tol, size=(R, n, 3)), angles)
    angles = np.where(pick > 0.9, rng.uniform(-179.0, 179.0, size=(R, n, 3)), angles)
    gimbal = rng.random(size=(R, n)) < 0.1
    angles[..., 1] = np.where(gimbal, rng.choice([-90.0, 90.0], size=(R, n)) + rng.normal(scale=1e-6, size=(R, n)),
                              angles[..., 1])
    angles[:, -3:] = rng.uniform(-tol, tol, size=(R, 3, 3)) * 0.999   # most runs settle
    _same(_euler_batch(rng, angles), tol)


@pytest.mark.parametrize('tol', [0.5, 2e-7, 30.0, 50.0])
def test_eigenaxis_errors_on_the_band(tol):
    """Rotation angles a few ulp to 1e-7 (relative) from the band: runs whose last samples cannot be
    told from numpy's arctan2 take it at every sample, the others at their last exit and end only."""
    rng = np.random.default_rng(int(tol * 100) + 5)
    R, n = 16, 40
    angle = tol * (1.0 + rng.choice([-1, 1], size=(R, n)) * 10.0 ** rng.uniform(-16, -7, size=(R, n)))
    angle[::2, n // 2:] = tol * rng.uniform(0.0, 0.99, size=(R // 2, n - n // 2))   # even runs settle
    angle[1::4, -1] = tol * 1.5
    angle[3, -5:] = np.nan
    with np.errstate(invalid='ignore'):
        q = _quaternions(rng, angle)
    batch = _result(q, rng.normal(size=(R, n - 1, 3)), rng.normal(size=(R, n, 3)), np.array([0.0, 0.0, 0.0, 1.0]))
    _same(batch, tol)
