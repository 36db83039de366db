"""Reading a ROS 2 params file (a scenario file) exactly as the nodes get it.

:func:`load_params_file` is the one reader: the runner, the batch engine's users and every node
(before ``rclpy.init`` parses the same file for its overrides) call it. It checks the file's size
and structure against limits first (bounded memory and time, a short message naming the limit),
then reads it with rcl's own parser (:mod:`adcs_msgs_py.rcl_params`), so the values and types are
those rcl gives the nodes and a file rcl refuses is refused. No graph, no DDS participant.
"""
from __future__ import annotations

import os
import re
from typing import Any

import yaml

from adcs_msgs_py.params import ParameterError

# Limits of a params file, checked before rcl parses it (a scenario file is a few kB, its longest
# array a few hundred values): a file past them is refused quickly, in bounded memory.
MAX_FILE_BYTES = 1 << 20
MAX_DEPTH = 16            # nested mappings and sequences
MAX_KEYS = 10_000         # mapping keys in the whole file
MAX_ARRAY_LENGTH = 100_000
WILDCARDS = ('*', '**')


EVENT_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)   # libyaml's scanner when PyYAML has it


def _count_item(top: list, path: str, keys: int) -> int:
    """One more item in the open collection ``top`` ([is_mapping, items]); returns 1 for a key."""
    top[1] += 1
    if top[0]:
        if top[1] % 2 == 0:
            return 0
        if keys + 1 > MAX_KEYS:
            raise ParameterError('<file>', f'{path} has more than {MAX_KEYS} keys (the limit)')
        return 1
    if top[1] > MAX_ARRAY_LENGTH:
        raise ParameterError('<file>', f'{path} has an array longer than {MAX_ARRAY_LENGTH} values (the limit)')
    return 0


def check_limits(path: str) -> str | None:
    """Check the file against :data:`MAX_FILE_BYTES`, :data:`MAX_DEPTH`, :data:`MAX_KEYS` and
    :data:`MAX_ARRAY_LENGTH` (ParameterError naming the limit). The structure is counted on
    libyaml's event stream (the scanner rcl's parser uses too; no value is built). Returns the
    YAML syntax error met, if any (its line and column), for rcl's refusal to quote."""
    try:
        size = os.stat(path).st_size
        if size > MAX_FILE_BYTES:
            raise ParameterError('<file>', f'{path} is {size} bytes; the limit is {MAX_FILE_BYTES} bytes')
        with open(path, 'rb') as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ParameterError('<file>', f'cannot read {path}: {exc.strerror}') from None
    if len(data) > MAX_FILE_BYTES:
        raise ParameterError('<file>', f'{path} is over the limit of {MAX_FILE_BYTES} bytes')
    stack: list[list] = []   # per open collection: [is_mapping, item count]
    keys = 0
    try:
        for event in yaml.parse(data, Loader=EVENT_LOADER):
            if isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                stack.pop()
                continue
            if stack and isinstance(event, (yaml.ScalarEvent, yaml.AliasEvent, yaml.CollectionStartEvent)):
                keys += _count_item(stack[-1], path, keys)
            if isinstance(event, yaml.CollectionStartEvent):
                stack.append([isinstance(event, yaml.MappingStartEvent), 0])
                if len(stack) > MAX_DEPTH:
                    raise ParameterError('<file>', f'{path} nests deeper than {MAX_DEPTH} levels (the limit)')
    except yaml.YAMLError as exc:
        return str(exc).replace('\n', ' ')
    return None


def _rcl_message(exc: ValueError) -> str:
    """rcl's message without the C source location it appends."""
    return re.sub(r', at \S+\.c:\d+', '', str(exc)).strip()


def load_params_file(path: str) -> dict[str, dict[str, Any]]:
    """Read a ROS 2 params file -> {node section: {dotted.name: value}}: exactly what rcl's parser
    gives the nodes (the same values, types and refusals), after :func:`check_limits`.

    Node names may be written with or without a leading ``/`` (sections of the same node merge,
    a later value winning, as rclpy applies them). Raises ParameterError: over a limit, refused
    by rcl (its message), no node section, or a wildcard section (``/**``: every scenario section
    names its node, so that the runner validates each node's parameters as that node gets them).
    """
    # rcl's parser is reached through rclpy's C extension (no participant, no DDS): loaded when a
    # file is read, not when the campaigns, the batch engine or the analysis are imported.
    from adcs_msgs_py.rcl_params import RclParseError, parse_file
    syntax_error = check_limits(path)
    try:
        parsed = parse_file(path)
    except RclParseError as exc:
        if syntax_error:
            raise ParameterError('<file>', f'{path} is not valid YAML: {syntax_error}') from None
        raise ParameterError('<file>', f'{path} is not a valid ROS 2 params file: {_rcl_message(exc)}') from None
    if not parsed:
        raise ParameterError('<file>', f'{path} must be a mapping of node sections '
                             '(<node>: {ros__parameters: {...}})')
    sections: dict[str, dict[str, Any]] = {}
    for node, params in parsed.items():
        name = node[1:] if node.startswith('/') else node
        if name in WILDCARDS or '*' in name:
            raise ParameterError('<file>', f'{path}: wildcard node section {node!r} is not supported in a '
                                 'scenario file: give each node its own section')
        untyped = sorted(k for k, v in params.items() if v is None)
        if untyped:
            raise ParameterError(untyped[0], 'has no value of a ROS type (an empty array has none): rclpy '
                                 'cannot declare it and the node would fail at start; leave the key out '
                                 'for its default', name)
        sections.setdefault(name, {}).update(params)
    return sections
