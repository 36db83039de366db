"""The report's findings, said in its lead section before the quantities: a wheel that spent time
at its speed limit (``wheel_time_at_speed_limit_s`` > 0) is flagged with its time there; a run
whose wheels never reach a limit has no finding."""
from __future__ import annotations

import pytest
from support.report_runs import SCENARIO, write_bag

from adcs_sim.app.report.loading import load_run
from adcs_sim.app.report.single_run import write_report

# rw_x spins up at 0.1 rad/s per second (support.report_runs): with a 14.5 rad/s limit its samples
# from t = 145 s (|Ω| >= 14.5 (1 - 1e-3)) to the last but one, t = 199 s, count: 55 s at the limit.
LIMITED = SCENARIO.replace('wheels: {names: [rw_x, rw_y, rw_z]}',
                           'wheels: {names: [rw_x, rw_y, rw_z], max_speed: [14.5, 100.0, .inf]}')


def _lead(tmp_path, scenario: str) -> str:
    bag = write_bag(tmp_path / 'run' / 'bag', scenario=scenario)
    report = write_report(load_run(bag, 'run'), tmp_path / 'report').read_text()
    return report.split('## What this run is', 1)[1].split('### Its quantities', 1)[0]


@pytest.mark.slow
def test_a_wheel_at_its_speed_limit_is_a_finding_of_the_lead(tmp_path):
    lead = _lead(tmp_path, LIMITED)
    findings = [line for line in lead.splitlines() if line.startswith('> Findings:')]
    assert len(findings) == 1
    assert '**wheel `rw_x` at its speed limit** (14.5 rad/s, `wheels.max_speed`) for 55 s' in findings[0]
    assert 'rw_y' not in findings[0] and 'rw_z' not in findings[0]


@pytest.mark.slow
def test_no_finding_when_no_wheel_reaches_a_limit(tmp_path):
    assert 'Findings' not in _lead(tmp_path, SCENARIO)
