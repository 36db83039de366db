"""Section IV of seed 004 (Horri, Palmer & Roberts): tuning the gain-scheduled min-norm law on the
single-axis eigenaxis model (eq. 21-31). Pure numpy/scipy, no ROS.

Model (eq. 21-23): ``J θ'' = u`` with, for a rest-to-rest manoeuvre from ``θ0`` (the paper's
choice of ε: low gains before the torque is turned off, high gains only afterwards)::

    u = u1 = -kp1/2 θ - kd1 θ'   from t = 0 until θ' + γ θ = 0                 (time t_s)
    u = 0                        until θ' + kp2/(2 kd2) θ = 0                   (time t_s')
    u = u2 = -kp2/2 θ - kd2 θ'   afterwards

(``sin(θ/2) ≈ θ/2``, eq. 20.) Both PD modes have the same damping ratio (IV.G):
``kd_i / J = 2 ζ sqrt(kp_i / (2J))``, i.e. ``ω_ni² = kp_i/(2J)``, ``kd_i = 2 ζ J ω_ni``. The
closed forms used (underdamped, ``ζ < 1``, as in the paper), with ``λ1 = ζ ω_n1``,
``Ω1 = ω_n1 sqrt(1 - ζ²)``:

* phase 1 (eq. 24, cosine form): ``θ = A1 cos(Ω1 t - φ1) e^{-λ1 t}`` with ``tan φ1 = λ1/Ω1`` and
  ``A1 = θ0 / cos φ1`` (for ``θ'(0) = 0``);
* switch-off time (text after eq. 24): ``t_s = (arctan((γ - λ1)/Ω1) + φ1) / Ω1``; there
  ``θ_s = θ(t_s)`` and ``θ'_s = -γ θ_s`` (the coast rate);
* settling-time limit (eq. 31), the limit of infinite high gains: ``t_sl = t_s + |θ_s/θ'_s| + 0
  = t_s + 1/γ``;
* high-gain peak torque (our derivation; the paper's eq. 32-33 are garbled, see
  docs/seed004_readings.md): ``u`` obeys the same oscillator equation, starts from ``u = 0`` at
  ``t_s'`` with ``u' = -J ω_n2² θ'_s``, so its first extremum, the largest, is
  ``|u|_peak = J ω_n2 |θ'_s| exp(-ζ arccos(ζ)/sqrt(1 - ζ²))`` at ``arccos(ζ)/Ω2`` after ``t_s'``;
* highest high gains under a torque limit ``u_max`` (closed form, no search: ``θ'_s`` does not
  depend on ``kp2``): ``ω_n2 = u_max / (J |θ'_s| exp(-ζ arccos ζ / sqrt(1-ζ²)))``,
  ``kp2 = 2 J ω_n2²``, ``kd2 = 2 ζ J ω_n2``. The paper's "maximum design torque" (IV.F) is the
  benchmark's initial torque ``kp1 |θ0| / 2``, the default limit here.

CLI: ``python -m adcs_sim.app.campaign.tuning --inertia 10 --angle-deg 30 --kp1 0.02 --kd1 0.5
--gamma 0.01 [--max-torque 0.005] [--simulate]``. Every argument is bounded to what the model can
take (:data:`BOUNDS`), the tuning must be finite and a ``--simulate`` run samplable
(:data:`MAX_SAMPLES`, :data:`MAX_RADIANS`): otherwise one line on stderr naming the argument, exit 2.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from adcs_msgs_py.help_text import command_parser
from adcs_sim.app.analysis.metrics import settling_time

PHASE_LOW_GAIN, PHASE_ZERO_TORQUE, PHASE_HIGH_GAIN = 0, 1, 2  # the GSMN mode codes


def damping_ratio(J: float, kp: float, kd: float) -> float:
    """ζ of ``J θ'' = -kp/2 θ - kd θ'``: ``kd/J = 2 ζ sqrt(kp/(2J))`` (eq. 23)."""
    return kd / (2.0 * J * math.sqrt(kp / (2.0 * J)))


def same_damping_kd(J: float, kp: float, zeta: float) -> float:
    """``kd = 2 ζ J sqrt(kp/(2J))``: the derivative gain keeping damping ratio ``ζ`` (IV.G rule)."""
    return 2.0 * zeta * J * math.sqrt(kp / (2.0 * J))


def _peak_factor(zeta: float) -> float:
    """``exp(-ζ arccos ζ / sqrt(1 - ζ²))``, so that ``|u|_peak = J ω_n2 |θ'_s| · factor``.

    ``u(τ) = -(J ω_n2 θ'_s / sqrt(1-ζ²)) e^{-ζ ω_n2 τ} sin(Ω2 τ)`` after reactivation; its first
    extremum is at ``Ω2 τ = arccos ζ`` where ``sin(Ω2 τ) = sqrt(1-ζ²)``."""
    return math.exp(-zeta * math.acos(zeta) / math.sqrt(1.0 - zeta * zeta))


@dataclass(frozen=True)
class SwitchPoint:
    """Where the low-gain phase ends (line ``θ' + γ θ = 0``)."""

    t_s: float          # switch-off time (s)
    theta_s: float      # θ(t_s) (rad)
    theta_dot_s: float  # θ'(t_s) = -γ θ_s (rad/s), the coast rate


def switch_point(J: float, kp1: float, kd1: float, gamma: float, theta0: float) -> SwitchPoint:
    """Closed-form end of the low-gain phase (eq. 24 and the ``t_s`` formula after it)."""
    if not (J > 0 and kp1 > 0 and kd1 > 0 and gamma > 0):
        raise ValueError('J, kp1, kd1 and gamma must be positive')
    zeta = damping_ratio(J, kp1, kd1)
    if zeta >= 1.0:
        raise ValueError(f'the closed forms of section IV need an underdamped low-gain mode '
                         f'(ζ = {zeta:.3f} >= 1)')
    wn = math.sqrt(kp1 / (2.0 * J))
    lam, Om = zeta * wn, wn * math.sqrt(1.0 - zeta * zeta)
    phi = math.atan(lam / Om)
    t_s = (math.atan((gamma - lam) / Om) + phi) / Om
    theta_s = theta0 / math.cos(phi) * math.cos(Om * t_s - phi) * math.exp(-lam * t_s)
    return SwitchPoint(t_s, theta_s, -gamma * theta_s)


def settling_time_limit(J: float, kp1: float, kd1: float, gamma: float, theta0: float) -> float:
    """``t_sl = t_s + |θ_s / θ'_s|`` (eq. 31): the settling time as ``kp2, kd2 -> ∞``."""
    sp = switch_point(J, kp1, kd1, gamma, theta0)
    return sp.t_s + abs(sp.theta_s / sp.theta_dot_s)


def high_gain_peak_torque(J: float, kp2: float, zeta: float, theta_dot_s: float) -> float:
    """``|u|`` peak of the high-gain phase: ``J ω_n2 |θ'_s| exp(-ζ arccos ζ / sqrt(1-ζ²))``."""
    return J * math.sqrt(kp2 / (2.0 * J)) * abs(theta_dot_s) * _peak_factor(zeta)


@dataclass(frozen=True)
class SingleAxisTuning:
    """Result of :func:`tune_single_axis` (SI units, angles in rad)."""

    zeta: float              # damping ratio of both PD modes
    t_s: float               # switch-off time
    theta_s: float           # attitude at switch-off
    theta_dot_s: float       # coast rate
    t_sl: float              # settling-time limit, eq. (31)
    max_torque: float        # torque limit used for the high-gain peak
    initial_torque: float    # benchmark's initial torque kp1 |θ0| / 2
    kp2: float               # highest high gains with peak torque <= max_torque
    kd2: float
    peak_torque: float       # high-gain peak at (kp2, kd2) (= max_torque)
    kp1: float               # the low (benchmark) proportional gain
    coasts: bool             # kp2/(2 kd2) > γ: the zero-torque phase exists

    @property
    def feasible(self) -> bool:
        """High gains at least the low ones, and a zero-torque phase (``kp2/(2 kd2) > γ``)."""
        return self.kp2 >= self.kp1 and self.coasts


def tune_single_axis(J: float, kp1: float, kd1: float, gamma: float, theta0: float,
                     max_torque: float | None = None) -> SingleAxisTuning:
    """Settling-time limit (eq. 31) and the highest ``kp2, kd2`` (same ζ as ``kp1, kd1``) whose
    high-gain peak torque stays under ``max_torque`` (default: the benchmark's initial torque
    ``kp1 |θ0| / 2``, the paper's "maximum design torque"). Closed form, see the module docstring.
    """
    sp = switch_point(J, kp1, kd1, gamma, theta0)
    zeta = damping_ratio(J, kp1, kd1)
    initial = 0.5 * kp1 * abs(theta0)
    limit = initial if max_torque is None else float(max_torque)
    if not limit > 0:
        raise ValueError('max_torque must be positive')
    wn2 = limit / (J * abs(sp.theta_dot_s) * _peak_factor(zeta))
    kp2 = 2.0 * J * wn2 * wn2
    kd2 = 2.0 * zeta * J * wn2
    return SingleAxisTuning(
        zeta=zeta, t_s=sp.t_s, theta_s=sp.theta_s, theta_dot_s=sp.theta_dot_s,
        t_sl=sp.t_s + abs(sp.theta_s / sp.theta_dot_s), max_torque=limit, initial_torque=initial,
        kp2=kp2, kd2=kd2, peak_torque=high_gain_peak_torque(J, kp2, zeta, sp.theta_dot_s),
        kp1=kp1, coasts=kp2 / (2.0 * kd2) > gamma)


# --- simulation of the single-axis model (eq. 21-22) --------------------------------------------

@dataclass(frozen=True)
class SingleAxisRun:
    """Samples of a simulated single-axis manoeuvre."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    u: np.ndarray
    phase: np.ndarray        # PHASE_LOW_GAIN / PHASE_ZERO_TORQUE / PHASE_HIGH_GAIN
    t_off: float             # end of the low-gain phase (t_s)
    t_on: float              # start of the high-gain phase (t_s'); inf if never reached


def simulate_single_axis(J: float, kp1: float, kd1: float, kp2: float, kd2: float, gamma: float,
                         theta0: float, t_end: float, dt: float = 0.1,
                         rtol: float = 1e-10) -> SingleAxisRun:
    """Integrate ``J θ'' = u`` under eq. (22) from rest at ``θ0`` (scipy ``solve_ivp``, RK45, the
    switching lines located as events), sampled every ``dt`` plus the switching instants.

    Phases follow the paper's rest-to-rest sequence (IV.B): low gains until ``θ' + γ θ = 0``,
    zero torque until ``θ' + kp2/(2 kd2) θ = 0`` (skipped if already past it), then high gains.
    """
    c2 = kp2 / (2.0 * kd2)
    laws = {PHASE_LOW_GAIN: (kp1, kd1), PHASE_ZERO_TORQUE: (0.0, 0.0), PHASE_HIGH_GAIN: (kp2, kd2)}
    lines = {PHASE_LOW_GAIN: gamma, PHASE_ZERO_TORQUE: c2}
    atol = 1e-12 * max(abs(theta0), 1e-12)
    t0, y0 = 0.0, np.array([theta0, 0.0])
    switch = {PHASE_LOW_GAIN: math.inf, PHASE_ZERO_TORQUE: math.inf}
    ts, ys, ph = [], [], []
    for phase in (PHASE_LOW_GAIN, PHASE_ZERO_TORQUE, PHASE_HIGH_GAIN):
        kp, kd = laws[phase]

        def rhs(t, y, kp=kp, kd=kd):
            return [y[1], (-0.5 * kp * y[0] - kd * y[1]) / J]

        events = None
        if phase in lines:
            c = lines[phase]
            if phase == PHASE_ZERO_TORQUE and np.sign(y0[1] + c * y0[0]) != np.sign(theta0):
                switch[phase] = t0  # already past the reactivation line: no coast
                continue

            def crossing(t, y, c=c):
                return y[1] + c * y[0]
            crossing.terminal = True
            events = [crossing]
        grid = np.arange(math.ceil(t0 / dt) * dt, t_end, dt)
        grid = grid[grid > t0]
        sol = solve_ivp(rhs, (t0, t_end), y0, method='RK45', rtol=rtol, atol=atol,
                        events=events, dense_output=True)
        t_stop = sol.t[-1]
        samples = np.concatenate([[t0], grid[grid < t_stop], [t_stop]])
        ts.append(samples)
        ys.append(sol.sol(samples).T)
        ph.append(np.full(samples.size, phase))
        if phase in lines:
            if sol.status == 1 and sol.t_events[0].size:
                switch[phase] = float(sol.t_events[0][0])
                t0, y0 = switch[phase], sol.y_events[0][0]
            else:
                break
    t = np.concatenate(ts)
    y = np.concatenate(ys)
    phase = np.concatenate(ph)
    kp_of = np.choose(phase, [kp1, 0.0, kp2])
    kd_of = np.choose(phase, [kd1, 0.0, kd2])
    u = -0.5 * kp_of * y[:, 0] - kd_of * y[:, 1]
    return SingleAxisRun(t, y[:, 0], y[:, 1], u, phase, switch[PHASE_LOW_GAIN],
                         switch[PHASE_ZERO_TORQUE])


def single_axis_settling_time(run: SingleAxisRun, tol: float) -> float:
    """Time after which ``|θ| <= tol`` to the end of ``run`` (last exit, interpolated;
    :func:`adcs_sim.app.analysis.metrics.settling_time`)."""
    return settling_time(run.t, np.abs(run.theta), tol)


# --- CLI ---------------------------------------------------------------------------------------

# What the single-axis model can take (SI): each positive value within 1e-9..1e9 (a nano-satellite's
# 1e-3 kg m^2 to a station's 1e8; gains and rates alike), an eigenaxis angle in (0, 180] deg, a
# settling band in (0, 100) %. Outside, the closed forms divide by zero or overflow.
BOUNDS = {'inertia': (1e-9, 1e9), 'kp1': (1e-9, 1e9), 'kd1': (1e-9, 1e9), 'gamma': (1e-9, 1e9),
          'max_torque': (1e-9, 1e9)}
# --simulate samples every SIM_DT over 3 t_sl: at most MAX_SAMPLES samples (8 B each, a few arrays)
# and MAX_RADIANS of the fastest mode's oscillation over the run (RK45 takes steps in proportion).
SIM_DT, MAX_SAMPLES, MAX_RADIANS = 0.1, 10**7, 1e6
MIN_ANGLE_DEG = 1e-6


def _check_args(args) -> None:
    """Every argument within what the model can take; ValueError '--option: why' otherwise."""
    for name, (lo, hi) in BOUNDS.items():
        value = getattr(args, name)
        if value is not None and not lo <= value <= hi:
            raise ValueError(f'--{name.replace("_", "-")}: must be in {lo:g}..{hi:g}, got {value:g}')
    if not MIN_ANGLE_DEG <= abs(args.angle_deg) <= 180:
        raise ValueError(f'--angle-deg: must be an eigenaxis angle of {MIN_ANGLE_DEG:g}..180 deg (either sign), '
                         f'got {args.angle_deg:g}')
    lo, hi = BOUNDS['max_torque']
    initial = 0.5 * args.kp1 * math.radians(abs(args.angle_deg))
    if args.max_torque is None and not lo <= initial <= hi:
        raise ValueError(f'--max-torque: the default, the initial torque kp1 θ0 / 2 = {initial:g} N m, is outside '
                         f'{lo:g}..{hi:g}: give one')
    if not 0 < args.tol_percent < 100:
        raise ValueError(f'--tol-percent: must be in (0, 100), got {args.tol_percent:g}')


def _check_result(r: SingleAxisTuning, J: float, simulate: bool) -> None:
    """The tuning is finite, and a simulation of it (``--simulate``) can be sampled and integrated."""
    numbers = {'t_s': r.t_s, 't_sl': r.t_sl, 'coast rate': r.theta_dot_s, 'kp2': r.kp2, 'kd2': r.kd2,
               'peak torque': r.peak_torque}
    bad = [k for k, v in numbers.items() if not (math.isfinite(v) and v != 0.0)]
    if bad:
        raise ValueError(f'the values give a degenerate tuning ({", ".join(bad)} zero or not finite)')
    if not simulate:
        return
    t_end = 3.0 * r.t_sl
    if t_end / SIM_DT > MAX_SAMPLES:
        raise ValueError(f'--simulate: 3 t_sl = {t_end:.3g} s is {t_end / SIM_DT:.3g} samples of {SIM_DT:g} s '
                         f'(at most {MAX_SAMPLES:.0e})')
    radians = t_end * math.sqrt(max(r.kp1, r.kp2) / (2.0 * J))
    if radians > MAX_RADIANS:
        raise ValueError(f'--simulate: the high-gain mode turns {radians:.3g} rad over 3 t_sl '
                         f'(at most {MAX_RADIANS:.0e}: the integrator would not finish)')


def main(argv: list[str] | None = None) -> int:
    parser = command_parser('adcs-tune-gsmn', 'tune the gain-scheduled min-norm law for a single-axis '
                            'rest-to-rest manoeuvre: its settling-time limit (eq. 31) and highest high gains '
                            '(section IV of Horri, Palmer & Roberts, Gain scheduled inverse optimal satellite '
                            'attitude control)')
    parser.add_argument('--inertia', type=float, required=True, help='the inertia J (kg m^2)')
    parser.add_argument('--angle-deg', type=float, required=True, help='initial eigenaxis angle (deg)')
    parser.add_argument('--kp1', type=float, required=True,
                        help="proportional gain of the low-gain phase, u1 = -kp1/2 θ - kd1 θ'")
    parser.add_argument('--kd1', type=float, required=True, help='derivative gain of the low-gain phase (kd1 in u1)')
    parser.add_argument('--gamma', type=float, required=True, help='the weight γ of eq. (22)')
    parser.add_argument('--max-torque', type=float, default=None,
                        help='torque limit for the high-gain peak, N m (default: the benchmark '
                             'initial torque kp1 θ0 / 2)')
    parser.add_argument('--simulate', action='store_true',
                        help='also simulate the single-axis model with the tuned gains')
    parser.add_argument('--tol-percent', type=float, default=2.0,
                        help='settling band for --simulate, %% of the initial angle (default 2)')
    args = parser.parse_args(argv)
    theta0 = math.radians(args.angle_deg)
    try:
        _check_args(args)
        r = tune_single_axis(args.inertia, args.kp1, args.kd1, args.gamma, theta0, args.max_torque)
        _check_result(r, args.inertia, args.simulate)
    except ValueError as exc:
        print(f'adcs-tune-gsmn: {exc}', file=sys.stderr)
        return 2
    print(f'damping ratio ζ            {r.zeta:.4f}')
    print(f'switch-off time t_s        {r.t_s:.3f} s  (θ_s = {math.degrees(r.theta_s):.3f} deg, '
          f'coast rate {math.degrees(r.theta_dot_s):.5f} deg/s)')
    print(f'settling-time limit t_sl   {r.t_sl:.3f} s  (eq. 31)')
    print(f'benchmark initial torque   {r.initial_torque:.6g} N m')
    print(f'torque limit               {r.max_torque:.6g} N m')
    print(f'highest kp2, kd2           {r.kp2:.6g}, {r.kd2:.6g}  (peak {r.peak_torque:.6g} N m)')
    if r.kp2 < args.kp1:
        print('warning: kp2 < kp1 (the limit is below what the low gains already need)')
    if not r.coasts:
        print('warning: kp2/(2 kd2) <= γ: no zero-torque phase, the closed forms do not apply')
    if args.simulate:
        t_end = 3.0 * r.t_sl
        run = simulate_single_axis(args.inertia, args.kp1, args.kd1, r.kp2, r.kd2, args.gamma,
                                   theta0, t_end)
        tol = args.tol_percent / 100.0 * abs(theta0)
        print(f'simulated: torque off at {run.t_off:.3f} s, on at {run.t_on:.3f} s, '
              f'peak |u| {np.max(np.abs(run.u[run.phase == PHASE_HIGH_GAIN])):.6g} N m, '
              f'{args.tol_percent:g}% settling time {single_axis_settling_time(run, tol):.3f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
