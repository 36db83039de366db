"""One reader of scenario files (issue #17): what the runner reads is what rcl gives the nodes.

``load_params_file`` (the runner's and every node's reading) against an in-process rclpy node
declaring its parameters from the same ``--params-file``: for random scenario-like documents
(YAML 1.1/1.2 corner cases: ``1e-3``, ``.inf``, ``yes``/``on``, numbers in quotes, ``1_000``,
hexadecimal, nested maps, long and empty arrays, mixed arrays) both give the same values of the
same types, and both accept or refuse the file together. The size and complexity limits refuse a
file quickly, before rcl parses it, each with a message naming its limit.
"""
from __future__ import annotations

import array
import math

import pytest
import rclpy
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions

from adcs_msgs_py import params_file as params_module
from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import load_params_file

BUILTINS = ('use_sim_time', 'start_type_description_service')
NODE_NAMES = ('dynamics', '/pd_controller', 'recorder', '/fault_injector')

TRICKY = ['1e-3', '1E5', '-2.5e+10', '.inf', '-.inf', '.Inf', '+.INF', '.nan', '.NaN', '3.', '.5', '0.0', '-0',
          '0x1F', '0o17', '017', '+5', '1_000', '12:30', 'yes', 'no', 'on', 'off', 'y', 'n', 'Y', 'True',
          'FALSE', 'true', 'null', '~', 'Null', '"12"', "'1e-3'", '"yes"', "'true'", '"~"', 'abc', 'a b',
          '"a: b"', "''", '""', '2001-12-14', '1.0.0', '9223372036854775807', '9223372036854775808',
          '-9223372036854775809', '1e400', '0b101', '=', '-', '"\\u00e9"']
INTS = st.integers(-2**63, 2**63 - 1).map(str)
FLOATS = st.floats(allow_nan=False, allow_infinity=False).flatmap(
    lambda x: st.sampled_from([repr(x), f'{x:e}', f'{x:.3g}']))
WORDS = st.from_regex(r'[a-z][a-z0-9_]{0,6}', fullmatch=True)
SCALARS = st.one_of(st.sampled_from(TRICKY), INTS, FLOATS, WORDS)
KEYS = st.from_regex(r'[a-z][a-z0-9_]{0,7}', fullmatch=True).filter(lambda k: k not in BUILTINS)


@st.composite
def arrays(draw, indent: str):
    kind = draw(st.sampled_from([st.sampled_from(TRICKY), INTS, FLOATS, WORDS, SCALARS]))
    values = draw(st.lists(kind, max_size=draw(st.sampled_from([3, 40, 300]))))
    if draw(st.booleans()) or not values:
        return ' [' + ', '.join(values) + ']'
    return ''.join(f'\n{indent}- {v}' for v in values)


@st.composite
def mapping(draw, indent: str, depth: int) -> str:
    lines = []
    for key in draw(st.lists(KEYS, min_size=1, max_size=5, unique=True)):
        choice = draw(st.integers(0, 9 if depth < 3 else 7))
        if choice < 5:
            lines.append(f'{indent}{key}: {draw(SCALARS)}')
        elif choice < 8:
            lines.append(f'{indent}{key}:{draw(arrays(indent + "  "))}')
        else:
            lines.append(f'{indent}{key}:\n{draw(mapping(indent + "  ", depth + 1))}')
    return '\n'.join(lines)


@st.composite
def documents(draw) -> str:
    nodes = draw(st.lists(st.sampled_from(NODE_NAMES), min_size=1, max_size=3, unique=True))
    return ''.join(f'{node}:\n  ros__parameters:\n{draw(mapping("    ", 1))}\n' for node in nodes)


def _canonical(value):
    """(type, value) with NaN comparable; arrays as lists."""
    if isinstance(value, array.array):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return ('list', tuple(_canonical(v) for v in value))
    if isinstance(value, float) and math.isnan(value):
        return ('float', 'nan')
    return (type(value).__name__, value)


def what_nodes_get(path) -> dict | None:
    """{node: {parameter: value}} as rclpy nodes declare them from ``--params-file path``, or None
    if rclpy.init refuses the file."""
    context = Context()
    try:
        rclpy.init(args=['--ros-args', '--params-file', str(path)], context=context,
                   signal_handler_options=SignalHandlerOptions.NO)
    except Exception:   # rclpy raises the rcl error as RCLError (a private type)
        return None
    out = {}
    try:
        for name in sorted({n.lstrip('/') for n in NODE_NAMES}):
            try:
                node = rclpy.create_node(name, context=context, automatically_declare_parameters_from_overrides=True,
                                         start_parameter_services=False, enable_rosout=False)
            except ValueError:   # e.g. an empty array: no type, rclpy cannot declare it
                return None
            try:
                got = {k: p.value for k, p in node.get_parameters_by_prefix('').items()
                       if k not in BUILTINS and p.type_ != p.Type.NOT_SET}
            finally:
                node.destroy_node()
            if got:
                out[name] = got
    finally:
        rclpy.try_shutdown(context=context)
    return out


def _runner_reads(path) -> dict | None:
    try:
        sections = load_params_file(str(path))
    except ParameterError:
        return None
    return {n: s for n, s in sections.items() if s}


@settings(max_examples=60, phases=[Phase.explicit, Phase.generate], derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(text=documents())
def test_runner_reads_what_the_nodes_get(ros_domain, tmp_path, text):
    path = tmp_path / 'scenario.yaml'
    path.write_text(text)
    ours, theirs = _runner_reads(path), what_nodes_get(path)
    assert (ours is None) == (theirs is None), f'runner {"refused" if ours is None else "accepted"}, ' \
                                              f'rcl {"refused" if theirs is None else "accepted"}:\n{text}'
    if ours is not None:
        assert {n: {k: _canonical(v) for k, v in s.items()} for n, s in ours.items()} == \
            {n: {k: _canonical(v) for k, v in s.items()} for n, s in theirs.items()}, text


def test_the_yaml_1_1_corner_cases_read_as_ros_reads_them(tmp_path):
    path = tmp_path / 'scenario.yaml'
    path.write_text('pd_controller:\n  ros__parameters:\n    kp: 1e-3\n    limit: .inf\n    on_flag: yes\n'
                    '    quoted: "12"\n    grouped: 1_000\n')
    assert load_params_file(str(path)) == {'pd_controller': {
        'kp': 0.001, 'limit': math.inf, 'on_flag': True, 'quoted': '12', 'grouped': '1_000'}}


def _refused_quickly(path, limit_words: str) -> None:
    with pytest.raises(ParameterError, match=limit_words) as info:
        load_params_file(str(path))
    assert len(str(info.value)) < 200 + len(str(path))   # a short message


@pytest.mark.parametrize('what, limit_words', [
    ('size', 'bytes'), ('depth', 'deeper than 16 levels'), ('keys', 'more than 10000 keys'),
    ('array', 'array longer than 100000 values'),
])
def test_each_limit_refuses_before_rcl_parses(tmp_path, monkeypatch, what, limit_words):
    path = tmp_path / f'{what}.yaml'
    head = 'dynamics:\n  ros__parameters:\n'
    if what == 'size':
        path.write_text(head + '    x: "' + 'a' * (params_module.MAX_FILE_BYTES + 1) + '"\n')
    elif what == 'depth':
        path.write_text(head + ''.join('  ' * (i + 2) + f'k{i}:\n' for i in range(20)) + '  ' * 22 + 'x: 1\n')
    elif what == 'keys':
        path.write_text(head + ''.join(f'    k{i}: 1\n' for i in range(params_module.MAX_KEYS + 1)))
    else:
        path.write_text(head + '    x: [' + ','.join(['1'] * (params_module.MAX_ARRAY_LENGTH + 1)) + ']\n')
    from adcs_msgs_py import rcl_params   # load_params_file imports rcl's parser from here when it reads
    monkeypatch.setattr(rcl_params, 'parse_file', lambda p: pytest.fail('rcl was asked to parse it'))
    _refused_quickly(path, limit_words)


def test_a_huge_file_is_refused_by_its_size_without_reading_it(tmp_path):
    path = tmp_path / 'huge.yaml'
    with open(path, 'wb') as f:
        f.truncate(64 << 30)   # 64 GiB, sparse: never read
    _refused_quickly(path, f'the limit is {params_module.MAX_FILE_BYTES} bytes')


def test_an_empty_array_is_refused_naming_the_key(ros_domain, tmp_path):
    """rcl reads ``[]`` as a value of no type, which rclpy cannot declare (the node would fail at
    start with a traceback): the reader refuses it first, naming the key."""
    path = tmp_path / 'scenario.yaml'
    path.write_text('dynamics:\n  ros__parameters:\n    duration: 5.0\n    wheels:\n      names: []\n')
    with pytest.raises(ParameterError, match=r"'dynamics\.ros__parameters\.wheels\.names'.*leave the key out"):
        load_params_file(str(path))
    assert what_nodes_get(path) is None
