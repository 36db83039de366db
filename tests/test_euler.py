"""adcs_core.attitude.euler_213 equals scipy's ``Rotation.from_quat(q).as_euler('YXZ')`` bit for bit.

Both of its paths (a few quaternions in Python, a batch in the compiled
:func:`adcs_core.euler_kernel.euler_213_rows`) against scipy, compared as int64 bit patterns (so
-0.0 against 0.0 and NaN payloads would show): derandomised, bounded hypothesis examples of unit
and non-unit quaternions (scipy normalises them), both signs of each, attitudes within 1e-12..1e-3
rad of gimbal lock (theta_1 = +-90 deg, where scipy sets the third angle to 0) and at exactly
0 / pi of its second half-angle, plus the rows scipy refuses (NaN, inf, zero) which give NaN.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from adcs_core.attitude import EULER_213, euler_213, scipy_rotation
from adcs_core.euler_kernel import euler_213_rows

FUZZ = settings(derandomize=True, max_examples=300, deadline=None, database=None)
component = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
scale = st.sampled_from([1.0, -1.0, 1e-150, 3.7, -250.0, 1e150, 2.0 ** -30])
near = st.floats(-1e-3, 1e-3, allow_nan=False).filter(lambda v: v == 0.0 or 1e-12 <= abs(v))


def scipy_euler(q: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')   # "Gimbal lock detected"
        return scipy_rotation().from_quat(np.atleast_2d(q)).as_euler(EULER_213)


def bits(a) -> list:
    return np.asarray(a, dtype=float).reshape(-1, 3).view(np.int64).tolist()


def check(rows: np.ndarray) -> None:
    """Both paths against scipy: the compiled kernel of the rows, euler_213 of them (Python up to
    SMALL_BATCH rows, else the kernel) and of each row (Python)."""
    want = scipy_euler(rows)
    kernel = np.empty((len(rows), 3))
    euler_213_rows(np.ascontiguousarray(rows), kernel)
    assert bits(kernel) == bits(want)
    assert bits(euler_213(rows)) == bits(want)
    for q, w in zip(rows, want):
        assert bits(euler_213(q)) == bits(w), q.tolist()


@FUZZ
@given(st.lists(st.tuples(component, component, component, component), min_size=1, max_size=8), scale)
def test_any_quaternion_any_norm_and_its_negative(quats, k):
    q = np.array(quats) * k
    q = q[np.sum(np.abs(q), axis=1) > 0]
    q = q[np.sqrt(np.sum(q * q, axis=1)) > 0]   # scipy refuses a zero (or underflowing) norm
    if q.size:
        check(np.concatenate([q, -q]))


@FUZZ
@given(st.floats(-math.pi, math.pi), st.sampled_from([1.0, -1.0]), near, st.floats(-math.pi, math.pi),
       st.sampled_from([1.0, -1.0, 0.3]))
def test_gimbal_lock_neighbourhoods(theta2, side, offset, theta3, k):
    """theta_1 = +-90 deg + offset: the second angle within 1e-7 of 0 or pi (scipy's degenerate
    cases) or just outside them."""
    angles = np.array([[theta2, side * math.pi / 2 + offset, theta3]])
    q = scipy_rotation().from_euler(EULER_213, angles).as_quat() * k
    check(np.concatenate([q, -q]))


def test_exact_degenerate_quaternions():
    """Half-angle components exactly zero (a = b = 0 or c = d = 0) and the axis rotations."""
    s = math.sqrt(0.5)
    rows = np.array([[0, 0, 0, 1], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [s, 0, 0, s], [-s, 0, 0, s],
                     [0, s, 0, s], [0, 0, s, s], [0.5, 0.5, 0.5, 0.5], [0.5, -0.5, 0.5, 0.5], [s, s, 0, 0],
                     [0, 0, s, -s], [1e-300, 0, 0, 1], [1e300, 1e300, 0, 0]], dtype=float)
    check(np.concatenate([rows, -rows]))


def test_refused_rows_are_nan_and_shapes_are_kept():
    q = np.array([[0, 0, 0, 1], [np.nan, 0, 0, 1], [0, np.inf, 0, 1], [0, 0, 0, 0], [1e-200, 0, 0, 0]])
    out = euler_213(q)
    assert np.isnan(out[1:]).all() and bits(out[:1]) == bits(scipy_euler(q[:1]))
    assert bits(euler_213(np.tile(q, (10, 1)))) == bits(np.tile(out, (10, 1)))   # the kernel's
    for row in q[1:]:
        assert np.isnan(euler_213(row)).all()
    stack = np.tile(q[:1], (2, 3, 1))
    assert euler_213(stack).shape == (2, 3, 3) and euler_213(np.zeros((0, 4))).shape == (0, 3)


@pytest.mark.parametrize('seed', [0, 1])
def test_large_random_batches(seed):
    """Many rows at once (the campaign's metrics convert ~600 000 per 1000 runs)."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(20000, 4)) * 10.0 ** rng.integers(-3, 4, size=(20000, 1))
    assert bits(euler_213(q)) == bits(scipy_euler(q))


def test_compiled_without_fastmath_and_with_numpy_errors():
    """What the bit-for-bit argument rests on (module doc of adcs_core.euler_kernel)."""
    options = euler_213_rows.targetoptions
    assert not options.get('fastmath', False)
    assert options['error_model'] == 'numpy'
    fresh = njit(error_model='numpy')(euler_213_rows.py_func)   # the cached one cannot be inspected
    fresh(np.full((2, 4), 0.5), np.empty((2, 3)))
    for asm in fresh.inspect_asm().values():
        assert 'fmadd' not in asm and 'fmsub' not in asm and 'atan2' in asm and 'hypot' in asm
