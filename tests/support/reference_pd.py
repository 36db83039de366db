"""An independent computation of the seed-004 PD slew loop, for checking the graph against.

Written from the paper, not from adcs_sim: seed 004 eq. (3)-(4) with body inertia
``I_b`` and absolute wheel momentum ``h`` (``I_b w' = -w x (I_b w + h) + N``, ``h' = -N``), the
PD law eq. (13) ``N = -kp I q - kd I w`` sampled every control period and held (zero-order
hold), each wheel's torque clipped at its limit, and scipy's adaptive ``solve_ivp`` (DOP853,
tight tolerances) between samples. Nothing here imports adcs_sim.

Our scenario gives the *total* inertia ``J`` (wheels included) and wheel spin inertia ``Js``
along the body axes, so ``I_b = J - Js I`` and the wheel speed relative to the body is
``h / Js - w``.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def _rhs(t, x, I_b, I_b_inv, N):
    q, w, h = x[:4], x[4:7], x[7:10]
    qv, q4 = q[:3], q[3]
    dqv = 0.5 * (q4 * w - np.cross(w, qv))           # seed 004 eq. (4)
    dq4 = -0.5 * w @ qv
    dw = I_b_inv @ (-np.cross(w, I_b @ w + h) + N)    # seed 004 eq. (3)
    return np.concatenate([dqv, [dq4], dw, -N])       # N = -h'


def pd_slew_reference(J_total, Js, q0, kp, kd, limit, period, n_steps, I_ctrl=None):
    """Return (t, q, w, wheel speed, N) at the sample times of the loop (N held after t_k)."""
    J_total = np.asarray(J_total, dtype=float)
    I_ctrl = J_total if I_ctrl is None else np.asarray(I_ctrl, dtype=float)
    I_b = J_total - Js * np.eye(3)
    I_b_inv = np.linalg.inv(I_b)
    q = np.asarray(q0, dtype=float) / np.linalg.norm(q0)
    x = np.concatenate([q, np.zeros(3), np.zeros(3)])
    ts, qs, ws, speeds, torques = [], [], [], [], []
    for k in range(n_steps + 1):
        q, w, h = x[:4], x[4:7], x[7:10]
        N = -kp * I_ctrl @ q[:3] - kd * I_ctrl @ w    # seed 004 eq. (13)
        N = np.clip(N, -limit, limit)                 # per-wheel limit (wheels on body axes)
        ts.append(k * period)
        qs.append(q.copy())
        ws.append(w.copy())
        speeds.append(h / Js - w)
        torques.append(N)
        if k == n_steps:
            break
        sol = solve_ivp(_rhs, (0.0, period), x, method='DOP853', rtol=1e-12, atol=1e-14,
                        args=(I_b, I_b_inv, N))
        x = sol.y[:, -1]
        x[:4] /= np.linalg.norm(x[:4])
    return (np.array(ts), np.array(qs), np.array(ws), np.array(speeds), np.array(torques))
