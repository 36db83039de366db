"""Parameter schemas: one declaration per node, used by the node at start and by the runner.

A scenario file is a plain ROS 2 params file (a section per node name with ``ros__parameters``).
Each node declares its parameters as a :class:`Schema`; :meth:`Schema.validate` turns a
``{dotted.name: value}`` dict into checked values or raises :class:`ParameterError` naming the
key. The same schema validates a YAML section before any process starts (runner) and the
parameter overrides a node received (node start), so both give the same message.

No rclpy here: this module is importable and testable without ROS (params files are read by
:mod:`adcs_msgs_py.params_file`, with rcl's own parser).
"""
from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

REQUIRED = object()

# ROS parameter kinds (what a params-file value may be).
KINDS = ('double', 'int', 'bool', 'string', 'double_array', 'int_array', 'string_array')

# How a schema's whole-section check may read a parameter (Param.cross).
CROSS_READS = ('value', 'length', 'none')

# Parameters every rclpy node has; never "unknown".
BUILTIN_PARAMETERS = frozenset({'use_sim_time', 'start_type_description_service'})


# Where every parameter of every node is described (a user's pointer from an unknown-key message).
PARAMETER_REFERENCE = 'docs/parameters.md'
MAX_SUGGESTIONS = 5


def did_you_mean(name: str, known) -> str:
    """``"did you mean 'a', 'b'?"`` with the (at most :data:`MAX_SUGGESTIONS`) close matches of
    ``name`` among ``known`` (difflib's ratio), or ``''`` when none is close."""
    close = difflib.get_close_matches(str(name), sorted(map(str, known)), n=MAX_SUGGESTIONS, cutoff=0.6)
    return f"did you mean {', '.join(repr(c) for c in close)}?" if close else ''


def unknown_parameter(names, node: str, known) -> str:
    """The one-line problem of unknown parameter(s) ``names`` of ``node``: the close matches of the
    first, and where every parameter is listed (never the whole list: a section has up to ~100)."""
    names = [names] if isinstance(names, str) else list(names)
    hint = did_you_mean(names[0], known)
    return (f'unknown parameter for node {node!r} (unknown: {", ".join(names)}'
            + (f'; {hint}' if hint else '')
            + f'); every parameter of the node is in {PARAMETER_REFERENCE} (or `{node} --help`)')


class ParameterError(ValueError):
    """A parameter is missing, of the wrong type, unknown or non-physical."""

    def __init__(self, key: str, problem: str, section: str | None = None) -> None:
        where = f'{section}.ros__parameters.{key}' if section else key
        super().__init__(f'parameter {where!r}: {problem}')
        self.key = key
        self.section = section


Check = Callable[[Any], 'str | None']


@dataclass(frozen=True)
class Param:
    """One parameter: name (dotted), kind, default (or REQUIRED), length, check, doc.

    ``batch``: the batch engine accepts different values of it across the runs of one batch
    (the plant or law code takes it with a leading batch axis); other parameters must agree.

    Doubles (and double-array elements) must be finite unless ``finite=False`` (limits where
    ``.inf`` means "none"); NaN is refused always.
    """

    name: str
    kind: str
    default: Any = REQUIRED
    doc: str = ''
    length: int | tuple[int, ...] | None = None
    check: Check | None = None
    choices: tuple[str, ...] | None = None
    finite: bool = True
    batch: bool = False  # may differ between the runs of one batch (a Monte Carlo dispersion)
    # How the schema's whole-section check reads it: 'value', 'length' (its length only), 'none'
    # (not at all). Lets a campaign validate its runs' draws at once (Schema.validate_stacked).
    cross: str = 'value'

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f'{self.name}: unknown kind {self.kind}')
        if self.cross not in CROSS_READS:
            raise ValueError(f'{self.name}: unknown cross {self.cross}')

    def coerce(self, value: Any) -> Any:
        """Check the type of ``value`` and return it in canonical form; raise on mismatch.

        Integers are accepted where a double is expected (``kp: 1`` means 1.0): ROS itself is
        strict here, but nothing is lost by converting, and users write integers.
        """
        kind = self.kind
        if kind == 'double':
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f'expected a number (double), got {value!r}')
            value = float(value)
            if math.isnan(value) or (self.finite and math.isinf(value)):
                raise ValueError(f'must be {"finite" if self.finite else "a number, not NaN"}, got {value!r}')
        elif kind == 'int':
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f'expected an integer, got {value!r}')
        elif kind == 'bool':
            if not isinstance(value, bool):
                raise TypeError(f'expected true or false, got {value!r}')
        elif kind == 'string':
            if not isinstance(value, str):
                raise TypeError(f'expected a string, got {value!r}')
        else:
            if not isinstance(value, (list, tuple)):
                raise TypeError(f'expected a list ({kind}), got {value!r}')
            elem = Param(self.name, kind[:-len('_array')], finite=self.finite)
            try:
                value = [elem.coerce(v) for v in value]
            except (TypeError, ValueError) as exc:
                raise type(exc)(f'element {exc}') from None
            if self.length is not None:
                allowed = self.length if isinstance(self.length, tuple) else (self.length,)
                if len(value) not in allowed:
                    raise ValueError(f'expected {" or ".join(map(str, allowed))} values, got {len(value)}')
        if self.choices is not None and value not in self.choices:
            raise ValueError(f'must be one of {list(self.choices)}, got {value!r}')
        if self.check is not None:
            problem = self.check(value)
            if problem:
                raise ValueError(problem)
        return value

    def coerce_many(self, values: np.ndarray) -> bool:
        """Whether :meth:`coerce` accepts every row of ``values`` (runs, ...): float64 rows of a
        ``double`` (array) or int64 of an ``int`` (Python floats, lists of floats and ints each), the
        NaN / inf rule, the length, and the check over the rows at once (its vectorised form
        :func:`vectorised` attached). False when it cannot tell (choices, a check without a
        vectorised form, another kind): then validate row by row, for the error naming the run."""
        values = np.asarray(values)
        kind = self.kind
        if kind in ('double', 'double_array'):
            if values.dtype != np.float64 or values.ndim != (1 if kind == 'double' else 2) or np.isnan(values).any():
                return False
            if self.finite and np.isinf(values).any():
                return False
            if kind == 'double_array' and self.length is not None:
                allowed = self.length if isinstance(self.length, tuple) else (self.length,)
                if values.shape[1] not in allowed:
                    return False
        elif kind != 'int' or values.dtype != np.int64 or values.ndim != 1:
            return False
        if self.choices is not None:
            return False
        if self.check is None:
            return True
        many = getattr(self.check, 'many', None)
        return many is not None and bool(many(values))


@dataclass
class Schema:
    """The parameters of one node, plus an optional whole-section check."""

    node: str
    params: list[Param]
    cross_check: Callable[[dict], None] | None = None
    doc: str = ''
    # (section, {name: values of the runs (runs, ...)}) -> whether every run passes cross_check, for
    # parameters it reads by value (Param.cross); None: such parameters are validated run by run
    batch_cross_check: Callable[[dict, dict], bool] | None = None
    by_name: dict[str, Param] = field(init=False)

    def __post_init__(self) -> None:
        self.by_name = {p.name: p for p in self.params}

    def validate(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Validate ``given`` (dotted names -> values); return every parameter's value.

        Raises :class:`ParameterError` for an unknown key, a missing required one, a wrong type or
        a value its check refuses; the cross-section check raises ParameterError itself.
        """
        unknown = sorted(set(given) - set(self.by_name) - BUILTIN_PARAMETERS)
        if unknown:
            raise ParameterError(unknown[0], unknown_parameter(unknown, self.node, self.by_name), self.node)
        out: dict[str, Any] = {}
        for p in self.params:
            if p.name in given:
                try:
                    out[p.name] = p.coerce(given[p.name])
                except (TypeError, ValueError) as exc:
                    raise ParameterError(p.name, str(exc), self.node) from None
            elif p.default is REQUIRED:
                raise ParameterError(p.name, f'required but missing ({p.doc})', self.node)
            else:
                out[p.name] = p.default
        return self._cross_checked(out)

    def revalidate(self, validated: Mapping[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
        """:meth:`validate` of a section already validated (``validated``, every parameter's value)
        with the values of ``changes`` given instead: the same result and the same errors, but
        only the changed values are coerced and checked (then the whole-section check runs), so a
        Monte Carlo run's dispersed section costs its dispersions, not its every parameter."""
        out = dict(validated)
        if not changes:
            return out
        for name, value in changes.items():
            p = self.by_name.get(name)
            if p is None:
                raise ParameterError(name, unknown_parameter(name, self.node, self.by_name), self.node)
            try:
                out[name] = p.coerce(value)
            except (TypeError, ValueError) as exc:
                raise ParameterError(name, str(exc), self.node) from None
        return self._cross_checked(out)

    def validate_stacked(self, validated: Mapping[str, Any], stacked: Mapping[str, np.ndarray],
                         first: Mapping[str, Any]) -> bool:
        """Whether :meth:`revalidate` accepts every run's ``changes`` at once: ``stacked`` holds the
        changed values of all the runs (one row per run), ``first`` the first run's changes as
        given. True only when proven: each value coerced over the rows (:meth:`Param.coerce_many`),
        the first run revalidated in full, and the whole-section check of the others follows from
        the first's (a parameter it does not read, or whose length only it reads: the rows have
        one length) or from :attr:`batch_cross_check` (a parameter it reads by value). False: the
        caller revalidates run by run, which raises the error naming the run and the key."""
        params = [self.by_name.get(name) for name in stacked]
        if any(p is None or not p.coerce_many(stacked[p.name]) for p in params):
            return False
        try:
            section = self.revalidate(validated, first)
        except ParameterError:
            return False
        if self.cross_check is None:
            return True
        by_value = {p.name: stacked[p.name] for p in params if p.cross == 'value'}
        return not by_value or (self.batch_cross_check is not None and self.batch_cross_check(section, by_value))

    def _cross_checked(self, out: dict[str, Any]) -> dict[str, Any]:
        """``out`` after the whole-section check (a ParameterError of it named in this section)."""
        if self.cross_check is not None:
            try:
                self.cross_check(out)
            except ParameterError as exc:
                if exc.section is None:
                    raise ParameterError(exc.key, str(exc).split(': ', 1)[1], self.node) from None
                raise
        return out

    def stack(self, runs: list[dict[str, Any]]) -> dict[str, Any]:
        """Validated sections of N runs -> one section whose varying values have a leading axis N.

        A value equal in every run stays as it is; one that differs becomes an array (N, ...) and
        must be declared ``batch=True``, else :class:`ParameterError` names it.
        """
        if not runs:
            raise ValueError('no runs to stack')
        return {name: self.stack_values(name, [r[name] for r in runs]) for name in runs[0]}

    def stack_values(self, name: str, values: list) -> Any:
        """One parameter's validated values in N runs, stacked as :meth:`stack` does."""
        first = values[0]
        if all(v == first for v in values[1:]):
            return first
        if name in self.by_name and self.by_name[name].batch:
            try:
                return np.asarray(values)
            except ValueError:
                raise ParameterError(name, 'has a different length in some runs of the batch',
                                     self.node) from None
        raise ParameterError(name, 'differs between the runs of one batch, which the batch '
                             'engine does not support for this parameter', self.node)

    def describe(self) -> str:
        """Markdown table of the parameters (used by ``--help`` and the docs)."""
        rows = ['| parameter | type | default | meaning |', '| --- | --- | --- | --- |']
        for p in self.params:
            default = 'required' if p.default is REQUIRED else repr(p.default)
            rows.append(f'| `{p.name}` | {p.kind} | {default} | {p.doc} |')
        return '\n'.join(rows)


# --- reusable checks --------------------------------------------------------------------------

def vectorised(many: Callable[[np.ndarray], bool]):
    """Attach to a check its form over many values at once: ``many(values)`` (one row per value,
    NaN already refused) is True only if the check passes every row (:meth:`Param.coerce_many`)."""
    def attach(check):
        check.many = many
        return check
    return attach


@vectorised(lambda a: np.all(a > 0))
def positive(v) -> str | None:
    return None if v > 0 else f'must be > 0, got {v!r}'


@vectorised(lambda a: np.all(a >= 0))
def non_negative(v) -> str | None:
    return None if v >= 0 else f'must be >= 0, got {v!r}'


@vectorised(lambda a: np.all(a > 0))
def all_positive(vs) -> str | None:
    bad = [v for v in vs if not v > 0]
    return None if not bad else f'every value must be > 0, got {vs!r}'


@vectorised(lambda a: not np.any(a < 0))
def all_non_negative(vs) -> str | None:
    bad = [v for v in vs if v < 0]
    return None if not bad else f'every value must be >= 0, got {vs!r}'


def domain_id(v) -> str | None:
    return None if 0 <= v <= 232 else f'ROS_DOMAIN_ID must be in 0..232, got {v}'


# --- params files -------------------------------------------------------------------------------

def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested dict of a ``ros__parameters`` section -> {dotted.name: value} (as ROS flattens)."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    """{dotted.name: value} -> nested dict: the inverse of :func:`flatten` (for writing params files)."""
    out: dict[str, Any] = {}
    for key, value in flat.items():
        node = out
        *parents, leaf = key.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return out
