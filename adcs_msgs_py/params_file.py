"""Reading YAML within limits, and a ROS 2 params file (a scenario file) exactly as the nodes get it.

:func:`check_limits` is the one gate in front of every YAML reader (scenario files, campaign files,
published figures, a bag's ``metadata.yaml``, its embedded scenario and QoS profiles): the size,
the encoding (UTF-8), the depth, the keys, the array lengths and the values that aliases expand to
are counted on libyaml's event stream before anything is built, so a hostile file is refused in
bounded memory and time, in one line naming it. :func:`load_yaml` then builds a plain document.

:func:`load_params_file` is the one reader of scenarios: the runner, the batch engine's users, the
API, every node (before ``rclpy.init`` parses the same file for its overrides) and the analysis (a
bag's embedded copy: :func:`load_params_text`) call it. After :func:`check_limits` it reads the
file with rcl's own parser (:mod:`adcs_msgs_py.rcl_params`), so the values and types are those rcl
gives the nodes and a file rcl refuses is refused; a section or parameter written twice (rcl merges
them) is warned about, naming both lines (:class:`RepeatedKeyWarning`). No graph, no DDS participant.
"""
from __future__ import annotations

import contextlib
import os
import re
import stat
import sys
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import yaml

from adcs_msgs_py.params import ParameterError

# Limits of a YAML file, checked before it is parsed (a scenario file is a few kB, its longest
# array a few hundred values): a file past them is refused quickly, in bounded memory.
MAX_FILE_BYTES = 1 << 20
MAX_DEPTH = 16            # nested mappings and sequences
MAX_KEYS = 10_000         # mapping keys in the whole file
MAX_ARRAY_LENGTH = 100_000
# Values of the whole document, aliases expanded: no more than a file at the size limit could spell
# out, so an alias "bomb" of a few hundred bytes is refused instead of expanding to billions.
MAX_NODES = MAX_FILE_BYTES
WILDCARDS = ('*', '**')
INT64 = (-(1 << 63), (1 << 63) - 1)


EVENT_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)   # libyaml's scanner when PyYAML has it


class YamlError(ValueError):
    """A YAML file refused: over a limit, not UTF-8, not YAML or a key written twice (one line, naming it)."""


class RepeatedKeyWarning(UserWarning):
    """A scenario writes a section or parameter twice: rcl merges them, so what flies is not what a
    reader keeping one of the two (PyYAML, a person) sees. The message names both lines."""


@dataclass
class _Open:
    """An open collection of the event stream."""
    mapping: bool
    path: tuple            # its place in the document (scenario: canonical parameter path)
    serial: int            # which collection (a repeat in the same mapping vs. in a repeated parent)
    anchor: str | None
    nodes0: int            # document totals when it opened (what an alias to it expands to)
    keys0: int
    items: int = 0
    height: int = 1        # collection levels in it, itself included
    key: Any = None        # the key whose value comes next (mapping)
    key_line: int = 0


@dataclass
class YamlCheck:
    """What :func:`check_limits` found: the text, libyaml's syntax error (one line) and the keys
    written twice (one line each, naming both lines)."""
    text: str
    syntax_error: str | None = None
    repeats: list[str] = field(default_factory=list)


def _line(event) -> int:
    return event.start_mark.line + 1


def _syntax(exc: yaml.YAMLError) -> str:
    """libyaml's error in one line, its place as ``line L, column C`` (no stream name)."""
    mark = getattr(exc, 'problem_mark', None)
    problem = getattr(exc, 'problem', None)
    if problem and mark is not None:
        return f'{problem} at line {mark.line + 1}, column {mark.column + 1}'
    return ' '.join(str(exc).split())


def _read(path, name: str) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_FILE_BYTES` (a FIFO or device is never
    opened: reading one may block or never end)."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            raise YamlError(f'{name} is not a regular file')
        if st.st_size > MAX_FILE_BYTES:
            raise YamlError(f'{name} is {st.st_size} bytes; the limit is {MAX_FILE_BYTES} bytes')
        with open(path, 'rb') as f:
            return f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise YamlError(f'cannot read {name}: {exc.strerror}') from None


def check_limits(data: bytes | str, name: str, aliases: bool = True, params: bool = False) -> YamlCheck:
    """Check a YAML document against :data:`MAX_FILE_BYTES`, UTF-8, :data:`MAX_DEPTH`,
    :data:`MAX_KEYS`, :data:`MAX_ARRAY_LENGTH` and :data:`MAX_NODES`, aliases counted as what they
    expand to (``aliases=False``: refused). Raises :class:`YamlError` naming ``name`` and the limit.

    Counted on libyaml's event stream (the scanner rcl's parser uses too; no value is built). Keys
    written twice are listed: in one mapping, or (``params``: a ROS params file, as rcl merges it) a
    section (``/node`` is ``node``) or a parameter (``a.b`` is ``a: {b}``) met again anywhere."""
    if isinstance(data, str):
        try:
            data = data.encode('utf-8', errors='surrogateescape')   # bytes a reader kept undecoded come back
        except UnicodeEncodeError as exc:
            raise YamlError(f'{name} is not UTF-8 text: character {exc.start} is a lone surrogate') from None
    if len(data) > MAX_FILE_BYTES:
        raise YamlError(f'{name} is {len(data)} bytes; the limit is {MAX_FILE_BYTES} bytes')
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise YamlError(f'{name} is not UTF-8 text: byte {exc.start} (0x{data[exc.start]:02x}) {exc.reason}') from None
    scan = _Scan(YamlCheck(text), name, aliases, params)
    try:
        for event in yaml.parse(text, Loader=EVENT_LOADER):
            scan.event(event)
    except yaml.YAMLError as exc:
        scan.out.syntax_error = _syntax(exc)
    return scan.out


class _Scan:
    """:func:`check_limits`' count of one document, event by event."""

    def __init__(self, out: YamlCheck, name: str, aliases: bool, params: bool) -> None:
        self.out, self.name, self.aliases, self.params = out, name, aliases, params
        self.stack: list[_Open] = []
        self.anchors: dict[str, tuple[int, int, int]] = {}   # anchor: (nodes, keys, height) it expands to
        self.seen: dict[tuple, tuple[int, int, bool]] = {}    # key path: (line, mapping serial, value is a leaf)
        self.nodes = self.keys = self.serial = 0

    def event(self, event) -> None:
        if isinstance(event, yaml.CollectionEndEvent):
            closed = self.stack.pop()
            if closed.anchor:
                self.anchors[closed.anchor] = (self.nodes - closed.nodes0, self.keys - closed.keys0, closed.height)
            if self.stack:
                self.stack[-1].height = max(self.stack[-1].height, closed.height + 1)
        elif isinstance(event, yaml.NodeEvent):
            weight = self._weight(event)
            path = self._item(event) if self.stack else ()
            self._count(weight, len(self.stack) + (1 if isinstance(event, yaml.CollectionStartEvent) else weight[2]))
            if isinstance(event, yaml.CollectionStartEvent):
                self.serial += 1
                self.stack.append(_Open(isinstance(event, yaml.MappingStartEvent), path, self.serial, event.anchor,
                                        self.nodes - 1, self.keys))
            elif isinstance(event, yaml.ScalarEvent) and event.anchor:
                self.anchors[event.anchor] = (1, 0, 0)

    def _weight(self, event) -> tuple[int, int, int]:
        """(values, keys, nesting) the node adds: an alias adds what its anchor holds."""
        if not isinstance(event, yaml.AliasEvent):
            return 1, 0, 0
        if not self.aliases:
            raise YamlError(f'{self.name}:{_line(event)}: alias *{event.anchor}: this kind of file has no '
                            'aliases (refused)')
        if event.anchor not in self.anchors:
            raise YamlError(f'{self.name}:{_line(event)}: alias *{event.anchor} names no complete anchor before it')
        return self.anchors[event.anchor]

    def _item(self, event) -> tuple:
        """One more item in the open collection: a key, its value or an array element; its path."""
        top = self.stack[-1]
        top.items += 1
        if top.mapping and top.items % 2:
            self.keys += 1
            top.key, top.key_line = (event.value if isinstance(event, yaml.ScalarEvent) else None), _line(event)
            return ()
        if top.mapping:
            path = _value_path(top, self.params)
            if top.key is not None:
                _repeat(self.out, self.seen, top, path, not isinstance(event, yaml.MappingStartEvent), self.name,
                        self.params)
            return path
        if top.items > MAX_ARRAY_LENGTH:
            raise YamlError(f'{self.name} has an array longer than {MAX_ARRAY_LENGTH} values (the limit)')
        return top.path + (top.items,)

    def _count(self, weight: tuple[int, int, int], depth: int) -> None:
        self.nodes += weight[0]
        self.keys += weight[1]
        if self.keys > MAX_KEYS:
            raise YamlError(f'{self.name} has more than {MAX_KEYS} keys (the limit; aliases count as what they repeat)')
        if self.nodes > MAX_NODES:
            raise YamlError(f'{self.name} expands to more than {MAX_NODES} values (the limit; aliases count as '
                            'what they repeat)')
        if depth > MAX_DEPTH:
            raise YamlError(f'{self.name} nests deeper than {MAX_DEPTH} levels (the limit)')


def _value_path(top: _Open, params: bool) -> tuple:
    """The path of ``top.key``'s value: in a params file rcl's parameter name (``/node`` is ``node``
    at the top, ``a.b`` is ``a: {b}``), else the key under its mapping."""
    if top.key is None:
        return top.path + (('?', top.serial),)
    if not params:
        return top.path + (top.key,)
    key = str(top.key)
    return top.path + ((key.lstrip('/'),) if not top.path else tuple(key.split('.')))


def _repeat(out: YamlCheck, seen: dict, top: _Open, path: tuple, leaf: bool, name: str, params: bool) -> None:
    """Record the key ``path`` (at ``top.key_line``); list it in ``out.repeats`` when it was met before:
    in the same mapping, or in a params file a section, or a parameter (a leaf either time)."""
    line = top.key_line
    if path not in seen:
        seen[path] = (line, top.serial, leaf)
        return
    first, serial, was_leaf = seen[path]
    if not params:
        if serial == top.serial:
            out.repeats.append(f'{name}:{line}: key {str(top.key)!r} repeats the one at line {first} '
                               '(a mapping holds each key once)')
        return
    if len(path) == 1:
        out.repeats.append(f'{name}:{line}: section {path[0]!r} repeats the one at line {first}: the node gets '
                           'the two merged (adcs-run --explain shows the values it gets)')
    elif serial == top.serial or leaf or was_leaf:
        out.repeats.append(f'{name}:{line}: {".".join(path)!r} repeats line {first}: the node gets one value '
                           'for both (adcs-run --explain shows which)')


def load_yaml(path, name: str | None = None, aliases: bool = True) -> Any:
    """The document of the YAML file at ``path`` (PyYAML's safe types), within :func:`check_limits`;
    :class:`YamlError` (one line naming ``name``, default the path) when it is refused."""
    name = name or str(path)
    return parse_yaml(_read(path, name), name, aliases)


def parse_yaml(data: bytes | str, name: str, aliases: bool = True) -> Any:
    """:func:`load_yaml` of a document in memory (e.g. a bag's channel metadata)."""
    check = check_limits(data, name, aliases)
    if check.syntax_error:
        raise YamlError(f'{name} is not valid YAML: {check.syntax_error}')
    if check.repeats:
        raise YamlError(check.repeats[0])
    loader = EVENT_LOADER(check.text)   # a safe loader (PyYAML's safe_load, on libyaml when it has it)
    try:
        return loader.get_single_data()
    except (yaml.YAMLError, ValueError, OverflowError) as exc:   # e.g. a date out of range, a 5000-digit int
        problem = _syntax(exc) if isinstance(exc, yaml.YAMLError) else exc
        raise YamlError(f'{name} is not valid YAML: {problem}') from None
    finally:
        loader.dispose()


def _rcl_message(exc: ValueError) -> str:
    """rcl's message without the C source location it appends."""
    return re.sub(r', at \S+\.c:\d+', '', str(exc)).strip()


def load_params_file(path: str, name: str | None = None) -> dict[str, dict[str, Any]]:
    """Read a ROS 2 params file -> {node section: {dotted.name: value}}: exactly what rcl's parser
    gives the nodes (the same values, types and refusals), after :func:`check_limits` (no aliases:
    rcl has none). ``name``: how messages name the file (default its path).

    Node names may be written with or without a leading ``/`` (sections of the same node merge,
    a later value winning, as rclpy applies them). Raises ParameterError: over a limit, refused
    by rcl (its message), no node section, or a wildcard section (``/**``: every scenario section
    names its node, so that the runner validates each node's parameters as that node gets them).
    Warns (:class:`RepeatedKeyWarning`) about each section or parameter written twice.
    """
    name = name or str(path)
    try:
        check = check_limits(_read(path, name), name, aliases=False, params=True)
    except YamlError as exc:
        raise ParameterError('<file>', str(exc)) from None
    return _params(path, name, check)


def load_params_text(text: bytes | str, name: str) -> dict[str, dict[str, Any]]:
    """:func:`load_params_file` of a params file's text (e.g. the scenario a bag embeds), read by rcl
    from a private temporary file; ``name`` names it in every message (never the temporary file)."""
    try:
        check = check_limits(text, name, aliases=False, params=True)
    except YamlError as exc:
        raise ParameterError('<file>', str(exc)) from None
    with tempfile.TemporaryDirectory(prefix='adcs_params_') as folder:   # mode 0700
        path = os.path.join(folder, 'params.yaml')
        with open(path, 'w', encoding='utf-8') as f:
            f.write(check.text)
        return _params(path, name, check)


def _params(path: str, name: str, check: YamlCheck) -> dict[str, dict[str, Any]]:
    # rcl's parser is reached through rclpy's C extension (no participant, no DDS): loaded when a
    # file is read, not when the campaigns, the batch engine or the analysis are imported.
    from adcs_msgs_py.rcl_params import RclParseError, parse_file
    try:
        parsed = parse_file(path)
    except RclParseError as exc:
        if check.syntax_error:
            raise ParameterError('<file>', f'{name} is not valid YAML: {check.syntax_error}') from None
        raise ParameterError('<file>', f'{name} is not a valid ROS 2 params file: {_rcl_message(exc)}') from None
    if not parsed:
        raise ParameterError('<file>', f'{name} must be a mapping of node sections '
                             '(<node>: {ros__parameters: {...}})')
    sections: dict[str, dict[str, Any]] = {}
    for node, params in parsed.items():
        section = node[1:] if node.startswith('/') else node
        if section in WILDCARDS or '*' in section:
            raise ParameterError('<file>', f'{name}: wildcard node section {node!r} is not supported in a '
                                 'scenario file: give each node its own section')
        untyped = sorted(k for k, v in params.items() if v is None)
        if untyped:
            raise ParameterError(untyped[0], 'has no value of a ROS type (an empty array has none): rclpy '
                                 'cannot declare it and the node would fail at start; leave the key out '
                                 'for its default', section)
        sections.setdefault(section, {}).update(params)
    for line in check.repeats:
        warnings.warn(line, RepeatedKeyWarning, stacklevel=1)   # once per process and text (default filter)
    return sections


@contextlib.contextmanager
def one_line_warnings(prog: str) -> Iterator[None]:
    """While open, each :class:`RepeatedKeyWarning` is printed once on stderr as ``<prog>: warning:
    <message>`` (a command line tool's convention; other warnings as Python shows them)."""
    shown: set[str] = set()
    with warnings.catch_warnings():
        warnings.simplefilter('always', RepeatedKeyWarning)
        python_way = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if not issubclass(category, RepeatedKeyWarning):
                return python_way(message, category, filename, lineno, file, line)
            if str(message) not in shown:
                shown.add(str(message))
                print(f'{prog}: warning: {message}', file=sys.stderr, flush=True)
            return None
        warnings.showwarning = show
        yield


# --- values a params file holds as rcl reads it -------------------------------------------------

def _element_kind(value: Any) -> str | None:
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'integer'
    if isinstance(value, float):
        return 'double'
    if isinstance(value, str):
        return 'string'
    return None


def _string_problem(value: str) -> str | None:
    """Why rcl would not read ``value`` back as written (NUL ends a C string, YAML folds NEL and the
    other control characters, a lone surrogate is not UTF-8); None when it would."""
    for ch in value:
        if ch in '\t\n\r':
            continue
        if ord(ch) < 0x20 or 0x7f <= ord(ch) <= 0x9f or 0xd800 <= ord(ch) <= 0xdfff:
            return f'a string parameter cannot hold the character {ch!r} (a params file cannot carry it)'
    return None


def ros_value_problem(value: Any) -> str | None:
    """Why ``value`` is not a value a params file gives a node (bool, a 64-bit integer, double or
    string, or a non-empty array of one of those kinds), None when it is one: what the batch engine
    and the node graph both accept, since rcl reads a params file holding it back unchanged."""
    kind = _element_kind(value)
    if kind == 'integer' and not INT64[0] <= value <= INT64[1]:
        return f'the integer {value} is outside the 64-bit range of a ROS parameter'
    if kind == 'string':
        return _string_problem(value)
    if kind is not None:
        return None
    if not isinstance(value, (list, tuple)):
        return (f'{type(value).__name__} {value!r} is not a ROS parameter value (bool, int, float, str or a list '
                'of one of them)')
    if not value:
        return 'an empty list has no ROS type (leave the key out for its default)'
    kinds = {_element_kind(v) for v in value}
    if None in kinds:
        bad = next(v for v in value if _element_kind(v) is None)
        return f'the list holds {type(bad).__name__} {bad!r}: a ROS array holds bools, ints, floats or strings'
    if len(kinds) > 1:
        return (f'the list mixes {" and ".join(sorted(k + "s" for k in kinds))}: a ROS array holds one kind '
                '(write every number as a float, e.g. 1.0, for a double array)')
    for v in value:
        problem = ros_value_problem(v)
        if problem:
            return problem
    return None


class _ParamsDumper(yaml.SafeDumper):
    """PyYAML's emitter with every string value quoted: rcl types an unquoted scalar by its own rules
    (``1e-3`` a double, ``yes`` a bool), so a plain string could come back as another type."""

    def represent_mapping(self, tag, mapping, flow_style=None):
        node = super().represent_mapping(tag, mapping, flow_style)
        for key, _ in node.value:
            if isinstance(key, yaml.ScalarNode) and key.tag == 'tag:yaml.org,2002:str':
                key.style = None   # names stay plain (PyYAML still quotes one that needs it)
        return node


_ParamsDumper.add_representer(str, lambda dumper, s: dumper.represent_scalar('tag:yaml.org,2002:str', s, style="'"))


def dump_params(tree: dict) -> str:
    """A params file's text of ``tree`` (``{node: {'ros__parameters': {...}}}``) that rcl reads back
    value for value, type for type (values as :func:`ros_value_problem` accepts them)."""
    return yaml.dump(tree, Dumper=_ParamsDumper, sort_keys=False, allow_unicode=True)
