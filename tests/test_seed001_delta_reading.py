"""Seed 001, figure 3: the best δ of eq. 27-29 (M2R, u_max = 1 N m) under the printed eq. 27-28 and with α and β
swapped (docs/seed001/delta_readings.py prints the same sweep; docs/seed001_readings.md R10 says what supports
or refutes the swap). Batch engine, config/m2r_umax1.yaml with only α and β changed; no ROS.

The paper's number is best δ = 0.4 on a grid it does not give; its figures are lost in the extraction. Our grid
is the 0.1 one of the studies (docs/seed001/studies.md): a paper's "0.4" is read as the best of 0.1 steps.
"""
from __future__ import annotations

import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

pytestmark = pytest.mark.paper

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location('delta_readings', ROOT / 'docs' / 'seed001' / 'delta_readings.py')
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)

DELTAS = np.round(np.arange(0.1, 0.95, 0.1), 2)


@lru_cache(maxsize=None)
def sweep(reading: str) -> np.ndarray:
    return study.k0_sweep(DELTAS, reading)


def test_swapped_alpha_beta_puts_the_best_delta_at_the_papers_0p4():
    """Paper (figure 3): best δ = 0.4, and δ away from the endpoints of [0, 1] gives faster manoeuvres. With
    α = (1 − δ) u_max, β = δ u_max: best δ = 0.4 (k0 = 50.4 s), and δ = 0.3-0.7 beat both ends of the grid
    (113.8 s at 0.1, > 300 s at 0.9; 0.8 is slower than 0.1, 158 s). Exact on the grid: no tolerance."""
    k0 = sweep('swapped')
    assert study.best_delta(DELTAS, k0) == 0.4
    assert k0[-1] < 0  # 0.9 never meets eq. 29 within the 300 s
    assert np.all((k0[2:7] > 0) & (k0[2:7] < k0[0]))


def test_disagreement_printed_eq27_28_best_delta_is_0p6_not_the_papers_0p4():
    """Paper: 0.4. Ours with eq. 27-28 as printed (α = δ u_max): 0.6 (k0 50.4 s; 0.4 is third at 59.7 s).
    The endpoint claim holds here too (> 300 s at 0.1, 113.8 s at 0.9, 0.3-0.7 faster than both)."""
    k0 = sweep('printed')
    assert study.best_delta(DELTAS, k0) == 0.6
    assert k0[3] > k0[4] > k0[5]  # 0.4 slower than 0.5, slower than 0.6
    assert k0[0] < 0 and np.all((k0[2:7] > 0) & (k0[2:7] < k0[-1]))


def test_the_swap_is_the_printed_sweep_mirrored_about_one_half():
    """What the swapped reading is: the same runs relabelled δ -> 1 − δ (k0 equal bit for bit), so it can only
    move the optimum from 0.6 to 0.4; it is not an independent check of the paper (docs/seed001_readings.md)."""
    assert_array_equal(sweep('swapped'), sweep('printed')[::-1])


def test_alpha_beta_keep_proposition_1s_bound_and_a_bad_reading_is_refused():
    """Both readings spend the same torque budget, α + β = u_max (eq. 18 with B = I); an unknown reading raises."""
    for d in DELTAS:
        for reading in study.READINGS:
            assert sum(study.alpha_beta(float(d), reading)) == pytest.approx(study.U_MAX, abs=1e-12)
    with pytest.raises(ValueError, match='reading must be one of'):
        study.alpha_beta(0.4, 'transposed')
