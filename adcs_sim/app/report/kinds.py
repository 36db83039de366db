"""What kind of run a bag holds, the reference its controller follows and the phases of the run.

A run's *kind* (:data:`adcs_controllers.families.RUN_KINDS`) is declared by its controller family
(``ControllerFamily.kind``): ``regulation`` (rest to rest; seed 000, seed 004, seed 001 M2R),
``tracking`` (an orbit-defined target; seed 002), ``spin`` (motion to spin; seed 001 M2S with a
non-zero ``target.rate``), ``pointing`` (one body axis at an inertial direction; seed 003). A bag
without a scenario, or whose scenario has no section of a known controller family, is
``unknown``: its report says so and shows the generic figures only.

The *reference* is the attitude the controller is asked to reach at each state sample: the
section's ``target.attitude``; for seed 000's three-wheel phase, that phase's own target (the
planned slew away from the identity) while the controller's status says ``phase: three_wheel``;
for seed 002 the target relative to the orbit frame (tracked until ``reference.hold_time``, then
held inertially), through the law's own :class:`~adcs_controllers.laws.backstepping.OrbitReference`.
A spin or a pointing run has no fixed attitude reference (None).

*Phases* are intervals ``(t0, t1, label)`` from the controller's status (``phase`` of the
two-wheel laws, ``mode`` of the pointing laws: stage 1 / LQR / B) and, for tracking, the hold
time. No matplotlib here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adcs_controllers.families import FAMILIES, RUN_KINDS
from adcs_controllers.laws.backstepping import OrbitReference
from adcs_core.orbit import CircularOrbit
from adcs_sim.app.analysis.run_data import RunData
from adcs_sim.app.analysis.status_records import status_column, texts

UNKNOWN = 'unknown'
# The status key whose text value names the run's phases, per kind.
PHASE_KEYS = {'regulation': 'phase', 'pointing': 'mode'}
PHASE_NAMES = {'three_wheel': 'three wheels: PD slew to the phase\'s target', 'two_wheel': 'two wheels',
               'unsupported': 'unsupported wheel set', 'A1_momentum': 'A, stage 1 (momentum)',
               'A2_lqr': 'A, stage 2 (LQR)', 'B': 'controller B'}


@dataclass
class RunKind:
    kind: str                       # a key of RUN_KINDS, or UNKNOWN
    why: str                        # how the kind was found (one line)
    controller: str | None = None   # the controller section
    params: dict = field(default_factory=dict)  # its ros__parameters

    @property
    def description(self) -> str:
        """The kind's one line, without a leading repeat of its name (the report prints the name before it)."""
        text = RUN_KINDS.get(self.kind, 'unknown: the report cannot tell what the run is meant to do')
        return text.removeprefix(f'{self.kind}: ')


def section_params(section) -> dict:
    params = (section or {}).get('ros__parameters') if isinstance(section, dict) else None
    return params if isinstance(params, dict) else {}


def param_value(params: dict, dotted: str, default=None):
    """``a.b.c`` of a parameters tree written nested (YAML) or flat (``a.b.c:``)."""
    if dotted in params:
        return params[dotted]
    node = params
    for part in dotted.split('.'):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node


def run_kind(scenario: dict | None) -> RunKind:
    """The kind of a run from its scenario's controller section (:data:`FAMILIES`)."""
    if not isinstance(scenario, dict):
        return RunKind(UNKNOWN, 'the bag carries no scenario (no MCAP metadata `scenario`)')
    for name, section in scenario.items():
        family = FAMILIES.get(str(name).lstrip('/'))
        if family is None:
            continue
        params = section_params(section)
        kind = family.kind
        why = f'controller `{family.node}` (family kind `{kind}`)'
        if kind == 'spin':
            rate = vector(param_value(params, 'target.rate'), 3)
            if rate is not None and not np.any(rate):
                kind, why = 'regulation', f'controller `{family.node}` with a zero target.rate (motion to rest)'
        return RunKind(kind, why, family.node, params)
    names = ', '.join(f'`{n}`' for n in scenario) or 'none'
    return RunKind(UNKNOWN, f'no section of a known controller family in the scenario (sections: {names})')


def vector(value, n: int) -> np.ndarray | None:
    """``value`` as a finite float vector of length ``n``, or None (absent, malformed)."""
    try:
        v = np.asarray(value, dtype=float).reshape(n)
    except (TypeError, ValueError):
        return None
    return v if np.all(np.isfinite(v)) else None


def _unit(q) -> np.ndarray | None:
    q = vector(q, 4)
    if q is None:
        return None
    n = np.linalg.norm(q)
    return q / n if np.isfinite(n) and n > 0 else None


def held_text(run: RunData, key: str) -> np.ndarray | None:
    """The controller's status value ``key`` held (zero-order) at each state sample, or None."""
    _, ts, raw = status_column(run.controller_status, key)
    if not ts.size:
        return None
    vs = texts(raw)
    k = np.clip(np.searchsorted(ts, run.t, side='right') - 1, 0, ts.size - 1)
    return vs[k]


def reference_attitude(run: RunData, rk: RunKind) -> tuple[np.ndarray | None, str]:
    """(q_ref (N, 4) at the state samples, one-line description); (None, why) without one."""
    if rk.kind == 'pointing':
        where = (f'body axis σ̂ = {_fmt_q(run.pointing[0])} toward the inertial τ̂ = {_fmt_q(run.pointing[1])}; '
                 if run.pointing is not None else '')
        return None, where + 'no fixed attitude target (the rotation about σ̂ is free)'
    if rk.kind == 'spin':
        rate = vector(param_value(rk.params, 'target.rate'), 3)
        spin = f'spin at ω_d = {_fmt_q(rate)} rad/s (target.rate), ' if rate is not None else ''
        return None, spin + 'R_d(t) = R_d(0) exp(ω_d t) from target.attitude: no fixed attitude target'
    if rk.kind == 'tracking':
        return _orbit_reference(run, rk)
    target = _unit(param_value(rk.params, 'target.attitude', [0.0, 0.0, 0.0, 1.0]))
    target = run.q_ref if target is None else target
    q_ref = np.broadcast_to(target, (run.t.size, 4)).copy()
    text = f'q_ref = {_fmt_q(target)} (target.attitude)'
    slew = _unit(param_value(rk.params, 'three_wheel.target.attitude')) if param_value(rk.params, 'three_wheel.enabled') else None
    phase = held_text(run, 'phase')
    if slew is not None and phase is not None:
        three = phase == 'three_wheel'
        q_ref[three] = slew
        text = (f'q_ref = {_fmt_q(slew)} in the three-wheel phase (three_wheel.target.attitude: the planned '
                f'slew), then {_fmt_q(target)} (target.attitude)')
    return q_ref, text


def _orbit_reference(run: RunData, rk: RunKind) -> tuple[np.ndarray | None, str]:
    p = rk.params
    try:
        orbit = CircularOrbit(altitude=float(param_value(p, 'orbit.altitude')),
                              inclination=math.radians(float(param_value(p, 'orbit.inclination_deg', 0.0))),
                              raan=math.radians(float(param_value(p, 'orbit.raan_deg', 0.0))),
                              arg_latitude0=math.radians(float(param_value(p, 'orbit.arg_latitude_deg', 0.0))))
        q_rel = _unit(param_value(p, 'target.attitude', [0.0, 0.0, 0.0, 1.0]))
        hold = float(param_value(p, 'reference.hold_time', 0.0))
        if q_rel is None or not orbit.altitude > 0:
            raise ValueError('target.attitude or orbit.altitude malformed')
    except (TypeError, ValueError) as exc:
        return None, f'none: the orbit reference of the controller section cannot be read ({exc})'
    ref = OrbitReference(orbit, q_rel, None if math.isinf(hold) else hold)
    q_ref = np.array([ref(float(t))[0] for t in run.t]).reshape(-1, 4)
    rel = f'{_fmt_q(q_rel)} (target.attitude, relative to the orbit frame q_io)'
    if math.isinf(hold):
        return q_ref, f'q_d(t) = q_io(t) ⊗ {rel}, tracked for ever'
    if hold == 0:
        return q_ref, f'q_d = q_io(0) ⊗ {rel}: the orbit frame at t = 0, held inertially (reference.hold_time 0)'
    return q_ref, f'q_d(t) = q_io(t) ⊗ {rel} until t = {hold:g} s (reference.hold_time), then held inertially'


def _fmt_q(q) -> str:
    return '[' + ', '.join(f'{v:.4g}' for v in q) + ']'


def phases(run: RunData, rk: RunKind) -> list[tuple[float, float, str]]:
    """(t0, t1, label) of the run's phases (the controller's status); [] when it has none."""
    key = PHASE_KEYS.get(rk.kind)
    out: list[tuple[float, float, str]] = []
    values = held_text(run, key) if key else None
    if values is not None and run.t.size:
        change = np.flatnonzero(values[1:] != values[:-1]) + 1
        starts = np.r_[0, change]
        ends = np.r_[change, run.t.size - 1]
        out = [(float(run.t[a]), float(run.t[b]), PHASE_NAMES.get(values[a], str(values[a])))
               for a, b in zip(starts, ends)]
    if rk.kind == 'tracking':
        hold = vector(param_value(rk.params, 'reference.hold_time', 0.0), 1)
        if hold is not None and 0 < hold[0] < run.t_end:
            hold = float(hold[0])
            out = [(0.0, hold, 'target fixed in the orbit frame'), (hold, run.t_end, 'target held inertially')]
    return out if len(out) > 1 else []  # one phase for the whole run: nothing to mark
