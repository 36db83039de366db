"""Single-frame (static) attitude determination: TRIAD, Davenport's q-method and QUEST, with the QUEST
measurement model's attitude error covariance. Pure numpy, leading batch axis, no ROS.

Reference: F. L. Markley and J. L. Crassidis, *Fundamentals of Spacecraft Attitude Determination and
Control*, Springer 2014, ch. 5 ("Static Attitude Determination Methods": TRIAD, Wahba's problem,
Davenport's q method, QUEST, covariance analysis); the originals are H. D. Black, AIAA J. 2(7), 1964
(TRIAD), P. B. Davenport, NASA X-546-65-437, 1968 (q-method) and M. D. Shuster and S. D. Oh,
J. Guidance and Control 4(1):70-77, 1981 (QUEST and its covariance). The equations used are written
out in each docstring; equation numbers are not quoted because they were not checked against the book.

Conventions. Measurements come in pairs: ``b`` a direction in body axes, ``r`` the same direction in
the reference (inertial) frame, arrays (..., n, 3); weights ``w`` (..., n) or (n,). The book's
attitude matrix ``A`` maps reference to body, ``b = A r``; the project's quaternion ``q`` (scalar last,
body in inertial, :func:`adcs_core.attitude.rotate_to_body`) has ``R(q) = Aᵀ``, and the book's
scalar-last quaternion of ``A`` is numerically the same ``q``. Every estimate is returned with
``q4 ≥ 0``. Wahba's loss is ``L(A) = ½ Σ w_i |b_i − A r_i|²``. Matrix-vector products go through
:func:`adcs_core.attitude.matvec` and dot products are summed in a fixed order (not ``einsum``, whose
summation order depends on the shapes), and iterations stop per element: an element of a batch gets
the bits it gets alone (a campaign's run as the run alone).

Bad input raises :class:`ValueError` naming the first bad batch element: a non-finite or zero-length
vector, a negative or non-finite weight, or an unobservable attitude (all weighted vectors parallel
in the body or the reference frame). Non-unit vectors are normalised (they are directions).
"""
from __future__ import annotations

import numpy as np

from adcs_core.attitude import cross, dot, matvec, quat_norm, scipy_rotation

# Observability: the smallest eigenvalue of Σ w_i (I − b_i b_iᵀ), relative to Σ w_i, below which the
# rotation about the common direction is undetermined (≈ the squared sine of the largest angle
# between the vectors: 1e-12 is a 1 µrad spread, far below any sensor).
OBSERVABILITY_MIN = 1e-12
# QUEST falls back to the q-method when the Gibbs vector's scalar part q4 = 1/√(1+|y|²) is below this
# (rotation within ~11.5° of 180°: (λ+σ)I − S becomes singular at 180°).
QUEST_Q4_MIN = 0.1
NEWTON_MAX_ITER = 50
# ... and when the Gibbs solution is not an eigenvector of K: |K q − λ q| > this × Σ w_i (at exactly
# 180° the solve of the singular system returns a finite but wrong vector).
QUEST_RESIDUAL_MAX = 1e-9


def _first_bad(bad: np.ndarray) -> str:
    idx = np.argwhere(np.atleast_1d(bad))
    return str(tuple(int(i) for i in idx[0])) if idx.size else '()'


def _directions(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.ndim < 1 or v.shape[-1] != 3:
        raise ValueError(f'{name}: expected 3-vectors on the last axis, got shape {v.shape}')
    n = np.sqrt(dot(v, v))
    bad = ~np.isfinite(v).all(axis=-1) | ~(n > 0) | ~np.isfinite(n)
    if bad.any():
        raise ValueError(f'{name}: non-finite or zero-length vector at {_first_bad(bad)}')
    return v / n[..., None]


def _check_observable(v: np.ndarray, w: np.ndarray, name: str) -> None:
    """Raise if the weighted directions ``v`` (..., n, 3) span a single line (the rotation about it
    would be undetermined)."""
    M = (w[..., None, None] * (np.eye(3) - v[..., :, None] * v[..., None, :])).sum(axis=-3)
    lam = np.linalg.eigvalsh(M)[..., 0]
    bad = ~(lam > OBSERVABILITY_MIN * w.sum(axis=-1))
    if bad.any():
        raise ValueError(f'{name}: attitude unobservable (weighted vectors parallel or weights zero) at '
                         f'{_first_bad(bad)}')


def _checked(b, r, w):
    """Unit ``b``, ``r`` (..., n, 3) and weights (..., n) broadcast together, observability checked."""
    b = _directions(b, 'body vectors')
    r = _directions(r, 'reference vectors')
    if b.ndim < 2 or r.ndim < 2:
        raise ValueError('body and reference vectors: expected arrays (..., n, 3)')
    w = np.ones(b.shape[-2]) if w is None else np.asarray(w, dtype=float)
    try:
        shape = np.broadcast_shapes(b.shape, r.shape, w.shape + (3,))
    except ValueError as exc:
        raise ValueError(f'shapes do not match: body {b.shape}, reference {r.shape}, weights {w.shape}') from exc
    b, r = np.broadcast_to(b, shape), np.broadcast_to(r, shape)
    w = np.broadcast_to(w, shape[:-1])
    bad = ~np.isfinite(w) | (w < 0)
    if bad.any():
        raise ValueError(f'weights: negative or non-finite at {_first_bad(bad)}')
    _check_observable(b, w, 'body vectors')
    _check_observable(r, w, 'reference vectors')
    return b, r, w


def _dot4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product of 4-vectors along the last axis in a fixed order (as :func:`adcs_core.attitude.dot`)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2] + a[..., 3] * b[..., 3]


def _canonical(q: np.ndarray) -> np.ndarray:
    """Unit quaternion with ``q4 ≥ 0``."""
    q = q / np.sqrt((q * q).sum(axis=-1))[..., None]
    return np.where(q[..., 3:4] < 0, -q, q)


def triad(b1, r1, b2, r2) -> np.ndarray:
    """TRIAD (Black 1964; Markley & Crassidis §5.1): the attitude that maps ``r1`` exactly onto ``b1``
    (the pair trusted more) and puts ``r2`` in the plane of ``b1, b2``.

    With the orthonormal triads ``v1 = r1, v2 = (r1 × r2)/|r1 × r2|, v3 = v1 × v2`` and
    ``w1 = b1, w2 = (b1 × b2)/|b1 × b2|, w3 = w1 × w2``, ``A = Σ_k w_k v_kᵀ`` (reference to body);
    returns the quaternion of ``R = Aᵀ`` (..., 4), ``q4 ≥ 0``. Inputs (..., 3), normalised here.
    """
    b1, r1 = _directions(b1, 'b1'), _directions(r1, 'r1')
    b2, r2 = _directions(b2, 'b2'), _directions(r2, 'r2')
    shape = np.broadcast_shapes(b1.shape, r1.shape, b2.shape, r2.shape)
    b1, r1, b2, r2 = (np.broadcast_to(x, shape) for x in (b1, r1, b2, r2))
    cb, cr = cross(b1, b2), cross(r1, r2)
    sb, sr = np.sqrt(dot(cb, cb)), np.sqrt(dot(cr, cr))
    bad = ~(sb > np.sqrt(OBSERVABILITY_MIN)) | ~(sr > np.sqrt(OBSERVABILITY_MIN))
    if bad.any():
        raise ValueError(f'TRIAD: the two vectors are parallel (attitude unobservable) at {_first_bad(bad)}')
    w2, v2 = cb / sb[..., None], cr / sr[..., None]
    w3, v3 = cross(b1, w2), cross(r1, v2)
    # R = A^T = sum_k v_k w_k^T
    R = sum(v[..., :, None] * w[..., None, :] for v, w in ((r1, b1), (v2, w2), (v3, w3)))
    flat = R.reshape(-1, 3, 3)
    q = scipy_rotation().from_matrix(flat).as_quat() if len(flat) else np.zeros((0, 4))
    return _canonical(q.reshape(shape[:-1] + (4,)))


def attitude_profile(b, r, w):
    """Davenport's quantities (Markley & Crassidis §5.3): the attitude profile matrix
    ``B = Σ w_i b_i r_iᵀ``, ``S = B + Bᵀ``, ``σ = tr B`` and ``z = Σ w_i b_i × r_i`` (inputs checked)."""
    B = (w[..., None, None] * b[..., :, None] * r[..., None, :]).sum(axis=-3)
    z = (w[..., None] * cross(b, r)).sum(axis=-2)
    return B, B + np.swapaxes(B, -1, -2), np.trace(B, axis1=-2, axis2=-1), z


def davenport_k(b, r, w=None) -> np.ndarray:
    """Davenport's K matrix (..., 4, 4), scalar last (Markley & Crassidis §5.3):
    ``K = [[S − σ I, z], [zᵀ, σ]]``; Wahba's gain ``g(q) = qᵀ K q`` is maximised by the
    eigenvector of its largest eigenvalue ``λmax`` (``L = λ0 − λmax``, ``λ0 = Σ w_i``)."""
    b, r, w = _checked(b, r, w)
    return _k_matrix(*attitude_profile(b, r, w)[1:])


def _k_matrix(S, sigma, z):
    top = np.concatenate([S - sigma[..., None, None] * np.eye(3), z[..., :, None]], axis=-1)
    bottom = np.concatenate([z, sigma[..., None]], axis=-1)[..., None, :]
    return np.concatenate([top, bottom], axis=-2)


def q_method(b, r, w=None) -> np.ndarray:
    """Davenport's q-method: the unit eigenvector of ``K`` (:func:`davenport_k`) for its largest
    eigenvalue (``numpy.linalg.eigh``), the optimal quaternion of Wahba's problem (..., 4), ``q4 ≥ 0``."""
    _, vec = np.linalg.eigh(davenport_k(b, r, w))
    return _canonical(vec[..., :, -1])


def _characteristic(S, sigma, z):
    """Coefficients of Shuster's characteristic equation of K (Shuster & Oh 1981; Markley & Crassidis
    §5.3 QUEST): ``f(λ) = λ⁴ − (a + b) λ² − c λ + (a b + c σ − d)`` with ``κ = tr adj S``,
    ``Δ = det S``, ``a = σ² − κ``, ``b = σ² + zᵀz``, ``c = Δ + zᵀ S z``, ``d = zᵀ S² z``."""
    Sz = matvec(S, z)
    kappa = (S[..., 1, 1] * S[..., 2, 2] - S[..., 1, 2] * S[..., 2, 1]
             + S[..., 0, 0] * S[..., 2, 2] - S[..., 0, 2] * S[..., 2, 0]
             + S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] * S[..., 1, 0])
    a = sigma ** 2 - kappa
    bb = sigma ** 2 + dot(z, z)
    c = np.linalg.det(S) + dot(z, Sz)
    d = dot(Sz, Sz)
    return a, bb, c, d


def quest_lambda_max(S, sigma, z, lam0) -> np.ndarray:
    """``λmax`` by Newton's iteration on the characteristic equation from ``λ0 = Σ w_i`` (exact for
    noiseless vectors); each element stops at its own relative step of 1e-15 (the steps after it
    are not taken: an element of a batch gets the bits it gets alone) or after ``NEWTON_MAX_ITER``
    steps."""
    a, bb, c, d = _characteristic(S, sigma, z)
    const = a * bb + c * sigma - d
    lam = np.broadcast_to(np.asarray(lam0, dtype=float), np.broadcast_shapes(np.shape(lam0), np.shape(a))).copy()
    done = np.zeros(lam.shape, dtype=bool)
    for _ in range(NEWTON_MAX_ITER):
        f = ((lam ** 2 - (a + bb)) * lam - c) * lam + const
        fp = (4.0 * lam ** 2 - 2.0 * (a + bb)) * lam - c
        step = np.where(fp != 0, f / np.where(fp != 0, fp, 1.0), 0.0)
        lam = np.where(done, lam, lam - step)
        done |= np.abs(step) <= 1e-15 * lam0
        if np.all(done):
            break
    return lam


def _gibbs(S, sigma, z, lam):
    """``q = [y; 1] / √(1 + |y|²)`` with ``y = [(λ + σ) I − S]⁻¹ z``, and where it is defined."""
    M = (lam + sigma)[..., None, None] * np.eye(3) - S
    with np.errstate(all='ignore'):
        safe = np.abs(np.linalg.det(M)) > 1e-300
        y = np.linalg.solve(np.where(safe[..., None, None], M, np.eye(3)), z[..., None])[..., 0]
        q = np.concatenate([y, np.ones(y.shape[:-1] + (1,))], axis=-1) / np.sqrt(1.0 + dot(y, y))[..., None]
    return q, safe & np.isfinite(q).all(axis=-1)


def quest(b, r, w=None) -> np.ndarray:
    """QUEST (Shuster & Oh 1981; Markley & Crassidis §5.3): ``λmax`` from the characteristic equation
    (:func:`quest_lambda_max`), then the Rodrigues (Gibbs) vector ``y = [(λmax + σ) I − S]⁻¹ z`` and
    ``q = [y; 1] / √(1 + |y|²)`` (..., 4), ``q4 ≥ 0``.

    The root of the quartic carries a rounding error ~ε λ0⁴ / f'(λmax), large when the two largest
    eigenvalues of K are close (two nearly parallel vectors): ``λ`` is then refined once by the
    Rayleigh quotient ``qᵀ K q`` of the first solution (error quadratic in that of ``q``) and ``y``
    solved again. Near 180° (``q4 < QUEST_Q4_MIN``, or a solution that is not an eigenvector of K to
    ``QUEST_RESIDUAL_MAX``) ``(λ + σ) I − S`` is singular and the element falls back to the q-method
    (:func:`q_method`) instead of Shuster's sequential rotations.
    """
    b, r, w = _checked(b, r, w)
    _, S, sigma, z = attitude_profile(b, r, w)
    K = _k_matrix(S, sigma, z)
    q, ok = _gibbs(S, sigma, z, quest_lambda_max(S, sigma, z, w.sum(axis=-1)))
    ok &= q[..., 3] >= QUEST_Q4_MIN           # decided on the first solution: near 180° it is garbage
    lam = _dot4(q, matvec(K, q))
    q, ok2 = _gibbs(S, sigma, z, lam)
    with np.errstate(all='ignore'):
        residual = quat_norm(matvec(K, q) - lam[..., None] * q)
    fall = ~ok | ~ok2 | (q[..., 3] < QUEST_Q4_MIN) | ~(residual <= QUEST_RESIDUAL_MAX * w.sum(axis=-1))
    if fall.any():
        q[fall] = np.linalg.eigh(K[fall])[1][..., :, -1]
    return _canonical(q)


def quest_covariance(b, sigma) -> np.ndarray:
    """The QUEST measurement model's attitude error covariance (Shuster & Oh 1981; Markley &
    Crassidis §5.5): ``P = (Σ σ_i⁻² (I − b_i b_iᵀ))⁻¹`` (..., 3, 3), rad², in body axes, for unit
    body vectors with isotropic noise of σ_i (rad) perpendicular to each, weighted ``w_i = σ_i⁻²``.
    It is the covariance of ``δθ``, the small rotation (body axes) from the estimated to the true
    attitude: ``R_true = R_est exp([δθ×])``, i.e. the vector part of ``2 q_est* ⊗ q_true``."""
    b = _directions(b, 'body vectors')
    s = np.asarray(sigma, dtype=float)
    bad = ~np.isfinite(s) | ~(s > 0)
    if bad.any():
        raise ValueError(f'sigma: non-positive or non-finite at {_first_bad(bad)}')
    w = np.broadcast_to(s ** -2.0, b.shape[:-1])
    _check_observable(b, w, 'body vectors')
    F = (w[..., None, None] * (np.eye(3) - b[..., :, None] * b[..., None, :])).sum(axis=-3)
    return np.linalg.inv(F)
