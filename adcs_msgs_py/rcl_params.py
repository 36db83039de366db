"""rcl's own params-file parser (``rcl_yaml_param_parser``), called from Python through ctypes.

A node receives its parameters from this parser: ``rclpy.init(args=['--ros-args', '--params-file',
path])`` hands the file to ``rcl_parse_yaml_file`` and the node's overrides are its result
(converted by rclpy: bool, int64, double, string and their arrays, byte arrays). The runner reads
scenario files with the same C function, so what it validated is what every node gets, value for
value, type for type, and a file rcl refuses is refused before anything starts.

rclpy exposes no Python binding for the parser (``rclpy.parameter.parameter_dict_from_yaml_file``
re-reads the file with PyYAML, which resolves scalars as YAML 1.1 does: ``1e-3`` is a string
there and a double for rcl), so the library rclpy's extension links is loaded here by name; the
structs mirror ``rcl_yaml_param_parser/types.h`` (Jazzy: rcl 9.2, the pinned ros-rclpy 7.1.6).
"""
from __future__ import annotations

import ctypes
import os

# Loads rclpy's C extension, and with it librcutils and librcl_yaml_param_parser (its
# dependencies): the names below then resolve to the very libraries the nodes use.
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy  # noqa: F401


class _Allocator(ctypes.Structure):
    _fields_ = [('allocate', ctypes.c_void_p), ('deallocate', ctypes.c_void_p),
                ('reallocate', ctypes.c_void_p), ('zero_allocate', ctypes.c_void_p),
                ('state', ctypes.c_void_p)]


def _array(ctype):
    class Array(ctypes.Structure):
        _fields_ = [('values', ctypes.POINTER(ctype)), ('size', ctypes.c_size_t)]
    return Array


_BoolArray, _Int64Array, _DoubleArray, _ByteArray = (
    _array(ctypes.c_bool), _array(ctypes.c_int64), _array(ctypes.c_double), _array(ctypes.c_uint8))


class _StringArray(ctypes.Structure):
    _fields_ = [('size', ctypes.c_size_t), ('data', ctypes.POINTER(ctypes.c_char_p)), ('allocator', _Allocator)]


class _Variant(ctypes.Structure):
    _fields_ = [('bool_value', ctypes.POINTER(ctypes.c_bool)),
                ('integer_value', ctypes.POINTER(ctypes.c_int64)),
                ('double_value', ctypes.POINTER(ctypes.c_double)),
                ('string_value', ctypes.c_char_p),
                ('byte_array_value', ctypes.POINTER(_ByteArray)),
                ('bool_array_value', ctypes.POINTER(_BoolArray)),
                ('integer_array_value', ctypes.POINTER(_Int64Array)),
                ('double_array_value', ctypes.POINTER(_DoubleArray)),
                ('string_array_value', ctypes.POINTER(_StringArray))]


class _NodeParams(ctypes.Structure):
    _fields_ = [('parameter_names', ctypes.POINTER(ctypes.c_char_p)),
                ('parameter_values', ctypes.POINTER(_Variant)),
                ('num_params', ctypes.c_size_t), ('capacity_params', ctypes.c_size_t)]


class _Params(ctypes.Structure):
    _fields_ = [('node_names', ctypes.POINTER(ctypes.c_char_p)), ('params', ctypes.POINTER(_NodeParams)),
                ('num_nodes', ctypes.c_size_t), ('capacity_nodes', ctypes.c_size_t), ('allocator', _Allocator)]


class _ErrorString(ctypes.Structure):
    _fields_ = [('str', ctypes.c_char * 1024)]   # RCUTILS_ERROR_MESSAGE_MAX_LENGTH


_rcutils = ctypes.CDLL('librcutils.so')
_parser = ctypes.CDLL('librcl_yaml_param_parser.so')
_rcutils.rcutils_get_default_allocator.restype = _Allocator
_rcutils.rcutils_get_error_string.restype = _ErrorString
_rcutils.rcutils_reset_error.restype = None
_parser.rcl_yaml_node_struct_init.argtypes = [_Allocator]
_parser.rcl_yaml_node_struct_init.restype = ctypes.POINTER(_Params)
_parser.rcl_parse_yaml_file.argtypes = [ctypes.c_char_p, ctypes.POINTER(_Params)]
_parser.rcl_parse_yaml_file.restype = ctypes.c_bool
_parser.rcl_yaml_node_struct_fini.argtypes = [ctypes.POINTER(_Params)]
_parser.rcl_yaml_node_struct_fini.restype = None


class RclParseError(ValueError):
    """rcl refused the file (its own message)."""


def _text(raw: bytes) -> str:
    return raw.decode('utf-8', errors='surrogateescape')


def _value(v: _Variant):
    """One rcl_variant_t -> the Python value rclpy gives a node for it."""
    if v.bool_value:
        return bool(v.bool_value[0])
    if v.integer_value:
        return int(v.integer_value[0])
    if v.double_value:
        return float(v.double_value[0])
    if v.string_value is not None:
        return _text(v.string_value)
    for field, convert in (('byte_array_value', bytes), ('bool_array_value', bool),
                           ('integer_array_value', int), ('double_array_value', float)):
        arr = getattr(v, field)
        if arr:
            values = arr[0].values[:arr[0].size]
            return [bytes([b]) for b in values] if convert is bytes else [convert(x) for x in values]
    if v.string_array_value:
        arr = v.string_array_value[0]
        return [_text(arr.data[i]) for i in range(arr.size)]
    return None   # no value (rcl leaves a parameter unset only on error paths)


def parse_file(path: str) -> dict[str, dict[str, object]]:
    """``rcl_parse_yaml_file(path)`` -> {node name as rcl stores it: {parameter name: value}}.

    Raises :class:`RclParseError` with rcl's message when rcl refuses the file."""
    params = _parser.rcl_yaml_node_struct_init(_rcutils.rcutils_get_default_allocator())
    if not params:
        raise MemoryError('rcl_yaml_node_struct_init failed')
    try:
        if not _parser.rcl_parse_yaml_file(os.fsencode(path), params):
            message = _text(_rcutils.rcutils_get_error_string().str)
            _rcutils.rcutils_reset_error()
            raise RclParseError(message)
        p = params[0]
        out: dict[str, dict[str, object]] = {}
        for i in range(p.num_nodes):
            node = p.params[i]
            out[_text(p.node_names[i])] = {_text(node.parameter_names[j]): _value(node.parameter_values[j])
                                           for j in range(node.num_params)}
        return out
    finally:
        _parser.rcl_yaml_node_struct_fini(params)
