"""Single-axis pointing with two reaction wheels and a non-zero angular momentum (seed 003,
"Single-axis pointing of an underactuated spacecraft with non-zero angular momentum"): the
geometry of the admissible final attitudes and the paper's two control laws. Pure numpy, no rclpy.

Model (eq. 1-5). Body axes are principal axes; wheels on ê1 and ê2 work, the wheel on ê3 (b̂)
failed. ``J`` is the total inertia (wheels locked, as :class:`adcs_sim.truth.plant.Plant`'s
``inertia``), ``h`` the wheels' angular momentum RELATIVE to the body (``h_i = J_w Ω_i``, Ω the
wheel speed relative to the body), ``u = -dh/dt`` the virtual body torque::

    H = J ω + h,   dH/dt + ω x H = 0,   J dω/dt = u - ω x (J ω + h),   dh/dt = -u,   u_3 = 0

(motor torque of wheel i: ``g_em,i = -u_i - J_w dω_i/dt``; the caller applies its saturation, the
paper's 20 mN m). ``wheel_momentum`` passed to the laws is this ``h`` in body axes, (..., 3).
Assumption for the failed Z wheel: its component ``h_3`` is used as given to form ``H`` (so the
attitude angles are right whatever the failed wheel holds), but every target follows the paper,
``h_f = H0 (sin Φ_f, cos Φ_f, 0)`` (eq. 17, "h = (h1, h2, 0)"): with a failed wheel at rest
relative to the body (or absent) ``h_3 = 0`` and the paper's model is exact.

Inertial frame (eq. 6), from the total momentum ``H`` and the target direction ``τ̂``::

    ô3 = H/|H|,   ô2 = (H x τ̂)/|H x τ̂|,   ô1 = ô2 x ô3,    τ̂ = (cos α, 0, sin α) in F_I

(τ̂ ∥ H: ô1, ô2 arbitrary; we take ô2 ⟂ ô3 from the coordinate axis least aligned with ô3).
Attitude: 3-1-3 precession Ψ, nutation Θ, spin Φ, ``T_BI = R3(Φ) R1(Θ) R3(Ψ)`` (eq. 7)::

    T_BI = [[ cΦcΨ - sΦcΘsΨ,   cΦsΨ + sΦcΘcΨ,  sΦsΘ],
            [-sΦcΨ - cΦcΘsΨ,   cΦcΘcΨ - sΦsΨ,  cΦsΘ],
            [ sΘsΨ,           -sΘcΨ,           cΘ  ]]

so ``H_B = H0 (sΦ sΘ, cΦ sΘ, cΘ)`` (eq. 17). Euler rates (eq. 8; eq. 23 for Ψ)::

    dΨ/dt = (sΦ ω1 + cΦ ω2)/sΘ,   dΘ/dt = cΦ ω1 - sΦ ω2,   dΦ/dt = -(sΦ ω1 + cΦ ω2)/tanΘ + ω3

Body axis ``σ̂ = (cλ cη, cλ sη, sλ)`` (eq. 9): elevation λ over ê1-ê2, azimuth η. At rest all
momentum is in the wheels: ``h3 = H0 cΘ = 0`` → ``Θ_f = π/2``; pointing ``σ̂ = τ̂`` (eq. 12) gives
(eq. 13-16, the auxiliary frame F_A = R3(η) F_B has Φ' = Φ + η)::

    sin Ψ* = sin λ / cos α                 feasible iff |α| <= π/2 - |λ|        (eq. 13, 14)
    Φ* = atan2(sin α, cos α cos Ψ*)                                            (eq. 15)
    (Ψ, Θ, Φ)_f ∈ {(Ψ*, π/2, Φ* - η),  (π - Ψ*, π/2, π - Φ* - η)}              (eq. 16)

(the paper restricts λ to [0, π/2] by choice of ê3's sign; the formulas hold for λ < 0 too, which
we allow since ê3 is fixed by the failed wheel). An infeasible request raises ValueError.

Controller A (section 3), two stages; law state: the stage of each run.

* Stage 1, momentum stabilisation (eq. 20-22): ``V = ½ ωᵀJω + ½ K_h e_hᵀe_h`` with
  ``e_h = h - h_f``, ``dV/dt = (ω - K_h e_h)ᵀ u`` (eq. 21), and ``u = -K_p (ω - K_h e_h)``,
  ``u_3 = 0``. Readings (docs/seed003_readings.md): eq. 22 prints ``u = +K_p(...)``, which gives
  ``dV/dt = +K_p |.|² >= 0``; eq. 20 prints ``K_h`` without the ½ that eq. 21 needs; ``h_f`` is
  printed ``(H0 sin Φ_f, H0 sin Φ_f, 0)`` where eq. 17 and section 3 give ``H0 (sin Φ_f, cos Φ_f, 0)``.
* Switch (section 3.3) when ``|ω| < ε_ω`` and ``|e_Φ| < ε_Φ`` (0.01 rad/s, 1°); stage 2 is kept
  (latched) once reached.
* Stage 2, LQR on the reduced linearisation (eq. 18), ``x = (e_Ψ, ω1, ω2, ω3, e_h1)``::

      dx/dt = [[0, h_fᵀ/H0, 0], [0, J⁻¹[h_f x], 0], [0, 0ᵀ, 0]] x + [[0], [J⁻¹ S], [G]] u,
      S = [[1, 0], [0, 1], [0, 0]],  G = (-1, 0)

  (``[h_f x] ω = h_f x ω``: the paper's ``-J⁻¹ h_f^×`` with its skew-matrix sign; we derive the
  sign from ``-ω x h_f``, checked by finite differences in the tests). ``u = -K x`` with
  ``K = R⁻¹ Bᵀ P`` from ``scipy.linalg.solve_continuous_are``, Q = diag(0.1, 100, 100, 100, 1),
  R = diag(100, 100). Dual state: ``e_h1`` loses controllability when ``h_f2 = 0``
  (Φ_f = ±π/2), ``e_h2`` (``G = (0, -1)``) when ``h_f1 = 0``; ``momentum_state='auto'`` takes
  ``e_h1`` when ``|cos Φ_f| >= |sin Φ_f|``, else ``e_h2``.

Controller B (section 4, eq. 24-33)::

    ω_des = -K_Ψ (sin Φ, cos Φ, 0) e_Ψ             → dΨ/dt = -K_Ψ e_Ψ / sin Θ under ω = ω_des
    e_ω = ω - ω_des,   u = -K_p (e_ω - K_h e_h),   u_3 = 0        (eq. 24, 33)

(eq. 24 prints ``(sin Φ cos Φ, 0)ᵀ``, read as the 3-vector ``(sin Φ, cos Φ, 0)`` of eq. 23/27;
``V_e = ½ e_Ψ² + ½ e_ωᵀJe_ω + ½ K_h e_hᵀe_h``, ``dV_e/dt = -K_Ψ e_Ψ²/sin Θ + (e_ω - K_h e_h)ᵀu``
for the nominal part, negative with the minus of eq. 33).

Angles: ``e_Ψ = wrap(Ψ - Ψ_f)``, ``e_Θ = Θ - π/2``, ``e_Φ = wrap(Φ - Φ_f)`` (wrap to [-π, π)).
Pointing error: the angle between ``σ̂`` and ``τ̂`` (atan2 of |σ̂ x τ̂| and σ̂·τ̂).

Batch: every function takes ``q`` (..., 4) scalar last (body in the inertial frame in which
``τ̂`` and ``H`` are given), ``w`` (..., 3), ``h`` (..., 3), gains scalar or (...,); matrix-vector
products through :func:`adcs_core.attitude.matvec` and cross products through
:func:`adcs_core.attitude.cross`, so a run in a batch gives the same bits as alone. The LQR gain is
solved per run (a (..., 2, 5) array).
"""
from __future__ import annotations

import numpy as np

from adcs_controllers.laws.base import SectionLaw
from adcs_core.attitude import (
    cross,
    dot,
    eigenaxis_angle,
    error_quaternion,
    gain_vector,
    matvec,
    norm,
    pointing_error,
    rotate_to_body,
    rotate_to_inertial,
    scipy_rotation,
    transpose,
    unit,
)
from adcs_msgs_py.params import Param, all_positive, positive

__all__ = [
    'STAGE_MOMENTUM', 'STAGE_LQR', 'STAGE_B', 'MODE_NAMES', 'Q_PAPER', 'R_PAPER',
    'EPS_OMEGA', 'EPS_PHI', 'wrap', 'inertial_frame', 'dcm_313', 'euler_313', 'euler_rates_313',
    'body_axis_angles', 'elevation', 'check_feasible', 'final_angles', 'final_attitudes',
    'target_momentum', 'attitude_angles', 'pointing_state',
    'linearisation', 'lqr_gain', 'momentum_state_choice', 'momentum_stabilisation_torque',
    'lqr_torque', 'controller_a_torque', 'desired_rate_b', 'controller_b_torque',
    'PointingALaw', 'PointingBLaw',
]

STAGE_MOMENTUM = 1  # controller A, stage 1 (eq. 22)
STAGE_LQR = 2       # controller A, stage 2 (LQR on eq. 18)
STAGE_B = 3         # controller B (eq. 33)
MODE_NAMES = {STAGE_MOMENTUM: 'A1_momentum', STAGE_LQR: 'A2_lqr', STAGE_B: 'B'}

Q_PAPER = (0.1, 100.0, 100.0, 100.0, 1.0)   # section 5.3
R_PAPER = (100.0, 100.0)
EPS_OMEGA = 0.01                # rad/s, section 3.3
EPS_PHI = np.deg2rad(1.0)       # rad, section 3.3


# The parameters of the pointing laws that have defaults (their schemas list these very objects).
SOLUTION = Param('solution', 'int', default=0, check=lambda s: None if s in (0, 1, 2) else
                 f'must be 0 (the final attitude of eq. 16 nearer to the initial one), 1 or 2, got {s!r}',
                 doc='which final attitude of eq. (16): 1 (Psi*), 2 (pi - Psi*), 0 the nearer to q(0)')
POINTING_A_PARAMS = (
    Param('Q', 'double_array', default=list(Q_PAPER), length=5, check=all_positive,
          doc='LQR state weights on (e_Psi, w1, w2, w3, e_h) (section 5.3)'),
    Param('R', 'double_array', default=list(R_PAPER), length=2, check=all_positive,
          doc='LQR control weights (section 5.3)'),
    Param('eps_omega', 'double', default=EPS_OMEGA, check=positive,
          doc='stage switch threshold on |w| (rad/s, section 3.3)'),
    Param('eps_Phi', 'double', default=float(EPS_PHI), check=positive,
          doc='stage switch threshold on |e_Phi| (rad; 1 deg, section 3.3)'),
    Param('momentum_state', 'string', default='auto', choices=('auto', 'h1', 'h2'),
          doc="fifth LQR state e_h1 or e_h2 (dual state of section 3.1); auto: e_h1 iff "
              "|cos Phi_f| >= |sin Phi_f|"),
)

_XY = np.array([1.0, 1.0, 0.0])


def wrap(a):
    """Angle wrapped to [-π, π)."""
    return np.mod(np.asarray(a, dtype=float) + np.pi, 2.0 * np.pi) - np.pi


# --- geometry ------------------------------------------------------------------------------------

def inertial_frame(H, tau):
    """Eq. (6): rows ``ô1, ô2, ô3`` (..., 3, 3) in the frame ``H`` and ``τ̂`` are given in.

    ``C @ v`` gives the F_I components of ``v``. For ``τ̂ ∥ H`` the paper leaves ô1, ô2 free:
    ô2 is then built from the coordinate axis least aligned with ``H``.
    """
    H = np.asarray(H, dtype=float)
    tau = np.broadcast_to(np.asarray(tau, dtype=float), np.broadcast_shapes(H.shape, np.shape(tau)))
    H = np.broadcast_to(H, tau.shape)
    o3 = unit(H)
    n = cross(H, tau)
    nn = norm(n)
    degenerate = nn <= 1e-12 * norm(H) * norm(tau)
    axis = np.eye(3)[np.argmin(np.abs(o3), axis=-1)]
    n = np.where(degenerate[..., None], cross(o3, axis), n)
    o2 = unit(n)
    o1 = cross(o2, o3)
    return np.stack([o1, o2, o3], axis=-2)


def dcm_313(psi, theta, phi):
    """``T_BI = R3(Φ) R1(Θ) R3(Ψ)`` of eq. (7), (..., 3, 3): F_I components → body components."""
    sps, cps = np.sin(psi), np.cos(psi)
    sth, cth = np.sin(theta), np.cos(theta)
    sph, cph = np.sin(phi), np.cos(phi)
    rows = [[cph * cps - sph * cth * sps, cph * sps + sph * cth * cps, sph * sth],
            [-sph * cps - cph * cth * sps, cph * cth * cps - sph * sps, cph * sth],
            [sth * sps, -sth * cps, cth + 0.0 * sps]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler_313(T):
    """(Ψ, Θ, Φ) of a ``T_BI`` matrix (eq. 7), Ψ, Φ in [-π, π], Θ in [0, π]."""
    T = np.asarray(T, dtype=float)
    psi = np.arctan2(T[..., 2, 0], -T[..., 2, 1])
    theta = np.arctan2(np.hypot(T[..., 0, 2], T[..., 1, 2]), T[..., 2, 2])
    phi = np.arctan2(T[..., 0, 2], T[..., 1, 2])
    return psi, theta, phi


def euler_rates_313(theta, phi, w):
    """Eq. (8): (dΨ/dt, dΘ/dt, dΦ/dt) for body rate ``w`` (..., 3); singular at Θ = 0, π."""
    w = np.asarray(w, dtype=float)
    s, c = np.sin(phi), np.cos(phi)
    a = s * w[..., 0] + c * w[..., 1]
    return a / np.sin(theta), c * w[..., 0] - s * w[..., 1], -a / np.tan(theta) + w[..., 2]


def body_axis_angles(sigma):
    """(λ, η) of eq. (9): elevation of σ̂ over ê1-ê2 and azimuth from ê1 (σ̂ normalised here)."""
    s = unit(np.asarray(sigma, dtype=float))
    return np.arcsin(np.clip(s[..., 2], -1.0, 1.0)), np.arctan2(s[..., 1], s[..., 0])


def elevation(tau, H):
    """α: elevation of τ̂ over the plane ⟂ H (the ô1-ô2 plane), in [-π/2, π/2]."""
    return np.arcsin(np.clip(dot(unit(np.asarray(tau, dtype=float)),
                                  unit(np.asarray(H, dtype=float))), -1.0, 1.0))


def check_feasible(lam, alpha, tol=1e-12):
    """Raise ValueError unless ``|α| <= π/2 - |λ|`` (eq. 14) for every element."""
    lam = np.asarray(lam, dtype=float)
    alpha = np.asarray(alpha, dtype=float)
    margin = np.pi / 2 - np.abs(lam) - np.abs(alpha)
    bad = ~(margin >= -tol)
    if np.any(bad):
        idx = np.argwhere(np.atleast_1d(bad)).ravel()
        la = np.broadcast_to(lam, bad.shape).ravel()
        al = np.broadcast_to(alpha, bad.shape).ravel()
        i = int(idx[0])
        where = '' if bad.ndim == 0 else f' (runs {idx.tolist()[:10]}{"..." if len(idx) > 10 else ""})'
        raise ValueError(
            'single-axis pointing infeasible: eq. (14) needs |alpha| <= pi/2 - |lambda|, got '
            f'|alpha| = {np.degrees(abs(al[i])):.6g} deg > 90 - |lambda| = '
            f'{90 - np.degrees(abs(la[i])):.6g} deg (lambda = {np.degrees(la[i]):.6g} deg: elevation '
            'of sigma over the wheels plane; alpha: elevation of tau over the plane normal to H)'
            + where)


def final_angles(lam, eta, alpha):
    """Eq. (13-16): the two final (Ψ_f, Φ_f), each (..., 2) [solution 1, solution 2]; Θ_f = π/2.

    Raises ValueError if eq. (14) fails. ``sin Ψ* = sin λ / cos α`` is clipped to [-1, 1]
    (equality in eq. 14); for ``cos α = 0`` (then λ = 0) Ψ* = 0 is taken (Ψ free).
    """
    lam, eta, alpha = (np.asarray(v, dtype=float) for v in (lam, eta, alpha))
    check_feasible(lam, alpha)
    ca = np.cos(alpha)
    ok = ca > 0
    s = np.where(ok, np.sin(lam) / np.where(ok, ca, 1.0), 0.0)
    psi_star = np.arcsin(np.clip(s, -1.0, 1.0))
    phi_star = np.arctan2(np.sin(alpha), ca * np.cos(psi_star))
    psi = np.stack([psi_star, wrap(np.pi - psi_star)], axis=-1)
    phi = np.stack([wrap(phi_star - eta), wrap(np.pi - phi_star - eta)], axis=-1)
    return psi, phi


def final_attitudes(sigma, tau, H):
    """The two attitudes of eq. (16) as quaternions (..., 2, 4), scalar last, body in the frame of
    ``τ̂`` and ``H``; also ``(Ψ_f, Φ_f)`` (..., 2) each. Raises ValueError if infeasible."""
    sigma, tau, H = (np.asarray(v, dtype=float) for v in (sigma, tau, H))
    lam, eta = body_axis_angles(sigma)
    C = inertial_frame(H, tau)
    alpha = elevation(tau, H)
    psi, phi = final_angles(lam, eta, alpha)
    T = dcm_313(psi, np.pi / 2 + 0.0 * psi, phi)                      # (..., 2, 3, 3) body <- F_I
    R = transpose(C)[..., None, :, :] @ transpose(T)  # body -> inertial
    shape = R.shape[:-2]
    q = scipy_rotation().from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(shape + (4,))
    return q, psi, phi


def target_momentum(phi_f, H0):
    """``h_f = H0 (sin Φ_f, cos Φ_f, 0)`` (eq. 17, section 3), (..., 3)."""
    phi_f = np.asarray(phi_f, dtype=float)
    H0 = np.asarray(H0, dtype=float)
    return np.stack([H0 * np.sin(phi_f), H0 * np.cos(phi_f), 0.0 * phi_f * H0], axis=-1)


def attitude_angles(q, frame):
    """(Ψ, Θ, Φ) of eq. (7) for attitude ``q`` (..., 4) and F_I rows ``frame`` (..., 3, 3)."""
    cols = [rotate_to_body(q, frame[..., j, :]) for j in range(3)]  # ô_j in body = column j of T_BI
    T = np.stack(cols, axis=-1)
    return euler_313(T)


def pointing_state(q, frame, sigma, tau, psi_f, phi_f):
    """Angles and errors: dict ``psi, theta, phi, e_psi, e_theta, e_phi, pointing_error``."""
    psi, theta, phi = attitude_angles(q, frame)
    return {'psi': psi, 'theta': theta, 'phi': phi, 'e_psi': wrap(psi - psi_f),
            'e_theta': theta - np.pi / 2, 'e_phi': wrap(phi - phi_f),
            'pointing_error': pointing_error(q, sigma, tau)}


# --- controller A --------------------------------------------------------------------------------

def linearisation(inertia, h_f, momentum_state='h1'):
    """(A (5, 5), B (5, 2)) of eq. (18) for ``x = (e_Ψ, ω, e_h1)`` (or ``e_h2``); one run."""
    J = np.asarray(inertia, dtype=float)
    h_f = np.asarray(h_f, dtype=float)
    H0 = np.linalg.norm(h_f)
    Jinv = np.linalg.inv(J)
    hx = np.array([[0.0, -h_f[2], h_f[1]], [h_f[2], 0.0, -h_f[0]], [-h_f[1], h_f[0], 0.0]])
    A = np.zeros((5, 5))
    A[0, 1:4] = h_f / H0
    A[1:4, 1:4] = Jinv @ hx               # -ω x h_f = h_f x ω
    B = np.zeros((5, 2))
    B[1:4, :] = Jinv[:, :2]               # J⁻¹ S
    B[4, 0 if momentum_state == 'h1' else 1] = -1.0   # G: dh/dt = -u
    return A, B


def lqr_gain(inertia, h_f, Q=Q_PAPER, R=R_PAPER, momentum_state='h1'):
    """K (2, 5), ``u = -K x``, from the ARE of eq. (18) (scipy ``solve_continuous_are``); one run."""
    A, B = linearisation(inertia, h_f, momentum_state)
    Q = np.diag(np.asarray(Q, dtype=float))
    R = np.diag(np.asarray(R, dtype=float))
    import scipy.linalg  # at first use: scipy.linalg costs ~0.3 s at import, every node paid it (#18)
    P = scipy.linalg.solve_continuous_are(A, B, Q, R)
    return np.linalg.solve(R, B.T @ P)


def momentum_state_choice(phi_f, choice='auto'):
    """1 (e_h1) or 2 (e_h2) per run: 'h1', 'h2', or 'auto' = e_h1 iff |cos Φ_f| >= |sin Φ_f|."""
    phi_f = np.asarray(phi_f, dtype=float)
    if choice in ('h1', 'h2'):
        return np.full(phi_f.shape, int(choice[1]))
    if choice != 'auto':
        raise ValueError(f"momentum_state must be 'h1', 'h2' or 'auto', got {choice!r}")
    return np.where(np.abs(np.cos(phi_f)) >= np.abs(np.sin(phi_f)), 1, 2)


def momentum_stabilisation_torque(w, h, h_f, K_p, K_h):
    """Stage 1 of controller A, eq. (22) with the sign that makes eq. (21) negative:
    ``u = -K_p (ω - K_h (h - h_f))``, ``u_3 = 0``."""
    e_h = np.asarray(h, dtype=float) - h_f
    return -gain_vector(K_p) * (np.asarray(w, dtype=float) - gain_vector(K_h) * e_h) * _XY


def lqr_torque(e_psi, w, h, h_f, gain, state_index):
    """Stage 2 of controller A: ``u = -K x``, ``x = (e_Ψ, ω, e_h{state_index})`` (eq. 18)."""
    e_h = np.asarray(h, dtype=float) - h_f
    e5 = np.where(np.asarray(state_index) == 1, e_h[..., 0], e_h[..., 1])
    x = np.concatenate([np.asarray(e_psi)[..., None], np.asarray(w, dtype=float), e5[..., None]],
                       axis=-1)
    u2 = -matvec(gain, x)
    return np.concatenate([u2, np.zeros(u2.shape[:-1] + (1,))], axis=-1)


def controller_a_torque(q, w, h, frame, sigma, tau, psi_f, phi_f, H0, K_p, K_h, gain, state_index,
                        stage, eps_omega=EPS_OMEGA, eps_phi=EPS_PHI):
    """Controller A (section 3): stage 1 (eq. 22) until ``|ω| < ε_ω`` and ``|e_Φ| < ε_Φ``, then the
    LQR (latched). ``stage`` (...,) the runs' current stages; returns ``(u, status)`` with the new
    ``status['stage']`` (the caller keeps it). ``gain`` (..., 2, 5) from :func:`lqr_gain`."""
    st = pointing_state(q, frame, sigma, tau, psi_f, phi_f)
    h_f = target_momentum(phi_f, H0)
    w = np.asarray(w, dtype=float)
    switch = (norm(w) < eps_omega) & (np.abs(st['e_phi']) < eps_phi)
    stage = np.where((np.asarray(stage) == STAGE_MOMENTUM) & switch, STAGE_LQR, stage)
    u1 = momentum_stabilisation_torque(w, h, h_f, K_p, K_h)
    u2 = lqr_torque(st['e_psi'], w, h, h_f, gain, state_index)
    u = np.where((stage == STAGE_LQR)[..., None], u2, u1)
    st.update(mode=stage, stage=stage)
    return u, st


# --- controller B --------------------------------------------------------------------------------

def desired_rate_b(phi, e_psi, K_Psi):
    """Eq. (24): ``ω_des = -K_Ψ (sin Φ, cos Φ, 0) e_Ψ``."""
    k = np.asarray(K_Psi, dtype=float) * e_psi
    return np.stack([-k * np.sin(phi), -k * np.cos(phi), 0.0 * k], axis=-1)


def controller_b_torque(q, w, h, frame, sigma, tau, psi_f, phi_f, H0, K_p, K_Psi, K_h):
    """Controller B (eq. 24-33): ``u = -K_p (ω - ω_des - K_h (h - h_f))``, ``u_3 = 0``."""
    st = pointing_state(q, frame, sigma, tau, psi_f, phi_f)
    h_f = target_momentum(phi_f, H0)
    w_des = desired_rate_b(st['phi'], st['e_psi'], K_Psi)
    e_w = np.asarray(w, dtype=float) - w_des
    e_h = np.asarray(h, dtype=float) - h_f
    u = -gain_vector(K_p) * (e_w - gain_vector(K_h) * e_h) * _XY
    stage = np.full(np.shape(st['psi']), STAGE_B)
    st.update(mode=stage, stage=stage, w_des=w_des)
    return u, st


# --- laws bound to validated controller sections -------------------------------------------------

class _PointingLaw(SectionLaw):
    """Common keys (paper symbols; SI units):

    * ``inertia``: J, the controller's model of the total inertia (wheels locked), 3 or 3x3;
    * ``sigma``: σ̂, body axis to point (3, normalised here);
    * ``tau``: τ̂, inertial target direction (3, in the frame of the attitude quaternion);
    * ``H`` (optional): total angular momentum in inertial axes (N m s); default: measured at the
      first call as ``R(q)(J ω + h)`` for each run (H0 = its norm);
    * ``solution``: which attitude of eq. (16): 1 (Ψ*), 2 (π - Ψ*) or 0 = the one nearer (smaller
      eigenaxis angle) to the attitude at the first call (default 0; the paper does not say);
    * ``K_p`` (N m s/rad), ``K_h`` (rad/(N m s)): gains of eq. 22 / 33.

    ``control(t, q, w, wheel_momentum) -> (u (..., 3), status)``; ``wheel_momentum`` (..., 3) is
    ``h`` (relative wheel momentum, body axes). Law state (per run, batch axis): the inertial frame,
    the targets and, for A, the stage and the LQR gain; set at the first call, cleared by
    :meth:`reset`. Infeasible geometry (eq. 14) raises ValueError (at construction when ``H`` is
    given, else at the first call). Saturation (the paper's 20 mN m) is the caller's.
    """

    mode_names = MODE_NAMES
    needs_wheel_momentum = True   # control() takes the wheels' momentum h (callers dispatch on it)

    params = (SOLUTION,)
    targeted = False   # no target attitude: one body axis is pointed

    def __init__(self, p, H=None) -> None:
        p = self.section(p)
        super().__init__(p)
        self.sigma = unit(np.asarray(p.sigma, dtype=float))
        self.tau = unit(np.asarray(p.tau, dtype=float))
        if H is None and hasattr(p, 'H'):   # a pure-law caller's dict may give H (not a schema parameter)
            H = p.H
        self.H = None if H is None else np.asarray(H, dtype=float)
        self.solution = int(p.solution)
        if self.solution not in (0, 1, 2):
            raise ValueError(f'solution must be 0 (nearest), 1 or 2, got {self.solution!r}')
        self.K_p = p.K_p
        self.K_h = p.K_h
        if self.H is not None:
            final_attitudes(self.sigma, self.tau, self.H)   # feasibility check now
        self._geo = None

    def reset(self) -> None:
        self._geo = None

    def _setup(self, q, w, h):
        """Per-run geometry at the first call: frame, (Ψ_f, Φ_f), H0."""
        if self.H is None:
            H = rotate_to_inertial(q, matvec(self.inertia, w) + h)
        else:
            H = np.broadcast_to(self.H, q.shape[:-1] + (3,))
        qf, psi, phi = final_attitudes(self.sigma, self.tau, H)
        if self.solution:
            k = np.full(q.shape[:-1], self.solution - 1)
        else:
            d = eigenaxis_angle(error_quaternion(q[..., None, :], qf))
            k = np.where(d[..., 1] < d[..., 0], 1, 0)
        pick = lambda a: np.where(k == 0, a[..., 0], a[..., 1])  # noqa: E731
        geo = {'frame': inertial_frame(H, self.tau), 'psi_f': pick(psi), 'phi_f': pick(phi),
               'H0': norm(H), 'q_f': np.where((k == 0)[..., None], qf[..., 0, :], qf[..., 1, :]),
               'shape': q.shape[:-1]}
        return geo

    def _ensure(self, q, w, h):
        if self._geo is None or self._geo['shape'] != q.shape[:-1]:
            self._geo = self._setup(q, w, h)
            self._init_state()
        return self._geo

    def _init_state(self) -> None:
        pass

    @staticmethod
    def _inputs(q, w, h):
        q = np.asarray(q, dtype=float)
        w = np.asarray(w, dtype=float)
        h = np.broadcast_to(np.asarray(h, dtype=float), w.shape)
        return q, w, h


class PointingALaw(_PointingLaw):
    """Controller A (section 3). Extra keys: ``Q`` (5 diagonal weights, default
    (0.1, 100, 100, 100, 1)), ``R`` (2, default (100, 100)), ``eps_omega`` (rad/s, default 0.01),
    ``eps_Phi`` (rad, default 1° = 0.017453), ``momentum_state`` ('auto' | 'h1' | 'h2', the dual
    state choice of section 3.1; default 'auto'). Status: ``mode``/``stage`` (1 = A1_momentum,
    2 = A2_lqr), ``psi``, ``theta``, ``phi``, ``e_psi``, ``e_theta``, ``e_phi``, ``pointing_error``
    (rad)."""

    params = (SOLUTION, *POINTING_A_PARAMS)

    def __init__(self, p, H=None) -> None:
        p = self.section(p)
        super().__init__(p, H)
        self.Q = tuple(p.Q)
        self.R = tuple(p.R)
        self.eps_omega = float(p.eps_omega)
        self.eps_phi = float(p.eps_Phi)
        self.momentum_state = p.momentum_state
        momentum_state_choice(0.0, self.momentum_state)   # validate
        self.stage = None

    def _init_state(self) -> None:
        geo = self._geo
        shape = geo['shape']
        idx = momentum_state_choice(geo['phi_f'], self.momentum_state)
        h_f = target_momentum(geo['phi_f'], geo['H0'])
        J = np.broadcast_to(self.inertia, shape + (3, 3))
        gain = np.empty(shape + (2, 5))
        for i in np.ndindex(shape):
            gain[i] = lqr_gain(J[i], h_f[i], self.Q, self.R, 'h1' if idx[i] == 1 else 'h2')
        geo['gain'], geo['state_index'] = gain, idx
        self.stage = np.full(shape, STAGE_MOMENTUM)

    def control(self, t, q, w, wheel_momentum):
        q, w, h = self._inputs(q, w, wheel_momentum)
        g = self._ensure(q, w, h)
        u, st = controller_a_torque(q, w, h, g['frame'], self.sigma, self.tau, g['psi_f'],
                                    g['phi_f'], g['H0'], self.K_p, self.K_h, g['gain'],
                                    g['state_index'], self.stage, self.eps_omega, self.eps_phi)
        self.stage = st['stage']
        return u, st


class PointingBLaw(_PointingLaw):
    """Controller B (section 4). Extra key: ``K_Psi`` (1/s, eq. 24). Status: ``mode``/``stage``
    (3 = B), the angles and errors as :class:`PointingALaw`, and ``w_des`` (eq. 24)."""

    def __init__(self, p, H=None) -> None:
        p = self.section(p)
        super().__init__(p, H)
        self.K_Psi = p.K_Psi

    def control(self, t, q, w, wheel_momentum):
        q, w, h = self._inputs(q, w, wheel_momentum)
        g = self._ensure(q, w, h)
        return controller_b_torque(q, w, h, g['frame'], self.sigma, self.tau, g['psi_f'],
                                   g['phi_f'], g['H0'], self.K_p, self.K_Psi, self.K_h)
