"""Underactuated (two-wheel) attitude laws of seed 000 (Horri & Palmer, "Practical implementation of
attitude control algorithms for an underactuated satellite"): three-axis control with reaction
wheels on body X and Y only (the Z wheel failed). Pure numpy, no rclpy.

Model (seed 000 eq. 3, 5): ``I dw/dt = -w x (I w + h) + u``, ``u = -dh/dt = [N1, N2, 0]`` (no Z
torque), quaternion kinematics ``dq/dt = -1/2 w x q + 1/2 q4 w``, ``dq4/dt = -1/2 wᵀq`` (the same
as :func:`adcs_core.attitude.quat_kinematics`). Quaternions are scalar last ``[x, y, z, w]`` =
the paper's ``[q1 q2 q3 q4]``; rates in rad/s; ``u`` is the BODY torque (the motor torque of a
wheel along +x / +y is ``-u_x`` / ``-u_y``). Regulation is to ``q = [0 0 0 1]``, ``w = 0``; with
``q_ref``/``w_ref`` the laws act on the error quaternion ``q_ref* ⊗ q`` and ``w - w_ref`` as the
seed 004 laws do (:func:`adcs_controllers.laws.inverse_optimal.error_state`; our extension).

Desired rates, singular quaternion law (eq. 7) and its saturated form (eq. 8)::

    r1 = q2 q3 / (q1² + q2² + ε₀),   r2 = q1 q3 / (q1² + q2² + ε₀)
    ωd1 = -k q1 + g sat(r1, a1),     ωd2 = -k q2 - g sat(r2, a2),     ωd3 = 0

``ε₀`` (argument ``eps_den``) is the "small positive constant" that section IV.B.2 adds to the
denominator ("necessary for in-orbit testing"); ``eps_den = 0`` and ``a = inf`` is eq. 7 exactly,
where the singular ratio is defined as 0 at ``q1 = q2 = 0`` (its limit on the closed-loop
trajectories, section III.C). ``sat(x, a) = clip(x, -a, a)``. With ``w3 = 0`` eq. 7 gives
``dq3/dt = -g/2 q3`` (eq. 9) and ``dq4/dt = k/2 (q1² + q2²)`` (eq. 10).
:func:`desired_rates` also returns ``dωd/dt`` along the actual motion (chain rule through the
kinematics with the measured ``w``; zero where a ratio is saturated).

Zero-momentum controller (eq. 12-13), attitude-only feedback: wheel SPEED commands (relative to the
body, for the plant's wheel speed mode) ``Ω_i = -I_i / I_wh,i ωd_i``, i = x, y.

Angular-velocity tracking controller "snlc" (eq. 14 / 24 / 31), body torque::

    u_i = -K_i (ω_i - ωd_i) + I_i dωd_i/dt,   i = 1, 2;   u_3 = 0

Reading (docs/seed000_readings.md): eq. 14/24 print ``I_i(-K_i(ω_i - ωd_i) + dωd_i/dt)``, eq. 31
prints ``-K_i(...) + I_i dωd_i/dt``; the paper's gain K = 10 "Nm.s/rad" only has the units of the
eq. 31 form, and ``I_i K_i = 400 /s`` with the paper's 1 s zero-order hold diverges. The eq. 31 form
is the default; ``scale_by_inertia=True`` gives the printed eq. 14 (kept for comparison).

Lyapunov function (eq. 15/16, and eq. 26 with ``ωγσ`` = eq. 27 = eq. 8 with gains ``γ, σ``)::

    V = k (qᵀq + (1 - q4)²) + 1/2 eᵀe = 2 k (1 - q4) + 1/2 eᵀe,      e = ω - ωγσ,  ωγσ3 = 0
    LgV = eᵀ I⁻¹ B,  B = [e1 e2] (only X and Y torques exist; z component of LgV set to 0)
    LfV = -2 k dq4/dt - eᵀ I⁻¹ (ω x (I ω + h)) - eᵀ dωγσ/dt

``h`` is the wheel momentum in body axes; ``h = None`` means the paper's zero total momentum
(``I ω + h = 0``, the gyroscopic term vanishes). Exact ``dV/dt = LfV + LgV u`` (the paper's eq.
17-19 and 28-29 drop the cross term ``k q_{12}ᵀ e_{12}``; see the readings).

Min-norm law on the snlc benchmark (eq. 25)::

    u = (LgV k(x)) LgVᵀ / (LgV LgVᵀ)   if LgV k(x) < 0,    else 0

(printed with a leading minus, which makes ``LgV u = -LgV k > 0``: an extraction artefact, as in
seed 004 eq. 14; eq. 30 has no minus). Gain-scheduled min-norm law, GSMN (eq. 30-32): low-gain law
``u_lg`` = snlc with ``(k1, g1, K1)``, high-gain law ``u_hg`` = snlc with ``(k2, g2, K2)`` (eq. 32's
``q2 q3`` in ``u_hg2`` read as ``q1 q3``, as eq. 8/31), and::

    LgV u_hg >= 0                    -> u = 0                              MODE_ZERO_TORQUE (1)
    LgV u_hg < 0, ‖u_hg‖∞ >= epsilon -> u = (LgV u_lg) LgVᵀ / (LgV LgVᵀ)    MODE_LOW_GAIN (0)
    LgV u_hg < 0, ‖u_hg‖∞ <  epsilon -> u = (LgV u_hg) LgVᵀ / (LgV LgVᵀ)    MODE_HIGH_GAIN (2)

Every function takes ``q`` (..., 4), ``w`` (..., 3), ``inertia`` (3, 3) or (..., 3, 3), gains as
scalars or arrays broadcasting over the batch axes; all matrix-vector products use
:func:`adcs_core.attitude.matvec` and cross products :func:`adcs_core.attitude.cross`, so a batch gives
the same bits as a loop of single calls. Torque laws return ``(u (..., 3), status)`` with
``u[..., 2] == 0`` exactly.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws import underactuated_scalar as scalar
from adcs_controllers.laws.base import SHORTEST_PATH, TARGET_PARAMS, SectionLaw
from adcs_controllers.laws.inverse_optimal import error_state, inertia_inverse
from adcs_core.attitude import cross, dot, gain_vector, matvec, quat_kinematics, transpose
from adcs_msgs_py.params import Param, non_negative, positive

__all__ = [
    'MODE_LOW_GAIN', 'MODE_ZERO_TORQUE', 'MODE_HIGH_GAIN', 'MODE_MIN_NORM', 'MODE_SNLC',
    'MODE_ZERO_MOMENTUM', 'desired_rates', 'zero_momentum_wheel_momentum', 'zero_momentum_wheel_speeds', 'snlc_torque',
    'lyapunov', 'lie_derivatives', 'min_norm_torque', 'gsmn_torque',
    'ZeroMomentumLaw', 'SnlcLaw', 'SnlcMinNormLaw', 'SnlcGsmnLaw',
]

MODE_LOW_GAIN = 0       # GSMN: projection of the low-gain snlc torque
MODE_ZERO_TORQUE = 1    # min-norm / GSMN: torque off
MODE_HIGH_GAIN = 2      # GSMN: projection of the high-gain snlc torque
MODE_MIN_NORM = 3       # standard min-norm: projection of the snlc torque
MODE_SNLC = 5           # snlc benchmark (continuous)
MODE_ZERO_MOMENTUM = 6  # zero-momentum wheel speed law

_XY = np.array([1.0, 1.0, 0.0])


def _sat_ratio(num, den, a):
    """``sat(num/den, a)`` and the indicator that it is NOT saturated; 0 where ``den == 0``."""
    ok = den > 0.0
    r = np.where(ok, num / np.where(ok, den, 1.0), 0.0)
    a = np.asarray(a, dtype=float)
    free = ok & (np.abs(r) < a)
    return np.clip(r, -a, a), free, r


def desired_rates(q, w, k, g, a1=np.inf, a2=np.inf, eps_den=0.0):
    """Desired body rates of eq. (7) (``a = inf``, ``eps_den = 0``) / eq. (8) with the IV.B.2
    denominator ``q1² + q2² + eps_den``; also eq. (27) with ``(k, g) = (γ, σ)``.

    ``q`` (..., 4) error quaternion, ``w`` (..., 3) measured rate (only used for the derivative).
    Returns ``(wd, wd_dot)``, both (..., 3) with a zero z component: ``wd_dot`` is ``dωd/dt``
    along ``dq/dt = quat_kinematics(q, w)`` (the ``ω̇d`` of eq. 14).
    """
    return _rates(_rate_terms(q, w, a1, a2, eps_den), k, g)


def _rate_terms(q, w, a1, a2, eps_den) -> tuple:
    """What :func:`desired_rates` computes before its gains ``k``, ``g`` enter: the same for every
    gain pair on one state, so a law that needs ``ωd`` for several pairs (GSMN: the Lyapunov
    function's, the low- and the high-gain benchmark's) computes it once (same operations, same bits)."""
    q = np.asarray(q, dtype=float)
    w = np.asarray(w, dtype=float)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    dq = quat_kinematics(q, w)
    d1, d2, d3 = dq[..., 0], dq[..., 1], dq[..., 2]
    den = q1 * q1 + q2 * q2 + eps_den
    s1, free1, r1 = _sat_ratio(q2 * q3, den, a1)
    s2, free2, r2 = _sat_ratio(q1 * q3, den, a2)
    ok = den > 0.0
    safe = np.where(ok, den, 1.0)
    dden = 2.0 * (q1 * d1 + q2 * d2)
    dr1 = (d2 * q3 + q2 * d3 - r1 * dden) / safe
    dr2 = (d1 * q3 + q1 * d3 - r2 * dden) / safe
    return q1, q2, d1, d2, s1, s2, np.where(free1, dr1, 0.0), np.where(free2, dr2, 0.0), np.zeros(q1.shape)


def _rates(terms: tuple, k, g):
    """(ωd, dωd/dt) of gains ``k``, ``g`` from :func:`_rate_terms`."""
    q1, q2, d1, d2, s1, s2, dr1_free, dr2_free, zero = terms
    k = np.asarray(k, dtype=float)
    g = np.asarray(g, dtype=float)
    wd = np.stack([-k * q1 + g * s1, -k * q2 - g * s2, zero + 0.0 * k], axis=-1)
    wd_dot = np.stack([-k * d1 + g * dr1_free, -k * d2 - g * dr2_free, zero + 0.0 * k], axis=-1)
    return wd, wd_dot


def _diag(inertia):
    inertia = np.asarray(inertia, dtype=float)
    return np.stack([inertia[..., 0, 0], inertia[..., 1, 1], inertia[..., 2, 2]], axis=-1)


def zero_momentum_wheel_momentum(q, inertia, k, g, a1=np.inf, a2=np.inf, eps_den=0.0, q_ref=None,
                                 shortest_path=False):
    """Zero-momentum controller, eq. (12-13), as the commanded wheel momentum in body axes.

    Attitude-only feedback (``ωd`` of eq. 7/8 needs no rate): ``h_cmd = [-I_1 ωd_1, -I_2 ωd_2, 0]``
    with ``I_i`` the total (wheels-locked) inertia, so that ``I ω + h = 0`` (eq. 12) holds when the
    body turns at ``ωd``. Returns ``(h_cmd (..., 3), status)``; ``status``: ``mode``
    (MODE_ZERO_MOMENTUM), ``wd``.
    """
    q = np.asarray(q, dtype=float)
    qe, _ = error_state(q, np.zeros(q.shape[:-1] + (3,)), q_ref, None, shortest_path)
    wd, _ = desired_rates(qe, np.zeros(qe.shape[:-1] + (3,)), k, g, a1, a2, eps_den)
    h_cmd = -_diag(inertia) * wd * _XY
    mode = np.full(h_cmd.shape[:-1], MODE_ZERO_MOMENTUM)
    return h_cmd, {'mode': mode, 'wd': wd}


def zero_momentum_wheel_speeds(q, inertia, wheel_inertia, k, g, a1=np.inf, a2=np.inf, eps_den=0.0,
                               q_ref=None, shortest_path=False):
    """Eq. (13) as printed: wheel speed commands ``Ω_i = -I_i / I_wh,i ωd_i`` (i = x, y).

    ``wheel_inertia`` (I_wh): scalar or (..., 2) spin inertias of the X and Y wheels. The speeds
    are relative to the body, for the plant's wheel speed mode: with ``I_i`` the total
    (wheels-locked) inertia, ``I_i ω_i + I_wh,i Ω_i = 0`` is exactly the zero total momentum of
    eq. (12). Returns ``(speed (..., 2), status)``; ``status`` as
    :func:`zero_momentum_wheel_momentum` plus ``h_cmd`` (..., 2).
    """
    h_cmd, status = zero_momentum_wheel_momentum(q, inertia, k, g, a1, a2, eps_den, q_ref, shortest_path)
    status['h_cmd'] = h_cmd[..., :2]
    return h_cmd[..., :2] / np.asarray(wheel_inertia, dtype=float), status


def _snlc(qe, we, Id, k, g, K, a1, a2, eps_den, scale_by_inertia, terms=None):
    """The snlc torque (law axes), ωd and dωd/dt; ``terms``: :func:`_rate_terms` of the state if known."""
    terms = _rate_terms(qe, we, a1, a2, eps_den) if terms is None else terms
    wd, wd_dot = _rates(terms, k, g)
    if scale_by_inertia:  # eq. 14 / 24 as printed: I_i (-K_i (ω_i - ωd_i) + ω̇d_i)
        u = Id * (-gain_vector(K) * (we - wd) + wd_dot)
    else:                 # eq. 31 form (default): -K_i (ω_i - ωd_i) + I_i ω̇d_i
        u = -gain_vector(K) * (we - wd) + Id * wd_dot
    return u * _XY, wd, wd_dot


def snlc_torque(q, w, inertia, k, g, K, a1=np.inf, a2=np.inf, eps_den=0.0, q_ref=None, w_ref=None,
                shortest_path=False, scale_by_inertia=False):
    """Angular-velocity tracking controller "snlc", eq. (14) / (24) (form of eq. 31, see module doc).

    ``u_i = -K_i (ω_i - ωd_i) + I_i dωd_i/dt`` (i = 1, 2), ``u_3 = 0``; ``ωd`` from eq. (7)/(8);
    ``K`` (N m s/rad) scalar, or per batch element. ``I_i`` are the diagonal entries of
    ``inertia`` (the paper's ``Ir = diag(I1, I2)``). Returns ``(u, status)``; ``status``:
    ``mode`` (MODE_SNLC), ``V`` (eq. 15/16 with the law's own ``k``, ``ωd``), ``wd``, ``wd_dot``.
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    u, wd, wd_dot = _snlc(qe, we, _diag(inertia), k, g, K, a1, a2, eps_den, scale_by_inertia)
    mode = np.full(u.shape[:-1], MODE_SNLC)
    e = we - wd
    V = 2.0 * np.asarray(k, dtype=float) * (1.0 - qe[..., 3]) + 0.5 * dot(e, e)  # eq. 15/16
    return u, {'mode': mode, 'V': V, 'wd': wd, 'wd_dot': wd_dot}


def _lie(qe, we, inertia, k, gamma, sigma, a1, a2, eps_den, h, terms=None):
    """(V, LfV, LgV (z = 0), w_gs) of eq. (26) on the error state; ``terms`` as for :func:`_snlc`."""
    terms = _rate_terms(qe, we, a1, a2, eps_den) if terms is None else terms
    w_gs, w_gs_dot = _rates(terms, gamma, sigma)
    e = we - w_gs
    Iinv = inertia_inverse(inertia)
    LgV = matvec(transpose(Iinv), e) * _XY
    dq4 = -0.5 * dot(qe[..., :3], we)
    k = np.asarray(k, dtype=float)
    LfV = -2.0 * k * dq4 - dot(e, w_gs_dot)
    if h is not None:
        L = matvec(inertia, we) + h
        LfV = LfV - dot(e, matvec(Iinv, cross(we, L)))
    V = 2.0 * k * (1.0 - qe[..., 3]) + 0.5 * dot(e, e)
    return V, LfV, LgV, w_gs


def lyapunov(q, w, k, gamma, sigma, a1=np.inf, a2=np.inf, eps_den=0.0, q_ref=None, w_ref=None,
             shortest_path=False):
    """V of eq. (26) (eq. 15/16 with ``γ = k, σ = g``): ``2 k (1 - q4) + 1/2 |ω - ωγσ|²``."""
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    wg, _ = desired_rates(qe, we, gamma, sigma, a1, a2, eps_den)
    e = we - wg
    return 2.0 * np.asarray(k, dtype=float) * (1.0 - qe[..., 3]) + 0.5 * dot(e, e)


def lie_derivatives(q, w, inertia, k, gamma, sigma, a1=np.inf, a2=np.inf, eps_den=0.0, h=None,
                    q_ref=None, w_ref=None, shortest_path=False):
    """``(LfV, LgV)`` of V (eq. 26) along eq. (3), (5); ``dV/dt = LfV + LgV u`` for ``u_z = 0``.

    ``h`` wheel momentum (body axes); ``None`` = zero total momentum (``I ω + h = 0``).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    _, LfV, LgV, _ = _lie(qe, we, np.asarray(inertia, dtype=float), k, gamma, sigma, a1, a2,
                          eps_den, None if h is None else np.asarray(h, dtype=float))
    return LfV, LgV


def _project(LgV, b, on):
    aa = dot(LgV, LgV)
    return np.where(on, b / np.where(on, aa, 1.0), 0.0)[..., None] * LgV


def _status(mode, V, LfV, LgV, u, wd, w_gs):
    LgV_u = dot(LgV, u)
    return {'mode': mode, 'V': V, 'Vdot': LfV + LgV_u, 'LgV_u': LgV_u, 'wd': wd, 'w_gs': w_gs}


def min_norm_torque(q, w, inertia, k, g, K, gamma, sigma, a1=np.inf, a2=np.inf, eps_den=0.0, h=None,
                    q_ref=None, w_ref=None, shortest_path=False, scale_by_inertia=False):
    """Standard min-norm law on the snlc benchmark, eq. (25) (leading minus dropped), V of eq. (26).

    ``u = (LgV u_snlc) LgVᵀ/(LgV LgVᵀ)`` if ``LgV u_snlc < 0`` (MODE_MIN_NORM) else 0
    (MODE_ZERO_TORQUE). ``k, g, K``: benchmark gains (eq. 24/8); ``γ, σ`` (< k, g): the gains of
    ``ωγσ`` (eq. 27) in V; ``k`` also weighs V's attitude term. ``h`` only enters ``Vdot``.
    Returns ``(u, status)`` with ``mode``, ``V``, ``Vdot``, ``LgV_u``, ``wd`` (benchmark's ωd),
    ``w_gs`` (ωγσ). By construction ``LgV u <= LgV u_snlc`` (``dV/dt`` no larger than under
    the benchmark).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    inertia = np.asarray(inertia, dtype=float)
    terms = _rate_terms(qe, we, a1, a2, eps_den)
    V, LfV, LgV, w_gs = _lie(qe, we, inertia, k, gamma, sigma, a1, a2, eps_den,
                             None if h is None else np.asarray(h, dtype=float), terms)
    ub, wd, _ = _snlc(qe, we, _diag(inertia), k, g, K, a1, a2, eps_den, scale_by_inertia, terms)
    b = dot(LgV, ub)
    on = b < 0.0
    u = _project(LgV, b, on)
    mode = np.where(on, MODE_MIN_NORM, MODE_ZERO_TORQUE)
    return u, _status(mode, V, LfV, LgV, u, wd, w_gs)


def gsmn_torque(q, w, inertia, k1, g1, K1, k2, g2, K2, gamma, sigma, epsilon, a1=np.inf, a2=np.inf,
                eps_den=0.0, h=None, q_ref=None, w_ref=None, shortest_path=False,
                scale_by_inertia=False):
    """Gain-scheduled min-norm law, eq. (30) with ``u_lg`` of eq. (31) and ``u_hg`` of eq. (32).

    ``u_lg`` = snlc with ``(k1, g1, K1)`` (the benchmark), ``u_hg`` = snlc with ``(k2, g2, K2)``;
    ``epsilon`` (N m) the torque threshold on ``‖u_hg‖∞``; V of eq. (26) with ``k1, γ, σ``.
    Modes: MODE_ZERO_TORQUE (``LgV u_hg >= 0``), MODE_LOW_GAIN, MODE_HIGH_GAIN (module doc).
    Returns ``(u, status)`` as :func:`min_norm_torque` (``wd`` = low-gain ωd).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    inertia = np.asarray(inertia, dtype=float)
    terms = _rate_terms(qe, we, a1, a2, eps_den)  # shared by the three ωd below
    V, LfV, LgV, w_gs = _lie(qe, we, inertia, k1, gamma, sigma, a1, a2, eps_den,
                             None if h is None else np.asarray(h, dtype=float), terms)
    Id = _diag(inertia)
    ulg, wd, _ = _snlc(qe, we, Id, k1, g1, K1, a1, a2, eps_den, scale_by_inertia, terms)
    uhg, _, _ = _snlc(qe, we, Id, k2, g2, K2, a1, a2, eps_den, scale_by_inertia, terms)
    bh = dot(LgV, uhg)
    on = bh < 0.0
    high = np.max(np.abs(uhg), axis=-1) < np.asarray(epsilon, dtype=float)
    b = np.where(high, bh, dot(LgV, ulg))  # low-gain mode projects u_lg as printed
    u = _project(LgV, b, on)
    mode = np.where(on, np.where(high, MODE_HIGH_GAIN, MODE_LOW_GAIN), MODE_ZERO_TORQUE)
    return u, _status(mode, V, LfV, LgV, u, wd, w_gs)


# --- laws bound to validated controller sections -------------------------------------------------

MODE_NAMES = {MODE_LOW_GAIN: 'low_gain', MODE_ZERO_TORQUE: 'zero_torque', MODE_HIGH_GAIN: 'high_gain',
              MODE_MIN_NORM: 'min_norm', MODE_SNLC: 'snlc', MODE_ZERO_MOMENTUM: 'zero_momentum'}

# The law's axes (1, 2, 3) as body axes, for each choice of unactuated body axis: a cyclic
# permutation (a proper rotation, so the quaternion kinematics and eq. 3 keep their form). Seed 000
# VI.B: UK-DMC has wheels on Y and Z, "subscripts 1, 2 and 3 ... represent the Y, Z and X axes".
AXIS_ORDER = {'z': (0, 1, 2), 'x': (1, 2, 0), 'y': (2, 0, 1)}
_VECTOR_STATUS = ('wd', 'wd_dot', 'w_gs')  # status 3-vectors (rotated back to body axes)


# The parameters of every seed 000 law (their schemas list these very objects).
TWO_WHEEL_PARAMS = (
    Param('a1', 'double', default=float('inf'), check=positive, finite=False, batch=True,
          doc='saturation of the singular term of eq. (8) on axis 1 (.inf: eq. 7)'),
    Param('a2', 'double', default=float('inf'), check=positive, finite=False, batch=True,
          doc='saturation of the singular term of eq. (8) on axis 2 (.inf: eq. 7)'),
    Param('eps_den', 'double', default=0.0, check=non_negative, batch=True,
          doc='the small constant added to q1^2 + q2^2 in eq. (7)/(8) (section IV.B.2; 0: none)'),
    Param('scale_by_inertia', 'bool', default=False,
          doc='eq. (14) as printed, I_i (-K_i (w_i - wd_i) + dwd_i/dt), instead of the eq. (31) '
              'form -K_i (w_i - wd_i) + I_i dwd_i/dt (docs/seed000_readings.md R3)'),
    Param('unactuated_axis', 'string', default='z', choices=('x', 'y', 'z'),
          doc="the body axis without a wheel, the law's axis 3 (UK-DMC: 'x'); follows the "
              'faults when two wheels are left'),
)


class _BoundLaw(SectionLaw):
    """Common parameters (paper symbols): ``a1``, ``a2`` saturation limits of eq. (8) (default
    inf = eq. 7), ``eps_den`` the denominator constant ε of section IV.B.2 (default 0),
    ``scale_by_inertia`` (eq. 14 as printed; default False = eq. 31 form), ``unactuated_axis``
    ('x', 'y' or 'z', default 'z'): the body axis without a wheel, the law's axis 3.

    Inputs and outputs are in body axes; the law runs in its own axes ``(1, 2, 3)`` =
    :data:`AXIS_ORDER` ``[unactuated_axis]`` and every 3-vector (torque, momentum, status vectors
    ``wd`` ...) is rotated back. :meth:`on_wheels` moves axis 3 to the axis that lost its wheel.
    """

    mode_names = MODE_NAMES
    params = (*TARGET_PARAMS, SHORTEST_PATH, *TWO_WHEEL_PARAMS)

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        self.shortest_path = p.shortest_path
        self.a1 = p.a1
        self.a2 = p.a2
        self.eps_den = p.eps_den
        self.scale_by_inertia = p.scale_by_inertia
        self.body_inertia, self.body_q_ref, self.body_w_ref = self.inertia, self.q_ref, self.w_ref
        self.set_unactuated_axis(p.unactuated_axis)

    def set_unactuated_axis(self, axis: str) -> None:
        """Run the law with body axis ``axis`` ('x', 'y', 'z') as its unactuated axis 3."""
        if axis not in AXIS_ORDER:
            raise ValueError(f"unactuated_axis must be one of {sorted(AXIS_ORDER)}, got {axis!r}")
        self.unactuated_axis = axis
        self.perm = np.array(AXIS_ORDER[axis])
        self.inv = np.argsort(self.perm)
        P = self.perm
        self.law_inertia = self.body_inertia[..., P, :][..., :, P]
        self.law_q_ref = self._to_law(self.body_q_ref, quaternion=True)
        self.law_w_ref = self._to_law(self.body_w_ref)

    def _to_law(self, v, quaternion=False):
        v = np.asarray(v, dtype=float)
        if quaternion:
            return np.concatenate([v[..., self.perm], v[..., 3:]], axis=-1)
        return v[..., self.perm]

    def _to_body(self, out: tuple) -> tuple:
        value, status = out
        status = {k: (x[..., self.inv] if k in _VECTOR_STATUS else x) for k, x in status.items()}
        return value[..., self.inv], status

    def _ref(self):
        return dict(q_ref=self.law_q_ref, w_ref=self.law_w_ref, shortest_path=self.shortest_path)

    def on_wheels(self, axes, available) -> str | None:
        """Follow a change of the usable wheels: with exactly two left whose axes span the plane
        normal to a body axis, make that axis the unactuated one. Returns a note, or None."""
        return self.follow_axis(unactuated_body_axis(axes, available))

    def follow_axis(self, axis: str | None) -> str | None:
        """Make ``axis`` (if not None) the unactuated one; a note if that changed, else None."""
        if axis is not None and axis != self.unactuated_axis:
            self.set_unactuated_axis(axis)
            return f'two-wheel law: unactuated axis is now {axis}'
        return None

    def control(self, t, q, w):
        q_l = self._to_law(q, quaternion=True)
        w_l = self._to_law(w)
        return self._to_body(self._control(t, q_l, w_l))

    def _control(self, t, q, w):
        raise NotImplementedError


def unactuated_body_axis(axes, available, tol: float = 1e-6) -> str | None:
    """The body axis ('x', 'y', 'z') left without control torque when the ``available`` wheels'
    spin ``axes`` (n, 3) span exactly the plane normal to it; None otherwise (three axes still
    span space, fewer than two independent axes remain, or the plane is not a body plane)."""
    A = np.asarray(axes, dtype=float)[np.asarray(available, dtype=bool)]
    if A.shape[0] < 2 or np.linalg.matrix_rank(A, tol=tol) != 2:
        return None
    normal = np.linalg.svd(A)[2][-1]  # the direction no available wheel can torque
    for name, e in zip('xyz', np.eye(3)):
        if abs(abs(normal @ e) - 1.0) < tol:
            return name
    return None


class ZeroMomentumLaw(_BoundLaw):
    """Eq. (12-13): gains ``k``, ``g`` (rad/s). ``control`` returns the commanded WHEEL MOMENTUM
    in body axes (``output = 'wheel_momentum'``; N m s), which the actuation turns into wheel speed
    commands ``Ω = A⁺ h / I_wh`` (eq. 13 for wheels on the law's axes 1, 2), not a torque."""

    output = 'wheel_momentum'

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.k, self.g = p.k, p.g

    def _control(self, t, q, w):
        qe, we = error_state(q, w, self.law_q_ref, self.law_w_ref, self.shortest_path)
        h, status = zero_momentum_wheel_momentum(qe, self.law_inertia, self.k, self.g, self.a1, self.a2,
                                                 self.eps_den)
        e = we - status['wd']
        status['V'] = 2.0 * np.asarray(self.k, dtype=float) * (1.0 - qe[..., 3]) + 0.5 * dot(e, e)
        return h, status


class SnlcLaw(_BoundLaw):
    """Eq. (14)/(24): gains ``k``, ``g`` (rad/s, eq. 7/8) and ``K`` (N m s/rad)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.k, self.g, self.K = p.k, p.g, p.K

    def _control(self, t, q, w):
        return snlc_torque(q, w, self.law_inertia, self.k, self.g, self.K, self.a1, self.a2,
                           self.eps_den, scale_by_inertia=self.scale_by_inertia, **self._ref())


class SnlcMinNormLaw(_BoundLaw):
    """Eq. (25-27): benchmark gains ``k``, ``g``, ``K`` and Lyapunov gains ``gamma``, ``sigma``."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.gains = (p.k, p.g, p.K, p.gamma, p.sigma)

    def _control(self, t, q, w):
        return min_norm_torque(q, w, self.law_inertia, *self.gains, a1=self.a1, a2=self.a2,
                               eps_den=self.eps_den, scale_by_inertia=self.scale_by_inertia,
                               **self._ref())


class SnlcGsmnLaw(_BoundLaw):
    """Eq. (30-32): low gains ``k1``, ``g1``, ``K1``; high gains ``k2``, ``g2``, ``K2``; Lyapunov
    gains ``gamma``, ``sigma``; torque threshold ``epsilon`` (N m, the ε of eq. 30)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.gains = (p.k1, p.g1, p.K1, p.k2, p.g2, p.K2, p.gamma, p.sigma)
        self.epsilon = p.epsilon
        self._scalar = None   # (axis, underactuated_scalar.GsmnConstants or None): the one-state path

    def _control(self, t, q, w):
        if self._scalar is None or self._scalar[0] != self.unactuated_axis:
            fits = scalar.applies(self.gains, self.epsilon, self.a1, self.a2, self.eps_den, self.law_q_ref,
                                  self.law_w_ref, self.law_inertia)
            self._scalar = (self.unactuated_axis, scalar.GsmnConstants(
                self.law_inertia, self.law_q_ref, self.law_w_ref, self.gains, self.epsilon, self.a1, self.a2,
                self.eps_den) if fits else None)
        if self._scalar[1] is not None and np.ndim(q) == 1 and np.ndim(w) == 1:   # one state: the same bits on floats
            return scalar.gsmn_control(self._scalar[1], q, w, self.shortest_path, self.scale_by_inertia)
        return gsmn_torque(q, w, self.law_inertia, *self.gains, epsilon=self.epsilon, a1=self.a1,
                           a2=self.a2, eps_den=self.eps_den, scale_by_inertia=self.scale_by_inertia,
                           **self._ref())
