"""The MEKF consistency campaign (config/campaigns/mekf_consistency.yaml, issue #20): 100 runs of the PD
slew on the MEKF estimate with a 100 s star tracker outage, each with its own sensor noise and initial
estimate error, in one batch of the batch engine (the nodes' own sensor, filter and law objects).

Figures (ours, 2026-12-01): NEES (6 dof, the filter's full error state) mean over runs 5.78, median
fraction of a run's steps inside the single-run 95 % bounds 0.964; star tracker NIS (3 dof) mean 2.84,
0.954 inside; the attitude error inside the filter's 3 sigma on 99.8 % of the steps (mean of runs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from adcs_sim.app.campaign.plan import Campaign, run_chunk

CAMPAIGN = Path(__file__).resolve().parents[1] / 'config' / 'campaigns' / 'mekf_consistency.yaml'


def test_mekf_campaign_of_100_runs_is_consistent():
    """Issue #20 Must show: over a 100-run Monte Carlo the NEES stays inside the 95 % chi-square bounds
    on >= 95 % of the steps. Per run that fraction scatters (correlated steps, a 600-step run, the outage
    and the 10 deg acquisition included), so the claim is tested on the campaign: the mean over runs of
    the fraction inside >= 0.93 (2 points below 95 %: the acquisition's first steps, where the
    linearisation of a 10 deg error is not exact, are in every run), the grand mean NEES within 10 % of
    6 and the NIS within 10 % of 3 (100 runs x 600 steps: a chi-square mean's standard error is < 1 %,
    10 % is the model's precision, the trapezoidal rate propagation). An overconfident filter fails this
    (tests/test_estimator_families.py)."""
    campaign = Campaign.load(CAMPAIGN)
    assert campaign.runs == 100
    rows = run_chunk(campaign, list(range(campaign.runs)))
    assert all(r['status'] == 'ok' for r in rows), [r['reason'] for r in rows if r['status'] != 'ok']
    m = {key: np.array([r['metrics'][key] for r in rows]) for key in rows[0]['metrics']}
    assert m['nees6_inside_95'].mean() >= 0.93
    assert abs(m['nees6_mean'].mean() / 6 - 1) < 0.10
    assert abs(m['nis_star_tracker_mean'].mean() / 3 - 1) < 0.10
    assert m['estimation_attitude_inside_3sigma'].mean() >= 0.99
    assert np.all(m['settling_eigenaxis_0.5deg_s'] < 400.0)      # every slew completes despite the outage
    seeds = {r['inputs']['dynamics.sensors.seed'] for r in rows}
    assert len(seeds) == 100                                        # each run its own noise
