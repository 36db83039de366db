"""Quaternion integrator backstepping with thruster + wheel allocation, seed 002 (Kristiansen &
Nicklasson, "Satellite attitude control by quaternion-based backstepping", ESEO). Pure numpy.

Conventions. The paper writes quaternions scalar FIRST ``q = [η, εᵀ]``; the code is scalar LAST
``[x, y, z, w] = [ε, η]`` (converted at the boundaries: inputs, ``status['q_err']``). ``q`` is the
body in the inertial frame, ``q_d`` the desired frame in the inertial frame, ``w`` = ``ω^b_ib``.

Error quaternion, eq. (11-12)::

    η̃ = η_d η + ε_dᵀ ε,      ε̃ = η_d ε - η ε_d - S(ε_d) ε

Eq. (12) is ``q̄_d ⊗ q`` (the body relative to the desired frame, our
:func:`adcs_core.attitude.error_quaternion`); eq. (11) prints ``q_d ⊗ q̄``, whose vector part has
the opposite sign on the first two terms: eq. (12) is the one that obeys eq. (13-14) with
``ω̃ = ω^b_db`` (docs/seed002_readings.md R2). Rate error, eq. (15): ``ω̃ = ω^b_ib - ω^b_id``
with ``ω^b_id = R(q̃)ᵀ ω^d_id`` and, along the motion, ``ω̇^b_id = R(q̃)ᵀ ω̇^d_id - ω̃ × ω^b_id``
(the reference generator gives ``ω^d_id`` and ``ω̇^d_id`` in the desired frame).

Backstepping, eq. (22-35), with ``sgn(x) = 1`` for ``x >= 0`` else -1::

    z1 = [1 - |η̃|, ε̃ᵀ]ᵀ                                         (22)
    Gᵀ(q̃) = [[sgn(η̃) ε̃ᵀ], [η̃ I + S(ε̃)]]       (4 x 3),  ż1 = 1/2 Gᵀ ω̃   (25)
    α1 = -K1 G z1,      z2 = ω̃ - α1                                (29), (24)
    α̇1 = -K1 (Ġ z1 + G ż1),   Ġ = [[sgn(η̃) ε̃̇ᵀ], [η̃̇ I + S(ε̃̇)]]ᵀ      (section 3.3)
    τ_a = -G z1 - K2 z2 + ω × (J ω) - τ_g + J ω̇^b_id + J α̇1         (32)
    V1 = z1ᵀ z1,   V2 = V1 + 1/2 z2ᵀ J z2,   V̇2 = -(G z1)ᵀ K1 (G z1) - z2ᵀ K2 z2   (27, 31, 33)

``η̃̇``, ``ε̃̇`` from eq. (13-14) with the measured ``ω̃``. ``G z1 = sgn(η̃) ε̃`` identically (so
``V1 = 2 (1 - |η̃|)``), and both ``q̃ = [±1, 0, 0, 0]`` are equilibria: the law turns the short
way (< 180°) whatever the sign of ``q_d``. ``τ_g`` is the gravity-gradient torque of eq. (19)
(:meth:`adcs_core.orbit.CircularOrbit.gravity_gradient`), compensated when given. ``K1`` (rad/s)
and ``K2`` (N m s) are scalars, per-run arrays (...,) or matrices (..., 3, 3) (``K = Kᵀ > 0``).

Actuators, eq. (20-21). ``τ_a = B_a u + D_a ω`` with ``u = [F_1 .. F_4, ḣ_wy]``; ``B_a`` has the
columns ``r_i × d_i`` (thruster i at ``r_i`` pushing along ``d_i``) and the wheel axis;
``D_a ω = ω × (h_wy a_w)`` (for the y wheel: ``D_a = [[0, 0, -h], [0, 0, 0], [h, 0, 0]]``). With the
physical wheel (momentum ``h_w = J_w (Ω + a·ω)`` along ``a``, motor torque ``τ_m`` putting
``-a τ_m`` on the body) the body receives ``-a τ_m - ω × (h_w a)``: the paper's signs hold with
``ḣ_wy = -τ_m`` and ``h_wy = -h_w`` (its "h_wy" is the momentum the body received; R4 of the
readings). The printed eq. (21) is :func:`eseo_actuator_matrix`; :func:`eseo_thruster_layout` gives
positions and directions that reproduce it (four thrusters on the ``+z`` face at
``(±r_x, ±r_y, r_z)`` pushing along the face diagonals). Its thruster columns have rank 3 only if
``r_x != r_y`` (else no thruster yaw torque and, with a y wheel, ``B_a Bᵀ_a`` is singular): R3.

Allocation: ``u = B_a† (τ_a - D_a ω)``, ``B_a† = B_aᵀ (B_a B_aᵀ)⁻¹`` (Moore-Penrose, minimum
norm). Thrusters only push, so a signed ``F`` is mapped to non-negative demands
(:func:`thrust_demand`): ``'pairs'`` moves a negative ``F_i`` onto the opposed thruster
(exact when the two torques are opposite), ``'nullspace'`` adds ``c n`` with ``n > 0`` a null
vector of the thruster torque matrix (here ``n = [1, 1, 1, 1]``; also zero net force) and
``c`` the least that makes every force >= 0 (Basilisk's thrForceMapping). Firing
(:func:`bang_bang`, Song & Agrawal 2001 as cited in 2.5.2): a thruster fires at full force over
the whole control period when its demand exceeds ``on_level`` (the "upper limit"), else stays off
(deadzone); with ``off_level < on_level`` a Schmitt trigger keeps a firing thruster on until the
demand falls below ``off_level`` (state with a batch axis).

Every function takes arrays with an optional leading batch axis; matrix-vector products go through
:func:`adcs_core.attitude.matvec` and cross products through :func:`adcs_core.attitude.cross`, so a
batch gives the same bits as a loop of single calls.
"""
from __future__ import annotations

import math

import numpy as np

from adcs_controllers.laws.allocation import Actuation
from adcs_controllers.laws.base import TARGET_PARAMS, SectionLaw
from adcs_core.attitude import (
    cross,
    dot,
    error_quaternion,
    gain_vector,
    hat,
    matvec,
    quat_multiply,
    rotate_to_body,
    transpose,
)
from adcs_core.orbit import CircularOrbit, orbit_frame_attitude, orbit_rate
from adcs_msgs_py.names import THRUSTERS_CMD, WHEELS_CMD
from adcs_msgs_py.params import Param, non_negative, positive

__all__ = [
    'MODE_TRACKING', 'eseo_thruster_layout', 'eseo_actuator_matrix', 'actuator_matrix',
    'pseudo_inverse', 'wheel_gyro_matrix', 'allocate', 'positive_null_vector', 'opposed_pairs',
    'thrust_demand', 'bang_bang', 'sgn', 'g_matrix', 'backstepping_torque', 'OrbitReference',
    'ThrusterWheelAllocation', 'BacksteppingLaw', 'ThrusterActuation',
]

MODE_TRACKING = 0
SQRT1_2 = math.sqrt(0.5)


# --- actuator matrix, eq. (20-21) ----------------------------------------------------------------

def eseo_thruster_layout(rx: float, ry: float, rz: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions (4, 3) and unit directions (4, 3) whose torques are the rows of eq. (21).

    Thrusters on the ``+z`` face at ``(∓r_x, ∓r_y, r_z)`` pushing along the face diagonals
    (``r × d / |d|`` gives the printed ``√2/2 [±r_z, ±r_z, ±(r_x - r_y)]``). Only the line of
    action matters: other positions on the same lines give the same ``B_a``.
    """
    p = np.array([[-rx, -ry, rz], [-rx, ry, rz], [rx, -ry, rz], [rx, ry, rz]], dtype=float)
    d = SQRT1_2 * np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0]])
    return p, d


def eseo_actuator_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """``B_a`` (3, 5) as printed in eq. (21) (the paper prints ``B_aᵀ``)."""
    s = math.sqrt(2.0)
    BT = np.array([[-rz, rz, -rx + ry],
                   [rz, rz, rx - ry],
                   [-rz, -rz, rx - ry],
                   [rz, -rz, -rx + ry],
                   [0.0, s, 0.0]]) * (s / 2.0)
    return BT.T


def actuator_matrix(positions, directions, wheel_axis=(0.0, 1.0, 0.0)) -> np.ndarray:
    """``B_a`` (3, n + 1): columns ``r_i × d_i`` (unit ``d_i``) then the wheel axis (None: (3, n))."""
    r = np.asarray(positions, dtype=float)
    d = np.asarray(directions, dtype=float)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    T = cross(r, d).T
    if wheel_axis is None:
        return np.ascontiguousarray(T)
    a = np.asarray(wheel_axis, dtype=float)
    return np.ascontiguousarray(np.column_stack([T, a / np.linalg.norm(a)]))


def pseudo_inverse(B: np.ndarray) -> np.ndarray:
    """``B† = Bᵀ (B Bᵀ)⁻¹`` (section 2.5.1) for a full-row-rank ``B`` (3, m); raises otherwise."""
    B = np.asarray(B, dtype=float)
    rank = np.linalg.matrix_rank(B)
    if rank < B.shape[0]:
        raise ValueError(f'actuator matrix has rank {rank} < {B.shape[0]}: B Bᵀ is singular '
                         '(for eq. 21: r_x = r_y gives no thruster yaw torque)')
    import scipy.linalg  # at first use: scipy.linalg costs ~0.3 s at import, every node paid it (#18)
    return scipy.linalg.pinv(B)


def wheel_gyro_matrix(h, wheel_axis=(0.0, 1.0, 0.0)) -> np.ndarray:
    """``D_a`` of eq. (20) (..., 3, 3): ``D_a ω = ω × (h a)``; for ``a = y``,
    ``[[0, 0, -h], [0, 0, 0], [h, 0, 0]]``. ``h`` is the paper's ``h_wy`` (scalar or (...,))."""
    hv = np.asarray(h, dtype=float)[..., None] * np.asarray(wheel_axis, dtype=float)
    x, y, z = hv[..., 0], hv[..., 1], hv[..., 2]
    zero = np.zeros(x.shape)
    return np.stack([np.stack([zero, z, -y], -1), np.stack([-z, zero, x], -1),
                     np.stack([y, -x, zero], -1)], -2)


def allocate(tau, w, B_pinv, h=0.0, wheel_axis=(0.0, 1.0, 0.0)) -> np.ndarray:
    """``u = B_a† (τ_a - D_a ω)`` (section 2.5.1): (..., m) signed forces then ``ḣ_wy``."""
    tau = np.asarray(tau, dtype=float)
    w = np.asarray(w, dtype=float)
    gyro = matvec(wheel_gyro_matrix(h, wheel_axis), w)
    return matvec(np.asarray(B_pinv, dtype=float), tau - gyro)


# --- signed forces -> firings ---------------------------------------------------------------------

def positive_null_vector(T: np.ndarray) -> np.ndarray:
    """A null vector ``n > 0`` (max entry 1) of the thruster torque matrix ``T`` (3, n): adding
    ``c n`` to the forces leaves the torque unchanged. Raises if the null space is not one line
    of one sign (the layout cannot be made all-pushing that way)."""
    import scipy.linalg  # at first use (see pseudo_inverse)
    N = scipy.linalg.null_space(np.asarray(T, dtype=float))
    if N.shape[1] != 1:
        raise ValueError(f'thruster null space has dimension {N.shape[1]}, need 1')
    n = N[:, 0] / N[np.argmax(np.abs(N[:, 0])), 0]
    if not np.all(n > 1e-12):
        raise ValueError(f'thruster null vector {n} is not of one sign')
    return n


def opposed_pairs(directions) -> np.ndarray:
    """For each thruster the index of the one pushing most nearly the opposite way."""
    d = np.asarray(directions, dtype=float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    dots = d @ d.T
    np.fill_diagonal(dots, np.inf)
    pair = np.argmin(dots, axis=1)
    if not np.all(dots[np.arange(len(d)), pair] < -0.99):
        raise ValueError('not every thruster has an opposed partner')
    return pair


def thrust_demand(F, mode: str, pairs=None, null_vector=None) -> np.ndarray:
    """Non-negative thrust demands (..., n) from signed allocated forces ``F`` (..., n).

    ``'pairs'``: ``D_i = max(F_i, 0) + max(-F_p(i), 0)`` with ``p = pairs`` (:func:`opposed_pairs`).
    ``'nullspace'``: ``D = F + c n``, ``c = max(0, max_i(-F_i / n_i))`` (``n`` from
    :func:`positive_null_vector`), the least shift making all demands >= 0; torque unchanged.
    """
    F = np.asarray(F, dtype=float)
    if mode == 'pairs':
        p = np.asarray(pairs)
        return np.maximum(F, 0.0) + np.maximum(-F[..., p], 0.0)
    if mode == 'nullspace':
        n = np.asarray(null_vector, dtype=float)
        c = np.maximum(np.max(-F / n, axis=-1), 0.0)
        return np.maximum(F + c[..., None] * n, 0.0)   # max() only removes rounding (-1e-17)
    raise ValueError(f"thrust mapping must be 'pairs' or 'nullspace', got {mode!r}")


def bang_bang(demand, on_level, off_level=None, state=None) -> np.ndarray:
    """Bang-bang firing with a deadzone (and a Schmitt trigger): (..., n) bool, fire or not.

    Without hysteresis (``off_level`` None or equal to ``on_level``): fire iff
    ``demand > on_level``. With ``off_level < on_level``: a thruster off fires when
    ``demand > on_level``; one firing (``state`` True) keeps firing while ``demand > off_level``.
    ``state`` (..., n) bool: the previous output (None = all off). The returned array is the new
    state.
    """
    demand = np.asarray(demand, dtype=float)
    on_level = np.asarray(on_level, dtype=float)
    if off_level is None:
        return demand > on_level
    off_level = np.asarray(off_level, dtype=float)
    if np.any(off_level > on_level):
        raise ValueError('hysteresis needs off_level <= on_level')
    prev = np.zeros(demand.shape, dtype=bool) if state is None else np.asarray(state, dtype=bool)
    return np.where(prev, demand > off_level, demand > on_level)


# --- the law, eq. (22-35) -------------------------------------------------------------------------

def sgn(x):
    """``sgn`` of section 3.1: 1 for ``x >= 0``, else -1 (never 0)."""
    return np.where(np.asarray(x) >= 0.0, 1.0, -1.0)


def g_matrix(eta, eps, s=None):
    """``G(q̃)`` (..., 3, 4) = transpose of ``[[s ε̃ᵀ], [η̃ I + S(ε̃)]]`` (eq. 25), scalar-first
    column order ``[η, ε]`` (``z1`` is ``[1 - |η̃|, ε̃]``). ``s`` defaults to ``sgn(η̃)``; passing
    ``(η̃̇, ε̃̇)`` with the same ``s`` gives ``Ġ`` (section 3.3)."""
    eta = np.asarray(eta, dtype=float)
    eps = np.asarray(eps, dtype=float)
    s = sgn(eta) if s is None else s
    GT_lower = eta[..., None, None] * np.eye(3) + hat(eps)          # (..., 3, 3)
    G_right = transpose(GT_lower)
    return np.concatenate([(s[..., None] * eps)[..., :, None], G_right], axis=-1)


def _gain(K, v):
    K = np.asarray(K, dtype=float)
    if K.ndim >= 2 and K.shape[-2:] == (3, 3):
        return matvec(K, v)
    return gain_vector(K) * v


def backstepping_torque(q, w, q_d, w_d, w_d_dot, inertia, K1, K2, tau_g=None):
    """Actuator torque of eq. (32) tracking ``q_d`` (..., 4) with desired rate ``w_d`` and its
    derivative ``w_d_dot`` (..., 3) given in the DESIRED frame (``ω^d_id``, ``ω̇^d_id``).

    ``q``, ``w``: body attitude (scalar last) and rate ``ω^b_ib``; ``inertia`` (3, 3) or
    (..., 3, 3); ``tau_g`` (..., 3) gravity-gradient torque to compensate (None: none).
    Returns ``(τ_a (..., 3), status)``; ``status``: ``mode``, ``q_err`` (q̃, scalar last),
    ``w_err`` (ω̃), ``z1`` ([1 - |η̃|, ε̃], paper order), ``z2``, ``alpha1``, ``alpha1_dot``,
    ``V1``, ``V2``, ``W`` (``V̇2 = -W`` along the closed loop, eq. 33), ``angle`` (rad, the
    eigenaxis angle of q̃ in [0, π]).
    """
    q = np.asarray(q, dtype=float)
    w = np.asarray(w, dtype=float)
    J = np.asarray(inertia, dtype=float)
    qe = error_quaternion(q, np.asarray(q_d, dtype=float))          # eq. (12), scalar last
    eps, eta = qe[..., :3], qe[..., 3]
    w_id = rotate_to_body(qe, np.asarray(w_d, dtype=float))         # ω^b_id
    we = w - w_id                                                   # eq. (15)
    w_id_dot = rotate_to_body(qe, np.asarray(w_d_dot, dtype=float)) - cross(we, w_id)
    s = sgn(eta)
    z1 = np.concatenate([(1.0 - np.abs(eta))[..., None], eps], axis=-1)   # eq. (22)
    G = g_matrix(eta, eps, s)
    Gz1 = matvec(G, z1)
    alpha1 = -_gain(K1, Gz1)                                        # eq. (29)
    z2 = we - alpha1                                                # eq. (24)
    eta_dot = -0.5 * dot(eps, we)                                   # eq. (13)
    eps_dot = 0.5 * (eta[..., None] * we + cross(eps, we))          # eq. (14)
    z1_dot = 0.5 * matvec(transpose(G), we)                         # eq. (25)
    G_dot = g_matrix(eta_dot, eps_dot, s)
    alpha1_dot = -_gain(K1, matvec(G_dot, z1) + matvec(G, z1_dot))  # section 3.3
    tau = (-Gz1 - _gain(K2, z2) + cross(w, matvec(J, w))
           + matvec(J, w_id_dot) + matvec(J, alpha1_dot))           # eq. (32)
    if tau_g is not None:
        tau = tau - np.asarray(tau_g, dtype=float)
    V1 = dot(z1[..., 1:], z1[..., 1:]) + z1[..., 0] ** 2             # eq. (27)
    V2 = V1 + 0.5 * dot(z2, matvec(J, z2))                          # eq. (31)
    W = dot(Gz1, _gain(K1, Gz1)) + dot(z2, _gain(K2, z2))           # eq. (33)
    angle = 2.0 * np.arctan2(np.sqrt(dot(eps, eps)), np.abs(eta))
    status = {'mode': np.full(eta.shape, MODE_TRACKING), 'q_err': qe, 'w_err': we, 'z1': z1,
              'z2': z2, 'alpha1': alpha1, 'alpha1_dot': alpha1_dot, 'V1': V1, 'V2': V2, 'W': W,
              'angle': angle}
    return tau, status


# --- reference trajectory (section 4.2) ----------------------------------------------------------

class OrbitReference:
    """Desired attitude fixed relative to the orbit frame, then held fixed in the inertial frame.

    ``q_rel`` (scalar last): the desired frame relative to the orbit frame. For ``t < hold_time``
    ``q_d(t) = q_io(t) ⊗ q_rel`` with ``ω^d_id = R(q_rel)ᵀ [0, -ω_o, 0]`` (constant, so
    ``ω̇^d_id = 0``); from ``hold_time`` on ``q_d = q_io(hold_time) ⊗ q_rel``, ``ω_d = 0``: one
    revolution per orbit relative to the orbit frame. The paper's section 4.2 is
    ``hold_time = 0`` (the target given relative to the orbit frame at perigee, then inertial);
    ``hold_time = None`` tracks the orbit frame for ever. ``ω_d`` steps at ``hold_time``.
    """

    def __init__(self, orbit: CircularOrbit, q_rel, hold_time: float | None = 0.0) -> None:
        self.orbit = orbit
        q_rel = np.asarray(q_rel, dtype=float)
        self.q_rel = q_rel / np.linalg.norm(q_rel, axis=-1, keepdims=True)
        self.hold_time = hold_time
        _, w_io = orbit_rate(orbit)
        self.w_track = rotate_to_body(self.q_rel, w_io)
        if hold_time is not None:
            self.q_hold = quat_multiply(orbit_frame_attitude(orbit, hold_time), self.q_rel)

    def __call__(self, t: float):
        """``(q_d (..., 4), ω^d_id (..., 3), ω̇^d_id (..., 3))`` at time ``t``."""
        zero = np.zeros(self.q_rel.shape[:-1] + (3,))
        if self.hold_time is not None and t >= self.hold_time:
            return self.q_hold, zero, zero
        return quat_multiply(orbit_frame_attitude(self.orbit, t), self.q_rel), self.w_track, zero


# --- allocation and firing bound together ---------------------------------------------------------

class ThrusterWheelAllocation:
    """Desired actuator torque -> thruster on-times and wheel motor torque (section 2.5).

    ``positions``/``directions`` (n, 3), ``max_force`` (N), ``wheel_axis``; ``wheel_inertia``
    ``J_w`` (kg m²), ``wheel_max_torque`` (N m), ``wheel_max_speed`` (rad/s, relative to the body);
    ``mapping`` ``'nullspace'`` or ``'pairs'``; ``on_level``/``off_level`` (N) the bang-bang
    levels; ``period`` (s) the control period (a firing lasts the whole period).
    ``reallocate_saturated_wheel`` (our addition, R5): when the wheel is at its speed limit and
    the demand would push it further, that run is allocated with the thrusters-only
    pseudo-inverse (the 0.021 N m s wheel saturates within 0.1 s of a slew otherwise and its share
    of the torque is lost).
    :meth:`command` keeps the Schmitt state per run (batch axis).
    """

    def __init__(self, positions, directions, max_force, wheel_axis=(0.0, 1.0, 0.0),
                 wheel_inertia=4e-5, wheel_max_torque=np.inf, wheel_max_speed=np.inf,
                 mapping='nullspace', on_level=0.0, off_level=None, period=0.1,
                 reallocate_saturated_wheel=True) -> None:
        self.positions = np.asarray(positions, dtype=float)
        self.directions = np.asarray(directions, dtype=float)
        self.directions = self.directions / np.linalg.norm(self.directions, axis=-1, keepdims=True)
        self.n = self.positions.shape[-2]
        self.max_force = np.asarray(max_force, dtype=float)
        self.wheel_axis = np.asarray(wheel_axis, dtype=float)
        # One geometry (n, 3), or a batch of them (N, n, 3) (the sensitivity grid): the matrices
        # are built per run (the same calls, so the same bits) and stacked.
        batched = self.positions.ndim == 3 or self.directions.ndim == 3
        if batched:   # either may be shared by every run
            shape = np.broadcast_shapes(self.positions.shape, self.directions.shape)
            self.positions = np.broadcast_to(self.positions, shape)
            self.directions = np.broadcast_to(self.directions, shape)
        geometries = (list(zip(self.positions, self.directions)) if batched
                      else [(self.positions, self.directions)])
        parts = []
        for r, d in geometries:
            B = actuator_matrix(r, d, self.wheel_axis)
            parts.append((B, pseudo_inverse(B), np.vstack([pseudo_inverse(B[:, :self.n]), np.zeros((1, 3))]),
                          positive_null_vector(B[:, :self.n]) if mapping == 'nullspace' else None,
                          opposed_pairs(d) if mapping == 'pairs' else None))
        stack = (lambda i: np.stack([p[i] for p in parts])) if batched \
            else (lambda i: parts[0][i])
        self.B, self.B_pinv, self.T_pinv = stack(0), stack(1), stack(2)
        self.null = stack(3) if mapping == 'nullspace' else None
        self.pairs = parts[0][4]
        if mapping == 'pairs' and any(not np.array_equal(p[4], self.pairs) for p in parts):
            raise ValueError("'pairs' mapping: the opposed thrusters differ between the runs of the batch")
        self.wheel_inertia = wheel_inertia
        self.wheel_max_torque = wheel_max_torque
        self.wheel_max_speed = wheel_max_speed
        self.mapping = mapping
        if mapping not in ('pairs', 'nullspace'):
            raise ValueError(f"mapping must be 'pairs' or 'nullspace', got {mapping!r}")
        self.on_level = on_level
        self.off_level = off_level
        self.period = period
        self.reallocate = reallocate_saturated_wheel
        self.state = None

    def reset(self) -> None:
        self.state = None

    def command(self, tau, w, wheel_speed=0.0):
        """``(on_time (..., n), wheel motor torque (...,), info)`` for desired torque ``τ_a``.

        ``wheel_speed`` Ω (relative to the body, rad/s). ``info``: ``u`` (allocation actually
        used), ``demand`` (non-negative thrust demands), ``fire`` (bool), ``wheel_free``.
        """
        tau = np.asarray(tau, dtype=float)
        w = np.asarray(w, dtype=float)
        speed = np.asarray(wheel_speed, dtype=float)
        h_w = self.wheel_inertia * (speed + dot(w, self.wheel_axis * np.ones(w.shape)))
        h = -h_w                                       # the paper's h_wy (module doc, R4)
        u = allocate(tau, w, self.B_pinv, h, self.wheel_axis)
        # What the wheel can deliver this period: its torque limit and the torque that brings it
        # to its speed limit at the end of the period (body rate held).
        room = self.wheel_inertia / self.period
        hi = np.minimum(self.wheel_max_torque, room * (self.wheel_max_speed - speed))
        lo = np.maximum(-self.wheel_max_torque, -room * (self.wheel_max_speed + speed))
        tau_m = np.clip(-u[..., self.n], lo, hi)
        free = tau_m == -u[..., self.n]
        if self.reallocate and not np.all(free):
            # the wheel gives what it can; the rest of the torque goes to the thrusters alone
            rest = tau + tau_m[..., None] * self.wheel_axis
            u_t = allocate(rest, w, self.T_pinv, h, self.wheel_axis)
            u_t = np.concatenate([u_t[..., :self.n], -tau_m[..., None]], axis=-1)
            u = np.where(free[..., None], u, u_t)
        demand = thrust_demand(u[..., :self.n], self.mapping, self.pairs, self.null)
        fire = bang_bang(demand, self.on_level, self.off_level, self.state)
        if self.off_level is not None:
            self.state = fire
        on_time = np.where(fire, self.period, 0.0)
        return on_time, tau_m, {'u': u, 'demand': demand, 'fire': fire, 'wheel_free': free}


# The orbit and reference parameters of the law (its schema lists these very objects).
ORBIT_REFERENCE_PARAMS = (
    Param('orbit.altitude', 'double', check=positive, doc='circular orbit altitude (m), as the dynamics'),
    Param('orbit.inclination_deg', 'double', default=0.0, doc='deg, as the dynamics'),
    Param('orbit.raan_deg', 'double', default=0.0, doc='deg, as the dynamics'),
    Param('orbit.arg_latitude_deg', 'double', default=0.0, doc='argument of latitude at t = 0 (deg)'),
    Param('reference.hold_time', 'double', default=0.0, check=non_negative, finite=False,
          doc='target.attitude is the desired frame relative to the orbit frame, tracked until this '
              'time (s) and then held inertially (section 4.2: 0); .inf: tracked for ever'),
    Param('gravity_gradient_compensation', 'bool', default=True,
          doc='subtract the modelled gravity-gradient torque of eq. (19) in eq. (32)'),
)


# --- bound to a validated controller section ------------------------------------------------------

class BacksteppingLaw(SectionLaw):
    """Eq. (32) bound to a validated ``backstepping_controller`` section
    (:data:`adcs_controllers.families.BACKSTEPPING_SCHEMA`): ``inertia``; ``target.attitude`` =
    ``q_rel`` (scalar last, the desired frame relative to the orbit frame, section 4.2);
    ``K1`` (rad/s), ``K2`` (N m s); ``orbit.altitude`` (m) and optional ``orbit.inclination_deg``,
    ``orbit.raan_deg``, ``orbit.arg_latitude_deg``; ``reference.hold_time`` (s; ``inf`` = track
    the orbit-fixed target for ever; default 0, the paper's: the target is taken relative to the
    orbit frame at t = 0, then held inertially); ``gravity_gradient_compensation`` (default True).
    ``target.rate`` is not used (the reference gives ω_d)."""

    mode_names = {MODE_TRACKING: 'tracking'}
    params = (*TARGET_PARAMS, *ORBIT_REFERENCE_PARAMS)

    def __init__(self, p) -> None:
        p = self.section(p)
        super().__init__(p)
        self.K1, self.K2 = p.K1, p.K2
        orbit = p.orbit
        self.orbit = CircularOrbit(altitude=float(orbit.altitude),
                                   inclination=math.radians(orbit.inclination_deg),
                                   raan=math.radians(orbit.raan_deg),
                                   arg_latitude0=math.radians(orbit.arg_latitude_deg))
        hold = p.reference.hold_time
        hold = None if hold is None or math.isinf(hold) else float(hold)
        self.reference = OrbitReference(self.orbit, self.q_ref, hold)
        self.compensate_gg = bool(p.gravity_gradient_compensation)

    def control(self, t, q, w):
        q_d, w_d, w_d_dot = self.reference(t)
        tau_g = self.orbit.gravity_gradient(t, np.asarray(q, dtype=float), self.inertia) \
            if self.compensate_gg else None
        tau, status = backstepping_torque(q, w, q_d, w_d, w_d_dot, self.inertia, self.K1, self.K2,
                                          tau_g)
        status['q_d'] = np.broadcast_to(q_d, np.shape(q))
        return tau, status

    def published_status(self, status: dict) -> dict:
        """The status the node publishes: the mode, V1, V2 (eq. 27, 31), W (eq. 33), η̃ and the
        eigenaxis error in degrees."""
        return {'mode': self.mode_names[int(status['mode'])],
                'V1': float(status['V1']), 'V2': float(status['V2']), 'W': float(status['W']),
                'eta_err': float(status['q_err'][3]), 'angle_deg': math.degrees(float(status['angle']))}


def _geometry(values, n: int) -> np.ndarray:
    """Flattened per-thruster vectors (3 n,) or a batch (N, 3 n) -> (n, 3) or (N, n, 3)."""
    arr = np.asarray(values, dtype=float)
    return arr.reshape(arr.shape[:-1] + (n, 3))


class ThrusterActuation(Actuation):
    """The controller's side of seed 002's actuators, built from a validated controller section:
    desired torque ``τ_a`` -> thruster on-times and the pitch wheel's motor torque
    (:class:`ThrusterWheelAllocation`: eq. 20-21 pseudo-inverse allocation, thrust mapping,
    bang-bang firing over the control period). The node and the batch engine build the same one.

    Keys: ``thrusters.names/positions/directions/max_force``; one wheel ``wheels.names/axes/
    max_torque/spin_inertia/max_speed``; ``allocation.mapping``; ``firing.on_level``,
    ``firing.off_level`` (N; equal: no hysteresis); ``allocation.reallocate_saturated_wheel``;
    ``control_period`` (s).
    """

    kind = 'thrusters'
    plant_actuators = ('thrusters', 'wheels')
    command_topics = (THRUSTERS_CMD, WHEELS_CMD)

    def __init__(self, p) -> None:
        p = self.section(p)
        thrusters, wheels = p.thrusters, p.wheels
        n = len(thrusters.names)
        self.thruster_names = list(thrusters.names)
        self.wheel_names = list(wheels.names)
        self.firings = 0   # thruster-periods fired so far (the node's status: actuate)
        axis = np.asarray(wheels.axes, dtype=float)
        on = np.asarray(p.firing.on_level, dtype=float)
        off = np.asarray(p.firing.off_level, dtype=float)
        same = bool(np.array_equal(on, off))
        # per run when either is (one dispersed, the other shared): against each run's (..., n) demands
        on, off = (on[..., None], off[..., None]) if on.ndim or off.ndim else (float(on), float(off))
        self.allocation = ThrusterWheelAllocation(
            _geometry(thrusters.positions, n), _geometry(thrusters.directions, n),
            np.asarray(thrusters.max_force, dtype=float),
            wheel_axis=axis / np.linalg.norm(axis), wheel_inertia=wheels.spin_inertia[0],
            wheel_max_torque=wheels.max_torque[0], wheel_max_speed=wheels.max_speed[0],
            mapping=p.allocation.mapping, on_level=on, off_level=None if same else off,
            period=p.control_period,
            reallocate_saturated_wheel=p.allocation.reallocate_saturated_wheel)

    def command(self, tau, w, wheel_speed):
        """``(on_time (..., n), wheel motor torques (..., 1), info)`` (see
        :meth:`ThrusterWheelAllocation.command`); ``wheel_speed`` (..., 1) rad/s."""
        speed = np.asarray(wheel_speed, dtype=float)[..., 0]
        on_time, tau_m, info = self.allocation.command(tau, w, speed)
        return on_time, np.asarray(tau_m, dtype=float)[..., None], info

    def command_messages(self, values):
        """``values``: ``(on_time, wheel motor torques)``: thrusters/cmd (on-times as efforts) and
        wheels/cmd (motor torque)."""
        on_time, wheel_torque = values
        return [(THRUSTERS_CMD, self.thruster_names, 'effort', on_time),
                (WHEELS_CMD, self.wheel_names, 'effort', wheel_torque)]

    def plant_commands(self, values, speed_mode: bool = False):
        """The wheel's motor torque (the thrusters' on-times: :meth:`thruster_on_time`)."""
        return {'wheels': (values[1], np.zeros(np.shape(values[1]), dtype=bool))}

    def thruster_on_time(self, values):
        return values[0]

    needs_wheel_speed = True

    def command_values(self, torque, w, wheel_speed):
        on_time, wheel_torque, _ = self.command(torque, w, wheel_speed)
        return on_time, wheel_torque

    def actuate(self, torque, w, wheel_speed):
        """The node's step (one run): the commands, the torque they ask of the actuators (as if each
        fired thruster gave its full force over the period: the status' u_x..), and the wheel torque,
        whether the wheel was free, the thrusters firing now and the thruster-periods fired so far."""
        on_time, wheel_torque, info = self.command(torque, w, wheel_speed)
        fired = int(np.count_nonzero(on_time > 0.0))
        self.firings += fired
        alloc = self.allocation
        u = alloc.B[:, :alloc.n] @ (on_time / alloc.period * alloc.max_force) - alloc.wheel_axis * wheel_torque[0]
        return (on_time, wheel_torque), u, {
            'wheel_torque': float(wheel_torque[0]), 'wheel_free': str(bool(info['wheel_free'])).lower(),
            'firing_now': fired, 'firing_count': self.firings}

    def usable_status(self) -> dict:
        return {}
