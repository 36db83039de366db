"""Typed parameter sections: a frozen object per validated section, generated from its schema.

A :class:`~adcs_msgs_py.params.Schema` declares each parameter once (name, kind, default, check,
doc). :func:`section_type` turns it into a frozen class (slots; the equivalent of a frozen
dataclass) whose fields are the parameters, the dotted names as nested groups (``orbit.altitude``
-> ``section.orbit.altitude``), each field typed from its kind and defaulting to the schema's
default (:func:`fields`); :func:`section` fills one from the values :meth:`Schema.validate`
returned (or :meth:`Schema.stack` stacked: a ``batch=True`` parameter then holds an array with a
leading run axis, which the field carries as it is). Laws, estimators and builders read
attributes (``p.orbit.inclination_deg``), so a reader or a tool can follow a parameter from the
YAML to where it acts, and the defaults live in the schema only.

Array parameters are stored as tuples (a section is frozen: no field can be rebound, and a
list value cannot be changed in place); stacked arrays are stored as given.

Pure; no rclpy.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from adcs_msgs_py.params import REQUIRED, Param, Schema

# The Python type of each parameter kind (a batch parameter may also hold a stacked array).
KIND_TYPES: dict[str, Any] = {
    'double': float, 'int': int, 'bool': bool, 'string': str,
    'double_array': tuple[float, ...], 'int_array': tuple[int, ...], 'string_array': tuple[str, ...],
}


class FrozenSectionError(AttributeError):
    """A section's field was assigned or deleted: sections are frozen."""


class Section:
    """Base of every generated section and group (:func:`section_type`): frozen (no field can be
    assigned or deleted, no attribute added: ``__slots__``), compared and shown by value.

    Each generated class lists its fields in ``FIELDS`` (name -> :class:`Field`). The classes are
    built with ``type()`` rather than :func:`dataclasses.make_dataclass`, whose generated methods
    cost tens of milliseconds per schema at a node's start."""

    __slots__ = ()
    FIELDS: dict[str, 'Field'] = {}

    def __init__(self, **values: Any) -> None:
        unknown = set(values) - set(self.FIELDS)
        if unknown:
            raise TypeError(f'{type(self).__name__}: unknown fields {sorted(unknown)}')
        for name, f in self.FIELDS.items():
            if name in values:
                value = values[name]
            elif f.default is not REQUIRED:
                value = f.default
            else:
                raise TypeError(f'{type(self).__name__}: missing field {name!r}')
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: Any) -> None:
        raise FrozenSectionError(f'{type(self).__name__} is frozen: cannot assign {name!r}')

    def __delattr__(self, name: str) -> None:
        raise FrozenSectionError(f'{type(self).__name__} is frozen: cannot delete {name!r}')

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(_same(getattr(self, n), getattr(other, n)) for n in self.FIELDS)

    __hash__ = None   # values may be arrays

    def __repr__(self) -> str:
        return f'{type(self).__name__}({", ".join(f"{n}={getattr(self, n)!r}" for n in self.FIELDS)})'


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return a == b


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of a generated section: its type (a parameter's, or a group's class) and default
    (the schema's, REQUIRED when it has none; a group has none)."""

    name: str
    type: Any
    default: Any = REQUIRED


def fields(cls: type[Section] | Section) -> tuple[Field, ...]:
    """The fields of a generated section type (or of a section)."""
    return tuple(cls.FIELDS.values())


def field_type(p: Param) -> Any:
    """The annotation of ``p``'s field: its kind's type, or that or an array for ``batch=True``."""
    kind = KIND_TYPES[p.kind]
    return kind | np.ndarray if p.batch else kind


def _frozen(value: Any) -> Any:
    """A validated value as a section stores it: lists as tuples, the rest as it is."""
    return tuple(value) if isinstance(value, list) else value


def _tree(names: list[str], title: str) -> dict[str, Any]:
    """Dotted names -> nested {part: name or sub-tree}; a name that is also a group is refused."""
    tree: dict[str, Any] = {}
    for name in names:
        node = tree
        *groups, leaf = name.split('.')
        for part in groups:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f'{title}: {name!r} is inside the parameter {part!r}')
        if leaf in node:
            raise ValueError(f'{title}: {name!r} is both a parameter and a group')
        node[leaf] = name
    return tree


def _class_name(title: str) -> str:
    return ''.join(part.capitalize() for part in title.replace('.', '_').split('_')) or 'Section'


def _make(title: str, tree: dict[str, Any], params: Mapping[str, Param | None]) -> tuple[type, tuple]:
    """The frozen class of one level of ``tree`` and its fill plan ((slot setter, name or sub-plan))."""
    fields_, plan = {}, []
    for key, item in tree.items():
        if not key.isidentifier() or key.startswith('__') or key == 'FIELDS':
            raise ValueError(f'{title}: {key!r} is not a field name')
        if isinstance(item, dict):
            sub = _make(f'{title}.{key}', item, params)
            fields_[key] = Field(key, sub[0])
            plan.append((key, sub))
            continue
        p = params.get(item)
        if p is None:
            fields_[key] = Field(key, Any)
        else:
            fields_[key] = Field(key, field_type(p), REQUIRED if p.default is REQUIRED else _frozen(p.default))
        plan.append((key, item))
    cls = type(_class_name(title), (Section,), {
        '__slots__': tuple(fields_), 'FIELDS': fields_, '__module__': __name__,
        '__annotations__': {k: f.type for k, f in fields_.items()},
        '__doc__': f'Typed parameters {title} (generated from its schema by adcs_msgs_py.sections).'})
    setters = tuple((getattr(cls, key).__set__, item) for key, item in plan)
    return cls, setters


def _fill(plan: tuple, values: Mapping[str, Any]) -> Section:
    """A section from ``values`` through ``plan``: the slots set directly (no per-field checks: the
    values are a schema's validated ones)."""
    cls, setters = plan
    obj = object.__new__(cls)
    for setter, item in setters:
        setter(obj, _fill(item, values) if isinstance(item, tuple) else _frozen(values[item]))
    return obj


_PLANS: dict[int, tuple[Schema, tuple]] = {}


def _plan(schema: Schema) -> tuple:
    cached = _PLANS.get(id(schema))
    if cached is None or cached[0] is not schema:
        params = {p.name: p for p in schema.params}
        cached = (schema, _make(schema.node, _tree(list(params), schema.node), params))
        _PLANS[id(schema)] = cached
    return cached[1]


def section_type(schema: Schema) -> type:
    """The frozen class of ``schema``'s sections (generated once per schema)."""
    return _plan(schema)[0]


def section(schema: Schema, values: Mapping[str, Any]) -> Section:
    """The typed section of ``values``: a validated section of ``schema`` (:meth:`Schema.validate`,
    every parameter present) or a stacked one (:meth:`Schema.stack`, arrays for what differs)."""
    if isinstance(values, Section):
        return values
    return _fill(_plan(schema), values)


def validated(schema: Schema, given: Mapping[str, Any]) -> Section:
    """:meth:`Schema.validate` of ``given`` as a typed section (the same checks, the same errors)."""
    return section(schema, schema.validate(given))


_AD_HOC: dict[tuple, tuple] = {}


def as_section(values: Mapping[str, Any] | Section, params: tuple[Param, ...] = ()) -> Section:
    """A section already typed as it is; a plain ``{dotted.name: value}`` dict (a law built by
    hand, in a test or a script) as a section of its own keys, plus each of ``params`` it lacks
    at that parameter's schema default (``params``: the optional parameters a law reads, the very
    Param objects its schema lists, so the default is declared once)."""
    if isinstance(values, Section):
        return values
    full = dict(values)
    for p in params:
        if p.name not in full and p.default is not REQUIRED:
            full[p.name] = p.default
    names = tuple(full)
    key = (names, tuple(id(p) for p in params))
    plan = _AD_HOC.get(key)
    if plan is None:
        by_name = {p.name: p for p in params}
        plan = _make('section', _tree(list(names), 'section'), {n: by_name.get(n) for n in names})
        _AD_HOC[key] = plan
    return _fill(plan, full)


def flat(sec: Section, prefix: str = '') -> dict[str, Any]:
    """A section back as ``{dotted.name: value}`` (for code below the interface that reads dicts)."""
    out: dict[str, Any] = {}
    for name in sec.FIELDS:
        value = getattr(sec, name)
        if isinstance(value, Section):
            out.update(flat(value, f'{prefix}{name}.'))
        else:
            out[f'{prefix}{name}'] = value
    return out
