"""Every YAML reader behind the same limits as scenario files (issue #31, "Campaigns" and "Tracebacks
instead of one line"): the campaign file, ``--reference``, the papers' ``docs/*/paper.yaml``, a bag's
``metadata.yaml`` (ours and rosbags'), its embedded scenario and its QoS profiles.

Each hostile document (an alias bomb of a few hundred bytes, nesting past 16 levels, more than
10 000 keys, over 1 MiB, bytes that are not UTF-8) is refused in one line naming the file and what
is wrong, in bounded memory, by a reader that raises; a lenient reader (a bag's listing, the papers'
figures, the embedded scenario, QoS) ignores it as it ignores any unreadable one. Fuzzed YAML text
gives a value or that one-line error, never a traceback.
"""
from __future__ import annotations

import tempfile
import tracemalloc
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adcs_msgs_py import params_file
from adcs_msgs_py.params import ParameterError
from adcs_sim.app.campaign.plan import Campaign, CampaignError
from adcs_sim.app.report.comparison import load_reference
from adcs_sim.app.report.lead import paper_values
from adcs_sim.app.analysis.run_data import _scenario
from adcs_sim.bag import repair, storage
from adcs_sim.bag.reader import read_raw

LIMIT = params_file.MAX_FILE_BYTES
BOMB = '[' + ', '.join(['&a [' + ', '.join(['"lol"'] * 9) + ']'] + [
    f'&{c} [' + ', '.join([f'*{p}'] * 9) + ']' for p, c in zip('abcdefgh', 'bcdefghi')]) + ']'   # 9**9 values
PAYLOADS = {   # a YAML value (one line), and the words of the refusal
    'alias bomb': (BOMB.encode(), 'alias'),
    'deep nesting': (b'[' * 20 + b']' * 20, 'deeper than 16 levels'),
    'too many keys': (('{' + ', '.join(f'k{i}: 1' for i in range(params_file.MAX_KEYS + 1)) + '}').encode(),
                      'more than 10000 keys'),
    'too big': (b'"' + b'a' * (LIMIT + 1) + b'"', f'the limit is {LIMIT} bytes'),
    'not UTF-8': (b'"caf\xe9"', 'not UTF-8 text: byte'),
}
# Each reader: (a valid document of its format ending where the payload goes, as one more key or item;
# where the file goes; how to read it: (value, error message or None)).
SCENARIO = b'dynamics:\n  ros__parameters:\n    duration: 5.0\n    extra: '


def _raising(read, errors):
    def attempt(path):
        try:
            return read(path), None
        except errors as exc:
            return None, str(exc)
    return attempt


def _paper(path):
    return paper_values('run_a', docs=path.parent.parent)


def _sqlite_bag(path):
    (path.parent / 'bag_0.db3').write_bytes(b'SQLite format 3\x00' + bytes(100))
    return list(read_raw(path.parent))


READERS = {
    'scenario': (SCENARIO, 'scenario.yaml', _raising(lambda p: params_file.load_params_file(str(p)), ParameterError)),
    'campaign': (b'campaign:\n  scenario: microsat_pd_slew.yaml\n  runs: 2\nextra: ', 'campaign.yaml',
                 _raising(Campaign.load, CampaignError)),
    'reference': (b'source: a paper\nruns:\n  run_a: {integrated_torque_Nms: 1.0}\nextra: ', 'paper.yaml',
                  _raising(load_reference, ValueError)),
    'rosbags metadata.yaml': (b'rosbag2_bagfile_information:\n  version: 5\nextra: ', 'bag/metadata.yaml',
                              _raising(_sqlite_bag, ValueError)),
}
LENIENT = {   # what the reader gives for a file it cannot read
    'papers': (b'source: a paper\nruns:\n  run_a: {m: 1.0}\nextra: ', 'docs/seed009/paper.yaml', _paper, ('', {})),
    'bag listing': (b'rosbag2_bagfile_information:\n  relative_file_paths: [bag_0.mcap]\nextra: ', 'bag/metadata.yaml',
                    lambda p: storage._listed_files(p.parent), []),
    'embedded scenario': (SCENARIO, 'scenario.yaml',
                          lambda p: _scenario(p.read_bytes().decode('utf-8', 'surrogateescape'), 'the bag'), None),
    'QoS profiles': (b'- {history: keep_last, depth: 10}\n- ', 'qos.yaml',
                     lambda p: repair._offered_qos(p.read_bytes().decode('utf-8', 'surrogateescape'), '/state'), []),
}


def _write(tmp_path: Path, where: str, base: bytes, payload: bytes) -> Path:
    path = tmp_path / where
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(base + payload + b'\n')
    return path


def _peak_mib(call):
    tracemalloc.start()
    try:
        result = call()
        return result, tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize('payload', PAYLOADS)
@pytest.mark.parametrize('reader', READERS)
def test_each_reader_refuses_a_hostile_file_in_one_line(tmp_path, reader, payload):
    base, where, read = READERS[reader]
    data, words = PAYLOADS[payload]
    path = _write(tmp_path, where, base, data)
    (value, error), peak = _peak_mib(lambda: read(path))
    assert error is not None, f'{reader} read {payload}: {value!r:.200}'
    assert '\n' not in error and words in error, error
    assert str(path) in error, error           # names the file
    assert peak < 40, f'{peak:.0f} MiB'        # never more than a small multiple of the 1 MiB limit


@pytest.mark.parametrize('payload', PAYLOADS)
@pytest.mark.parametrize('reader', LENIENT)
def test_each_lenient_reader_ignores_a_hostile_file(tmp_path, reader, payload):
    base, where, read, unreadable = LENIENT[reader]
    path = _write(tmp_path, where, base, PAYLOADS[payload][0])
    value, peak = _peak_mib(lambda: read(path))
    assert value == unreadable, f'{reader} read {payload}: {value!r:.200}'
    assert peak < 40, f'{peak:.0f} MiB'
    assert read(_write(tmp_path / 'plain', where, base, b'1')) != unreadable   # the same file, plain: read


def test_the_limits_allow_what_a_file_within_them_holds():
    """Aliases count as what they repeat, within the same limits as a file that spells it out."""
    assert params_file.parse_yaml('base: &b {kp: 1.0, kd: [1, 2]}\nrun: {<<: *b, kp: 2.0}\n', 'x.yaml') == {
        'base': {'kp': 1.0, 'kd': [1, 2]}, 'run': {'kp': 2.0, 'kd': [1, 2]}}
    with pytest.raises(params_file.YamlError, match=r"x\.yaml:3: key 'a' repeats the one at line 1"):
        params_file.parse_yaml('a: 1\nb: 2\na: 3\n', 'x.yaml')
    with pytest.raises(params_file.YamlError, match='x.yaml is not a regular file'):
        params_file.load_yaml('/dev/null', 'x.yaml')


TOKENS = ['a', 'b', ':', ': ', ' ', '  ', '\n', '- ', '[', ']', '{', '}', ',', '&a ', '*a', '&b ', '*b', '<<: ',
          '"', "'", '!!str ', '!!int ', '!!python/object/apply:os.system ', '1', '-1', '1e-3', '.inf', '.nan',
          '0x1F', '2020-13-45', '12:30:45', '~', 'null', 'yes', '#', '? ', '|', '>', '%YAML 1.1\n', '---\n',
          '...\n', '\t', '\x00', '\udcff', '\udce9', 'é', '\u2028', '9' * 30, 'ros__parameters', 'dynamics',
          'campaign', 'runs', 'rosbag2_bagfile_information']


@settings(derandomize=True, max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(text=st.lists(st.sampled_from(TOKENS), max_size=40).map(''.join))
def test_fuzzed_yaml_gives_a_value_or_one_line(text):
    data = text.encode('utf-8', 'surrogateescape')
    with tempfile.TemporaryDirectory() as folder:
        for name, (_, where, read) in READERS.items():
            if name == 'rosbags metadata.yaml':
                continue   # rosbags' own reader: its errors are one line already (storage.any_reader)
            path = Path(folder) / name / Path(where).name
            path.parent.mkdir(exist_ok=True)
            path.write_bytes(data)
            _, error = read(path)
            assert error is None or '\n' not in error, (name, error)
        for name, (_, where, read, _) in LENIENT.items():
            path = Path(folder) / name / where
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            read(path)   # a value (what it could read, or its "unreadable" one), never an exception
