"""A shipped scenario or campaign is named as a user of the clone writes it (``uosat12_gsmn.yaml``,
``uosat12_gsmn``, ``config/uosat12_gsmn.yaml``; ``config/campaigns/pd_slew_30deg.yaml``) from any
folder, as after ``pip install`` where no ``config/`` is beside the user; an unknown name fails in
one line naming the close matches."""
from __future__ import annotations

from pathlib import Path

import pytest
from support.paths import CONFIG

from adcs_sim.app.campaign.checks import CampaignError, resolve_campaign
from adcs_sim.app.graph import runner
from adcs_sim.app.scenario.files import RunError, resolve_scenario


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    """The current folder is not the clone (no config/ in it)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize('name', ['uosat12_gsmn.yaml', 'uosat12_gsmn', 'config/uosat12_gsmn.yaml'])
def test_a_shipped_scenario_by_any_of_its_names_from_another_folder(elsewhere, name):
    assert resolve_scenario(name) == (CONFIG / 'uosat12_gsmn.yaml').resolve()


@pytest.mark.parametrize('name', ['pd_slew_30deg.yaml', 'pd_slew_30deg', 'config/campaigns/pd_slew_30deg.yaml'])
def test_a_shipped_campaign_by_any_of_its_names_from_another_folder(elsewhere, name):
    assert resolve_campaign(Path(name)) == (CONFIG / 'campaigns' / 'pd_slew_30deg.yaml').resolve()


def test_a_file_of_the_users_wins_over_a_shipped_name(elsewhere):
    (elsewhere / 'config').mkdir()
    mine = elsewhere / 'config' / 'uosat12_gsmn.yaml'
    mine.write_text((CONFIG / 'uosat12_gsmn.yaml').read_text())
    assert resolve_scenario('config/uosat12_gsmn.yaml') == mine.resolve()


@pytest.mark.parametrize('name, suggested', [('uosat12_gsnm', "'uosat12_gsmn.yaml'"),
                                             ('config/microsat_pd_slw.yaml', "'microsat_pd_slew.yaml'")])
def test_an_unknown_scenario_names_its_close_matches_in_one_line(elsewhere, name, suggested):
    with pytest.raises(RunError) as err:
        resolve_scenario(name)
    message = str(err.value)
    assert '\n' not in message and message.startswith(f'scenario {name!r} not found')
    assert 'did you mean' in message and suggested in message
    assert message.count('.yaml') <= 6   # the close matches, not the list of every shipped file


def test_an_unknown_campaign_names_its_close_matches(elsewhere):
    with pytest.raises(CampaignError, match=r"did you mean 'pd_slew_30deg.yaml'"):
        resolve_campaign(Path('pd_slew_30'))


def test_adcs_run_takes_the_name_from_another_folder(elsewhere, capsys):
    assert runner.main(['config/microsat_pd_slew.yaml', '--explain']) == 0
    assert 'pd_controller' in capsys.readouterr().out
    assert runner.main(['microsat_pd_slw', '--explain']) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "did you mean 'microsat_pd_slew.yaml'" in err
