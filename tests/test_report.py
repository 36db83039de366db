"""Reports and comparisons (``adcs-analyze``) on synthetic bags: no ROS process, known signals.

Each synthetic run is a rotation about body x whose angle falls linearly from 30° to 0 at a
known rate (linear between samples, so the interpolated settling times are exact), a piecewise
constant applied torque, linearly growing wheel speeds, a controller status with a mode switch,
and the final ``dynamics/status``. Expected numbers are computed from these definitions here.
"""
from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.report_runs import RUNS, THETA0, U_ON, N, write_bag

from adcs_sim.app.analysis.analyze import main as analyze_main

FIGURES = ['attitude_error', 'quaternion', 'euler_213', 'body_rates', 'torque', 'wheels',
           'phase_portrait', 'controller_status']


def expected(rate_deg_s, torque, wheel_rate, missed):
    """The comparison numbers of a synthetic run, from the definitions."""
    torque, wheel_rate = np.asarray(torque), np.asarray(wheel_rate)
    t_end = N - 1
    return {
        'settling_euler213_theta1_x_1deg_s': (THETA0 - 1.0) / rate_deg_s,
        'settling_euler213_theta1_x_0.5deg_s': (THETA0 - 0.5) / rate_deg_s,
        'settling_euler213_theta2_y_1deg_s': 0.0, 'settling_euler213_theta3_z_0.5deg_s': 0.0,
        'settling_euler213_all_1deg_s': (THETA0 - 1.0) / rate_deg_s,
        'settling_eigenaxis_0.5deg_s': (THETA0 - 0.5) / rate_deg_s,
        'integrated_torque_Nms': U_ON * np.linalg.norm(torque),
        'control_energy_N2m2s': U_ON * float(torque @ torque),
        'peak_torque_x_Nm': abs(torque[0]), 'peak_torque_y_Nm': abs(torque[1]), 'peak_torque_z_Nm': abs(torque[2]),
        'peak_wheel_speed_rad_s': float(np.abs(wheel_rate).max() * t_end),
        'missed_steps': missed,
    }




@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('runs')
    return {name: write_bag(root / name / 'bag', **kw) for name, kw in RUNS.items()}


def _svg_text(path) -> str:
    return path.read_text()


@pytest.mark.slow
def test_report_of_one_run_beside_the_bag(bags, capsys):
    bag = bags['run_a']
    assert analyze_main([str(bag), '--json']) == 0
    captured = capsys.readouterr()
    metrics = json.loads(captured.out)[str(bag)]  # --json output is unchanged: pure JSON on stdout
    assert metrics['settling_eigenaxis_0.5deg_s'] == pytest.approx((THETA0 - 0.5) / 0.3)
    out = bag.parent / 'report'
    assert f'report: {out / "report.md"}' in captured.err
    text = (out / 'report.md').read_text()
    assert text.startswith('# Run report: run_a')
    assert 'recording | complete' in text and 'truncated' not in text
    assert '```yaml\n# synthetic run for the report tests\ndynamics:' in text
    assert '| `integrated_torque_Nms` | ' + f'{50 * np.linalg.norm([1e-3, -2e-3, 0.5e-3]):.6g}' in text
    for name in FIGURES:
        assert f']({name}.png)' in text and f']({name}.svg)' in text, name
        for ext in ('png', 'svg'):
            assert (out / f'{name}.{ext}').stat().st_size > 1000, (name, ext)
    assert (out / 'attitude_error.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'Skipped: no thruster topic recorded' in text and not list(out.glob('thrusters.*'))
    assert 'Missing topics: none.' in text
    # The fault: one onset at 50 s (the repeated ERROR at 51 s and the OK at 0 s are no events),
    # in the text and as a marker with its legend on the time plots.
    assert 'fault at t = 50 s: `rw_x`: wheel stuck' in text
    assert text.count('fault at t =') == 1
    for name in ('attitude_error', 'euler_213', 'torque', 'wheels', 'controller_status'):
        assert 'fault: rw_x (t = 50 s)' in _svg_text(out / f'{name}.svg'), name
    # Controller status: the string 'mode' as a timeline, numeric keys as panels, u_* elsewhere, a
    # value that never changes named in the caption (not drawn).
    status_svg = _svg_text(out / 'controller_status.svg')
    assert all(s in status_svg for s in ('mode = slew', 'mode = coast', 'lyapunov'))
    assert 'rejected_messages' not in status_svg
    assert 'timelines of `mode` (top); `lyapunov` (unit not declared).' in text
    assert 'Constant over the run (not drawn): `rejected_messages` = 0.' in text
    # Commanded (status u_x, u_y, u_z: 1.5 x applied here) and applied torque in one figure.
    torque_svg = _svg_text(out / 'torque.svg')
    assert 'commanded' in torque_svg and 'applied' in torque_svg
    assert 'no commanded torque' not in text and 'no applied torque' not in text


def test_missing_topics_give_the_figures_they_can(tmp_path, capsys):
    bag = write_bag(tmp_path / 'partial' / 'bag', skip=('/wheels/state', '/controller/status', '/faults'))
    out = tmp_path / 'out'
    assert analyze_main([str(bag), '--out', str(out)]) == 0
    assert f'report: {out / "report.md"}' in capsys.readouterr().out
    text = (out / 'report.md').read_text()
    assert '**Missing topics** (no messages in the bag): `wheels/state`, `controller/status`.' in text
    assert 'Skipped: no wheel states (wheels/state).' in text
    assert 'Skipped: no controller status (controller/status).' in text
    assert 'no commanded torque recorded' in text  # torque figure: applied only
    assert 'No fault events' in text
    made = sorted(p.stem for p in out.glob('*.png'))
    assert made == sorted(set(FIGURES) - {'wheels', 'controller_status'})
    assert not (tmp_path / 'partial' / 'report').exists()  # --out was honoured


@pytest.mark.slow
def test_truncated_bag_is_recovered_and_says_so(bags, tmp_path):
    bag = tmp_path / 'killed' / 'bag'
    shutil.copytree(bags['run_b'], bag)
    (bag / 'metadata.yaml').unlink()
    mcap = next(bag.glob('*.mcap'))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 2])
    from adcs_sim.bag.reader import read_raw
    readable = sum(1 for _ in read_raw(bag))
    total = N + N + (N - 1) * 2 + 2  # state, wheels, status + torque, dynamics/status
    assert 0 < readable < total
    assert analyze_main([str(bag), '--no-report']) == 0
    assert not (bag.parent / 'report').exists()  # --no-report writes nothing
    assert analyze_main([str(bag)]) == 0
    text = (bag.parent / 'report' / 'report.md').read_text()
    assert 'recovered from a truncated file' in text
    assert f'{readable} messages recovered' in text
    assert (bag.parent / 'report' / 'attitude_error.png').stat().st_size > 1000


@pytest.mark.parametrize('kind', ['text file', 'empty folder', 'missing path', 'junk .mcap'])
def test_not_a_bag_is_one_line_on_stderr(tmp_path, capsys, kind):
    path = tmp_path / 'input'
    if kind == 'text file':
        path.write_text('hello\n')
    elif kind == 'empty folder':
        path.mkdir()
    elif kind == 'junk .mcap':
        path.mkdir()
        (path / 'input_0.mcap').write_bytes(bytes(range(256)) * 8)
    assert analyze_main([str(path)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ''
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'adcs-analyze: {path}: '), captured.err
    assert 'Traceback' not in captured.err
    assert not (tmp_path / 'report').exists()


def test_comparison_table_and_overlaid_figures(bags, tmp_path, capsys):
    out = tmp_path / 'cmp'
    assert analyze_main(['--compare', str(bags['run_a']), str(bags['run_b']), '--out', str(out), '--no-report']) == 0
    assert not out.exists()  # --no-report: metrics only
    assert analyze_main(['--compare', str(bags['run_a']), str(bags['run_b']), '--out', str(out)]) == 0
    assert 'comparison:' in capsys.readouterr().out
    with open(out / 'comparison.csv', newline='') as f:
        rows = list(csv.reader(f))
    assert rows[0] == ['metric', 'run_a', 'run_b']
    table = {r[0]: r[1:] for r in rows[1:]}
    assert all(len(v) == 2 for v in table.values())
    for col, name in enumerate(['run_a', 'run_b']):
        kw = RUNS[name]
        for key, value in expected(kw['rate_deg_s'], kw['torque'], kw['wheel_rate'], kw['missed']).items():
            assert float(table[key][col]) == pytest.approx(value, rel=1e-6, abs=1e-9), (name, key)
    assert table['thruster_impulse_Ns'] == ['n/a', 'n/a']
    md = (out / 'comparison.md').read_text()
    assert '| metric | run_a | run_b | meaning |' in md
    for name in ('compare_attitude_error', 'compare_torque_norm', 'compare_wheel_speed_norm'):
        assert f']({name}.png)' in md
        for ext in ('png', 'svg'):
            assert (out / f'{name}.{ext}').stat().st_size > 1000
        svg = _svg_text(out / f'{name}.svg')
        assert 'run_a' in svg and 'run_b' in svg  # one labelled line per run


def test_comparison_default_folder_and_bad_member(bags, tmp_path, capsys, monkeypatch):
    """Without --out: a new runs/comparison-<time> (git-ignored), a second comparison a second
    folder, nothing among the inputs nor a bare comparison/ in the current directory; an
    unreadable bag is reported, the rest compared."""
    monkeypatch.chdir(tmp_path)
    inputs = sorted(bags['run_a'].parent.parent.rglob('*'))
    junk = tmp_path / 'junk.txt'
    junk.write_text('not a bag')
    status = analyze_main(['--compare', str(bags['run_a']), str(bags['run_b']), str(junk), '--json'])
    assert status == 1
    captured = capsys.readouterr()
    assert set(json.loads(captured.out)) == {str(bags['run_a']), str(bags['run_b'])}
    assert [line for line in captured.err.splitlines() if line.startswith('adcs-analyze:')] == \
        [line for line in captured.err.splitlines() if str(junk) in line]
    assert sorted(bags['run_a'].parent.parent.rglob('*')) == inputs   # nothing written beside the bags
    assert not (tmp_path / 'comparison').exists()
    [out] = (tmp_path / 'runs').glob('comparison-*')
    rows = csv.reader(open(out / 'comparison.csv'))
    assert math.isclose(float(next(r for r in rows if r[0] == 'missed_steps')[2]), 3)
    first = (out / 'comparison.md').read_text()
    assert analyze_main(['--compare', str(bags['run_a']), str(bags['run_b'])]) == 0
    assert len(list((tmp_path / 'runs').glob('comparison-*'))) == 2
    assert (out / 'comparison.md').read_text() == first   # the first comparison left as it was


@pytest.mark.slow
def test_report_of_a_bag_in_a_read_only_folder_goes_to_the_current_directory(bags, tmp_path, capsys,
                                                                            monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = bags['run_b'].parent
    real_access = os.access
    monkeypatch.setattr(os, 'access', lambda p, mode: False if Path(p) == folder else real_access(p, mode))
    before = sorted(folder.rglob('*'))
    assert analyze_main([str(bags['run_b'])]) == 0
    assert f'report: {tmp_path / "run_b-report" / "report.md"}' in capsys.readouterr().out
    assert (tmp_path / 'run_b-report' / 'report.md').is_file()
    assert sorted(folder.rglob('*')) == before


def test_report_module_is_pure():
    """No rclpy and no pyplot (GUI backends) behind the report modules."""
    code = ('import sys, adcs_sim.app.report.single_run, adcs_sim.app.report.comparison; '
            'print("rclpy" in sys.modules, "matplotlib.pyplot" in sys.modules)')
    from support.paths import ROOT
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.split() == ['False', 'False']
