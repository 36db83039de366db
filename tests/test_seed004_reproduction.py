"""Seed 004 (Horri, Palmer & Roberts) reproduced through the ROS graph: the recorded bags in bags/.

Each reference recording was made by ``adcs-run`` (dynamics + controller + recorder as separate
processes, lockstep) from its config/ scenario (bags/regenerate.py). The tests read the bags,
compute the paper's metrics with the analysis library and compare them with the paper's figures;
each test states the paper's figure, ours and the tolerance. A first test checks that each
recording is still what the current code computes (the batch engine on the same scenario), so a
stale bag cannot pass for a reproduction.

Figures that cannot be reproduced from the paper's text are documented in docs/seed004.md with
what was tried; for them the paper's qualitative claim is tested.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from support.comparison import assert_recorded_run_equal, reference_comparison
from support.scenarios import batch_run_data

from adcs_sim.app.analysis.metrics import RunData, run_metrics, settling_times
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.files import validate_scenario

pytestmark = pytest.mark.paper

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / 'bags'


@lru_cache(maxsize=None)
def run(name: str) -> RunData:
    return RunData.from_bag(BAGS / name / 'bag')


@lru_cache(maxsize=None)
def metrics(name: str) -> dict:
    return run_metrics(run(name))


def per_axis(name: str, tol: float) -> dict[str, float]:
    """Settling time per body axis (2-1-3 Euler angles; the library gives them in sequence order y, x, z)."""
    y, x, z = settling_times(run(name), (tol,))[tol]['euler213_per_axis']
    return {'X': x, 'Y': y, 'Z': z}


def peak_signed(name: str) -> np.ndarray:
    """Per axis, the applied torque of largest magnitude, with its sign (Table I prints signed peaks)."""
    u = run(name).u
    return u[np.abs(u).argmax(axis=0), [0, 1, 2]]


def rel(ours: float, paper: float) -> float:
    return abs(ours - paper) / abs(paper)


@pytest.mark.slow
@pytest.mark.parametrize('name', ['microsat_pd_slew', 'microsat_gsmn_slew', 'microsat_minnorm_slew', 'table1_gsmn',
                                  'table1_krstic_tsiotras'])
def test_recording_is_what_the_code_computes(name):
    """The graph's recording equals the batch engine's run of the same scenario: the bag is current, and the
    graph ran the law as the pure code defines it. q and u as every committed bag against a fresh run
    (support.comparison.assert_recorded_run_equal: bit for bit on the recording CPU, as observed here; CROSS_CPU_RTOL
    elsewhere; was atol 1e-9, called round-off); the stamps to 1e-12 s (sec + nanosec; observed 3.6e-15)."""
    batch = batch_run_data(validate_scenario(BAGS / name / 'scenario.yaml'))
    graph = run(name)
    assert graph.missed_steps == 0
    np.testing.assert_allclose(batch.t, graph.t, rtol=0, atol=1e-12)  # bag stamps: sec + nanosec
    assert_recorded_run_equal(batch.q, graph.q)
    assert_recorded_run_equal(batch.u, graph.u)


# --- section III.F: the micro-satellite slew (0.01 N m wheels) --------------------------------

def test_disagreement_gsmn_settles_3pct_before_the_paper_iii_f():
    """DISAGREEMENT with III.F, pinned: the paper's GSMN settles to 0.5 deg on all 3 axes in 123.8 s (printed to
    0.1 s). Ours (LgV = (w + γq)ᵀ, the default; 0.1 s control period, a reading): 119.8 s, 3.3 % early. The
    period, which the paper does not give, moves ours by 1.8 % at most (117.7 s at 1 s, 119.4-120.1 s from 0.5 s
    to 0.01 s; docs/seed004.md), so the miss is beyond the method's sensitivity: a disagreement, small.
    Ours pinned to half a unit of the digit docs/seed004.md prints (119.8: 0.05 s), a regression value of the
    deterministic bag; the miss asserted above the period's 1.8 %. (Was: within 5 %, a tolerance with no
    measured reason.)"""
    ours = metrics('microsat_gsmn_slew')['settling_euler213_0.5deg_s']
    assert abs(ours - 119.8) <= 0.05, ours
    assert rel(ours, 123.8) > rel(117.7, 119.8), ours   # 3.3 % > the period's 1.8 %


def test_gsmn_beats_pd_with_admissible_torque_iii_f():
    """Paper: GSMN 123.8 s vs PD 228.2 s (0.54 of it), integrated torque 0.214 vs 0.245, "admissible
    instantaneous torque". Ours: 119.8 s (0.1 s period) vs 183.1 s (PD at 1 s; 186.3 s at 0.1 s; 0.65 of
    it), 0.181 vs 0.268. The claim is an ordering, asserted as one (was: < 0.8 x PD's, a margin with no
    reason). GSMN's applied torque never
    exceeds the PD's peak (nor the 0.01 N m limit: its demand stays below it). The two peaks are the
    t = 0 torques on X and equal: -kp1 (qᵀIq/qᵀq) q1 and -kp1 I_x q1 with qᵀIq/qᵀq = 12 = I_x for this
    q(0), so the comparison allows round-off (1e-12 relative)."""
    g, p = metrics('microsat_gsmn_slew'), metrics('microsat_pd_slew')
    assert g['settling_euler213_0.5deg_s'] < p['settling_euler213_0.5deg_s']
    assert g['integrated_torque_Nms'] < p['integrated_torque_Nms']
    assert max(g['peak_torque_Nm']) <= max(p['peak_torque_Nm']) * (1 + 1e-12)
    demand = [float(s['demand_max']) for _, _, s in run('microsat_gsmn_slew').controller_status]
    assert max(demand) < 0.01


def test_high_gain_min_norm_exceeds_the_torque_limit_iii_f():
    """Paper (fig. 3): the standard min-norm law with the higher gains "causes a higher initial
    torque value, potentially causing torque saturation" - why gain scheduling is needed. Ours:
    its demand peaks at 0.0776 N m, 7.8 times the 0.01 N m the wheels give (they saturate). The claim is
    asserted against the limit itself (was: > 0.05, no reason); ours pinned to half a unit of the digit
    docs/seed004.md prints (0.078: 0.0005 N m), a regression value of the deterministic bag."""
    demand = [float(s['demand_max']) for _, _, s in run('microsat_minnorm_slew').controller_status]
    assert max(demand) > 0.01
    assert abs(max(demand) - 0.078) <= 0.0005, max(demand)
    assert max(metrics('microsat_minnorm_slew')['peak_torque_Nm']) == pytest.approx(0.01, rel=1e-9)
    modes = {s['mode'] for _, _, s in run('microsat_minnorm_slew').controller_status}
    assert modes == {'min_norm', 'zero_torque'}


def pd_at(period: float) -> dict:
    """The PD benchmark's metrics at another control period (batch engine; the PD bag is the 1 s run)."""
    validated = validate_scenario(ROOT / 'config' / 'microsat_pd_slew.yaml')
    validated['dynamics'].update({'control_period': period, 'integrator.max_step': period})
    return run_metrics(BatchSimulation.from_runs([validated]).run().run_data(0))


def test_saturated_high_gain_min_norm_settles_before_pd_iii_f():
    """Paper (figure 2): the standard min-norm law with the higher gains settles faster than PD. Ours at the
    0.1 s period the III.F scenarios read: 116.9 s against PD's 186.3 s at 0.1 s (183.1 s at 1 s, the PD
    bag). No tolerance: an ordering."""
    mn = metrics('microsat_minnorm_slew')['settling_euler213_0.5deg_s']
    assert mn < pd_at(0.1)['settling_euler213_0.5deg_s']
    assert mn < metrics('microsat_pd_slew')['settling_euler213_0.5deg_s']


def test_sensitivity_at_a_1s_period_the_saturated_min_norm_is_slower_than_pd_iii_f():
    """Why the III.F scenarios run at 0.1 s: at 1 s (the period used before) the saturated high-gain min-norm
    law settles in 262.3 s, after PD's 183.1 s, against figure 2; the ordering flips between 0.5 s (241.7 s)
    and 0.25 s (121.5 s). GSMN at 1 s: 117.7 s, still within 5 % of 123.8 s (docs/seed004.md)."""
    validated = validate_scenario(ROOT / 'config' / 'microsat_minnorm_slew.yaml')
    validated['dynamics'].update({'control_period': 1.0, 'integrator.max_step': 1.0})
    mn = run_metrics(BatchSimulation.from_runs([validated]).run().run_data(0))['settling_euler213_0.5deg_s']
    assert mn > metrics('microsat_pd_slew')['settling_euler213_0.5deg_s']


# The paper's own scale of "the same" integrated torque (III.F.2): GSMN's 0.214 against PD's 0.245 it calls
# "smaller", so two integrals 12.7 % apart are not "the same" in its words.
PAPER_SMALLER_GAP = (0.245 - 0.214) / 0.245


@pytest.mark.slow
def test_disagreement_iii_f_min_norm_integrated_torque_is_not_pds():
    """DISAGREEMENT with III.F.2, pinned: min-norm's gains kp = 0.02, kd = 0.15 "were tuned to consume the same
    overall integrated torque as the PD benchmark". Ours with those printed gains: ∫‖u‖dt 0.197 N m s against
    PD's 0.268 (bags; 0.266 for PD at 0.1 s), 26 % less. Tolerance, the paper's own: it calls GSMN's 0.214 against
    0.245 "smaller", a 12.7 % gap, so "the same" is closer than that; ours is twice as far. No reading the text
    leaves open gives the equality (docs/seed004/minnorm_torque_readings.py, docs/seed004.md): ∫‖u‖dt stays at
    0.71-0.86 of PD's with the wheels unlimited, the demand scaled, LgV printed or a 1 s period, and III.D's
    own ∫uᵀu dt puts min-norm on the other side (1.96 times PD's as run; 9.6 with the wheels unlimited, the
    law's "higher initial torque" applied: checked here on a fresh batch run). The two bag figures are pinned
    to half a unit of the digit docs/seed004.md prints (0.0005 N m s)."""
    mn, pd = metrics('microsat_minnorm_slew'), metrics('microsat_pd_slew')
    assert abs(mn['integrated_torque_Nms'] - 0.197) <= 0.0005 and abs(pd['integrated_torque_Nms'] - 0.268) <= 0.0005
    assert mn['integrated_torque_Nms'] < (1 - PAPER_SMALLER_GAP) * pd['integrated_torque_Nms']
    assert mn['control_energy_N2m2s'] > pd['control_energy_N2m2s'] / (1 - PAPER_SMALLER_GAP)
    validated = validate_scenario(ROOT / 'config' / 'microsat_minnorm_slew.yaml')
    for section in ('dynamics', 'minnorm_controller'):
        validated[section]['wheels.max_torque'] = [1.0, 1.0, 1.0]   # N m: the 0.078 N m demand applied
    unlimited = run_metrics(BatchSimulation.from_runs([validated]).run().run_data(0))
    assert max(unlimited['peak_torque_Nm']) > 0.07
    assert unlimited['integrated_torque_Nms'] < (1 - PAPER_SMALLER_GAP) * pd['integrated_torque_Nms']
    assert unlimited['control_energy_N2m2s'] > pd['control_energy_N2m2s'] / (1 - PAPER_SMALLER_GAP)


def test_gsmn_uses_all_three_modes_iii_f():
    """Eq. 17: low gains first, torque off, then high gains (section IV's assumed sequence)."""
    modes = [s['mode'] for _, _, s in run('microsat_gsmn_slew').controller_status]
    first = {m: modes.index(m) for m in ('low_gain', 'zero_torque', 'high_gain')}
    assert first['low_gain'] < first['zero_torque'] < first['high_gain']
    assert 'low_gain' not in modes[first['high_gain']:]


# --- Table I: GSMN vs Krstic-Tsiotras (140 N m) -------------------------------------------

def test_kt_integrated_torque_table1():
    """Paper: KT total integrated torque 35.66 N m s. Ours: 35.79 (+0.36 %). Tolerance 1 %, the method's (as for
    GSMN's): the paper gives no control period, and 1 ms -> 10 ms moves ours by +1.1 % (36.18 N m s;
    docs/seed004.md). (Was 2 %, with no reason.)"""
    ours = metrics('table1_krstic_tsiotras')['integrated_torque_Nms']
    assert rel(ours, 35.66) < 0.01, ours


def test_gsmn_saves_integrated_torque_over_kt_table1():
    """Paper (Table I): GSMN needs less integrated torque than KT (26.95 vs 35.66 N m s, a 24.4 %
    saving). Ours: 26.86 vs 35.79 (24.9 %, +0.5 point). Tolerance on the saving 1 - g/k: the two integrals'
    1 % tolerances (test_gsmn_integrated_torque_table1, test_kt_integrated_torque_table1) carried through,
    (g/k) x (1 % + 1 %) = 1.5 points with the paper's g/k = 0.756. (Was 1 point, said to be that sum: it
    is not.)"""
    g = metrics('table1_gsmn')['integrated_torque_Nms']
    k = metrics('table1_krstic_tsiotras')['integrated_torque_Nms']
    assert g < k, (g, k)
    assert abs((1 - g / k) - (1 - 26.95 / 35.66)) < 26.95 / 35.66 * (0.01 + 0.01), (g, k)


def test_gsmn_integrated_torque_table1():
    """Paper: GSMN ∫‖u‖dt 26.95 N m s. Ours (recorded, LgV = (w + γq)ᵀ): 26.86 (-0.33 %). Tolerance 1 %,
    the method's: the paper gives no control period, and 1 ms -> 10 ms moves ours by +1.0 % (the printed
    I⁻¹ reading gives 27.66, +2.6 %: tests/test_seed004_lgv_reading.py)."""
    g = metrics('table1_gsmn')['integrated_torque_Nms']
    assert rel(g, 26.95) < 0.01, g


def test_gsmn_peak_torques_table1():
    """Paper: GSMN peaks X -40.4, Y -16.77, Z -69.98 N m. Ours (recorded): -40.41 / -16.77 / -70.00
    (0.03 % / 0.004 % / 0.02 %). Tolerance 0.15 %, the coarsest printed precision (-40.4: half a unit of
    the last digit is 0.12 %) plus q(0)'s rounding to 4 decimals (≤ 0.02 %); the issue asks 1 %. Per-axis
    bands, and the Z miss of 1.6 units of its last digit, are in tests/test_seed004_lgv_reading.py."""
    for ours, paper in zip(peak_signed('table1_gsmn'), (-40.4, -16.77, -69.98)):
        assert rel(ours, paper) < 0.0015, (ours, paper)


def test_gsmn_faster_than_kt_on_every_axis_table1():
    """Paper (Table I): GSMN settles faster than KT on every axis at 1 deg and 0.5 deg. Ours too."""
    for tol in (1.0, 0.5):
        g, k = per_axis('table1_gsmn', tol), per_axis('table1_krstic_tsiotras', tol)
        for axis in 'XYZ':
            assert g[axis] < k[axis], (tol, axis, g, k)


def test_gsmn_peak_torque_below_kt_table1():
    """Paper: GSMN "tuned to deliver a lower maximum instantaneous torque" (69.98 vs 139 N m: the
    claim is "lower", the paper's own ratio 0.503). Ours: 70.00 vs 133.5 N m (0.524). Every peak is
    negative, as Table I prints them."""
    g, k = np.abs(peak_signed('table1_gsmn')), np.abs(peak_signed('table1_krstic_tsiotras'))
    assert g.max() < k.max()
    assert np.all(peak_signed('table1_gsmn') < 0) and np.all(peak_signed('table1_krstic_tsiotras') < 0)


@pytest.mark.slow
def test_table1_control_period_is_converged():
    """The 1 ms control period of the Table I scenarios is converged to Table I's printed precision: halving it
    moves the integrated torque by less than half a unit of the paper's last digit (26.95: 0.005 N m s; observed
    0.0016) and no per-axis settling time by more than half of its 0.1 s (0.05 s; observed 0.009 s), batch
    engine. (Was 0.2 % and 0.02 s, with no reason.)"""
    out = {}
    for period in (0.001, 0.0005):
        validated = validate_scenario(ROOT / 'config' / 'table1_gsmn.yaml')
        validated['dynamics'].update({'control_period': period, 'integrator.max_step': period,
                                      'duration': 12.0})
        result = BatchSimulation.from_runs([validated]).run().run_data(0)
        out[period] = (run_metrics(result)['integrated_torque_Nms'],
                       settling_times(result, (1.0, 0.5)))
    (i1, s1), (i2, s2) = out[0.001], out[0.0005]
    assert abs(i1 - i2) < 0.005
    for tol in (1.0, 0.5):
        assert np.max(np.abs(np.subtract(s1[tol]['euler213_per_axis'], s2[tol]["euler213_per_axis"]))) < 0.05
    assert all(math.isfinite(v) for v in s1[0.5]['euler213_per_axis'])


def test_paper_comparison_table_is_generated_by_adcs_analyze(tmp_path, capsys):
    """docs/seed004's published-vs-ours tables come from ``adcs-analyze --compare --reference``."""
    from adcs_sim.app.analysis.analyze import main as analyze
    bags = [str(BAGS / n / 'bag') for n in ('microsat_pd_slew', 'microsat_gsmn_slew')]
    paper = ROOT / 'docs' / 'seed004' / 'paper.yaml'
    text = reference_comparison(bags, paper, tmp_path / 'cmp')
    assert '| microsat_gsmn_slew | `settling_euler213_all_0.5deg_s` | 123.8 | 119.776 | -3.3 % |' in text
    bad = tmp_path / 'bad.yaml'
    bad.write_text('source: x\nruns:\n  microsat_gsmn_slew:\n    settling_time: 1.0\n')
    assert analyze([*bags, '--compare', '--reference', str(bad), '--out', str(tmp_path / 'c2')]) == 2
    assert "settling_time: not a comparison metric" in capsys.readouterr().err


def test_iii_f_pd_slew_report_leads_with_iii_f_even_through_a_sensor_outage():
    """bags/microsat_pd_slew_star_tracker_outage is III.F's PD slew flown on the MEKF with a 100 s star tracker
    outage (issue #20). A sensor's outage is not seed 000's wheel fault: the law's task is unchanged, so its
    committed report leads with III.F's quantities (the all-axes 0.5° settling, ∫‖u‖dt) and the Euler-settling
    figure, not with 1 − |q4| after the fault and "the paper's bands" of another paper (as it did)."""
    text = (BAGS / 'microsat_pd_slew_star_tracker_outage' / 'report' / 'report.md').read_text(encoding='utf-8')
    lead = text.split('## What this run is: ', 1)[1].split('\n## ', 1)[0]
    assert lead.startswith('regulation')
    assert '| `settling_euler213_all_0.5deg_s` |' in lead and '| `integrated_torque_Nms` |' in lead
    assert 'settling_q4' not in lead and 'euler_settling.png' in lead


def _doc_row(doc: str, label: str) -> str:
    rows = [line for line in doc.splitlines() if line.startswith(f'| {label} |')]
    assert len(rows) == 1, label
    return rows[0]


@pytest.mark.slow
def test_doc_tables_are_the_tools_rows(tmp_path):
    """docs/seed004.md's III.F and Table I tables, paper and ours, are ``adcs-analyze --compare --reference
    docs/seed004/paper.yaml`` on the committed bags, rounded as the doc prints them (III.F to 0.1 s and
    0.001 N m s with the difference to 0.1 %; Table I to 0.01, peaks signed as Table I prints them, negative:
    test_gsmn_peak_torque_below_kt_table1): the doc cannot drift from the bags (was: one III.F row checked)."""
    import csv
    paper = ROOT / 'docs' / 'seed004' / 'paper.yaml'
    rows = {}
    for name, bags in (('iii_f', ('microsat_pd_slew', 'microsat_gsmn_slew')),
                       ('table1', ('table1_krstic_tsiotras', 'table1_gsmn'))):
        reference_comparison([BAGS / b / 'bag' for b in bags], paper, tmp_path / name)
        with open(tmp_path / name / 'reference_comparison.csv', newline='', encoding='utf-8') as f:
            rows.update({(r['run'], r['metric']): (float(r['published']), float(r['ours'])) for r in csv.DictReader(f)})
    doc = (ROOT / 'docs' / 'seed004.md').read_text(encoding='utf-8')
    minus = str.maketrans({'-': '\u2212'})
    for law, run_name in (('GSMN', 'microsat_gsmn_slew'), ('PD', 'microsat_pd_slew')):
        for label, metric, digits in ((f'{law} settling, 0.5° all axes (s)', 'settling_euler213_all_0.5deg_s', 1),
                                      (f'{law} ∫‖u‖dt', 'integrated_torque_Nms', 3)):
            pub, ours = rows[(run_name, metric)]
            cell = f'| {label} | {pub:g} | {ours:.{digits}f}'
            assert _doc_row(doc, label).startswith(cell), cell
            assert f'{100 * (ours - pub) / pub:+.1f} %'.translate(minus) in _doc_row(doc, label), label
    kt, gs = 'table1_krstic_tsiotras', 'table1_gsmn'
    pub_k, ours_k = rows[(kt, 'integrated_torque_Nms')]
    pub_g, ours_g = rows[(gs, 'integrated_torque_Nms')]
    assert _doc_row(doc, '∫‖u‖dt (N·m·s)').startswith(f'| ∫‖u‖dt (N·m·s) | {pub_k:g} | {ours_k:.2f} |')
    assert f'| {pub_g:g} | {ours_g:.2f} |' in _doc_row(doc, '∫‖u‖dt (N·m·s)')
    for axis in 'xyz':
        row = _doc_row(doc, f'peak {axis.upper()} (N·m)')
        (pk, ok), (pg, og) = rows[(kt, f'peak_torque_{axis}_Nm')], rows[(gs, f'peak_torque_{axis}_Nm')]
        assert row.startswith(f'| peak {axis.upper()} (N·m) | −{pk:g} | −{ok:.2f} |'), row
        assert f'| −{pg:g} | −{og:.2f} |' in row, row
        angle = {'x': 'theta1_x', 'y': 'theta2_y', 'z': 'theta3_z'}[axis]
        row = _doc_row(doc, f'settling {axis.upper()} 1° / 0.5° (s)')
        for run_name in (kt, gs):
            (p1, o1), (p05, o05) = (rows[(run_name, f'settling_euler213_{angle}_{b}deg_s')] for b in ('1', '0.5'))
            assert f'| {p1:g} / {p05:g} | {o1:.2f} / {o05:.2f} |' in row, (run_name, row)
