"""Inertia-free adaptive motion to spin (M2S), seed 001 section 5 (Theorem 2), with the saturation
handling of sections 6-7 (:mod:`adcs_controllers.laws.saturation`). Pure numpy, no rclpy. The
model, S (eq. 13) and the section keys shared with M2R: :mod:`adcs_controllers.laws.motion_to_rest`.

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

Arrays take an optional LEADING BATCH AXIS: ``R`` (..., 3, 3), ``q`` (..., 4) scalar last,
``w`` (..., 3), scalar gains as scalars or (...,); matrices (``B``, ``K1``, ``Kv``) (3, 3) or
(..., 3, 3). Matrix-vector products go through :func:`adcs_core.attitude.matvec`, cross products
through :func:`adcs_core.attitude.cross`, matrix products through
:func:`adcs_core.attitude.matmul` (built on ``matvec``): a run in a batch gives the same bits as
alone.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_controllers.laws.motion_to_rest import (
    InertiaFreeLaw,
    given,
    matrix_param,
    s_of_rows,
    s_vector,
    trace_a,
    trace_term,
)
from adcs_controllers.laws.saturation import (
    MODE_SATURATED,
    MODE_UNSATURATED,
    SAT_CODES,
    extremum_tracking_step,
    outside_box,
    qsat,
    sat_cutoff,
    sat_scaling,
    saturate,
)
from adcs_core.attitude import (
    attitude_error,
    cross,
    dot,
    eigenaxis_error,
    gain_vector,
    matmul,
    matvec,
    rotation_exp,
    rotation_from_quaternion,
    transpose,
)

__all__ = [
    'GAMMA_NAMES', 'l_matrix', 'gamma_from_inertia', 'inertia_from_gamma', 's_dot', 'm2s_terms',
    'm2s_torque', 'm2s_estimator_inputs', 'm2s_estimator_rates', 'm2s_lyapunov', 'M2sLaw',
]

GAMMA_NAMES = ('11', '22', '33', '23', '13', '12')  # γ = [J11 J22 J33 J23 J13 J12], eq. (31)


def s_dot(R_err: np.ndarray, w_err: np.ndarray, a) -> np.ndarray:
    """``Ṡ = Σ a_i [(R̃ᵀ e_i) × ω̃] × e_i`` (eq. 38), the derivative of S along ``dR̃/dt = R̃ ω̃×``."""
    R_err = np.asarray(R_err, dtype=float)
    rows = cross(R_err, np.broadcast_to(np.asarray(w_err, dtype=float)[..., None, :], R_err.shape))
    return s_of_rows(rows, a)


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
    RT = transpose(R_err)
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
    return raw_g, (None if C_d is None else matvec(transpose(np.asarray(C_d, dtype=float)), z))


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
    v3 = -matvec(Kv, terms['z']) - gain_vector(Kp) * terms['S']
    v = v1 + v2 + v3
    u = v if B_inv is None else matvec(B_inv, v)
    return u, {'v1': v1, 'v2': v2, 'v3': v3}


def m2s_lyapunov(terms, a, Kp, inertia, gamma_hat, Q, d_tilde=None, D=None):
    """V of eq. (36): ``½ zᵀJz + Kp tr(A - A R̃) + ½ γ̃ᵀQγ̃ (+ ½ d̃ᵀDd̃ when d̃ is given)``,
    J the true inertia (``γ̃ = γ(J) - γ̂``)."""
    z = terms['z']
    gt = gamma_from_inertia(inertia) - gamma_hat
    V = (0.5 * dot(z, matvec(inertia, z)) + Kp * trace_term(terms['R_err'], a)
         + 0.5 * (gt * matvec(Q, gt)).sum(axis=-1))
    if d_tilde is not None:
        V = V + 0.5 * (d_tilde * matvec(D, d_tilde)).sum(axis=-1)
    return V


class M2sLaw(InertiaFreeLaw):
    """M2S dynamic compensator (Theorem 2, eq. 31-46) with saturation (47-51), VAG (55-58) and
    extremum tracking (60-67), bound to a controller section. Keys (paper symbols):

    * ``inertia`` (true J: only for the status V of eq. 36), ``target.attitude`` (R_d(0) as a
      quaternion), ``target.rate`` (ω_d, rad/s, constant; eq. 54 / 59),
    * ``alpha``, ``beta``: Kp = α/tr A, Kv = β I (reading R5); ``A``; ``K1`` (scalar, 3 or 9
      values; empty: I),
    * ``Q`` (6 or 36 values, empty: I6: Q₀ of Q = q Q₀), ``J_hat0`` (3 or 9 values),
    * disturbance model: ``C_d`` (3 x nd; empty or zero: not estimated), ``A_d`` (nd x nd; empty:
      0), ``D`` (empty: I), ``d_hat0`` (empty: 0), ``d_true`` (true d, for V only; empty: none),
    * ``saturation``: ``'clip'`` (alias ``'cutoff'``), ``'scale'`` (alias ``'scaling'``) or, for a
      pure-law caller, ``'none'`` (or one per batch element); u_max (``torquers.max_torque``, or
      ``u_max``: N m, scalar, 3, (..., 1) or (..., 3)); ``B`` (empty: I),
    * VAG: ``vag`` (bool, or one per batch element), ``q_max``, ``K_Q``, ``vag_excess``,
      ``vag_disturbance`` (bool, also divide the rate of d̂ by q; not in the paper's examples),
    * extremum tracking: ``extremum`` (bool), ``t_max`` (s), ``phi_max`` (rad), ``K_omega``,
      ``delta0`` (0: ‖ω_d‖),
    * ``max_step`` (s): the largest RK4 step of the estimator between two control calls.

    Defaults: :data:`adcs_controllers.families.M2S_SCHEMA` (the only place they are kept; the law
    reads every key of the validated section).

    The compensator states (γ̂, d̂, q, ω̄, R_d) are continuous-time (q, ω̄ per call): each
    ``control(t, q, w)`` first advances γ̂ and d̂ from the previous call's time to ``t`` with the
    previous measurement held and R_d(s) exact (fixed-step RK4, ``ceil(Δt/max_step)`` steps),
    then computes u from the new measurement and updates q (eq. 56) and ω̄ (eq. 62). The batch
    shape is taken from the first call. ``reset()`` forgets the states.

    Status: ``V`` (eq. 36), ``theta`` (eq. 10), ``gamma_hat`` (6), ``d_hat``, ``z_hat`` (ẑ_d, when estimated),
    ``q_vag`` (q), ``omega_bar`` (commanded spin rate), ``w_d``, ``u_cmd`` (u of eq. 41 before
    saturation), ``mode``."""

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        self.w_d0 = np.asarray(self.w_ref, dtype=float)
        self.Kp = self.alpha / trace_a(self.a)
        self.Kv = gain_vector(self.beta)[..., None] * np.eye(3) if self.beta.ndim else self.beta * np.eye(3)
        self.K1 = matrix_param(p.K1, 'K1', np.eye(3))
        self.Q0 = matrix_param(p.Q, 'Q', np.eye(6))
        self.Q0_inv = np.linalg.inv(self.Q0)
        Jh = np.asarray(p.J_hat0, dtype=float)
        self.gamma0 = gamma_from_inertia(Jh[..., :, None] * np.eye(3) if Jh.shape[-1] == 3
                                         else Jh.reshape(Jh.shape[:-1] + (3, 3)))
        C_d = given(p.C_d)
        self.C_d = None if C_d is None else np.asarray(C_d, dtype=float).reshape(3, -1)
        if self.C_d is not None and not np.any(self.C_d):
            self.C_d = None  # the paper's "C_d = 0": disturbance not estimated
        nd = 0 if self.C_d is None else self.C_d.shape[-1]
        self.A_d = None if given(p.A_d) is None else np.asarray(p.A_d, dtype=float).reshape(nd, nd)
        self.D = matrix_param(p.D, 'D', np.eye(max(nd, 1)))
        self.D_inv = np.linalg.inv(self.D) if nd else None
        d0 = given(p.d_hat0)
        self.d_hat0 = np.broadcast_to(np.asarray(0.0 if d0 is None else d0, dtype=float), (nd,))
        self.d_true = None if given(p.d_true) is None else np.asarray(p.d_true, dtype=float)
        sat = p.saturation
        self.saturation = np.vectorize(SAT_CODES.__getitem__, otypes=[int])(sat) \
            if np.all(np.isin(sat, list(SAT_CODES))) else saturate(np.zeros(3), 1.0, str(sat))
        self.vag = np.asarray(p.vag, dtype=bool)
        self.q_max = float(p.q_max)
        self.K_Q = float(p.K_Q)
        self.vag_excess = p.vag_excess
        self.vag_disturbance = bool(p.vag_disturbance)
        self.extremum = bool(p.extremum)
        self.t_max = float(p.t_max)
        self.phi_max = float(p.phi_max)
        self.K_omega = float(p.K_omega)
        n0 = np.sqrt(dot(self.w_d0, self.w_d0))
        self.omega_bar0 = n0
        self.axis = self.w_d0 / np.where(n0 > 0, n0, 1.0)[..., None]
        delta0 = p.delta0
        self.delta0 = np.asarray(n0 if np.all(delta0 == 0) else delta0, dtype=float)
        self.max_step = float(p.max_step)
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
        sat = outside_box(u, self.u_max)
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
