"""Issue #31, class "Work lost after it is done": a campaign whose ``--out`` is unusable is refused
before any run (today it runs every run, then tracebacks); an existing output folder is refused
unless ``--overwrite`` names a campaign output of this tool, which is then replaced whole (never
mixed with the new one); ``run_batch`` copies nothing after the simulation.
"""
from __future__ import annotations

import copy

import pytest
from support.edge_paths import fifo, one_line, read_only, tiny_campaign

from adcs_sim.app.campaign import montecarlo
from adcs_sim.app.api import Scenario
from adcs_sim.app.batch.engine import BatchSimulation


def _campaign(tmp_path, runs: int = 3):
    return tiny_campaign(tmp_path / 'in', 4.0, 5, runs)


@pytest.fixture
def no_run(monkeypatch):
    """montecarlo.execute replaced: the list of its calls (a refusal leaves it empty)."""
    calls = []
    monkeypatch.setattr(montecarlo, 'execute', lambda *a, **k: calls.append(a) or [])
    return calls


def _tree(root):
    return sorted((str(p.relative_to(root)), p.read_bytes() if p.is_file() and not p.is_fifo() else None)
                  for p in root.rglob('*'))


@pytest.mark.parametrize('kind', ['file', 'fifo', 'symlink_to_fifo', 'under_a_file', 'read_only', 'read_only_self',
                                  'holds_the_campaign', 'paired_with'])
def test_an_unusable_out_is_refused_before_any_run(tmp_path, kind, no_run, capsys):
    campaign = _campaign(tmp_path)
    extra = []
    (tmp_path / 'a_file').write_text('mine\n')
    with read_only(tmp_path / 'ro'):
        out = {'file': tmp_path / 'a_file', 'fifo': tmp_path / 'a_fifo', 'symlink_to_fifo': tmp_path / 'link',
               'under_a_file': tmp_path / 'a_file' / 'out', 'read_only': tmp_path / 'ro' / 'out',
               'read_only_self': tmp_path / 'ro', 'holds_the_campaign': tmp_path / 'in',
               'paired_with': tmp_path / 'other'}[kind]
        if kind in ('fifo', 'symlink_to_fifo'):
            fifo(tmp_path / 'a_fifo')
            if kind == 'symlink_to_fifo':
                out.symlink_to(tmp_path / 'a_fifo')
        if kind == 'paired_with':
            out.mkdir()
            (out / 'results.csv').write_text('run,status\n')
            extra = ['--paired-with', str(out), '--overwrite']
        before = _tree(tmp_path)
        assert montecarlo.main([str(campaign), '--out', str(out), '--scheduler', 'none', '--quiet', *extra]) == 2
        assert _tree(tmp_path) == before
    one_line(capsys.readouterr().err, 'adcs-montecarlo', out)
    assert not no_run


def test_a_folder_of_other_things_is_never_replaced(tmp_path, no_run, capsys):
    campaign = _campaign(tmp_path)
    out = tmp_path / 'mine'
    out.mkdir()
    (out / 'notes.txt').write_text('mine\n')
    (out / 'summary.json').write_text('{}\n')   # a name of ours among others: still not ours
    (out / 'campaign.yaml').write_text('mine too\n')
    before = _tree(tmp_path)
    for overwrite in ([], ['--overwrite']):
        assert montecarlo.main([str(campaign), '--out', str(out), '--scheduler', 'none', '--quiet',
                                *overwrite]) == 2
        one_line(capsys.readouterr().err, 'adcs-montecarlo', out, 'not empty' if not overwrite else 'not an output')
    assert _tree(tmp_path) == before and not no_run


def test_an_existing_campaign_is_refused_then_replaced_whole_with_overwrite(tmp_path, capsys):
    campaign = _campaign(tmp_path)
    out = tmp_path / 'out'
    argv = [str(campaign), '--out', str(out), '--scheduler', 'none', '--quiet', '--no-figures']
    assert montecarlo.main(argv) == 0
    assert montecarlo.is_campaign_output(out)
    # what an older, other campaign left there: names this tool writes, for runs this one has not
    (out / 'replay').mkdir(exist_ok=True)
    (out / 'replay' / 'run_99.yaml').write_text('old\n')
    (out / 'figures').mkdir(exist_ok=True)
    (out / 'figures' / 'hist_old_metric.png').write_bytes(b'old')
    (out / 'paired.md').write_text('old\n')
    results = (out / 'results.csv').read_bytes()
    capsys.readouterr()
    before = _tree(tmp_path)
    assert montecarlo.main(argv) == 2                      # not asked to overwrite: refused, untouched
    one_line(capsys.readouterr().err, 'adcs-montecarlo', out, 'not empty')
    assert _tree(tmp_path) == before
    assert montecarlo.main([*argv, '--overwrite']) == 0    # replaced whole: nothing of the old one stays
    assert not (out / 'replay' / 'run_99.yaml').exists() and not (out / 'figures').exists()
    assert not (out / 'paired.md').exists()
    assert (out / 'results.csv').read_bytes() == results and montecarlo.is_campaign_output(out)


def test_an_export_never_replaces_a_file(tmp_path, capsys):
    campaign = _campaign(tmp_path)
    target = tmp_path / 'run_1.yaml'
    assert montecarlo.main([str(campaign), '--export-run', '1', '--out', str(target)]) == 0
    text = target.read_text()
    target.write_text(text + '# my notes\n')
    assert montecarlo.main([str(campaign), '--export-run', '1', '--out', str(target)]) == 2
    one_line(capsys.readouterr().err, 'adcs-montecarlo', target)
    assert target.read_text() == text + '# my notes\n'


def test_run_batch_copies_nothing_after_the_simulation(monkeypatch):
    """A copy after the simulation (of every run's sections) is where a large batch was lost to a
    MemoryError: any deepcopy once the batch has run fails here."""
    scenario = Scenario.load('microsat_pd_slew.yaml', {'dynamics.duration': 2.0})
    simulated = []
    run = BatchSimulation.run

    def tracked(self, *a, **k):
        result = run(self, *a, **k)
        simulated.append(True)
        return result

    deepcopy = copy.deepcopy

    def guarded(*a, **k):
        if simulated:
            raise MemoryError('a copy after the simulation')
        return deepcopy(*a, **k)

    monkeypatch.setattr(BatchSimulation, 'run', tracked)
    monkeypatch.setattr('adcs_sim.app.api.copy.deepcopy', guarded)
    for variants in (None, [{'pd_controller.kd': kd} for kd in (0.3, 0.4, 0.5)]):
        simulated.clear()
        batch = scenario.run_batch(variants)
        assert simulated and len(batch) == len(batch.sections) == (3 if variants else 1)
        assert all(s is not scenario.validated for s in batch.sections)
        assert batch.sections[0]['dynamics'] is not scenario.validated['dynamics']   # the user's scenario stays its own
        assert batch[0].metrics()['integrated_torque_Nms'] > 0
