"""The two-wheel GSMN law of seed 000 (eq. 30-32) for ONE state, on Python floats.

:func:`adcs_controllers.laws.underactuated.gsmn_torque` is written for a batch (..., 4): on one state
each of its ~150 numpy operations costs a 0-d/1-d array (about 1 µs each; 266 µs a call, 53 % of the
showcase's batch profile). A controller node calls it on one state per step, so this module does the
SAME arithmetic on Python floats: the same operations in the same order (no FMA: CPython's ``float``
multiply and add are the IEEE double operations numpy's element-wise loops make), so the same bits,
signed zeros included (``x * 0.0`` is ``-0.0`` for a negative ``x``, as numpy's ``* _XY`` gives).
Each line below names the numpy expression it reproduces; tests/test_underactuated_scalar.py checks
every output and status value bit for bit against the numpy law on fuzzed and edge states.

Used by :class:`~adcs_controllers.laws.underactuated.SnlcGsmnLaw` when the call is one state with
scalar gains (the node's case); a batch (leading axis) still takes the numpy path.
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.inverse_optimal import inertia_inverse

MODE_LOW_GAIN, MODE_ZERO_TORQUE, MODE_HIGH_GAIN = 0, 1, 2   # as adcs_controllers.laws.underactuated


def applies(gains, epsilon, a1, a2, eps_den, q_ref, w_ref, inertia) -> bool:
    """Whether the float path gives the numpy law's bits for a one-state call: scalar gains, limits
    and reference, saturation limits > 0 (``np.clip`` treats the sign of zero its own way at ``a = 0``)."""
    scalars = (*gains, epsilon, a1, a2, eps_den)
    return (np.ndim(q_ref) == 1 and np.ndim(w_ref) == 1 and np.ndim(inertia) == 2
            and all(np.ndim(x) == 0 for x in scalars) and float(a1) > 0.0 and float(a2) > 0.0)


class GsmnConstants:
    """What does not change from call to call: the law-axes inertia's diagonal and inverse, the
    reference as floats, and the gains (a law rebuilds it when its axes change)."""

    def __init__(self, inertia, q_ref, w_ref, gains, epsilon, a1, a2, eps_den) -> None:
        inertia = np.asarray(inertia, dtype=float)
        self.Id = tuple(float(inertia[i, i]) for i in range(3))                 # _diag(inertia)
        self.Iinv = [[float(x) for x in row] for row in inertia_inverse(inertia)]
        self.q_ref = tuple(float(x) for x in np.asarray(q_ref, dtype=float))
        self.w_ref = tuple(float(x) for x in np.asarray(w_ref, dtype=float))
        self.gains = tuple(float(g) for g in gains)
        self.epsilon, self.a1, self.a2, self.eps_den = float(epsilon), float(a1), float(a2), float(eps_den)


def _error_state(c: GsmnConstants, q, w, shortest_path: bool):
    """error_state(q, w, q_ref, w_ref): ``quat_multiply(quat_conjugate(q_ref), q)``, ``w - w_ref``."""
    r0, r1, r2, p4 = c.q_ref
    p0, p1, p2 = -r0, -r1, -r2                       # quat_conjugate
    x0, x1, x2, x4 = q
    v0 = p4 * x0 + x4 * p0 + (p1 * x2 - p2 * x1)     # p4 qv + q4 pv + cross(pv, qv)
    v1 = p4 * x1 + x4 * p1 + (p2 * x0 - p0 * x2)
    v2 = p4 * x2 + x4 * p2 + (p0 * x1 - p1 * x0)
    s = p4 * x4 - (0.0 + p0 * x0 + p1 * x1 + p2 * x2)  # p4 q4 - (pv * qv).sum(-1)
    qe = [v0, v1, v2, s]
    if shortest_path and s < 0:
        qe = [-x for x in qe]
    we = [w[0] - c.w_ref[0], w[1] - c.w_ref[1], w[2] - c.w_ref[2]]
    return qe, we


def _sat(num: float, den: float, a: float):
    """_sat_ratio: (clipped ratio, not saturated, ratio); 0 where den <= 0 (``a > 0``)."""
    if not den > 0.0:
        return 0.0, False, 0.0
    r = num / den
    if abs(r) < a:
        return r, True, r
    return (a if r >= a else -a), False, r


def _rate_terms(c: GsmnConstants, qe, we):
    """_rate_terms(qe, we, a1, a2, eps_den)."""
    q1, q2, q3, q4 = qe
    w0, w1, w2 = we
    d1 = 0.5 * (q4 * w0 - (w1 * q3 - w2 * q2))       # quat_kinematics: 1/2 (q4 w - cross(w, qv))
    d2 = 0.5 * (q4 * w1 - (w2 * q1 - w0 * q3))
    d3 = 0.5 * (q4 * w2 - (w0 * q2 - w1 * q1))
    den = q1 * q1 + q2 * q2 + c.eps_den
    s1, free1, r1 = _sat(q2 * q3, den, c.a1)
    s2, free2, r2 = _sat(q1 * q3, den, c.a2)
    safe = den if den > 0.0 else 1.0
    dden = 2.0 * (q1 * d1 + q2 * d2)
    dr1 = (d2 * q3 + q2 * d3 - r1 * dden) / safe
    dr2 = (d1 * q3 + q1 * d3 - r2 * dden) / safe
    return q1, q2, d1, d2, s1, s2, (dr1 if free1 else 0.0), (dr2 if free2 else 0.0)


def _rates(terms, k: float, g: float):
    """_rates(terms, k, g): (ωd, dωd/dt) with their z components ``0 + 0 k``."""
    q1, q2, d1, d2, s1, s2, dr1, dr2 = terms
    z = 0.0 + 0.0 * k
    return ([-k * q1 + g * s1, -k * q2 - g * s2, z], [-k * d1 + g * dr1, -k * d2 - g * dr2, z])


def _dot(a, b) -> float:
    """adcs_core.attitude.dot: ``a1 b1 + a2 b2 + a3 b3`` from the left."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _snlc(c: GsmnConstants, we, terms, k, g, K, scale_by_inertia: bool):
    """_snlc: the snlc torque (times _XY) and ωd."""
    wd, wd_dot = _rates(terms, k, g)
    Id = c.Id
    if scale_by_inertia:
        u = [Id[i] * (-K * (we[i] - wd[i]) + wd_dot[i]) for i in range(3)]
    else:
        u = [-K * (we[i] - wd[i]) + Id[i] * wd_dot[i] for i in range(3)]
    return [u[0] * 1.0, u[1] * 1.0, u[2] * 0.0], wd


def _lie(c: GsmnConstants, qe, we, terms, k, gamma, sigma):
    """_lie with ``h = None``: V, LfV, LgV (z = 0 * ...), ωγσ."""
    w_gs, w_gs_dot = _rates(terms, gamma, sigma)
    e = [we[0] - w_gs[0], we[1] - w_gs[1], we[2] - w_gs[2]]
    Ii = c.Iinv   # matvec(transpose(Iinv), e): sum over j of Iinv[j][i] e[j], from j = 0
    LgV = [(Ii[0][i] * e[0] + Ii[1][i] * e[1] + Ii[2][i] * e[2]) * xy for i, xy in enumerate((1.0, 1.0, 0.0))]
    dq4 = -0.5 * _dot(qe, we)
    LfV = -2.0 * k * dq4 - _dot(e, w_gs_dot)
    V = 2.0 * k * (1.0 - qe[3]) + 0.5 * _dot(e, e)
    return V, LfV, LgV, w_gs


def gsmn_control(c: GsmnConstants, q, w, shortest_path: bool, scale_by_inertia: bool):
    """gsmn_torque(q, w, law_inertia, *gains, epsilon, a1, a2, eps_den, q_ref, w_ref, shortest_path,
    scale_by_inertia) for one state (law axes): ``(u (3,), status)`` with the numpy law's types."""
    k1, g1, K1, k2, g2, K2, gamma, sigma = c.gains
    qe, we = _error_state(c, q.tolist(), w.tolist(), shortest_path)
    terms = _rate_terms(c, qe, we)
    V, LfV, LgV, w_gs = _lie(c, qe, we, terms, k1, gamma, sigma)
    ulg, wd = _snlc(c, we, terms, k1, g1, K1, scale_by_inertia)
    uhg, _ = _snlc(c, we, terms, k2, g2, K2, scale_by_inertia)
    bh = _dot(LgV, uhg)
    on = bh < 0.0
    high = max(abs(uhg[0]), abs(uhg[1]), abs(uhg[2])) < c.epsilon
    b = bh if high else _dot(LgV, ulg)
    coef = b / _dot(LgV, LgV) if on else 0.0          # _project
    u = [coef * LgV[0], coef * LgV[1], coef * LgV[2]]
    mode = (MODE_HIGH_GAIN if high else MODE_LOW_GAIN) if on else MODE_ZERO_TORQUE
    LgV_u = _dot(LgV, u)
    status = {'mode': np.array(mode), 'V': np.float64(V), 'Vdot': np.float64(LfV + LgV_u),
              'LgV_u': np.float64(LgV_u), 'wd': np.array(wd), 'w_gs': np.array(w_gs)}
    return np.array(u), status
