"""Issue #31, class "Tracebacks instead of one line": every tool's output paths of every kind (a
file, a FIFO, a read-only folder, the tool's own input), ``adcs-tune-gsmn``'s values, the Dask
scheduler address, and a fuzz of each CLI's arguments. Each refusal is one line on stderr naming
the input, a non-zero exit in the tool's set, before any work (the function that would do the
work is replaced by one that records it was called) and nothing created.
"""
from __future__ import annotations

import contextlib
import socket
import threading
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.edge_paths import fifo, one_line, read_only, tiny_campaign
from support.paths import ROOT
from support.scenarios import make_scenario

from adcs_sim.app.analysis import analyze

from adcs_sim.app.campaign import montecarlo

from adcs_sim.app.analysis import repair

from adcs_sim.app.graph import runner

from adcs_sim.app.campaign import tuning

BAG = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'


class Reached(Exception):
    """The work of a tool was reached: its checks all passed."""


def _reached(*args, **kwargs):
    raise Reached


def _campaign(folder: Path, runs: int = 3) -> Path:
    return tiny_campaign(folder, 5.0, 3, runs)


@contextlib.contextmanager
def bad_output(tmp_path: Path, kind: str, input_folder: Path):
    """An unusable output path of ``kind``; ``input_folder`` holds the tool's input."""
    if kind == 'file':
        (tmp_path / 'a_file').write_text('mine\n')
        yield tmp_path / 'a_file'
    elif kind == 'fifo':
        yield fifo(tmp_path / 'a_fifo')
    elif kind == 'under_a_file':
        (tmp_path / 'a_file').write_text('mine\n')
        yield tmp_path / 'a_file' / 'out'
    elif kind == 'symlink_to_fifo':
        (tmp_path / 'link').symlink_to(fifo(tmp_path / 'a_fifo'))
        yield tmp_path / 'link'
    elif kind == 'read_only':
        with read_only(tmp_path / 'ro') as ro:
            yield ro / 'out'
    elif kind == 'input':
        yield input_folder
    else:
        raise AssertionError(kind)


KINDS = ['file', 'fifo', 'under_a_file', 'symlink_to_fifo', 'read_only', 'input']


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob('*'))


# --- adcs-run --out ----------------------------------------------------------------------------------

@pytest.mark.parametrize('kind', [k for k in KINDS if k != 'input'])   # (a scenario is a file: 'file')
def test_adcs_run_refuses_an_unusable_out_before_anything_starts(tmp_path, kind, monkeypatch, capsys):
    started = []
    monkeypatch.setattr(runner, 'lease_domain', lambda *a: started.append(a) or _reached())
    scenario = make_scenario(tmp_path)
    with bad_output(tmp_path, kind, tmp_path) as out:
        before = _listing(tmp_path)
        assert runner.main([str(scenario), '--out', str(out), '--no-progress']) == 1
        assert _listing(tmp_path) == before
    one_line(capsys.readouterr().err, 'adcs-run', out)
    assert not started


# --- adcs-analyze: report folders, --compare, layouts -----------------------------------------------

@pytest.mark.parametrize('kind', KINDS)
@pytest.mark.parametrize('mode', ['report', 'compare', 'foxglove', 'plotjuggler'])
def test_adcs_analyze_refuses_an_unusable_output_before_reading(tmp_path, kind, mode, monkeypatch, capsys):
    loaded = []
    monkeypatch.setattr(analyze, 'load_run', lambda *a, **k: loaded.append(a) or _reached())
    monkeypatch.setattr('adcs_sim.app.graph.layouts.load_run', lambda *a, **k: loaded.append(a) or _reached())
    bag = tmp_path / 'run' / 'bag'
    bag.mkdir(parents=True)
    for f in BAG.iterdir():
        (bag / f.name).symlink_to(f)
    option = {'report': ['--out'], 'compare': ['--compare', '--out'], 'foxglove': ['--foxglove-layout'],
              'plotjuggler': ['--plotjuggler-layout']}[mode]
    bags = [str(bag)] if mode != 'compare' else [str(bag), str(BAG)]
    with bad_output(tmp_path, kind, bag) as out:
        before = _listing(tmp_path)
        assert analyze.main([*bags, *option, str(out)]) != 0
        assert _listing(tmp_path) == before
    one_line(capsys.readouterr().err, 'adcs-analyze', out)
    assert not loaded


def test_adcs_analyze_compare_default_is_checked_and_relative(tmp_path, monkeypatch, capsys):
    """--compare with no --out: a new ``runs/comparison-<time>`` under the current folder, checked like
    any --out (here ``runs`` is a file of the user's: refused in one line, left as it was)."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(analyze, 'load_run', _reached)
    (tmp_path / 'runs').write_text('not a folder\n')
    assert analyze.main([str(BAG), str(BAG), '--compare']) == 2
    one_line(capsys.readouterr().err, 'adcs-analyze', 'runs/comparison-', 'not a folder')
    assert (tmp_path / 'runs').read_text() == 'not a folder\n'


# --- adcs-montecarlo --export-run and --scheduler -----------------------------------------------------

@pytest.mark.parametrize('kind', ['file', 'fifo', 'under_a_file', 'symlink_to_fifo', 'read_only', 'campaign',
                                  'folder'])
def test_export_run_refuses_an_unusable_target(tmp_path, kind, capsys):
    campaign = _campaign(tmp_path / 'c')
    if kind == 'campaign':
        target = contextlib.nullcontext(campaign)
    elif kind == 'folder':
        target = contextlib.nullcontext(tmp_path)
    else:
        target = bad_output(tmp_path, kind, tmp_path / 'c')
    with target as out:
        before = {p: p.read_bytes() for p in tmp_path.rglob('*') if p.is_file() and not p.is_symlink()}
        assert montecarlo.main([str(campaign), '--export-run', '1', '--out', str(out)]) == 2
        assert {p: p.read_bytes() for p in tmp_path.rglob('*') if p.is_file() and not p.is_symlink()} == before
    one_line(capsys.readouterr().err, 'adcs-montecarlo', out)


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.mark.parametrize('address', ['tcp://', 'tcp://127.0.0.1', 'tcp://127.0.0.1:0', 'tcp://127.0.0.1:99999',
                                     'tcp://127.0.0.1:x', 'ftp://127.0.0.1:8786', 'tcp://a b:8786', '::::',
                                     'tcp://127.0.0.1:8786/path', '', 'tcp://[::1:8786'])
def test_a_malformed_scheduler_address_is_refused_at_once(tmp_path, address, monkeypatch, capsys):
    monkeypatch.setattr(montecarlo, 'execute', _reached)
    monkeypatch.setattr(montecarlo.Campaign, 'load', _reached)
    assert montecarlo.main([str(_campaign(tmp_path)), '--scheduler', address, '--out', str(tmp_path / 'o')]) == 2
    one_line(capsys.readouterr().err, 'adcs-montecarlo', '--scheduler')
    assert not (tmp_path / 'o').exists()


def test_an_unreachable_scheduler_is_one_line_before_any_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(montecarlo, 'execute', _reached)
    address = f'tcp://127.0.0.1:{_closed_port()}'
    assert montecarlo.main([str(_campaign(tmp_path)), '--scheduler', address, '--out', str(tmp_path / 'o')]) == 2
    one_line(capsys.readouterr().err, 'adcs-montecarlo', address)
    assert not (tmp_path / 'o').exists()


@contextlib.contextmanager
def _foreign_server(reply: bytes):
    """A loopback TCP server that is no Dask scheduler: it accepts, sends ``reply``, then nothing."""
    server = socket.create_server(('127.0.0.1', 0))
    accepted = []

    def serve():
        conn, _ = server.accept()
        accepted.append(conn)
        conn.sendall(reply)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f'tcp://127.0.0.1:{server.getsockname()[1]}'
    finally:
        server.close()
        for conn in accepted:
            conn.close()


@pytest.mark.parametrize('reply', [b'', b'\xff' * 64], ids=['silent', 'garbage'])
def test_a_server_that_is_no_scheduler_is_one_line_before_any_run(tmp_path, reply, monkeypatch, capsys):
    """A silent server (the connection timeout, shortened here) or one answering garbage (the
    Dask client then read a frame length of 3 EiB and tracebacked on the allocation)."""
    monkeypatch.setattr(montecarlo, 'CONNECT_TIMEOUT_S', 0.5, raising=False)
    campaign = _campaign(tmp_path)
    monkeypatch.setattr(montecarlo, 'run_chunk', _reached)
    with _foreign_server(reply) as address:
        assert montecarlo.main([str(campaign), '--scheduler', address, '--out', str(tmp_path / 'o'), '--quiet']) == 2
    one_line(capsys.readouterr().err, 'adcs-montecarlo', address)
    assert not (tmp_path / 'o').exists()


@pytest.mark.parametrize('server', ['closed', 'garbage'])
def test_execute_names_an_unusable_scheduler_in_one_error(tmp_path, server, monkeypatch):
    """The connection itself (a scheduler gone between main's check and the run, or the API's
    execute): one CampaignError naming the address, whatever answered (a garbage answer made the
    Dask client allocate 3 EiB)."""
    from adcs_sim.app.campaign.plan import Campaign, CampaignError
    monkeypatch.setattr(montecarlo, 'CONNECT_TIMEOUT_S', 0.5, raising=False)
    campaign = Campaign.load(_campaign(tmp_path))
    with (_foreign_server(b'\xff' * 64) if server == 'garbage'
          else contextlib.nullcontext(f'tcp://127.0.0.1:{_closed_port()}')) as address:
        with pytest.raises(CampaignError, match=address.replace('.', r'\.')) as caught:
            montecarlo.execute(campaign, address, progress=False)
    assert len(str(caught.value).splitlines()) == 1


# --- adcs-bag-repair --------------------------------------------------------------------------------

def _truncated_bag(folder: Path) -> Path:
    folder.mkdir(parents=True)
    mcap = next(BAG.glob('*.mcap'))
    data = mcap.read_bytes()
    (folder / mcap.name.replace(BAG.name, folder.name)).write_bytes(data[:len(data) // 2])
    return folder


@pytest.mark.parametrize('kind', ['fifo', 'symlink_to_fifo', 'socket', 'device', 'read_only', 'read_only_file'])
def test_adcs_bag_repair_refuses_a_bag_it_cannot_rewrite_in_one_line(tmp_path, kind, monkeypatch, capsys):
    called = []
    monkeypatch.setattr(repair, 'repair', lambda *a, **k: called.append(a) or _reached())
    with contextlib.ExitStack() as stack:
        if kind == 'fifo':
            bag = fifo(tmp_path / 'bag')
        elif kind == 'symlink_to_fifo':
            bag = tmp_path / 'link'
            bag.symlink_to(fifo(tmp_path / 'bag'))
        elif kind == 'socket':
            bag = tmp_path / 'sock'
            server = stack.enter_context(socket.socket(socket.AF_UNIX))
            server.bind(str(bag))
        elif kind == 'device':
            bag = Path('/dev/null')
        else:
            folder = _truncated_bag(tmp_path / 'bag')
            stack.enter_context(read_only(folder))
            bag = folder if kind == 'read_only' else next(folder.glob('*.mcap'))
        assert repair.main([str(bag)]) == 1
    one_line(capsys.readouterr().err, 'adcs-bag-repair', bag)
    assert not called


# --- adcs-tune-gsmn ---------------------------------------------------------------------------------

TUNING = {'--inertia': '10', '--angle-deg': '30', '--kp1': '0.02', '--kd1': '0.5', '--gamma': '0.01'}


@pytest.mark.parametrize('option, value', [
    ('--inertia', '0'), ('--inertia', '-10'), ('--inertia', 'inf'), ('--inertia', 'nan'), ('--inertia', '1e-300'),
    ('--angle-deg', '0'), ('--angle-deg', 'nan'), ('--angle-deg', 'inf'), ('--angle-deg', '1e-300'),
    ('--angle-deg', '400'), ('--kp1', '0'), ('--kp1', '-1'), ('--kp1', 'inf'), ('--kp1', '1e-300'),
    ('--kd1', '0'), ('--kd1', 'nan'), ('--kd1', '1e300'), ('--gamma', '0'), ('--gamma', 'inf'),
    ('--gamma', '1e-300'), ('--gamma', 'nan'), ('--max-torque', '0'), ('--max-torque', 'inf'),
    ('--max-torque', 'nan'), ('--max-torque', '1e-320'), ('--tol-percent', '0'), ('--tol-percent', 'nan'),
    ('--tol-percent', '-2'), ('--tol-percent', 'inf')])
def test_tune_gsmn_refuses_a_value_the_model_cannot_take_in_one_line(option, value, monkeypatch, capsys):
    monkeypatch.setattr(tuning, 'simulate_single_axis', _reached)
    args = {**TUNING, option: value}
    assert tuning.main([x for kv in args.items() for x in kv] + ['--simulate']) == 2
    out, err = capsys.readouterr()
    one_line(err, 'adcs-tune-gsmn', option)
    assert 'nan' not in out


@pytest.mark.parametrize('args', [
    {'--kp1': '1e-12', '--kd1': '1e-7'},                 # t_sl of 1e9 s: a 224 GiB sample grid
    {'--gamma': '1e-9'},                                 # a coast of 1e9 s
    {'--inertia': '1e-6', '--kp1': '1e3', '--kd1': '1'},  # far past the closed forms' underdamped mode
])
def test_tune_gsmn_refuses_a_simulation_it_cannot_sample(args, monkeypatch, capsys):
    monkeypatch.setattr(tuning, 'simulate_single_axis', _reached)
    argv = {**TUNING, **args}
    assert tuning.main([x for kv in argv.items() for x in kv] + ['--simulate']) == 2
    one_line(capsys.readouterr().err, 'adcs-tune-gsmn')


# --- a fuzz of each CLI's arguments -------------------------------------------------------------------

@pytest.fixture(scope='module')
def paths(tmp_path_factory):
    """Paths of every kind, shared by the fuzzers' examples: inputs and outputs."""
    root = tmp_path_factory.mktemp('fuzz')
    campaign = _campaign(root / 'campaign')
    (root / 'file').write_text('x: 1\n')
    (root / 'junk').write_bytes(bytes(range(256)))
    bag = root / 'run' / 'bag'   # the committed bag's files, linked: a report beside it is written in root
    bag.mkdir(parents=True)
    for f in BAG.iterdir():
        (bag / f.name).symlink_to(f)
    (root / 'full').mkdir()
    (root / 'full' / 'mine').write_text('mine\n')
    fifo(root / 'fifo')
    with read_only(root / 'ro'):
        untouched = [root / 'file', root / 'junk', root / 'full' / 'mine', campaign, *bag.iterdir()]
        yield {'root': root, 'campaign': campaign, 'bag': bag, 'untouched': untouched,
               'scenario': next((root / 'campaign').glob('scenario_*')),
               'outputs': [str(root / n) for n in ('file', 'full', 'fifo', 'ro', 'ro/x', 'file/x', 'new', 'junk')]
               + [str(campaign), str(bag), ''],
               'inputs': [str(root / n) for n in ('file', 'full', 'missing')]}
    # (a non-UTF-8 scenario or campaign file: the YAML readers' part of issue #31, not fuzzed here)


NUMBERS = ['0', '-1', '1', '3', 'nan', 'inf', '-inf', '1e-300', '1e300', '0.5', '10', 'x', '']
VALUES = ['0', '-1', 'nan', 'inf', '1e-300', '1e300', '0.01', '0.02', '0.5', '10', '30']   # parse as floats


def _call(main, argv, codes, untouched=()):
    """``main(argv)`` exits with a code of ``codes`` (or reaches the work), no exception escapes,
    and the files in ``untouched`` (the user's, the inputs) are as they were."""
    before = {p: p.read_bytes() for p in untouched}
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    except Reached:
        code = None
    assert code is None or code in codes, (argv, code)
    assert {p: p.read_bytes() for p in untouched} == before, argv


def _argv(draw, paths, first: list[str], options: dict[str, str]) -> list[str]:
    argv = [draw(st.sampled_from(first))]
    for option in draw(st.lists(st.sampled_from(sorted(options)), max_size=4)):
        kind = options[option]
        argv.append(option)
        if kind == 'flag':
            continue
        pool = {'out': paths['outputs'], 'in': paths['inputs'], 'number': NUMBERS,
                'scheduler': ['none', 'local', 'tcp://127.0.0.1:1', 'tcp://', 'x:y', 'tcp://[::1]:0']}[kind]
        argv.append(draw(st.sampled_from(pool)))
    return argv


FUZZ = settings(derandomize=True, max_examples=30, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


@FUZZ
@given(data=st.data())
def test_fuzz_adcs_run_argv(paths, monkeypatch, data, capsys):
    monkeypatch.chdir(paths['root'])
    monkeypatch.setattr(runner, 'lease_domain', _reached)
    argv = _argv(data.draw, paths, [str(paths['scenario']), *paths['inputs']],
                 {'--out': 'out', '--duration': 'number', '--tolerance-deg': 'number', '--domain-id': 'number',
                  '--restart': 'number', '--no-progress': 'flag'})
    _call(runner.main, argv, {1, 2}, paths['untouched'])


def _probe_writer(out, comparison: bool = False):
    """Stands for a report writer (slow: matplotlib): what it does first to ``out`` (create it, write
    a file), done here; reached only with an output that takes it, holding nothing but a report."""
    out = Path(out)
    if out.is_dir():
        assert all(p.suffix in ('.md', '.png', '.svg', '.csv') for p in out.iterdir()), out
    out.mkdir(parents=True, exist_ok=True)
    (out / 'report.md').write_text('probe\n')
    return (out / 'comparison.csv', out / 'comparison.md') if comparison else out / 'report.md'


@FUZZ
@given(data=st.data())
def test_fuzz_adcs_analyze_argv(paths, monkeypatch, data, capsys):
    from adcs_sim.app.report import comparison, single_run
    monkeypatch.chdir(paths['root'])
    monkeypatch.setattr(single_run, 'write_report', lambda run, out, *a, **k: _probe_writer(out))
    monkeypatch.setattr(comparison, 'write_comparison', lambda runs, out, *a, **k: _probe_writer(out, True))
    argv = _argv(data.draw, paths, [str(paths['bag'])] * 3 + paths['inputs'],
                 {'--out': 'out', '--compare': 'flag', '--foxglove-layout': 'out', '--plotjuggler-layout': 'out',
                  '--tolerance-deg': 'number', '--no-report': 'flag'})
    if data.draw(st.booleans()):   # a second bag (--compare, one report folder per run)
        argv.insert(1, str(paths['bag']))
    _call(analyze.main, argv, {0, 1, 2}, paths['untouched'])


@FUZZ
@given(data=st.data())
def test_fuzz_adcs_montecarlo_argv(paths, monkeypatch, data, capsys):
    """The campaign runs (3 short runs, in this process: 'local' is run as 'none')."""
    monkeypatch.chdir(paths['root'])
    execute = montecarlo.execute
    monkeypatch.setattr(montecarlo, 'execute', lambda c, s, w, progress: execute(
        c, 'none' if s == 'local' else s, w, progress=False))
    argv = _argv(data.draw, paths, [str(paths['campaign'])] * 3 + paths['inputs'],
                 {'--runs': 'number', '--workers': 'number', '--export-run': 'number',
                  '--scheduler': 'scheduler', '--overwrite': 'flag', '--paired-with': 'out'})
    out = ['--out', data.draw(st.sampled_from(paths['outputs']))]   # every example: an output of some kind
    _call(montecarlo.main, [*argv, *out, '--no-figures', '--quiet'], {0, 1, 2}, paths['untouched'])


@FUZZ
@given(data=st.data())
def test_fuzz_adcs_bag_repair_argv(paths, data, capsys):
    pool = [p for p in paths['outputs'] if p != str(paths['bag'])]   # (a bag is rewritten in place)
    _call(repair.main, _argv(data.draw, {**paths, 'outputs': pool}, pool, {'--force': 'flag'}),
          {0, 1, 2}, paths['untouched'])


@FUZZ
@given(values=st.lists(st.sampled_from(VALUES), min_size=6, max_size=6), simulate=st.booleans())
def test_fuzz_adcs_tune_gsmn_values(monkeypatch, capsys, values, simulate):
    monkeypatch.setattr(tuning, 'simulate_single_axis', _reached)
    names = ['--inertia', '--angle-deg', '--kp1', '--kd1', '--gamma', '--max-torque']
    argv = [x for kv in zip(names, values) for x in kv] + (['--simulate'] if simulate else [])
    capsys.readouterr()
    _call(tuning.main, argv, {0, 2})
    out = capsys.readouterr().out
    assert 'nan' not in out and ' inf' not in out, (argv, out)
