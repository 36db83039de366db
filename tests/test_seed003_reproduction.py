"""Seed 003 (single-axis pointing with two wheels and non-zero momentum) against the paper,
from the recordings of the ROS graph (bags/pointing_controller_{a,b}, made by
``bags/regenerate.py``) and the committed Monte Carlo results (docs/montecarlo/pointing_table1*,
made by ``adcs-montecarlo``). docs/seed003.md.

Tolerances: the paper gives no number for the single run of section 5.2 (Fig. 4-8), only the
shape: both converge; B is faster to large errors, A (LQR tail) to fine ones; A's stage 1 ends
with a large precession error. Table 1's numbers are NOT reproduced (ours are ~2x faster, with
the paper's gains: docs/seed003.md); we assert the comparison the paper draws from it.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from support.comparison import assert_recorded_run_equal

from adcs_sim.app.analysis.metrics import RunData, pointing_error_deg, run_metrics
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

pytestmark = pytest.mark.paper

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / 'bags'
MC = ROOT / 'docs' / 'montecarlo'


def run(which: str) -> RunData:
    return RunData.from_bag(BAGS / f'pointing_controller_{which}' / 'bag')


@pytest.mark.parametrize('which', ['a', 'b'])
def test_recording_is_what_the_code_computes(which):
    """The bag equals the batch engine's run of its scenario (the graph runs the pure law; the
    recording is current). Tolerances: the stamps to 1e-12 s (sec + nanosec); q and u as every committed bag
    against a fresh run (support.comparison.assert_recorded_run_equal: CROSS_CPU_RTOL). Not bit for bit even here: the
    node runs the law step by step, the batch engine vectorised (round-off, observed 3.8e-15 on q, 9.5e-16 on
    u; was atol 1e-12 / 1e-15, the latter just above the observed, with no reason)."""
    graph = run(which)
    batch = BatchSimulation.from_runs([validate_scenario(BAGS / f'pointing_controller_{which}' / 'scenario.yaml')]
                                      ).run().run_data(0)
    assert graph.missed_steps == 0
    np.testing.assert_allclose(batch.t, graph.t, rtol=0, atol=1e-12)
    assert_recorded_run_equal(batch.q, graph.q)
    assert_recorded_run_equal(batch.u, graph.u)


@pytest.mark.parametrize('which', ['a', 'b'])
def test_both_controllers_converge_through_the_graph(which):
    r = run(which)
    m = run_metrics(r)
    assert math.isfinite(m['pointing_settling_0.01deg_s']) and m['final_pointing_error_deg'] < 1e-3
    assert np.abs(r.u).max() <= 0.02 + 1e-12            # 20 mN m
    assert np.all(r.wheel_speed[:, 2] == 0.0)           # the failed Z wheel holds no momentum
    # the momentum ends in the two wheels: |h| = J_w |Omega| -> H0 = 0.85 N m s, body at rest. Tolerance: what
    # the rate bound below leaves in the body, max(I) x 1e-6 rad/s = 1e-5 N m s, 1.2e-5 of H0 (was 1e-4, no
    # reason; observed 3e-8 A / 6e-8 B)
    h = 0.0077 * np.linalg.norm(r.wheel_speed[-1, :2])
    assert np.linalg.norm(r.w[-1]) < 1e-6
    assert h == pytest.approx(0.85, rel=10.0 * 1e-6 / 0.85)


def test_comparison_of_a_and_b_from_the_same_initial_condition():
    """Section 5.2 / Fig. 4: same initial state; B is faster to 1 deg, A faster to 0.01 deg; A's
    stage 1 ends (switch to the LQR) with the pointing error still large (precession error)."""
    a, b = run('a'), run('b')
    np.testing.assert_array_equal(a.q[0], b.q[0])
    np.testing.assert_array_equal(a.w[0], b.w[0])
    ma, mb = run_metrics(a), run_metrics(b)
    assert mb['pointing_first_1deg_s'] < ma['pointing_first_1deg_s']
    assert ma['pointing_settling_0.01deg_s'] < mb['pointing_settling_0.01deg_s']
    stages = [(t, v['mode']) for t, _, v in a.controller_status]
    switch = next(t for t, mode in stages if mode == 'A2_lqr')
    assert all(mode == 'A1_momentum' for t, mode in stages if t < switch)
    assert all(mode == 'A2_lqr' for t, mode in stages if t >= switch)
    e_a = pointing_error_deg(a)
    assert e_a[np.searchsorted(a.t, switch)] > 1.0     # large error when the LQR takes over
    assert {v['mode'] for _, _, v in b.controller_status} == {'B'}


# --- Table 1: the committed Monte Carlo ----------------------------------------------------------

def results(name: str) -> list[dict]:
    with open(MC / name / 'results.csv', newline='', encoding='utf-8') as f:
        return list(csv.DictReader(f))


def column(rows, key):
    return np.array([float(r[key]) for r in rows])


def test_table1_all_runs_converge_and_the_papers_comparison_holds():
    b, a = results('pointing_table1'), results('pointing_table1_a')
    assert len(a) == len(b) == 1000
    for rows in (a, b):
        assert all(r['status'] == 'ok' for r in rows)
        assert np.all(np.isfinite(column(rows, 'pointing_settling_0.01deg_s')))
        assert np.all(column(rows, 'final_pointing_error_deg') < 0.01)
    # the same draws, run by run
    assert [r['dynamics.initial.attitude[0]'] for r in a] == [r['dynamics.initial.attitude[0]'] for r in b]
    # B faster to large errors, A faster to fine ones (section 5.3)
    assert column(b, 'pointing_first_1deg_s').mean() < column(a, 'pointing_first_1deg_s').mean()
    assert column(a, 'pointing_settling_0.01deg_s').mean() < column(b, 'pointing_settling_0.01deg_s').mean()


PINNED_B_SPREAD_RATIO = 1.290865412931518  # ours, from docs/montecarlo/pointing_table1/results.csv


def test_disagreement_b_spread_grows_with_the_precision():
    """DISAGREEMENT with the paper's remark on Table 1, pinned: its B spread is "apparently
    unaffected by the required level of pointing precision" (98 / 100 / 101 s: max/min 1.03, and at most
    101.5 / 97.5 = 1.041 within its printed precision, half a second); ours grows from 42 to 54 s
    (staying below; max/min 1.29) while the mean doubles (282 -> 599 s): above the paper's 1.041
    (was: a 1.05 with no reason). The ratio is pinned to 1e-9 (the campaign's rows are deterministic)."""
    b = results('pointing_table1')
    std = [column(b, f'pointing_settling_{x}deg_s').std() for x in ('1', '0.1', '0.01')]
    paper_max = (101 + 0.5) / (98 - 0.5)      # the paper's ratio at the edge of its printed digits
    assert max(std) / min(std) > paper_max
    assert max(std) / min(std) == pytest.approx(PINNED_B_SPREAD_RATIO, rel=1e-9)


def summary(name: str) -> dict:
    return json.loads((MC / name / 'summary.json').read_text(encoding='utf-8'))['metrics']


def table1_b_rows() -> list[str]:
    """The six Table 1 rows (paper / ours / difference) as the docs print them: the paper's figures of
    docs/seed003/paper.yaml (its one home; keyed by our campaign, not by a bag: the paper prints no single-run
    number) beside the committed B campaign's summary.json (``adcs-montecarlo``)."""
    paper = yaml.safe_load((ROOT / 'docs' / 'seed003' / 'paper.yaml').read_text(encoding='utf-8'))
    assert paper['runs'] == {}
    published = paper['campaigns']['pointing_table1']
    assert len(published) == 3
    ours, rows = summary('pointing_table1'), []
    for stat in ('mean', 'std'):
        for key, figures in published.items():
            band = key.split('_')[2].removesuffix('deg')
            diff = f'{100 * (ours[key][stat] - figures[stat]) / figures[stat]:+.1f} %'.replace('-', '\u2212')
            rows.append(f'| Table 1, B: time to {band}°, {stat} (s) | {figures[stat]} | {ours[key][stat]:.1f} | {diff} |')
    return rows


def test_table1_rows_of_the_doc_are_the_committed_campaign():
    """docs/seed003.md's six Table 1 rows are :func:`table1_b_rows`, written from the paper's yaml and the
    committed campaign: the doc cannot drift from the campaign. Table 1 is not reproduced (ours ~2x faster):
    the rows are reported, not asserted against the paper."""
    doc = (ROOT / 'docs' / 'seed003.md').read_text(encoding='utf-8')
    for row in table1_b_rows():
        assert row in doc, row


def test_readings_r7_rows_are_the_committed_campaigns():
    """docs/seed003_readings.md R7's table (paper / ours / difference / test) is written from the committed
    campaigns, as docs/seed003.md's: the six Table 1 rows, B and A (same draws) first entry and staying below,
    the orderings the paper draws (section 5.3) and B's spread ratio (from results.csv, as
    test_disagreement_b_spread_grows_with_the_precision computes it)."""
    doc = (ROOT / 'docs' / 'seed003_readings.md').read_text(encoding='utf-8')
    r7 = doc[doc.index('## R7.'):doc.index('## R8.')]
    b, a = summary('pointing_table1'), summary('pointing_table1_a')

    def bands(d, kind):
        return ' / '.join(f"{d[f'pointing_{kind}_{x}deg_s']['mean']:.1f} ± {d[f'pointing_{kind}_{x}deg_s']['std']:.1f}"
                          for x in ('1', '0.1', '0.01'))
    rows = table1_b_rows() + [
        f'| B, staying below 1° / 0.1° / 0.01°: mean ± std (s) | not given | {bands(b, "settling")} |',
        f'| A (same draws), first entry below 1° / 0.1° / 0.01°: mean ± std (s) | not given | {bands(a, "first")} |',
        f'| A (same draws), staying below 1° / 0.1° / 0.01°: mean ± std (s) | not given | {bands(a, "settling")} |',
        f"| B faster to 1° (first entry), A faster to 0.01° (staying below): means (s) | section 5.3 | "
        f"B {b['pointing_first_1deg_s']['mean']:.1f} vs A {a['pointing_first_1deg_s']['mean']:.1f}; "
        f"A {a['pointing_settling_0.01deg_s']['mean']:.1f} vs B {b['pointing_settling_0.01deg_s']['mean']:.1f} | ✔ |"]
    std = [column(results('pointing_table1'), f'pointing_settling_{x}deg_s').std() for x in ('1', '0.1', '0.01')]
    rows.append(f"| B's std, max / min over the three bands (staying below) | 1.03 (98 / 100 / 101 s) | "
                f"{max(std) / min(std):.2f} | ✘ |")
    for row in rows:
        assert row in r7, row


@pytest.mark.parametrize('name, campaign', [('pointing_table1', 'pointing_table1.yaml'),
                                            ('pointing_table1_a', 'pointing_table1_a.yaml')])
def test_committed_table1_results_are_not_stale(name, campaign):
    """Four runs of each campaign recomputed now with the batch engine equal the committed rows
    (run i's inputs and results do not depend on the batch it was in)."""
    from adcs_sim.app.campaign.plan import Campaign, run_chunk
    c = Campaign.load(ROOT / 'config' / 'campaigns' / campaign)
    committed = results(name)
    indices = [0, 1, 500, 999]
    for row in run_chunk(c, indices):
        old = committed[row['run']]
        assert old['status'] == row['status']
        for m, v in row['metrics'].items():
            assert float(old[m]) == pytest.approx(v, rel=1e-9, abs=1e-12), (row['run'], m)


def test_small_campaign_through_the_cli_equals_the_committed_rows(tmp_path):
    """adcs-montecarlo on the first 20 runs of the B campaign (one process): the pointing metrics,
    the series and the all-runs figure are written, and each row equals the committed 1000-run
    campaign's (a run does not depend on the campaign's size or split)."""
    from adcs_sim.app.campaign.montecarlo import main
    out = tmp_path / 'mc'
    assert main([str(ROOT / 'config' / 'campaigns' / 'pointing_table1.yaml'), '--runs', '20',
                 '--out', str(out), '--scheduler', 'none', '--quiet', '--no-figures']) == 0
    with open(out / 'results.csv', newline='', encoding='utf-8') as f:
        small = list(csv.DictReader(f))
    committed = results('pointing_table1')
    assert len(small) == 20
    for row in small:
        old = committed[int(row['run'])]
        assert row.keys() == old.keys()
        for key, value in row.items():
            # Bit for bit on the machine that made the rows; across CPUs numpy's SIMD paths for
            # sin/cos/arctan2 (AVX-512 vs AVX2) may differ by an ulp, which the settling of a
            # 1e-4 deg error turns into ~1e-9 relative: the sibling test's tolerance.
            try:
                assert float(value) == pytest.approx(float(old[key]), rel=1e-9, abs=1e-12), (row['run'], key)
            except ValueError:
                assert value == old[key], (row['run'], key)
    series = np.load(out / 'series.npz')
    assert series['error_deg'].shape == (20, 151) and series['t'][-1] == 1500.0
    assert np.all(series['error_deg'][:, -1] < 0.01)
