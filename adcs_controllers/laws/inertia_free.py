"""Inertia-free attitude laws under torque saturation, seed 001 (motion to rest, M2R, and adaptive
motion to spin, M2S, on rotation matrices). Pure numpy, no rclpy.

Model (eq. 1-2): ``J dω/dt = (Jω) × ω + B u + z_d``, ``dR/dt = R ω×``; ``R`` maps body vectors to
inertial ones (= :func:`rotation_from_quaternion` of our scalar-last quaternion, the plant's
convention). Desired attitude ``dR_d/dt = R_d ω_d×`` (eq. 5), attitude error ``R̃ = R_dᵀ R`` (eq. 7),
rate error ``ω̃ = ω - R̃ᵀ ω_d`` (after eq. 8), eigenaxis error ``θ = acos((tr R̃ - 1)/2)`` (eq. 10).

M2R (section 3, eq. 11-25), ``ω_d = 0``, ``R_d`` constant::

    S = Σ_i a_i (R̃ᵀ e_i) × e_i                                    (13)
    u = -B⁻¹ (Kp S + Kv(ω) ω)                                       (12)
    Kp = α / tr A,  Kv(ω) = β diag(f(ω1), f(ω2), f(ω3))             (15, 16)
    f(x) = 1/(1 + |x|)                                              (24)
    f(x) = 1/ω̄ (|x| ≤ ω̄),  1/|x| (|x| > ω̄)                         (25)
    V = ½ ωᵀJω + Kp tr(A - A R̃),   dV/dt = -ωᵀ Kv ω                (11, 14)
    ‖u‖∞ ≤ (α + β)/σmin(B)                     Proposition 1, (18); need ≤ u_max (20)
    |u_i| ≤ ‖b_i‖ (α + √3 β)  (b_i row i of B⁻¹)  Proposition 2, (22); need ≤ u_max,i (23)

The proof of Proposition 1 uses ``‖B⁻¹x‖∞ ≤ σmax(B⁻¹)‖x‖∞``, true when every row of B⁻¹ has an
absolute sum ≤ σmax(B⁻¹) (diagonal B, e.g. the paper's B = I) but not for a general B (a rotation
B is a counterexample, docs/seed001_readings.md R2): :func:`check_m2r_gains` refuses Proposition 1
for such a B and names Proposition 2 instead.

M2S (section 5, Theorem 2, eq. 31-46), ``Jω = L(ω) γ``, ``γ = [J11 J22 J33 J23 J13 J12]``::

    L(ω) = [[ω1, 0, 0, 0, ω3, ω2], [0, ω2, 0, ω3, 0, ω1], [0, 0, ω3, ω2, ω1, 0]]   (31)
    Ṡ = Σ_i a_i [(R̃ᵀ e_i) × ω̃] × e_i,   z = ω̃ + K1 S                          (38)
    X = K1 Ṡ + ω̃ × ω - R̃ᵀ dω_d/dt
    dγ̂/dt = Q⁻¹ [Lᵀ(ω) (ω × z) + Lᵀ(X) z]                                      (37)
    dd̂/dt = A_d d̂ + D⁻¹ C_dᵀ z,   ẑ_d = C_d d̂      (model ḋ = A_d d, z_d = C_d d; 34-35, 39-40)
    v1 = -(Ĵω) × ω - Ĵ X,   v2 = -ẑ_d,   v3 = -Kv z - Kp S,   u = B⁻¹(v1 + v2 + v3)   (41-44)
    V = ½ zᵀJz + Kp tr(A - A R̃) + ½ γ̃ᵀQγ̃ + ½ d̃ᵀDd̃                              (36)
    dV/dt = -zᵀKv z - Kp SᵀK1 S + ½ d̃ᵀ(A_dᵀD + DA_d) d̃   (unsaturated)            (45)

The paper's M2S examples give "α = β = 1" for the gains of eq. 44: read as ``Kp = α/tr A`` (15)
and ``Kv = β I`` (Theorem 2 needs a constant positive-definite Kv); see the readings, R5.

Saturation (section 6) of the commanded u (eq. 41), box ``B(u_max) = {|u_i| ≤ u_max,i}``::

    cutoff  u'_i = sat(u_i, u_max,i)                                     (47, 48)
    scaling u' = α_max u,  α_max = max{α ∈ (0, 1]: α u ∈ B} = min(1, min_i u_max,i/|u_i|)   (49-51)

Varying adaptation gain (section 7.1), ``Q = q Q₀`` (eq. 55, Q₀ = I6 in the paper), per control
step k, with u the commanded (unsaturated) torque::

    q_k = q_{k-1}                                 if u ∈ B(u_max)
          q_max                                   if q_{k-1} ≥ q_max
          (1 + K_Q ‖|u| - u_max‖/‖u_max‖) q_{k-1}   otherwise (capped at q_max, "not allowed to
                                                  increase above q_max")              (56-58)

VAG-C = cutoff + eq. 56, VAG-S = scaling + eq. 56. ``excess='printed'`` uses ``‖|u| - u_max‖``
over all three axes as printed; ``excess='positive'`` only the exceeding parts (R6).

Extremum tracking (section 7.4) of the commanded spin rate ``ω̄`` (``ω_d = ω̄ ω̂_d``)::

    φ̃_k = acos(ω̂_kᵀ ω̂_d)   (ω̂_k body rate direction, ω̂_d the desired body spin axis)  (60)
    Δt = t - t̄_k   (time of the last command change)                                 (61)
    ω̄_{k+1} = ω̄_k - δ_{k+1}   if φ̃_k > φ̃_max and Δt > t_max
              ω̄_k + δ_{k+1}   if φ̃_k ≤ φ̃_max and ω̄_k < ω̄_0 and Δt > t_max
              ω̄_k             otherwise                                              (62)
    δ_{k+1} = K_ω δ_k  (at each command change; δ_0 = ω̄_0: a bisection of (0, ω̄_0])  (63)

Arrays take an optional LEADING BATCH AXIS: ``R`` (..., 3, 3), ``q`` (..., 4) scalar last,
``w`` (..., 3), scalar gains as scalars or (...,); matrices (``B``, ``K1``, ``Kv``) (3, 3) or
(..., 3, 3). Matrix-vector products go through :func:`adcs_core.attitude.matvec`, cross products
through :func:`adcs_core.attitude.cross`, matrix products through :func:`matmul` (built on
``matvec``): a run in a batch gives the same bits as alone.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_controllers.laws.base import SectionLaw
from adcs_core.attitude import cross, matvec

__all__ = [
    'rotation_from_quaternion', 'quaternion_from_rotation', 'hat', 'matmul', 'rotation_exp',
    'attitude_error', 'eigenaxis_error', 's_vector', 's_dot', 'f_eq24', 'f_eq25', 'm2r_gains',
    'm2r_torque', 'm2r_lyapunov', 'prop1_bound', 'prop2_bound', 'check_m2r_gains',
    'l_matrix', 'gamma_from_inertia', 'inertia_from_gamma', 'm2s_terms', 'm2s_torque',
    'm2s_estimator_inputs', 'm2s_estimator_rates', 'm2s_lyapunov', 'sat_cutoff', 'sat_scaling', 'saturate', 'qsat',
    'extremum_tracking_step', 'k0_metric', 'actuation_matrix', 'M2rLaw', 'M2sLaw', 'MODE_NAMES',
]

MODE_UNSATURATED = 0  # commanded torque inside the box B(u_max)
MODE_SATURATED = 1    # commanded torque outside the box: cutoff/scaling applied
MODE_NAMES = {MODE_UNSATURATED: 'unsaturated', MODE_SATURATED: 'saturated'}
GAMMA_NAMES = ('11', '22', '33', '23', '13', '12')  # γ = [J11 J22 J33 J23 J13 J12], eq. (31)

_E = np.eye(3)


# --- rotation matrices ---------------------------------------------------------------------------

def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _g(k):
    """A gain (scalar or (...,)) as a multiplier of (..., 3) vectors."""
    k = np.asarray(k, dtype=float)
    return k[..., None] if k.ndim else k


def _T(M):
    return np.swapaxes(M, -1, -2)


def matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` for (..., 3, 3) matrices, column by column through :func:`matvec` (fixed order)."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    return np.stack([matvec(A, B[..., :, j]) for j in range(B.shape[-1])], axis=-1)


def hat(w: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``w×`` (..., 3, 3) of ``w`` (..., 3)."""
    w = np.asarray(w, dtype=float)
    z = np.zeros(w.shape[:-1])
    x, y, s = w[..., 0], w[..., 1], w[..., 2]
    return np.stack([np.stack([z, -s, y], -1), np.stack([s, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def rotation_from_quaternion(q: np.ndarray) -> np.ndarray:
    """``R`` (..., 3, 3) of a scalar-last quaternion ``q = [x, y, z, w]`` (normalised here): maps
    body vectors to inertial ones, the paper's R and ``Rotation.from_quat(q).as_matrix()``."""
    q = np.asarray(q, dtype=float)
    q = q / np.sqrt(q[..., 0] ** 2 + q[..., 1] ** 2 + q[..., 2] ** 2 + q[..., 3] ** 2)[..., None]
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def quaternion_from_rotation(R: np.ndarray) -> np.ndarray:
    """Scalar-last unit quaternion (..., 4) of rotation matrices ``R`` (..., 3, 3), with ``w ≥ 0``
    (scipy's ``Rotation.from_matrix``, applied element by element along the batch axes)."""
    from scipy.spatial.transform import Rotation
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    q = np.stack([Rotation.from_matrix(m).as_quat() for m in flat]) if len(flat) else np.zeros((0, 4))
    q = np.where(q[:, 3:4] < 0, -q, q)
    return q.reshape(R.shape[:-2] + (4,))


def rotation_exp(w: np.ndarray, t) -> np.ndarray:
    """``exp(t w×)`` (..., 3, 3), Rodrigues' formula: the rotation in ``t`` seconds at body rate
    ``w`` (so ``R_d(t) = R_d(0) exp(t ω_d×)`` solves eq. 5 for constant ω_d)."""
    w = np.asarray(w, dtype=float)
    n = np.sqrt(_dot(w, w))
    th = n * t
    safe = np.where(n > 0, n, 1.0)
    s = np.where(n > 0, np.sin(th) / safe, t)
    c = np.where(n > 0, (1.0 - np.cos(th)) / (safe * safe), 0.5 * t * t)
    K = hat(w)
    return np.eye(3) + s[..., None, None] * K + c[..., None, None] * matmul(K, K)


def attitude_error(R: np.ndarray, R_d: np.ndarray) -> np.ndarray:
    """``R̃ = R_dᵀ R`` (eq. 7)."""
    return matmul(_T(np.asarray(R_d, dtype=float)), R)


def eigenaxis_error(R_err: np.ndarray) -> np.ndarray:
    """Eigenaxis attitude error ``θ = acos((tr R̃ - 1)/2)`` (eq. 10), rad in [0, π]."""
    tr = R_err[..., 0, 0] + R_err[..., 1, 1] + R_err[..., 2, 2]
    return np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))


def _a_vec(a):
    a = np.asarray(a, dtype=float)
    return a if a.ndim and a.shape[-1] == 3 else np.broadcast_to(a[..., None], a.shape + (3,))


def _s_of_rows(r, a):
    """``Σ a_i r_i × e_i`` for rows ``r_i = r[..., i, :]``, written out:
    ``[a3 r32 - a2 r23, a1 r13 - a3 r31, a2 r21 - a1 r12]`` (1-based)."""
    a = _a_vec(a)
    a1, a2, a3 = a[..., 0], a[..., 1], a[..., 2]
    return np.stack([a3 * r[..., 2, 1] - a2 * r[..., 1, 2], a1 * r[..., 0, 2] - a3 * r[..., 2, 0],
                     a2 * r[..., 1, 0] - a1 * r[..., 0, 1]], -1)


def s_vector(R_err: np.ndarray, a) -> np.ndarray:
    """``S = Σ a_i (R̃ᵀ e_i) × e_i`` (eq. 13); ``a`` the diagonal of A, (3,) or (..., 3).
    ``R̃ᵀ e_i`` is row i of R̃."""
    return _s_of_rows(np.asarray(R_err, dtype=float), a)


def s_dot(R_err: np.ndarray, w_err: np.ndarray, a) -> np.ndarray:
    """``Ṡ = Σ a_i [(R̃ᵀ e_i) × ω̃] × e_i`` (eq. 38), the derivative of S along ``dR̃/dt = R̃ ω̃×``."""
    R_err = np.asarray(R_err, dtype=float)
    rows = cross(R_err, np.broadcast_to(np.asarray(w_err, dtype=float)[..., None, :], R_err.shape))
    return _s_of_rows(rows, a)


def _trace_term(R_err, a):
    """``tr(A - A R̃) = Σ a_i (1 - R̃_ii)``."""
    a = _a_vec(a)
    return (a[..., 0] * (1.0 - R_err[..., 0, 0]) + a[..., 1] * (1.0 - R_err[..., 1, 1])
            + a[..., 2] * (1.0 - R_err[..., 2, 2]))


def _trace_a(a):
    a = _a_vec(a)
    return a[..., 0] + a[..., 1] + a[..., 2]


# --- M2R (section 3) -----------------------------------------------------------------------------

def f_eq24(x: np.ndarray) -> np.ndarray:
    """``f(x) = 1/(1 + |x|)`` (eq. 24, the choice of [1]); ``|f(x) x| < 1``."""
    return 1.0 / (1.0 + np.abs(x))


def f_eq25(x: np.ndarray, omega_bar) -> np.ndarray:
    """``f(x) = 1/ω̄`` for ``|x| ≤ ω̄``, ``1/|x|`` above (eq. 25); ``|f(x) x| ≤ 1``."""
    ax = np.abs(x)
    ob = np.asarray(omega_bar, dtype=float)
    ob = ob[..., None] if ob.ndim else ob
    return 1.0 / np.maximum(ax, ob)


def m2r_gains(alpha, beta, a, w, f: str = 'eq25', omega_bar=0.2):
    """``(Kp (...,), kv (..., 3))``: Kp = α/tr A (eq. 15) and the diagonal of Kv(ω) (eq. 16) with
    ``f`` = ``'eq24'`` or ``'eq25'`` (ω̄ = ``omega_bar``, rad/s)."""
    w = np.asarray(w, dtype=float)
    if f == 'eq24':
        fw = f_eq24(w)
    elif f == 'eq25':
        fw = f_eq25(w, omega_bar)
    else:
        raise ValueError(f"f must be 'eq24' or 'eq25', got {f!r}")
    Kp = np.asarray(alpha, dtype=float) / _trace_a(a)
    return Kp, _g(beta) * fw


def m2r_torque(R: np.ndarray, w: np.ndarray, R_d: np.ndarray, alpha, beta, a, B_inv=None,
               f: str = 'eq25', omega_bar=0.2):
    """M2R law, eq. (12)-(16) with f of eq. (24) or (25): ``u = -B⁻¹(Kp S + Kv(ω) ω)``.

    ``R`` (..., 3, 3) attitude, ``w`` (..., 3) body rate, ``R_d`` the constant desired attitude,
    ``a`` diag(A) (3,) or (..., 3), ``B_inv`` B⁻¹ (None = identity, the paper's B = I).
    Returns ``(u, status)``; status: ``S``, ``Kp``, ``kv`` (diag of Kv), ``theta`` (eq. 10).
    """
    R = np.asarray(R, dtype=float)
    w = np.asarray(w, dtype=float)
    R_err = attitude_error(R, R_d)
    S = s_vector(R_err, a)
    Kp, kv = m2r_gains(alpha, beta, a, w, f, omega_bar)
    v = _g(Kp) * S + kv * w
    u = -v if B_inv is None else -matvec(B_inv, v)
    return u, {'S': S, 'Kp': Kp, 'kv': kv, 'theta': eigenaxis_error(R_err)}


def m2r_lyapunov(R, w, R_d, inertia, alpha, a):
    """``V = ½ ωᵀJω + Kp tr(A - A R̃)`` (eq. 11) with Kp = α/tr A; J the true inertia."""
    R_err = attitude_error(np.asarray(R, dtype=float), R_d)
    w = np.asarray(w, dtype=float)
    Kp = np.asarray(alpha, dtype=float) / _trace_a(a)
    return 0.5 * _dot(w, matvec(inertia, w)) + Kp * _trace_term(R_err, a)


def _b_inv(B):
    return np.eye(3) if B is None else np.linalg.inv(np.asarray(B, dtype=float))


def prop1_bound(alpha, beta, B=None):
    """Bound of Proposition 1, eq. (18): ``‖u‖∞ ≤ (α + β)/σmin(B)`` (N m; B = I by default)."""
    smin = 1.0 if B is None else np.linalg.svd(np.asarray(B, dtype=float), compute_uv=False)[..., -1]
    return (np.asarray(alpha, dtype=float) + beta) / smin


def prop2_bound(alpha, beta, B=None):
    """Bounds of Proposition 2, eq. (22): ``|u_i| ≤ ‖b_i‖ (α + √3 β)``, (3,) (N m)."""
    rows = np.linalg.norm(_b_inv(B), axis=-1)
    return rows * (np.asarray(alpha, dtype=float) + math.sqrt(3.0) * np.asarray(beta, dtype=float))


def _prop1_applies(B) -> bool:
    """Whether the proof of Proposition 1 holds for B: ``‖B⁻¹‖∞ ≤ σmax(B⁻¹)`` (max absolute row sum)."""
    Bi = _b_inv(B)
    return bool(np.abs(Bi).sum(axis=-1).max() <= np.linalg.norm(Bi, 2) * (1 + 1e-12))


def check_m2r_gains(alpha, beta, u_max, B=None, proposition: int = 1) -> None:
    """Refuse M2R gains that do not guarantee the torque limit: eq. (20) (``proposition=1``,
    ``(α + β)/σmin(B) ≤ u_max``) or eq. (23) (``proposition=2``, ``‖b_i‖(α + √3β) ≤ u_max,i``).

    ``alpha``, ``beta`` scalars or (...,) (one per run); ``u_max`` scalar, (3,), (..., 1) or
    (..., 3). Raises ValueError naming α, β, the bound and the limit; also when α or β is not
    positive, and for Proposition 1 when its proof does not hold for B (the bound (18) is then
    not a bound: use Proposition 2)."""
    for name, v in (('alpha', alpha), ('beta', beta)):
        if not np.all(np.asarray(v, dtype=float) > 0):
            raise ValueError(f'{name} (α/β of eq. 15-16) must be positive, got {v}')
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    u_max = np.asarray(u_max, dtype=float)
    u_max = np.broadcast_to(u_max, (u_max.shape[:-1] if u_max.ndim else ()) + (3,))
    if not np.all(u_max > 0):
        raise ValueError(f'u_max must be positive, got {u_max.tolist()}')
    if proposition == 1:
        if not _prop1_applies(B):
            raise ValueError('Proposition 1 (eq. 18/20) does not bound the torque for this B '
                             '(‖B⁻¹‖∞ > σmax(B⁻¹)): use proposition=2 (eq. 22/23)')
        bound, limit = np.broadcast_arrays(prop1_bound(alpha, beta, B), u_max.min(axis=-1))
        bad = np.argwhere(np.atleast_1d(bound > limit * (1 + 1e-12)))
        if len(bad):
            i = tuple(bad[0]) if bound.ndim else ()
            raise ValueError(f'alpha={np.broadcast_to(alpha, bound.shape)[i]:g}, beta='
                             f'{np.broadcast_to(beta, bound.shape)[i]:g} violate eq. (20): '
                             f'(α + β)/σmin(B) = {bound[i]:g} N m > u_max = {limit[i]:g} N m')
    elif proposition == 2:
        ab = (np.asarray(alpha, dtype=float) + math.sqrt(3.0) * beta)[..., None]
        bound, limit = np.broadcast_arrays(np.linalg.norm(_b_inv(B), axis=-1) * ab, u_max)
        bad = np.argwhere(bound > limit * (1 + 1e-12))
        if len(bad):
            i = tuple(bad[0])
            ax = i[-1] + 1
            al = np.broadcast_to(alpha[..., None], bound.shape)[i]
            be = np.broadcast_to(beta[..., None], bound.shape)[i]
            raise ValueError(f'alpha={al:g}, beta={be:g} violate eq. (23) on axis {ax}: '
                             f'‖b_{ax}‖(α + √3 β) = {bound[i]:g} N m > u_max,{ax} = {limit[i]:g} N m')
    else:
        raise ValueError(f'proposition must be 1 or 2, got {proposition}')


def k0_metric(e: np.ndarray, window: int = 200, threshold: float = 0.03, reduce: str = 'max'):
    """Settling index of eq. (29): the first step k > window such that the last ``window`` errors
    ``e(k-1) .. e(k-window)`` are below ``threshold`` (``reduce='max'``, as printed) or average
    below it (``reduce='mean'``, the text's wording). ``e`` (..., n) sampled errors; -1 if never."""
    e = np.asarray(e, dtype=float)
    n = e.shape[-1]
    c = np.concatenate([np.zeros(e.shape[:-1] + (1,)), np.cumsum(e, axis=-1)], axis=-1)
    if reduce == 'mean':
        ok = (c[..., window:] - c[..., :-window]) / window < threshold
    elif reduce == 'max':
        bad = np.concatenate([np.zeros(e.shape[:-1] + (1,)), np.cumsum(e >= threshold, axis=-1)], -1)
        ok = (bad[..., window:] - bad[..., :-window]) == 0
    else:
        raise ValueError(f"reduce must be 'max' or 'mean', got {reduce!r}")
    ok = ok[..., 1:]  # k = window + 1 .. n: window e(k-1) .. e(k-window)
    k = np.where(ok.any(axis=-1), np.argmax(ok, axis=-1) + window + 1, -1)
    return k if n > window else np.full(e.shape[:-1], -1)


# --- M2S (section 5) -----------------------------------------------------------------------------

def l_matrix(w: np.ndarray) -> np.ndarray:
    """``L(ω)`` (..., 3, 6) of eq. (31): ``Jω = L(ω) γ``."""
    w = np.asarray(w, dtype=float)
    z = np.zeros(w.shape[:-1])
    w1, w2, w3 = w[..., 0], w[..., 1], w[..., 2]
    return np.stack([np.stack([w1, z, z, z, w3, w2], -1), np.stack([z, w2, z, w3, z, w1], -1),
                     np.stack([z, z, w3, w2, w1, z], -1)], -2)


def _lt(w, v):
    """``L(ω)ᵀ v`` (..., 6)."""
    w1, w2, w3 = w[..., 0], w[..., 1], w[..., 2]
    v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([w1 * v1, w2 * v2, w3 * v3, w3 * v2 + w2 * v3, w3 * v1 + w1 * v3,
                     w2 * v1 + w1 * v2], -1)


def gamma_from_inertia(J) -> np.ndarray:
    """``γ = [J11 J22 J33 J23 J13 J12]`` (..., 6) (after eq. 31)."""
    J = np.asarray(J, dtype=float)
    return np.stack([J[..., 0, 0], J[..., 1, 1], J[..., 2, 2], J[..., 1, 2], J[..., 0, 2],
                     J[..., 0, 1]], -1)


def inertia_from_gamma(g) -> np.ndarray:
    """The symmetric J (..., 3, 3) of ``γ`` (..., 6)."""
    g = np.asarray(g, dtype=float)
    return np.stack([np.stack([g[..., 0], g[..., 5], g[..., 4]], -1),
                     np.stack([g[..., 5], g[..., 1], g[..., 3]], -1),
                     np.stack([g[..., 4], g[..., 3], g[..., 2]], -1)], -2)


def m2s_terms(R, w, R_d, w_d, a, K1, w_d_dot=None):
    """Error quantities of section 5 at one instant: dict with ``R_err`` (R̃), ``w_err`` (ω̃),
    ``S`` (13), ``S_dot`` (38), ``z = ω̃ + K1 S`` and ``X = K1 Ṡ + ω̃ × ω - R̃ᵀ ω̇_d``."""
    R = np.asarray(R, dtype=float)
    w = np.asarray(w, dtype=float)
    R_err = attitude_error(R, R_d)
    RT = _T(R_err)
    w_err = w - matvec(RT, np.broadcast_to(np.asarray(w_d, dtype=float), w.shape))
    S = s_vector(R_err, a)
    Sd = s_dot(R_err, w_err, a)
    z = w_err + matvec(K1, S)
    X = matvec(K1, Sd) + cross(w_err, w)
    if w_d_dot is not None:
        X = X - matvec(RT, np.broadcast_to(np.asarray(w_d_dot, dtype=float), w.shape))
    return {'R_err': R_err, 'w_err': w_err, 'S': S, 'S_dot': Sd, 'z': z, 'X': X}


def m2s_estimator_inputs(w, terms, C_d=None):
    """The measurement-driven parts of eq. (37) and (39): ``(Lᵀ(ω)(ω × z) + Lᵀ(X) z (..., 6),
    C_dᵀ z (..., nd) or None)``; ``dγ̂/dt = Q⁻¹ ·`` the first, ``dd̂/dt = A_d d̂ + D⁻¹ ·`` the second."""
    z, X = terms['z'], terms['X']
    raw_g = _lt(w, cross(w, z)) + _lt(X, z)
    return raw_g, (None if C_d is None else matvec(_T(np.asarray(C_d, dtype=float)), z))


def m2s_estimator_rates(w, terms, Q_inv, A_d=None, C_d=None, D_inv=None, d_hat=None):
    """``(dγ̂/dt (..., 6), dd̂/dt (..., nd) or None)``: eq. (37) and eq. (39).

    ``Q_inv`` (6, 6) or (..., 6, 6); ``A_d`` (nd, nd), ``C_d`` (3, nd), ``D_inv`` (nd, nd)."""
    raw_g, raw_d = m2s_estimator_inputs(w, terms, C_d)
    g_dot = matvec(Q_inv, raw_g)
    if raw_d is None:
        return g_dot, None
    d_dot = matvec(D_inv, raw_d)
    if A_d is not None:
        d_dot = matvec(A_d, d_hat) + d_dot
    return g_dot, d_dot


def m2s_torque(w, terms, gamma_hat, Kp, Kv, z_hat=None, B_inv=None):
    """Eq. (41)-(44): ``u = B⁻¹(v1 + v2 + v3)`` with ``v1 = -(Ĵω) × ω - Ĵ X``, ``v2 = -ẑ_d``,
    ``v3 = -Kv z - Kp S``. ``Kv`` (3, 3) or (..., 3, 3); ``Kp`` scalar or (...,).
    Returns ``(u, {'v1', 'v2', 'v3'})``."""
    w = np.asarray(w, dtype=float)
    J_hat = inertia_from_gamma(gamma_hat)
    v1 = -cross(matvec(J_hat, w), w) - matvec(J_hat, terms['X'])
    v2 = np.zeros(w.shape) if z_hat is None else -np.asarray(z_hat, dtype=float)
    v3 = -matvec(Kv, terms['z']) - _g(Kp) * terms['S']
    v = v1 + v2 + v3
    u = v if B_inv is None else matvec(B_inv, v)
    return u, {'v1': v1, 'v2': v2, 'v3': v3}


def m2s_lyapunov(terms, a, Kp, inertia, gamma_hat, Q, d_tilde=None, D=None):
    """V of eq. (36): ``½ zᵀJz + Kp tr(A - A R̃) + ½ γ̃ᵀQγ̃ (+ ½ d̃ᵀDd̃ when d̃ is given)``,
    J the true inertia (``γ̃ = γ(J) - γ̂``)."""
    z = terms['z']
    gt = gamma_from_inertia(inertia) - gamma_hat
    V = (0.5 * _dot(z, matvec(inertia, z)) + Kp * _trace_term(terms['R_err'], a)
         + 0.5 * (gt * matvec(Q, gt)).sum(axis=-1))
    if d_tilde is not None:
        V = V + 0.5 * (d_tilde * matvec(D, d_tilde)).sum(axis=-1)
    return V


# --- saturation (section 6) and VAG (section 7.1) -------------------------------------------------

def sat_cutoff(u: np.ndarray, u_max) -> np.ndarray:
    """Torque cutoff, eq. (47)-(48): per component ``sat(u_i, u_max,i)``."""
    u_max = np.asarray(u_max, dtype=float)
    return np.clip(u, -u_max, u_max)


def sat_scaling(u: np.ndarray, u_max) -> np.ndarray:
    """Torque scaling, eq. (49)-(51), box region: ``α_max u`` with ``α_max = min(1, min_i u_max,i/|u_i|)``
    (direction kept, largest vector inside the box)."""
    u = np.asarray(u, dtype=float)
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), u.shape)
    au = np.abs(u)
    ratio = np.where(au > u_max, u_max / np.where(au > 0, au, 1.0), 1.0)
    alpha = np.minimum(np.minimum(ratio[..., 0], ratio[..., 1]), ratio[..., 2])
    return alpha[..., None] * u


def saturate(u, u_max, method: str):
    """``method``: ``'none'``, ``'cutoff'`` (eq. 48) or ``'scaling'`` (eq. 51)."""
    if method == 'cutoff':
        return sat_cutoff(u, u_max)
    if method == 'scaling':
        return sat_scaling(u, u_max)
    if method == 'none':
        return np.asarray(u, dtype=float)
    raise ValueError(f"saturation must be 'none', 'cutoff' or 'scaling', got {method!r}")


# 'clip'/'scale': the names of the controller sections' common ``saturation`` parameter
_SAT_CODES = {'none': 0, 'cutoff': 1, 'clip': 1, 'scaling': 2, 'scale': 2}


def _outside(u, u_max):
    return np.any(np.abs(u) > u_max, axis=-1)


def qsat(q, q_max, u, u_max, K_Q, excess: str = 'printed'):
    """Adaptation-rate saturation function, eq. (56): the new q of ``Q = q I6`` (eq. 55).

    ``u`` the commanded (unsaturated) torque (..., 3); ``u_max`` scalar or (..., 3). ``excess``:
    ``'printed'`` = ``‖|u| - u_max‖/‖u_max‖`` (all axes), ``'positive'`` = only exceeding parts.
    Increase capped at ``q_max`` (the text: q "is not allowed to increase above" q_max)."""
    u = np.asarray(u, dtype=float)
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), u.shape)
    q = np.asarray(q, dtype=float)
    d = np.abs(u) - u_max
    if excess == 'positive':
        d = np.maximum(d, 0.0)
    elif excess != 'printed':
        raise ValueError(f"excess must be 'printed' or 'positive', got {excess!r}")
    with np.errstate(invalid='ignore', divide='ignore'):  # u_max = inf: never outside, unused
        ratio = np.sqrt(_dot(d, d)) / np.sqrt(_dot(u_max, u_max))
    grown = np.minimum((1.0 + np.asarray(K_Q, dtype=float) * ratio) * q, q_max)
    return np.where(_outside(u, u_max), np.where(q >= q_max, q_max, grown), q)


def extremum_tracking_step(t, w, axis, omega_bar, omega_bar0, delta, t_last, t_max, phi_max, K_omega):
    """One evaluation of eq. (60)-(64) at time ``t``.

    ``w`` (..., 3) body rate, ``axis`` (..., 3) unit desired spin axis ω̂_d, ``omega_bar`` current
    commanded rate ω̄_k, ``delta`` δ_k, ``t_last`` t̄_k. Returns ``(omega_bar, delta, t_last, phi)``
    after the step (δ and t̄ change only with the command)."""
    w = np.asarray(w, dtype=float)
    n = np.sqrt(_dot(w, w))
    cosphi = _dot(w, axis) / np.where(n > 0, n, 1.0)
    phi = np.where(n > 0, np.arccos(np.clip(cosphi, -1.0, 1.0)), np.pi)
    due = (t - t_last) > t_max
    new_delta = K_omega * delta
    down = due & (phi > phi_max)
    up = due & (phi <= phi_max) & (omega_bar < omega_bar0)
    change = down | up
    omega_new = np.where(down, omega_bar - new_delta, np.where(up, omega_bar + new_delta, omega_bar))
    return (omega_new, np.where(change, new_delta, delta), np.where(change, t, t_last), phi)


# --- laws bound to validated controller sections -------------------------------------------------

def _given(p, key):
    """``p[key]``, or None when absent or empty (a params file's ``[]`` means "the default")."""
    v = p.get(key)
    return None if v is None or np.size(v) == 0 else v


def _matrix_param(p, key, default):
    """An n x n gain from a section: absent -> ``default`` (n x n), a scalar (times ``default``),
    n diagonal values, or n² row-major values."""
    v = _given(p, key)
    if v is None:
        return default
    v = np.asarray(v, dtype=float)
    n = default.shape[-1]
    if v.size == 1:
        return v.reshape(()) * default
    if v.size == n:
        return np.diag(v.reshape(n))
    if v.size == n * n:
        return v.reshape(n, n)
    raise ValueError(f'{key} must be a scalar, {n} diagonal or {n * n} row-major values, got shape {v.shape}')


def actuation_matrix(p) -> np.ndarray | None:
    """B of eq. (1) from a section's ``B`` (3 diagonal or 9 row-major values), None when empty
    (B = I)."""
    return None if _given(p, 'B') is None else _matrix_param(p, 'B', np.eye(3))


class _InertiaFreeLaw(SectionLaw):
    """Common keys: ``A`` diag(A) (3 values, eq. 13), ``alpha``, ``beta`` (eq. 15-16 / 44), ``B``
    (3 diagonal or 9 row-major values, default I), ``u_max`` (N m, scalar or 3; default: the
    section's ``torquers.max_torque``, else inf)."""

    mode_names = MODE_NAMES

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        self.a = np.asarray(p.get('A', [1.0, 2.0, 3.0]), dtype=float)
        if self.a.shape[-1:] != (3,) or not np.all(self.a > 0) or np.any(
                (self.a[..., 0] == self.a[..., 1]) | (self.a[..., 1] == self.a[..., 2])
                | (self.a[..., 0] == self.a[..., 2])):
            raise ValueError(f'A must be 3 distinct positive diagonal entries (eq. 13), got {self.a.tolist()}')
        self.alpha = np.asarray(p['alpha'], dtype=float)
        self.beta = np.asarray(p['beta'], dtype=float)
        self.B = actuation_matrix(p)
        self.B_inv = None if self.B is None else np.linalg.inv(self.B)
        if 'u_max' in p:
            self.u_max = np.asarray(p['u_max'], dtype=float)
        else:  # the section's scalar torquer limit (one per run in a batch): per axis, (..., 1)
            self.u_max = np.asarray(p.get('torquers.max_torque', np.inf), dtype=float)[..., None]
        self.R_d0 = rotation_from_quaternion(self.q_ref)


class M2rLaw(_InertiaFreeLaw):
    """M2R (eq. 11-25) bound to a controller section. Keys (paper symbols):

    * ``inertia`` (J, used only for the status V of eq. 11), ``target.attitude`` (R_d as a
      scalar-last quaternion), ``target.rate`` (must be zero: M2R),
    * ``alpha``, ``beta`` (N m; Kp = α/tr A, Kv = β diag f), ``A`` (diag, default [1, 2, 3]),
    * ``f``: ``'eq25'`` (default, with ``omega_bar`` ω̄ rad/s, default 0.2) or ``'eq24'``,
    * ``B`` (default I), ``u_max`` (N m; when finite the gains are checked against eq. 20, or
      eq. 23 with ``proposition: 2``, and the torque is cut off at it as the torquers do).

    Status: ``V`` (eq. 11), ``theta`` (eq. 10), ``S``, ``mode`` (saturated or not)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        if np.any(np.asarray(self.w_ref) != 0):
            raise ValueError('M2R regulates to rest: target.rate must be zero')
        self.f = p.get('f', 'eq25')
        self.omega_bar = p.get('omega_bar', 0.2)
        if np.all(np.isfinite(self.u_max)):
            check_m2r_gains(self.alpha, self.beta, self.u_max, self.B, int(p.get('proposition', 1)))

    def control(self, t, q, w):
        R = rotation_from_quaternion(q)
        w = np.asarray(w, dtype=float)
        u, st = m2r_torque(R, w, self.R_d0, self.alpha, self.beta, self.a, self.B_inv, self.f,
                           self.omega_bar)
        mode = np.where(_outside(u, self.u_max), MODE_SATURATED, MODE_UNSATURATED)
        V = m2r_lyapunov(R, w, self.R_d0, self.inertia, self.alpha, self.a)
        return sat_cutoff(u, self.u_max), {'mode': mode, 'V': V, 'theta': st['theta'], 'S': st['S']}


class M2sLaw(_InertiaFreeLaw):
    """M2S dynamic compensator (Theorem 2, eq. 31-46) with saturation (47-51), VAG (55-58) and
    extremum tracking (60-67), bound to a controller section. Keys (paper symbols):

    * ``inertia`` (true J: only for the status V of eq. 36), ``target.attitude`` (R_d(0) as a
      quaternion), ``target.rate`` (ω_d, rad/s, constant; eq. 54 / 59),
    * ``alpha``, ``beta``: Kp = α/tr A, Kv = β I (reading R5); ``A`` (default [1, 2, 3]); ``K1``
      (scalar, 3 or 9 values; default I),
    * ``Q`` (6 or 36 values, default I6: Q₀ of Q = q Q₀), ``J_hat0`` (3 or 9 values, default I),
    * disturbance model: ``C_d`` (3 x nd, default none: not estimated), ``A_d`` (nd x nd, default 0),
      ``D`` (default I), ``d_hat0`` (default 0), ``d_true`` (true d, for V only, optional),
    * ``saturation``: ``'none'`` (default), ``'cutoff'`` (alias ``'clip'``) or ``'scaling'``
      (alias ``'scale'``) (or one per batch
      element); ``u_max`` (N m, scalar, 3, (..., 1) or (..., 3)); ``B`` (default I),
    * VAG: ``vag`` (bool, or one per batch element), ``q_max`` (10 000), ``K_Q`` (0.001), ``vag_excess`` ('printed'),
      ``vag_disturbance`` (bool, also divide the rate of d̂ by q; not in the paper's examples),
    * extremum tracking: ``extremum`` (bool), ``t_max`` (s), ``phi_max`` (rad), ``K_omega``,
      ``delta0`` (default, or 0: ‖ω_d‖),
    * ``max_step`` (s): the largest RK4 step of the estimator between two control calls
      (default 0.05).

    The compensator states (γ̂, d̂, q, ω̄, R_d) are continuous-time (q, ω̄ per call): each
    ``control(t, q, w)`` first advances γ̂ and d̂ from the previous call's time to ``t`` with the
    previous measurement held and R_d(s) exact (fixed-step RK4, ``ceil(Δt/max_step)`` steps),
    then computes u from the new measurement and updates q (eq. 56) and ω̄ (eq. 62). The batch
    shape is taken from the first call. ``reset()`` forgets the states.

    Status: ``V`` (eq. 36), ``theta`` (eq. 10), ``gamma_hat`` (6), ``d_hat``, ``z_hat`` (ẑ_d, when estimated),
    ``q_vag`` (q), ``omega_bar`` (commanded spin rate), ``w_d``, ``u_cmd`` (u of eq. 41 before
    saturation), ``mode``."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        self.w_d0 = np.asarray(self.w_ref, dtype=float)
        self.Kp = self.alpha / _trace_a(self.a)
        self.Kv = _g(self.beta)[..., None] * np.eye(3) if self.beta.ndim else self.beta * np.eye(3)
        self.K1 = _matrix_param(p, 'K1', np.eye(3))
        self.Q0 = _matrix_param(p, 'Q', np.eye(6))
        self.Q0_inv = np.linalg.inv(self.Q0)
        Jh = np.asarray(p.get('J_hat0', [1.0, 1.0, 1.0]), dtype=float)
        self.gamma0 = gamma_from_inertia(Jh[..., :, None] * np.eye(3) if Jh.shape[-1] == 3
                                         else Jh.reshape(Jh.shape[:-1] + (3, 3)))
        C_d = _given(p, 'C_d')
        self.C_d = None if C_d is None else np.asarray(C_d, dtype=float).reshape(3, -1)
        if self.C_d is not None and not np.any(self.C_d):
            self.C_d = None  # the paper's "C_d = 0": disturbance not estimated
        nd = 0 if self.C_d is None else self.C_d.shape[-1]
        self.A_d = None if _given(p, 'A_d') is None else np.asarray(p['A_d'], dtype=float).reshape(nd, nd)
        self.D = _matrix_param(p, 'D', np.eye(max(nd, 1)))
        self.D_inv = np.linalg.inv(self.D) if nd else None
        d0 = _given(p, 'd_hat0')
        self.d_hat0 = np.broadcast_to(np.asarray(0.0 if d0 is None else d0, dtype=float), (nd,))
        self.d_true = None if _given(p, 'd_true') is None else np.asarray(p['d_true'], dtype=float)
        sat = p.get('saturation', 'none')
        self.saturation = np.vectorize(_SAT_CODES.__getitem__, otypes=[int])(sat) \
            if np.all(np.isin(sat, list(_SAT_CODES))) else saturate(np.zeros(3), 1.0, str(sat))
        self.vag = np.asarray(p.get('vag', False), dtype=bool)
        self.q_max = float(p.get('q_max', 10000.0))
        self.K_Q = float(p.get('K_Q', 0.001))
        self.vag_excess = p.get('vag_excess', 'printed')
        self.vag_disturbance = bool(p.get('vag_disturbance', False))
        self.extremum = bool(p.get('extremum', False))
        self.t_max = float(p.get('t_max', 250.0))
        self.phi_max = float(p.get('phi_max', math.radians(10.0)))
        self.K_omega = float(p.get('K_omega', 0.5))
        n0 = np.sqrt(_dot(self.w_d0, self.w_d0))
        self.omega_bar0 = n0
        self.axis = self.w_d0 / np.where(n0 > 0, n0, 1.0)[..., None]
        delta0 = p.get('delta0')
        self.delta0 = np.asarray(n0 if delta0 is None or np.all(delta0 == 0) else delta0, dtype=float)
        self.max_step = float(p.get('max_step', 0.05))
        if not self.max_step > 0:
            raise ValueError(f'max_step must be positive, got {self.max_step}')
        self.reset()

    def reset(self) -> None:
        self.t_prev = None

    def published_status(self, status: dict) -> dict:
        """As the base class, with the inertia estimate γ̂ (eq. 31 order) as ``J_hat_11``,
        ``J_hat_22``, ``J_hat_33``, ``J_hat_23``, ``J_hat_13``, ``J_hat_12`` and the disturbance
        state estimate d̂ as ``d_hat_1``.. (``d_hat_x``.. when it has 3 components)."""
        status = dict(status)
        gamma = np.asarray(status.pop('gamma_hat'))
        d_hat = np.asarray(status.pop('d_hat'))
        out = super().published_status(status)
        out.update({f'J_hat_{ij}': float(g) for ij, g in zip(GAMMA_NAMES, gamma)})
        if d_hat.size:
            out.update(super().published_status({'d_hat': d_hat}) if d_hat.shape == (3,) else
                       {f'd_hat_{i + 1}': float(d) for i, d in enumerate(d_hat)})
        return out

    def _init_states(self, t, shape):
        self.gamma_hat = np.broadcast_to(self.gamma0, shape + (6,)).copy()
        self.d_hat = np.broadcast_to(self.d_hat0, shape + self.d_hat0.shape).copy()
        self.q_vag = np.ones(shape)
        self.omega_bar = np.broadcast_to(self.omega_bar0, shape).copy()
        self.delta = np.broadcast_to(self.delta0, shape).copy()
        self.t_change = np.full(shape, float(t))
        self.t_anchor = np.full(shape, float(t))
        self.R_anchor = np.broadcast_to(self.R_d0, shape + (3, 3)).copy()

    def _w_d(self):
        return self.omega_bar[..., None] * np.broadcast_to(self.axis, self.omega_bar.shape + (3,))

    def _R_d(self, t):
        return matmul(self.R_anchor, rotation_exp(self._w_d(), t - self.t_anchor))

    def _q_inv(self):
        return self.Q0_inv / self.q_vag[..., None, None]

    def _inputs(self, s, R, w):
        """Raw estimator inputs (:func:`m2s_estimator_inputs`) at times ``s`` (n,) with (R, ω)
        held and R_d(s) exact, each with a leading node axis."""
        shape = self.omega_bar.shape
        s = np.asarray(s, dtype=float).reshape((-1,) + (1,) * len(shape))
        R_d = matmul(self.R_anchor, rotation_exp(self._w_d(), s - self.t_anchor))
        terms = m2s_terms(R, w, R_d, self._w_d(), self.a, self.K1)
        return m2s_estimator_inputs(w, terms, self.C_d)

    def _advance(self, t):
        """Fixed-step RK4 of (γ̂, d̂) over [t_prev, t] with the previous call's measurement (R, ω)
        held and R_d(s) exact: ``n = ceil(Δt/max_step)`` steps of ``h``. The right-hand side of
        eq. (37) does not depend on γ̂ and eq. (39) is linear in d̂, so the measurement-driven
        inputs are evaluated once at the 2n + 1 distinct stage times (nodes and midpoints; the
        first is the previous call's own evaluation) and RK4 is applied to them: the same
        numbers as a generic RK4 at a fraction of the cost. Q (and D) are constant on the
        interval, so Q⁻¹ multiplies the integrated input."""
        span = t - self.t_prev
        if span <= 0:
            return
        n = max(1, math.ceil(span / self.max_step - 1e-9))
        h = span / n
        nodes = self.t_prev + (0.5 * h) * np.arange(1, 2 * n + 1)
        bg, bd = self._inputs(nodes, self.R_prev, self.w_prev)
        g0, d0 = self.raw_prev
        bg = [g0] + list(bg)
        bd = None if bd is None else [d0] + list(bd)
        acc = 0.0
        for i in range(n):
            j = 2 * i
            acc = acc + (h / 6.0) * (bg[j] + bg[j + 2]) + (h / 3.0) * (bg[j + 1] + bg[j + 1])
        self.gamma_hat = self.gamma_hat + matvec(self._q_inv(), acc)
        if bd is not None:
            D_inv = self.D_inv
            if self.vag_disturbance:
                D_inv = D_inv / self.q_vag[..., None, None]
            c = [matvec(D_inv, b) for b in bd]
            d = self.d_hat
            for i in range(n):
                j = 2 * i
                if self.A_d is None:
                    d = d + (h / 6.0) * (c[j] + c[j + 2]) + (h / 3.0) * (c[j + 1] + c[j + 1])
                else:
                    A = self.A_d
                    k1 = matvec(A, d) + c[j]
                    k2 = matvec(A, d + 0.5 * h * k1) + c[j + 1]
                    k3 = matvec(A, d + 0.5 * h * k2) + c[j + 1]
                    k4 = matvec(A, d + h * k3) + c[j + 2]
                    d = d + (h / 6.0) * (k1 + k4) + (h / 3.0) * (k2 + k3)
            self.d_hat = d

    def control(self, t, q, w):
        t = float(t)
        R = rotation_from_quaternion(q)
        w = np.asarray(w, dtype=float)
        if self.t_prev is None:
            self._init_states(t, w.shape[:-1])
        else:
            self._advance(t)
        if self.extremum:
            R_d_now = self._R_d(t)
            ob, self.delta, self.t_change, _ = extremum_tracking_step(
                t, w, self.axis, self.omega_bar, self.omega_bar0, self.delta, self.t_change,
                self.t_max, self.phi_max, self.K_omega)
            change = ob != self.omega_bar  # re-anchor R_d(t) where the command changed
            self.R_anchor = np.where(change[..., None, None], R_d_now, self.R_anchor)
            self.t_anchor = np.where(change, t, self.t_anchor)
            self.omega_bar = ob
        w_d = self._w_d()
        R_d = self._R_d(t)
        terms = m2s_terms(R, w, R_d, w_d, self.a, self.K1)
        z_hat = None if self.C_d is None else matvec(self.C_d, self.d_hat)
        u, parts = m2s_torque(w, terms, self.gamma_hat, self.Kp, self.Kv, z_hat, self.B_inv)
        sat = _outside(u, self.u_max)
        code = self.saturation[..., None] if self.saturation.ndim else self.saturation
        u_out = np.where(code == 1, sat_cutoff(u, self.u_max),
                         np.where(code == 2, sat_scaling(u, self.u_max), u))
        Q = self.Q0 * self.q_vag[..., None, None]
        d_tilde = D = None
        if self.d_true is not None and self.C_d is not None:
            d_tilde, D = self.d_true - self.d_hat, self.D
        V = m2s_lyapunov(terms, self.a, self.Kp, self.inertia, self.gamma_hat, Q, d_tilde, D)
        status = {'mode': np.where(sat, MODE_SATURATED, MODE_UNSATURATED), 'V': V,
                  'theta': eigenaxis_error(terms['R_err']), 'gamma_hat': self.gamma_hat.copy(),
                  'd_hat': self.d_hat.copy(),
                  'q_vag': self.q_vag.copy(), 'omega_bar': self.omega_bar.copy(), 'w_d': w_d,
                  'u_cmd': u, 'w_err': terms['w_err']}
        if z_hat is not None:
            status['z_hat'] = z_hat
        if np.any(self.vag):
            self.q_vag = np.where(self.vag, qsat(self.q_vag, self.q_max, u, self.u_max, self.K_Q,
                                                 self.vag_excess), self.q_vag)
        self.raw_prev = m2s_estimator_inputs(w, terms, self.C_d)
        self.t_prev, self.R_prev, self.w_prev = t, R, w
        return u_out, status
