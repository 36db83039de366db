"""The figures a report leads with, one set per kind of run (:mod:`.kinds`): the error against
the reference the controller follows, with its phases shaded (regulation, tracking); seed 000's
1 − |q4| with the paper's bands after the fault; the spin's attitude and rate errors (spin); the
pointing error with Table 1's bands (pointing). Each builder returns (Figure, caption) or a string
(why the figure is skipped), as :data:`.figures.FIGURES`."""
from __future__ import annotations

import math

import numpy as np

from adcs_core.attitude import eigenaxis_angle, error_quaternion
from adcs_sim.app.analysis.metrics import POINTING_BANDS_DEG, first_entry_time, pointing_error_deg, settling_time
from adcs_sim.app.report.envelope import reduced
from adcs_sim.app.report.figures import (
    LINE,
    Context,
    add_legend,
    log_positive,
    mark_faults,
    new_figure,
    shade_phases,
    step_plot,
)
from adcs_sim.app.report.kinds import param_value, section_params, vector
from adcs_sim.app.report.lead import SPIN_RATE_BAND_RAD_S, SPIN_THETA_BAND_RAD, TRACKING_BAND_DEG, status_array


def _settling(c: Context, series: str, band: float, t: np.ndarray, error: np.ndarray) -> float:
    """settling_time of ``error``, or the whole run's when it was streamed (``c.settled``)."""
    if (series, band) in c.settled:
        return c.settled[series, band]
    return settling_time(t, error, band)


def _published(c: Context, key: str) -> float | None:
    return next((m.paper for m in c.lead if m.key == key and m.paper is not None), None)


def fig_reference_error(c: Context):
    """Regulation and tracking: the eigenaxis error to the reference the controller follows."""
    if c.q_ref is None:
        return f'no attitude reference for this run ({c.reference_text})'
    eigen = np.degrees(eigenaxis_angle(error_quaternion(c.run.q, c.q_ref)))
    tol = TRACKING_BAND_DEG if c.kind.kind == 'tracking' else c.eigen_tol_deg
    fig, (ax,) = new_figure(height=3.4)
    shade_phases([ax], c.phases)
    ax.plot(*reduced(c.run.t, log_positive(eigen)), color='C0', label='error to the reference')
    ax.set_yscale('log')
    ax.axhline(tol, color='0.3', linestyle=':', label=f'band {tol:g}°')
    ts = _settling(c, 'eigen', tol, c.run.t, eigen)
    if math.isfinite(ts):
        ax.axvline(ts, color='C2', linestyle='-.', linewidth=1, label=f'settled to {tol:g}° at {ts:.1f} s')
    paper = _published(c, f'settling_eigenaxis_{tol:g}deg_s')
    if paper is not None:
        ax.axvline(paper, color='k', linestyle=(0, (1, 2)), linewidth=1.2, label=f'paper: {paper:g} s')
    ax.set_ylabel('eigenaxis error (deg, log)')
    what = 'tracking error to q_d(t)' if c.kind.kind == 'tracking' else 'attitude error to the reference'
    ax.set_title(f'{what[0].upper()}{what[1:]}: eigenaxis angle of $q_{{ref}}(t)^* \\otimes q$')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, (f'Eigenaxis {what} (deg, log scale). Reference: {c.reference_text}. '
                 + ('Shaded: the phases of the run (controller status). ' if c.phases else '')
                 + f'Dotted: the {tol:g}° band; dash-dot: our settling time'
                 + ('; fine dotted: the paper\'s.' if paper is not None else '.'))


def fig_q4_bands(c: Context):
    """Seed 000 VI.A: 1 − |q4| of the error to the final target, with the paper's bands."""
    if not c.events:
        return 'no fault in this run: the q4 bands of seed 000 are counted from the first fault'
    t0 = c.events[0][0]
    qe = error_quaternion(c.run.q, c.q_ref[-1] if c.q_ref is not None else c.run.q_ref)
    e = 1.0 - np.abs(qe[:, 3])
    fig, (ax,) = new_figure(height=3.6)
    shade_phases([ax], c.phases)
    ax.plot(*reduced(c.run.t, log_positive(e)), color='C0', label='1 − |q4| (to the final target)')
    ax.set_yscale('log')
    after = c.run.t >= t0
    for band, style, colour in ((0.02, '--', 'C1'), (0.01, ':', 'C3')):
        ax.axhline(band, color=colour, linestyle=style, linewidth=1, label=f'band 1 ± {band:g}')
        ts = settling_time(c.run.t[after], e[after], band)
        if math.isfinite(ts):
            ax.plot(ts, band, 'o', color=colour, label=f'ours: {ts - t0:.0f} s after t0')
        paper = _published(c, f'settling_q4_{band:g}_after_fault_s')
        if paper is not None:
            ax.plot(t0 + paper, band, 'x', color=colour, markersize=9, mew=2, label=f'paper: {paper:g} s after t0')
    floor = e[after & (e > 0)]
    if floor.size:   # the range after t0 (the three-wheel phase starts at the final target: 1 − |q4| ~ 0)
        ax.set_ylim(bottom=min(0.3 * float(floor.min()), 0.003))
    ax.set_ylabel('1 − |q4| (–, log)')
    ax.set_title('Scalar part of the error quaternion after the first fault: 1 − |q4| (seed 000\'s bands)')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, ('1 − |q4| of the error quaternion to the final target (log scale), with the paper\'s bands '
                 '1 ± 0.02 and 1 ± 0.01 (dashed, dotted); circles: the time after the fault t0 from which '
                 'ours stays in each band, crosses: the paper\'s (VI.A). Shaded: the three-wheel phase (the '
                 'planned slew away from the final target) and the two-wheel phase; red dashed: the fault.')


def fig_spin(c: Context):
    """Motion to spin: θ and ‖ω̃‖ as the law computes them, ‖ω‖ against ‖ω_d‖, |u| against the limit."""
    theta = status_array(c.run, ['theta'])
    w_err = status_array(c.run, ['w_err_x', 'w_err_y', 'w_err_z'])
    if theta is None or w_err is None:
        return 'the controller status has no `theta` and `w_err_x/y/z` (the spin errors of the M2S law)'
    fig, (ax_t, ax_w, ax_r, ax_u) = new_figure(rows=4, height=1.9)
    ax_t.plot(*reduced(theta[0], log_positive(theta[1][:, 0])), color='C0', label='θ')
    ax_t.axhline(SPIN_THETA_BAND_RAD, color='0.3', linestyle=':', label=f'{SPIN_THETA_BAND_RAD:g} rad')
    ax_w.plot(*reduced(w_err[0], log_positive(np.linalg.norm(w_err[1], axis=1))), color='C1', label='‖ω̃‖')
    ax_w.axhline(SPIN_RATE_BAND_RAD_S, color='0.3', linestyle=':', label=f'{SPIN_RATE_BAND_RAD_S:g} rad/s')
    for ax in (ax_t, ax_w):
        ax.set_yscale('log')
    w_d = vector(param_value(c.kind.params, 'target.rate'), 3)
    w_d = float(np.linalg.norm(w_d)) if w_d is not None else math.nan
    ax_r.plot(*reduced(c.run.t, np.linalg.norm(c.run.w, axis=1)), color='C0', label='‖ω‖')
    ax_r.axhline(w_d, color='k', linestyle='--', linewidth=1, label=f'‖ω_d‖ = {w_d:.4g} rad/s')
    if c.run.u.size:
        for i, a in enumerate('xyz'):
            step_plot(ax_u, c.run.t_u, c.run.u[:, i], c.run.t_end, **LINE[a], label=f'$u_{a}$')
        limits = vector(param_value(section_params((c.run.scenario or {}).get('dynamics')), 'torquers.max_torque'), 3)
        limit = float(np.max(limits)) if limits is not None else float(np.abs(c.run.u).max())
        for s in (1, -1):
            ax_u.axhline(s * limit, color='0.3', linestyle=':', linewidth=1, label='torque limit' if s > 0 else None)
        for i, a in enumerate('xyz'):
            paper = _published(c, f'steady_torque_{a}_Nm')
            if paper is not None:
                ax_u.plot(c.run.t_end, paper, 'x', color=LINE[a]['color'], markersize=9, mew=2,
                          label='paper: steady u (eq. 59)' if i == 0 else None)
    ax_t.set_ylabel('θ (rad, log)')
    ax_w.set_ylabel('‖ω̃‖ (rad/s, log)')
    ax_r.set_ylabel('‖ω‖ (rad/s)')
    ax_u.set_ylabel('u (N·m)')
    ax_t.set_title('Motion to spin: errors to the spinning target, spin rate, torque')
    mark_faults([ax_t, ax_w, ax_r, ax_u], c.events)
    for ax in (ax_t, ax_w, ax_r, ax_u):
        add_legend(ax)
    return fig, ('Motion to spin (seed 001 M2S): θ, the eigenaxis angle of R_d(t)ᵀR (rad, log), and ‖ω̃‖ = '
                 '‖ω − R̃ᵀω_d‖ (rad/s, log), as the law publishes them on `controller/status`; the body\'s '
                 '‖ω‖ against the commanded ‖ω_d‖; the applied torque (N·m) within the torquers\' limit'
                 + ('; crosses: the paper\'s steady torque.' if _published(c, 'steady_torque_x_Nm') is not None else '.'))


def fig_pointing(c: Context):
    """Single-axis pointing: the angle between σ̂ and τ̂ with Table 1's bands."""
    if c.run.pointing is None:
        return 'the scenario gives no pointing request (sigma, tau)'
    err = pointing_error_deg(c.run)
    fig, (ax,) = new_figure(height=3.6)
    shade_phases([ax], c.phases)
    ax.plot(*reduced(c.run.t, log_positive(err)), color='C0', label='pointing error ∠(σ̂, τ̂)')
    ax.set_yscale('log')
    for b, style in zip(POINTING_BANDS_DEG, ('--', '-.', ':')):
        ax.axhline(b, color='0.3', linestyle=style, linewidth=1)
        tf = first_entry_time(c.run.t, err, b)
        if math.isfinite(tf):
            ax.plot(tf, b, 'o', color='C3', markersize=5, label=f'{b:g}° reached at {tf:.0f} s')
    ax.set_ylabel('pointing error (deg, log)')
    ax.set_title('Single-axis pointing: angle between the body axis σ̂ and the direction τ̂')
    mark_faults([ax], c.events)
    add_legend(ax)
    return fig, ('Pointing error (deg, log scale): the angle between the body axis σ̂ and the inertial '
                 'direction τ̂ (the rotation about σ̂ is free), with Table 1\'s bands 1°, 0.1°, 0.01° and the '
                 'first time each is reached' + (' ; shaded: the controller\'s stages.' if c.phases else '.'))


EULER_NAMES = (('theta2_y', 0, r'$\theta_2$ (about y)'), ('theta1_x', 1, r'$\theta_1$ (about x)'),
               ('theta3_z', 2, r'$\theta_3$ (about z)'))


def fig_euler_settling(c: Context):
    """Seed 004: each 2-1-3 Euler angle of the error with the ±1° / ±0.5° bands, our settling times
    (circles) and the paper's (crosses, Table I), and all three within ±0.5° (III.F: verticals)."""
    _, _, euler = c.errors
    fig, axes = new_figure(rows=3, height=1.7)
    all_ours = _settling(c, 'euler_all', 0.5, c.run.t, np.abs(euler).max(axis=1))
    all_paper = _published(c, 'settling_euler213_all_0.5deg_s')
    for k, (ax, (name, i, label)) in enumerate(zip(axes, EULER_NAMES)):
        ax.plot(*reduced(c.run.t, log_positive(np.abs(euler[:, i]))), color='C0', label=f'|{label}|')
        ax.set_yscale('log')
        for band, colour in ((1.0, 'C1'), (0.5, 'C3')):
            ax.axhline(band, color=colour, linestyle=':', linewidth=1)
            ts = _settling(c, f'euler_{i}', band, c.run.t, np.abs(euler[:, i]))
            if math.isfinite(ts):
                ax.plot(ts, band, 'o', color=colour, label=f'ours ±{band:g}°: {ts:.1f} s')
            paper = _published(c, f'settling_euler213_{name}_{band:g}deg_s')
            if paper is not None:
                ax.plot(paper, band, 'x', color=colour, markersize=9, mew=2, label=f'paper ±{band:g}°: {paper:g} s')
        if math.isfinite(all_ours):
            ax.axvline(all_ours, color='C2', linestyle='-.', linewidth=1,
                       label=f'all three ±0.5°, ours: {all_ours:.1f} s' if k == 0 else None)
        if all_paper is not None:
            ax.axvline(all_paper, color='k', linestyle=(0, (1, 2)), linewidth=1.2,
                       label=f'all three ±0.5°, paper: {all_paper:g} s' if k == 0 else None)
        ax.set_ylim(bottom=max(ax.get_ylim()[0], 1e-4))  # below 1e-4 deg: numerical detail, not the paper's
        ax.set_ylabel('deg (log)')
        add_legend(ax)
    axes[0].set_title('2-1-3 Euler angles of the attitude error and their settling (seed 004 Table I, III.F)')
    mark_faults(axes, c.events, legend=False)
    return fig, ('Absolute 2-1-3 Euler angles of the attitude error (deg, log scale), one panel per angle, with '
                 'the ±1° and ±0.5° bands (dotted); circles: the time after which ours stays in the band, '
                 'crosses: the paper\'s (Table I) where it gives one; verticals: all three angles within ±0.5° '
                 '(dash-dot ours, fine dotted the paper\'s, III.F).')


# (file name, title, builder) per kind, in the order the report shows them
LEAD_FIGURES = {
    'regulation': [('attitude_error', 'Attitude error to the reference', fig_reference_error),
                   ('euler_settling', '2-1-3 Euler angles and their settling', fig_euler_settling)],
    'regulation_after_fault': [('attitude_error', 'Attitude error to the reference', fig_reference_error),
                               ('q4_bands', '1 − |q4| with the paper\'s bands', fig_q4_bands)],
    'tracking': [('attitude_error', 'Tracking error to the orbit-defined target', fig_reference_error)],
    'spin': [('spin', 'Spin errors, rate and torque', fig_spin)],
    'pointing': [('pointing_error', 'Pointing error', fig_pointing)],
}
