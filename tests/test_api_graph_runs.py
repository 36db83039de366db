"""``Scenario.run_graph`` as a script or a notebook calls it: the same lines run twice give two
runs (a fresh folder by default, never the first run's), ``overwrite=True`` replaces only an
earlier run's output, ``domain_id=`` picks the run's ROS_DOMAIN_ID (checked before anything
starts), and nothing is printed on stdout unless asked (the runner's lines go to logging)."""
from __future__ import annotations

import logging

import pytest

from adcs_sim.app.api import Scenario
from adcs_sim.app.scenario.files import RunError

PD = 'microsat_pd_slew.yaml'


@pytest.fixture(scope='module')
def tiny_slew():
    return Scenario.load(PD, {'dynamics.duration': 3.0})


def test_running_the_same_lines_twice_gives_two_quiet_runs(tiny_slew, ros_domain, tmp_path, monkeypatch,
                                                          capfd, caplog):
    monkeypatch.chdir(tmp_path)
    caplog.set_level(logging.INFO, logger='adcs_sim.api')
    first = tiny_slew.run_graph()
    second = tiny_slew.run_graph()
    assert first.bag != second.bag
    assert sorted(p.name for p in (tmp_path / 'runs').iterdir()) == sorted([first.bag.parent.name,
                                                                           second.bag.parent.name])
    assert all(p.name.startswith('microsat_pd_slew-') for p in (tmp_path / 'runs').iterdir())
    assert first.data.t[-1] == second.data.t[-1] == 3.0
    assert capfd.readouterr().out == ''                       # quiet: nothing on stdout
    assert sum('ROS_DOMAIN_ID=' in r.getMessage() for r in caplog.records) == 2   # logged instead


def test_a_given_domain_id_is_the_runs_and_overwrite_replaces_only_a_run(tiny_slew, ros_domain, tmp_path,
                                                                          caplog, capfd):
    domain = ros_domain.domain_id
    ros_domain.release()                 # free for the run to lease (the fixture's id: no other test has it)
    caplog.set_level(logging.INFO, logger='adcs_sim.api')
    out = tmp_path / 'run'
    tiny_slew.run_graph(out, domain_id=domain)
    assert any(f'ROS_DOMAIN_ID={domain},' in r.getMessage() for r in caplog.records)
    with pytest.raises(RunError, match='exists and is not empty'):
        tiny_slew.run_graph(out, domain_id=domain)          # not without overwrite
    (out / 'notes.txt').write_text('mine')
    with pytest.raises(RunError, match='not an output of this tool'):
        tiny_slew.run_graph(out, domain_id=domain, overwrite=True)   # a file of the user's: not replaced
    assert (out / 'notes.txt').read_text() == 'mine'
    (out / 'notes.txt').unlink()
    (out / 'logs' / 'stale.log').write_text('from the first run')
    again = tiny_slew.run_graph(out, domain_id=domain, overwrite=True, verbose=True)
    assert again.bag == out / 'bag' and not (out / 'logs' / 'stale.log').exists()
    assert f'ROS_DOMAIN_ID={domain},' in capfd.readouterr().out   # verbose: the runner's lines printed


@pytest.mark.parametrize('bad', [-1, 233, 1000, 1.5, '7', True])
def test_a_bad_domain_id_fails_in_one_line_before_anything(tiny_slew, tmp_path, bad):
    out = tmp_path / 'run'
    with pytest.raises(ValueError) as err:
        tiny_slew.run_graph(out, domain_id=bad)
    message = str(err.value)
    assert message.startswith('domain_id: must be an integer in 0..232') and '\n' not in message
    assert not out.exists()
