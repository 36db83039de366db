"""Inverse optimal attitude laws of seed 004 (Horri, Palmer & Roberts, "Gain scheduled inverse optimal
satellite attitude control"): the bilinear Lyapunov function, the standard minimum-norm law, the
gain-scheduled minimum-norm law (GSMN) and the Krstic-Tsiotras law used for comparison.

Model (seed 004 eq. 3-5): ``I dw/dt = -w x (I w + h) + u``, quaternion kinematics (eq. 4)
``dq/dt = 1/2 (q4 w - w x q)``, ``dq4/dt = -1/2 w.q``, with ``I`` the body inertia (the
``inertia`` argument), ``h`` the wheel angular momentum in body axes and ``u`` the body torque
(``N = -dh/dt``). Regulation is to ``q = [0 0 0 1]``, ``w = 0``; with ``q_ref``/``w_ref`` the laws
act on the error quaternion ``q_ref* ⊗ q`` and ``w - w_ref`` exactly as
:func:`adcs_controllers.laws.pd.pd_torque` does (for a fixed target, ``w_ref = 0``, the error
obeys the same equations, so V and its derivative below are exact; a moving target is our
extension).

Lyapunov function (eq. 15) and its Lie derivatives (derived here from eq. 3-4; the paper prints
only ``LgV``)::

    V    = 2 (kp + γ kd)(1 - q4) + 1/2 wᵀw + γ qᵀw
    LgV  = (w + γ q)ᵀ I⁻¹
    LfV  = (kp + γ kd) qᵀw + γ/2 q4 wᵀw - LgV (w x (I w + h))

Reading ``lgv='inertia_weighted'`` (the printed ``I⁻¹`` dropped: ``LgV = (w + γ q)ᵀ``) is the exact
``LgV`` of the inertia-weighted function (ours; it equals ``ι`` times eq. 15 when ``I = ι 1``)::

    V_I  = c (1 - q4) + 1/2 wᵀ I w + γ qᵀ I w,   c = 2 (kp + γ kd) ι,   ι = tr(I)/3
    LgV  = (w + γ q)ᵀ
    LfV  = c/2 qᵀw + γ/2 q4 wᵀ I w + γ/2 (q x w)ᵀ I w - γ qᵀ (w x (I w + h))

(from ``dq4/dt = -1/2 wᵀq``, ``dq/dt = 1/2 (q4 w + q x w)``, ``wᵀ(w x ·) = 0``). ``c`` does not
change the torque, only ``V``/``Vdot`` of the status; with the PD torque the cross term
``qᵀ(c/2 - (kp + γ kd) I) w`` no longer cancels unless ``I`` is scalar, so ``dV/dt <= 0`` is
checked on random states (tests/test_seed004_lgv_reading.py).

PD benchmark (eq. 13): ``u_PD = -kp I q - kd I w`` — :func:`pd_torque`, re-exported from
:mod:`adcs_controllers.laws.pd`.

Minimum-norm law (eq. 10 with b = LgV u_PD, eq. 12; eq. 14)::

    u = (LgV u_PD) LgVᵀ / (LgV LgVᵀ)   if LgV u_PD < 0
    u = 0                              if LgV u_PD >= 0

It is the least-norm torque with ``LgV u <= LgV u_PD``, hence ``dV/dt <= dV/dt|u_PD``. Eq. 14 is
printed with a leading minus on the projection; that sign makes ``LgV u = -LgV u_PD > 0`` and
``dV/dt > 0`` on most states, so it is read as an extraction artefact (eq. 10 and 17 have no minus;
docs/seed004_readings.md).

Gain-scheduled minimum-norm law, GSMN (eq. 16-17), ``u_i = -kp_i I q - kd_i I w`` (i = 1 low
gains = the benchmark, i = 2 high gains), mode codes in ``status['mode']``::

    MODE_LOW_GAIN    (0): u = (LgV u1) LgVᵀ/(LgV LgVᵀ)  if LgV u2 < 0 and ‖u2‖∞ >= ε
    MODE_ZERO_TORQUE (1): u = 0                         if LgV u2 >= 0
    MODE_HIGH_GAIN   (2): u = (LgV u2) LgVᵀ/(LgV LgVᵀ)  if LgV u2 < 0 and ‖u2‖∞ < ε

as printed: the zero-torque test uses ``u2`` in every region (the torque is off between the lines
``LgV = 0`` and ``LgV u2 = 0``; the single-axis form eq. 22 has the same zero region). ``ε`` is an
absolute torque (N m) that the paper describes as "a percentage of the maximum torque value":
pass it from the actuator limit, e.g. ``epsilon = 0.8 * max_torque``. ``V``/``Vdot`` of the GSMN
status are those of the benchmark's Lyapunov function (eq. 15 with ``kp1, kd1``); ``dV/dt <= 0``
holds in every mode where the benchmark's does (low gain: equal to it; high gain and zero torque:
checked on random states in tests/test_laws_inverse_optimal.py; zero torque needs
``(kp1 + γ kd1) kd2 / (kp2 + γ kd2) > γ/2`` plus margin for the gyroscopic term).

Standard minimum-norm law status: ``MODE_ZERO_TORQUE`` (1) when off, ``MODE_MIN_NORM`` (3) when
on. Krstic-Tsiotras law: constant ``MODE_CONTINUOUS`` (4).

Krstic-Tsiotras inverse optimal law (eq. 18), Gibbs parameters ``p = q / q4``::

    u = -I ((2 k2 + k1) 1 + k1 p pᵀ + 4/k1 I⁻¹ S(w)ᵀ I² S(w) I⁻¹) (w + k1 p),  S(w) y = w x y

Its status uses the Lyapunov function ``V = k1²/2 pᵀp + 1/2 zᵀz``, ``z = w + k1 p`` (derived here:
the paper does not print it), for which eq. 18 gives ``dV/dt <= -(3/8) k1³ |p|² - (2 k2 + 3k1/8) |z|²``
without wheel momentum (h = 0). ``p`` is singular at ``q4 = 0`` (a 180° error) and the same for
``q`` and ``-q``.

Saturation is not part of these laws (the actuator layer clips per wheel,
:func:`adcs_controllers.laws.allocation.saturate`). Every function takes ``q`` (..., 4) scalar last,
``w`` (..., 3) rad/s, ``inertia`` (3, 3) or (..., 3, 3), gains as scalars or arrays broadcasting over
the batch axes, and returns ``u`` (..., 3); all matrix-vector products use
:func:`adcs_core.attitude.matvec` so that a batch gives the same bits as a loop of single calls.
:class:`MinNormLaw`, :class:`GsmnLaw` and :class:`KtLaw` bind them to validated controller sections
(``control(t, q, w) -> (torque, status)``, as :class:`adcs_controllers.laws.pd.PdLaw`).
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.base import SHORTEST_PATH, TARGET_PARAMS, SectionLaw
from adcs_controllers.laws.pd import pd_torque
from adcs_core.attitude import cross, dot, error_quaternion, gain_vector, matvec, transpose
from adcs_msgs_py.params import Param

__all__ = [
    'MODE_LOW_GAIN', 'MODE_ZERO_TORQUE', 'MODE_HIGH_GAIN', 'MODE_MIN_NORM', 'MODE_CONTINUOUS', 'LGV_READINGS',
    'pd_torque', 'inertia_inverse', 'error_state', 'lyapunov', 'lyapunov_inertia_weighted', 'lie_derivatives',
    'min_norm_projection', 'min_norm_torque', 'gsmn_torque', 'gibbs', 'kt_lyapunov', 'kt_torque',
    'MinNormLaw', 'GsmnLaw', 'KtLaw',
]

MODE_LOW_GAIN = 0      # GSMN: projection of the low-gain (benchmark) PD torque u1
MODE_ZERO_TORQUE = 1   # min-norm and GSMN: torque off
MODE_HIGH_GAIN = 2     # GSMN: projection of the high-gain PD torque u2
MODE_MIN_NORM = 3      # standard min-norm: projection of u_PD
MODE_CONTINUOUS = 4    # Krstic-Tsiotras: one continuous law

# The two readings of the projection direction LgV of eq. (14)/(17) (docs/seed004_readings.md, eq. 17):
# 'printed' LgV = (w + γq)ᵀ I⁻¹ with V of eq. (15); 'inertia_weighted' LgV = (w + γq)ᵀ with V_I.
LGV_READINGS = ('printed', 'inertia_weighted')
# The section laws' default (the node schemas' too): the reading Table I's numbers support. The pure
# functions below keep lgv='printed' as their default, the paper's text.
DEFAULT_LGV = 'inertia_weighted'

# The default is the reading the paper's own Table I numbers support (peaks to 4 digits, integrated torque
# within 0.4 %); the printed text is (a) (docs/seed004_readings.md, "Eq. 14/17: the projection direction LgV").
LGV = Param('lgv', 'string', default=DEFAULT_LGV, choices=LGV_READINGS,
            doc="projection direction of the min-norm torque: 'inertia_weighted' (default: Table I's numbers) "
                "LgV = (w + gamma q)^T, the exact LgV of V_I = c(1 - q4) + 1/2 w^T I w + gamma q^T I w; "
                "'printed' LgV = (w + gamma q)^T I^-1 with V of eq. (15), as the text prints it "
                "(docs/seed004_readings.md, eq. 17)")


# --- helpers -------------------------------------------------------------------------------------

def inertia_inverse(inertia: np.ndarray) -> np.ndarray:
    """Inverse of 3 x 3 matrices (..., 3, 3) by cofactors (cross products of the columns).

    Element-wise arithmetic only, so a batch gives the same bits as single calls.
    """
    M = np.asarray(inertia, dtype=float)
    a0, a1, a2 = M[..., :, 0], M[..., :, 1], M[..., :, 2]
    r0, r1, r2 = cross(a1, a2), cross(a2, a0), cross(a0, a1)
    det = dot(a0, r0)[..., None, None]
    return np.stack([r0, r1, r2], axis=-2) / det


def error_state(q: np.ndarray, w: np.ndarray, q_ref: np.ndarray | None = None,
                w_ref: np.ndarray | None = None, shortest_path: bool = False):
    """Error quaternion ``q_ref* ⊗ q`` (``q`` if no reference) and rate error ``w - w_ref``.

    ``shortest_path`` flips the whole error quaternion when its scalar part is negative (same
    attitude; the laws then regulate to ``q4 = +1`` the short way). As printed (default) the
    paper assumes ``q4 > 0`` (it "can be initialized as positive", text after eq. 15).
    """
    q = np.asarray(q, dtype=float)
    w = np.asarray(w, dtype=float)
    qe = q if q_ref is None else error_quaternion(q, np.asarray(q_ref, dtype=float))
    we = w if w_ref is None else w - np.asarray(w_ref, dtype=float)
    if shortest_path:
        qe = np.where(qe[..., 3:4] < 0, -qe, qe)
    return qe, we


# --- bilinear Lyapunov function (eq. 15) ---------------------------------------------------------

def lyapunov(q: np.ndarray, w: np.ndarray, kp, kd, gamma, q_ref: np.ndarray | None = None,
             w_ref: np.ndarray | None = None, shortest_path: bool = False) -> np.ndarray:
    """V of eq. (15): ``2 (kp + γ kd)(1 - q4) + 1/2 wᵀw + γ qᵀw`` (batch shape of ``q``).

    ``2 (1 - q4) = qᵀq + (1 - q4)²`` for a unit quaternion (the two printed lines of eq. 15).
    Positive definite for ``γ`` small enough (appendix eq. 36: ``K`` positive definite).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    kp, kd, gamma = (np.asarray(k, dtype=float) for k in (kp, kd, gamma))
    qv = qe[..., :3]
    return 2.0 * (kp + gamma * kd) * (1.0 - qe[..., 3]) + 0.5 * dot(we, we) + gamma * dot(qv, we)


def _lie(qe, we, inertia, inertia_inv, kp, kd, gamma, h):
    """(LfV, LgVᵀ) of eq. (15) on the error state; ``h`` wheel momentum (..., 3) or None."""
    qv, q4 = qe[..., :3], qe[..., 3]
    kp, kd, gamma = (np.asarray(k, dtype=float) for k in (kp, kd, gamma))
    LgV = matvec(transpose(inertia_inv), we + gain_vector(gamma) * qv)
    H = matvec(inertia, we)
    if h is not None:
        H = H + h
    LfV = ((kp + gamma * kd) * dot(qv, we) + 0.5 * gamma * q4 * dot(we, we)
           - dot(LgV, cross(we, H)))
    return LfV, LgV


def _lie_inertia_weighted(qe, we, inertia, kp, kd, gamma, h):
    """(LfV, LgVᵀ) of V_I (reading 'inertia_weighted') on the error state; ``h`` (..., 3) or None."""
    qv, q4 = qe[..., :3], qe[..., 3]
    kp, kd, gamma = (np.asarray(k, dtype=float) for k in (kp, kd, gamma))
    half_c = (kp + gamma * kd) * _mean_inertia(inertia)
    LgV = we + gain_vector(gamma) * qv
    Iw = matvec(inertia, we)
    H = Iw if h is None else Iw + h
    LfV = (half_c * dot(qv, we) + 0.5 * gamma * q4 * dot(we, Iw) + 0.5 * gamma * dot(cross(qv, we), Iw)
           - gamma * dot(qv, cross(we, H)))
    return LfV, LgV


def _mean_inertia(inertia):
    """ι = tr(I)/3 (batch shape of ``inertia``)."""
    return (inertia[..., 0, 0] + inertia[..., 1, 1] + inertia[..., 2, 2]) / 3.0


def lyapunov_inertia_weighted(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, kp, kd, gamma,
                              q_ref: np.ndarray | None = None, w_ref: np.ndarray | None = None,
                              shortest_path: bool = False) -> np.ndarray:
    """V_I = ``c (1 - q4) + 1/2 wᵀIw + γ qᵀIw``, ``c = 2 (kp + γ kd) tr(I)/3``: the function whose
    exact ``LgV`` is ``(w + γ q)ᵀ`` (reading 'inertia_weighted'; ι V of eq. 15 for ``I = ι 1``)."""
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    inertia = np.asarray(inertia, dtype=float)
    kp, kd, gamma = (np.asarray(k, dtype=float) for k in (kp, kd, gamma))
    qv, Iw = qe[..., :3], matvec(inertia, we)
    c = 2.0 * (kp + gamma * kd) * _mean_inertia(inertia)
    return c * (1.0 - qe[..., 3]) + 0.5 * dot(we, Iw) + gamma * dot(qv, Iw)


def _lie_and_v(qe, we, inertia, kp, kd, gamma, h, lgv):
    """(LfV, LgV, V) of the reading ``lgv`` (one of LGV_READINGS) on the error state."""
    h = None if h is None else np.asarray(h, dtype=float)
    if lgv == 'printed':
        LfV, LgV = _lie(qe, we, inertia, inertia_inverse(inertia), kp, kd, gamma, h)
        return LfV, LgV, lyapunov(qe, we, kp, kd, gamma)
    if lgv == 'inertia_weighted':
        LfV, LgV = _lie_inertia_weighted(qe, we, inertia, kp, kd, gamma, h)
        return LfV, LgV, lyapunov_inertia_weighted(qe, we, inertia, kp, kd, gamma)
    raise ValueError(f'lgv must be one of {list(LGV_READINGS)}, got {lgv!r}')


def lie_derivatives(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, kp, kd, gamma,
                    h: np.ndarray | None = None, q_ref: np.ndarray | None = None,
                    w_ref: np.ndarray | None = None, shortest_path: bool = False, lgv: str = 'printed'):
    """``(LfV, LgV)`` of V (eq. 15) along ``I dw/dt = -w x (I w + h) + u`` and eq. (4).

    ``LgV = (w + γ q)ᵀ I⁻¹`` (text after eq. 15), returned as a (..., 3) array;
    ``LfV = (kp + γ kd) qᵀw + γ/2 q4 wᵀw - LgV (w x (I w + h))`` (scalar per state; eq. 37-38 of
    the appendix with ``u`` removed). ``h`` is the wheel momentum in body axes (default zero).
    ``dV/dt = LfV + LgV u``. ``lgv='inertia_weighted'``: those of V_I (``LgV = (w + γ q)ᵀ``).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    LfV, LgV, _ = _lie_and_v(qe, we, np.asarray(inertia, dtype=float), kp, kd, gamma, h, lgv)
    return LfV, LgV


# --- minimum-norm laws (eq. 10, 14, 17) ----------------------------------------------------------

def min_norm_projection(LgV: np.ndarray, u_bench: np.ndarray):
    """Least-norm ``u`` with ``LgV u <= LgV u_bench`` (eq. 8-10 with b = LgV u_bench, eq. 12).

    Returns ``(u, on)``: ``u = (LgV u_bench) LgVᵀ / (LgV LgVᵀ)`` where ``LgV u_bench < 0``
    (``on`` True), else ``u = 0``. ``LgV`` and ``u_bench`` are (..., 3).
    """
    b = dot(LgV, u_bench)
    on = b < 0.0  # LgV = 0 gives b = 0: off, no division by zero
    aa = dot(LgV, LgV)
    scale = np.where(on, b / np.where(on, aa, 1.0), 0.0)
    return scale[..., None] * LgV, on


def _status(mode, V, LfV, LgV, u):
    LgV_u = dot(LgV, u)
    return {'mode': mode, 'V': V, 'Vdot': LfV + LgV_u, 'LgV_u': LgV_u}


def min_norm_torque(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, kp, kd, gamma,
                    h: np.ndarray | None = None, q_ref: np.ndarray | None = None,
                    w_ref: np.ndarray | None = None, shortest_path: bool = False, lgv: str = 'printed'):
    """Standard minimum-norm law, eq. (14), with the PD benchmark ``u_PD`` of eq. (13).

    ``u = (LgV u_PD) LgVᵀ / (LgV LgVᵀ)`` if ``LgV u_PD < 0`` (mode ``MODE_MIN_NORM``), else 0
    (``MODE_ZERO_TORQUE``). Returns ``(u, status)``; ``status['V']``/``['Vdot']`` are V of eq. (15)
    with the same ``kp, kd, γ`` and ``LfV + LgV u``; ``h`` (wheel momentum) only enters ``Vdot``.
    ``lgv`` (one of LGV_READINGS): the projection direction and V (module docstring).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    inertia = np.asarray(inertia, dtype=float)
    LfV, LgV, V = _lie_and_v(qe, we, inertia, kp, kd, gamma, h, lgv)
    u, on = min_norm_projection(LgV, pd_torque(qe, we, inertia, kp, kd))
    mode = np.where(on, MODE_MIN_NORM, MODE_ZERO_TORQUE)
    return u, _status(mode, V, LfV, LgV, u)


def gsmn_torque(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, kp1, kd1, kp2, kd2, gamma,
                epsilon, h: np.ndarray | None = None, q_ref: np.ndarray | None = None,
                w_ref: np.ndarray | None = None, shortest_path: bool = False, lgv: str = 'printed'):
    """Gain-scheduled minimum-norm law, eq. (17) (solution of eq. 16 as printed).

    ``u_i = -kp_i I q - kd_i I w``; ``LgV`` of eq. (15) (independent of the PD gains)::

        LgV u2 >= 0                  -> u = 0                         MODE_ZERO_TORQUE (1)
        LgV u2 < 0, ‖u2‖∞ >= epsilon -> u = (LgV u1) LgVᵀ/(LgV LgVᵀ)   MODE_LOW_GAIN (0)
        LgV u2 < 0, ‖u2‖∞ <  epsilon -> u = (LgV u2) LgVᵀ/(LgV LgVᵀ)   MODE_HIGH_GAIN (2)

    ``epsilon`` (N m, scalar or per batch element) is the paper's ε, "a percentage of the maximum
    torque value". Returns ``(u, status)``; ``status['V']``/``['Vdot']`` are those of the
    benchmark's V (eq. 15 with ``kp1, kd1, γ``; V_I with them for ``lgv='inertia_weighted'``).
    """
    qe, we = error_state(q, w, q_ref, w_ref, shortest_path)
    inertia = np.asarray(inertia, dtype=float)
    LfV, LgV, V = _lie_and_v(qe, we, inertia, kp1, kd1, gamma, h, lgv)
    u1 = pd_torque(qe, we, inertia, kp1, kd1)
    u2 = pd_torque(qe, we, inertia, kp2, kd2)
    b2 = dot(LgV, u2)
    on = b2 < 0.0  # LgV = 0 gives b2 = 0: off, no division by zero
    high = np.max(np.abs(u2), axis=-1) < np.asarray(epsilon, dtype=float)
    # Low-gain mode projects u1 whatever the sign of LgV u1 (as printed; the region is set by u2).
    b = np.where(high, b2, dot(LgV, u1))
    aa = dot(LgV, LgV)
    u = np.where(on, b / np.where(on, aa, 1.0), 0.0)[..., None] * LgV
    mode = np.where(on, np.where(high, MODE_HIGH_GAIN, MODE_LOW_GAIN), MODE_ZERO_TORQUE)
    return u, _status(mode, V, LfV, LgV, u)


# --- Krstic-Tsiotras inverse optimal law (eq. 18) ------------------------------------------------

def gibbs(q: np.ndarray) -> np.ndarray:
    """Rodrigues-Gibbs parameters ``p = q / q4`` (text after eq. 18); infinite at ``q4 = 0``."""
    q = np.asarray(q, dtype=float)
    return q[..., :3] / q[..., 3:4]


def kt_lyapunov(q: np.ndarray, w: np.ndarray, k1, q_ref: np.ndarray | None = None,
                w_ref: np.ndarray | None = None) -> np.ndarray:
    """``V = k1²/2 pᵀp + 1/2 zᵀz``, ``z = w + k1 p``: a Lyapunov function for eq. (18) (ours)."""
    qe, we = error_state(q, w, q_ref, w_ref)
    p = gibbs(qe)
    k1 = np.asarray(k1, dtype=float)
    z = we + gain_vector(k1) * p
    return 0.5 * k1 ** 2 * dot(p, p) + 0.5 * dot(z, z)


def kt_torque(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, k1, k2,
              h: np.ndarray | None = None, q_ref: np.ndarray | None = None,
              w_ref: np.ndarray | None = None):
    """Krstic-Tsiotras law, eq. (18)::

        u = -I ((2 k2 + k1) z + k1 p (pᵀz) + 4/k1 I⁻¹ S(w)ᵀ I² S(w) I⁻¹ z),  z = w + k1 p

    with ``p`` the Gibbs parameters of the error quaternion and ``S(w) y = w x y``. Returns
    ``(u, status)``; ``status['mode']`` is ``MODE_CONTINUOUS``; ``V``/``Vdot`` those of
    :func:`kt_lyapunov` along ``I dw/dt = -w x (I w + h) + u`` and ``dp/dt = 1/2 (w + p x w + p pᵀw)``
    (eq. 4 divided by q4): ``LgV = zᵀ I⁻¹``, ``LfV = (k1² p + k1 z)ᵀ dp/dt - LgV (w x (I w + h))``.
    """
    qe, we = error_state(q, w, q_ref, w_ref)
    inertia = np.asarray(inertia, dtype=float)
    inertia_inv = inertia_inverse(inertia)
    k1 = np.asarray(k1, dtype=float)
    k2 = np.asarray(k2, dtype=float)
    p = gibbs(qe)
    z = we + gain_vector(k1) * p
    # 4/k1 I⁻¹ S(w)ᵀ I² S(w) I⁻¹ z, right to left; S(w)ᵀ y = -w x y
    s = cross(we, matvec(inertia_inv, z))
    gyro = matvec(inertia_inv, -cross(we, matvec(inertia, matvec(inertia, s))))
    inner = (gain_vector(2.0 * k2 + k1) * z + gain_vector(k1 * dot(p, z)) * p
             + gain_vector(4.0 / k1) * gyro)
    u = -matvec(inertia, inner)
    # status: V = k1²/2 |p|² + 1/2 |z|²
    LgV = matvec(transpose(inertia_inv), z)
    pdot = 0.5 * (we + cross(p, we) + gain_vector(dot(p, we)) * p)
    H = matvec(inertia, we)
    if h is not None:
        H = H + np.asarray(h, dtype=float)
    LfV = dot(gain_vector(k1 ** 2) * p + gain_vector(k1) * z, pdot) - dot(LgV, cross(we, H))
    V = 0.5 * k1 ** 2 * dot(p, p) + 0.5 * dot(z, z)
    mode = np.full(V.shape, MODE_CONTINUOUS)
    return u, _status(mode, V, LfV, LgV, u)


# --- laws bound to validated controller sections (node and batch engine) ------------------------

MODE_NAMES = {MODE_LOW_GAIN: 'low_gain', MODE_ZERO_TORQUE: 'zero_torque', MODE_HIGH_GAIN: 'high_gain',
              MODE_MIN_NORM: 'min_norm', MODE_CONTINUOUS: 'continuous'}


class _BoundLaw(SectionLaw):
    """The section-bound laws of this module publish their mode codes by name."""

    mode_names = MODE_NAMES
    params = (*TARGET_PARAMS, SHORTEST_PATH, LGV)


class MinNormLaw(_BoundLaw):
    """Eq. (14) bound to a validated ``minnorm_controller`` section (kp, kd, gamma)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.kp, self.kd, self.gamma = p.kp, p.kd, p.gamma
        self.lgv = p.lgv
        self.shortest_path = p.shortest_path

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        return min_norm_torque(q, w, self.inertia, self.kp, self.kd, self.gamma, q_ref=self.q_ref,
                               w_ref=self.w_ref, shortest_path=self.shortest_path, lgv=self.lgv)


class GsmnLaw(_BoundLaw):
    """Eq. (17) bound to a validated ``gsmn_controller`` section (kp1, kd1, kp2, kd2, gamma, epsilon)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.gains = (p.kp1, p.kd1, p.kp2, p.kd2, p.gamma)
        self.epsilon = p.epsilon
        self.lgv = p.lgv
        self.shortest_path = p.shortest_path

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        return gsmn_torque(q, w, self.inertia, *self.gains, epsilon=self.epsilon, q_ref=self.q_ref,
                           w_ref=self.w_ref, shortest_path=self.shortest_path, lgv=self.lgv)


class KtLaw(_BoundLaw):
    """Eq. (18) bound to a validated ``kt_controller`` section (k1, k2)."""

    def __init__(self, p: dict) -> None:
        super().__init__(p)
        p = self.section(p)
        self.k1, self.k2 = p.k1, p.k2

    def control(self, t: float, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, dict]:
        return kt_torque(q, w, self.inertia, self.k1, self.k2, q_ref=self.q_ref, w_ref=self.w_ref)
