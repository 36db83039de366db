"""Inertia-free motion to rest (M2R) under torque saturation, seed 001 section 3, on rotation
matrices; with the model, the attitude-error vector S and the section keys that M2S
(:mod:`adcs_controllers.laws.motion_to_spin`) shares. Pure numpy, no rclpy.

Model (eq. 1-2): ``J dω/dt = (Jω) × ω + B u + z_d``, ``dR/dt = R ω×``; ``R`` maps body vectors to
inertial ones (= :func:`adcs_core.attitude.rotation_from_quaternion` of our scalar-last quaternion,
the plant's convention). Desired attitude ``dR_d/dt = R_d ω_d×`` (eq. 5), attitude error
``R̃ = R_dᵀ R`` (eq. 7, :func:`adcs_core.attitude.attitude_error`), rate error ``ω̃ = ω - R̃ᵀ ω_d``
(after eq. 8), eigenaxis error ``θ = acos((tr R̃ - 1)/2)`` (eq. 10,
:func:`adcs_core.attitude.eigenaxis_error`).

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

Arrays take an optional LEADING BATCH AXIS: ``R`` (..., 3, 3), ``q`` (..., 4) scalar last,
``w`` (..., 3), scalar gains as scalars or (...,); matrices (``B``, ``Kv``) (3, 3) or
(..., 3, 3). Matrix-vector products go through :func:`adcs_core.attitude.matvec` (fixed order):
a run in a batch gives the same bits as alone.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_controllers.laws.base import SectionLaw
from adcs_controllers.laws.saturation import MODE_NAMES, MODE_SATURATED, MODE_UNSATURATED, outside_box, sat_cutoff
from adcs_core.attitude import attitude_error, dot, eigenaxis_error, gain_vector, matvec, rotation_from_quaternion

__all__ = [
    's_of_rows', 's_vector', 'trace_term', 'trace_a', 'f_eq24', 'f_eq25', 'm2r_gains', 'm2r_torque',
    'm2r_lyapunov', 'prop1_bound', 'prop2_bound', 'check_m2r_gains', 'given', 'matrix_param',
    'actuation_matrix', 'InertiaFreeLaw', 'M2rLaw',
]


# --- the attitude-error vector S (eq. 13) and the trace term of V (eq. 11, 36) --------------------

def _a_vec(a):
    a = np.asarray(a, dtype=float)
    return a if a.ndim and a.shape[-1] == 3 else np.broadcast_to(a[..., None], a.shape + (3,))


def s_of_rows(r, a):
    """``Σ a_i r_i × e_i`` for rows ``r_i = r[..., i, :]``, written out:
    ``[a3 r32 - a2 r23, a1 r13 - a3 r31, a2 r21 - a1 r12]`` (1-based)."""
    a = _a_vec(a)
    a1, a2, a3 = a[..., 0], a[..., 1], a[..., 2]
    return np.stack([a3 * r[..., 2, 1] - a2 * r[..., 1, 2], a1 * r[..., 0, 2] - a3 * r[..., 2, 0],
                     a2 * r[..., 1, 0] - a1 * r[..., 0, 1]], -1)


def s_vector(R_err: np.ndarray, a) -> np.ndarray:
    """``S = Σ a_i (R̃ᵀ e_i) × e_i`` (eq. 13); ``a`` the diagonal of A, (3,) or (..., 3).
    ``R̃ᵀ e_i`` is row i of R̃."""
    return s_of_rows(np.asarray(R_err, dtype=float), a)


def trace_term(R_err, a):
    """``tr(A - A R̃) = Σ a_i (1 - R̃_ii)``."""
    a = _a_vec(a)
    return (a[..., 0] * (1.0 - R_err[..., 0, 0]) + a[..., 1] * (1.0 - R_err[..., 1, 1])
            + a[..., 2] * (1.0 - R_err[..., 2, 2]))


def trace_a(a):
    """``tr A = Σ a_i``."""
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
    Kp = np.asarray(alpha, dtype=float) / trace_a(a)
    return Kp, gain_vector(beta) * fw


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
    v = gain_vector(Kp) * S + kv * w
    u = -v if B_inv is None else -matvec(B_inv, v)
    return u, {'S': S, 'Kp': Kp, 'kv': kv, 'theta': eigenaxis_error(R_err)}


def m2r_lyapunov(R, w, R_d, inertia, alpha, a):
    """``V = ½ ωᵀJω + Kp tr(A - A R̃)`` (eq. 11) with Kp = α/tr A; J the true inertia."""
    R_err = attitude_error(np.asarray(R, dtype=float), R_d)
    w = np.asarray(w, dtype=float)
    Kp = np.asarray(alpha, dtype=float) / trace_a(a)
    return 0.5 * dot(w, matvec(inertia, w)) + Kp * trace_term(R_err, a)


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
    """Whether the proof of Proposition 1 holds for B (or each B of a batch (..., 3, 3)):
    ``‖B⁻¹‖∞ ≤ σmax(B⁻¹)`` (max absolute row sum)."""
    Bi = _b_inv(B)
    row_sums = np.abs(Bi).sum(axis=-1).max(axis=-1)
    return bool(np.all(row_sums <= np.linalg.norm(Bi, 2, axis=(-2, -1)) * (1 + 1e-12)))


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


# --- the section keys shared by M2R and M2S ------------------------------------------------------

def given(v):
    """A parameter's value ``v``, or None when it is empty (a params file's ``[]``: the meaning the
    schema gives an empty value, e.g. B = I). A typed section has every parameter (the schema,
    :mod:`adcs_controllers.families`, is the one source of defaults)."""
    return None if v is None or np.size(v) == 0 else v


def matrix_param(value, key, default):
    """An n x n gain from a section: empty -> ``default`` (n x n), a scalar (times ``default``),
    n diagonal values, or n² row-major values; the values on the last axis, any leading axes a
    batch (one gain per run, as :meth:`Schema.stack` gives a dispersed key): (..., n, n). A
    (3, 3) array is three runs' diagonals, not one matrix (a matrix is its 9 values)."""
    v = given(value)
    if v is None:
        return default
    v = np.asarray(v, dtype=float)
    n = default.shape[-1]
    size = v.shape[-1] if v.ndim else 1
    batch = v.shape[:-1]
    if size == 1:
        return v.reshape(batch + (1, 1)) * default
    if size == n:   # exact zeros off the diagonal, as np.diag (not v * I: -0.0 for negative values)
        out = np.zeros(batch + (n, n))
        out[..., np.arange(n), np.arange(n)] = v
        return out
    if size == n * n:
        return v.reshape(batch + (n, n))
    raise ValueError(f'{key} must be a scalar, {n} diagonal or {n * n} row-major values, got shape {v.shape}')


def actuation_matrix(B) -> np.ndarray | None:
    """B of eq. (1) from a section's ``B`` value (3 diagonal or 9 row-major values), None when
    empty (B = I)."""
    return None if given(B) is None else matrix_param(B, 'B', np.eye(3))


class InertiaFreeLaw(SectionLaw):
    """Common keys: ``A`` diag(A) (3 values, eq. 13), ``alpha``, ``beta`` (eq. 15-16 / 44), ``B``
    (3 diagonal or 9 row-major values, or one row of them per run, (N, 3) or (N, 9); empty: I),
    ``torquers.max_torque`` (u_max, N m; a pure-law caller may give ``u_max`` instead: scalar, 3,
    (..., 1) or (..., 3)).

    ``p`` is a validated section (:data:`adcs_controllers.families.M2R_SCHEMA` /
    ``M2S_SCHEMA``): every key is there, with the schema's default where the file has none; the
    laws keep no defaults of their own."""

    mode_names = MODE_NAMES

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        self.a = np.asarray(p.A, dtype=float)
        if self.a.shape[-1:] != (3,) or not np.all(self.a > 0) or np.any(
                (self.a[..., 0] == self.a[..., 1]) | (self.a[..., 1] == self.a[..., 2])
                | (self.a[..., 0] == self.a[..., 2])):
            raise ValueError(f'A must be 3 distinct positive diagonal entries (eq. 13), got {self.a.tolist()}')
        self.alpha = np.asarray(p.alpha, dtype=float)
        self.beta = np.asarray(p.beta, dtype=float)
        self.B = actuation_matrix(p.B)
        self.B_inv = None if self.B is None else np.linalg.inv(self.B)
        if hasattr(p, 'u_max'):   # a pure-law caller's own limit (not a schema parameter)
            self.u_max = np.asarray(p.u_max, dtype=float)
        else:  # the section's scalar torquer limit (one per run in a batch): per axis, (..., 1)
            self.u_max = np.asarray(p.torquers.max_torque, dtype=float)[..., None]
        self.R_d0 = rotation_from_quaternion(self.q_ref)


class M2rLaw(InertiaFreeLaw):
    """M2R (eq. 11-25) bound to a controller section. Keys (paper symbols):

    * ``inertia`` (J, used only for the status V of eq. 11), ``target.attitude`` (R_d as a
      scalar-last quaternion), ``target.rate`` (must be zero: M2R),
    * ``alpha``, ``beta`` (N m; Kp = α/tr A, Kv = β diag f), ``A`` (diag),
    * ``f``: ``'eq25'`` (with ``omega_bar`` ω̄ rad/s) or ``'eq24'``,
    * ``B``, u_max (N m; when finite the gains are checked against eq. 20, or eq. 23 with
      ``proposition: 2``, and the torque is cut off at it as the torquers do).

    Defaults: :data:`adcs_controllers.families.M2R_SCHEMA` (the only place they are kept).

    Status: ``V`` (eq. 11), ``theta`` (eq. 10), ``S``, ``mode`` (saturated or not)."""

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        if np.any(np.asarray(self.w_ref) != 0):
            raise ValueError('M2R regulates to rest: target.rate must be zero')
        self.f = p.f
        self.omega_bar = p.omega_bar
        if np.all(np.isfinite(self.u_max)):
            check_m2r_gains(self.alpha, self.beta, self.u_max, self.B, int(p.proposition))

    def control(self, t, q, w):
        R = rotation_from_quaternion(q)
        w = np.asarray(w, dtype=float)
        u, st = m2r_torque(R, w, self.R_d0, self.alpha, self.beta, self.a, self.B_inv, self.f,
                           self.omega_bar)
        mode = np.where(outside_box(u, self.u_max), MODE_SATURATED, MODE_UNSATURATED)
        V = m2r_lyapunov(R, w, self.R_d0, self.inertia, self.alpha, self.a)
        return sat_cutoff(u, self.u_max), {'mode': mode, 'V': V, 'theta': st['theta'], 'S': st['S']}
