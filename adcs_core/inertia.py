"""Inertia matrices: from scenario values, and the checks that a matrix is a rigid body's (pure)."""
from __future__ import annotations

import numpy as np


def check_inertia(J: np.ndarray, what: str = 'inertia') -> str | None:
    """Why ``J`` is not a physical inertia matrix, or None (symmetric, PD, triangle inequality)."""
    J = np.asarray(J, dtype=float)
    if J.shape != (3, 3) or not np.all(np.isfinite(J)):
        return f'{what} must be a finite 3x3 matrix'
    # |J - Jᵀ| <= atol elementwise: np.allclose(J, J.T, rtol=0, atol) for a finite J, without its overhead
    if not (np.abs(J - J.T) <= 1e-12 * max(1.0, float(np.abs(J).max()))).all():
        return f'{what} must be symmetric'
    eig = np.linalg.eigvalsh(J)
    if eig[0] <= 0:
        return f'{what} must be positive definite (principal moments {eig.tolist()})'
    a, b, c = eig
    if a + b < c * (1 - 1e-12):
        return (f'{what} violates the triangle inequality of principal moments '
                f'({a:g} + {b:g} < {c:g}): no rigid body has it')
    return None


def _all_physical(J: np.ndarray) -> bool:
    """Whether every matrix of a batch (..., 3, 3) passes :func:`check_inertia`: its tests over the
    stack at once (each matrix's eigenvalues from the same LAPACK call), for a campaign's thousand
    inertias without a Python loop."""
    with np.errstate(all='ignore'):
        if not np.isfinite(J).all():
            return False
        tol = 1e-12 * np.maximum(1.0, np.abs(J).max(axis=(-2, -1)))
        if not (np.abs(J - np.swapaxes(J, -1, -2)) <= tol[..., None, None]).all():
            return False
        eig = np.linalg.eigvalsh(J)
        a, b, c = eig[..., 0], eig[..., 1], eig[..., 2]
        return not (a <= 0).any() and not (a + b < c * (1 - 1e-12)).any()


def check_inertias(J: np.ndarray, what: str) -> None:
    """Raise ValueError unless ``J`` (3, 3) or each of a batch (..., 3, 3) is a physical inertia
    (a batch is checked as one stack; only when it fails does the per-matrix loop run, for the
    message naming the first bad run)."""
    if J.shape[-2:] != (3, 3):
        raise ValueError(f'{what} must be 3x3 (or a batch of 3x3), got shape {J.shape}')
    if J.ndim > 2 and J.size and _all_physical(J):
        return
    for i, Ji in enumerate(J.reshape(-1, 3, 3)):
        problem = check_inertia(Ji, what)
        if problem:
            raise ValueError(problem if J.ndim == 2 else f'run {i}: {problem}')


def inertia_matrix(values) -> np.ndarray:
    """3 principal moments or 9 row-major entries -> 3x3 matrix (batch: (..., 3) -> (..., 3, 3))."""
    arr = np.asarray(values, dtype=float)
    if arr.shape[-1] == 3:
        return arr[..., :, None] * np.eye(3)
    return arr.reshape(arr.shape[:-1] + (3, 3))
