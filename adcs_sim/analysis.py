"""Run metrics: numpy in, numbers out, and the extraction of a run's time series from a bag.

Definitions (every metric printed by ``adcs-run`` and ``adcs-analyze``):

* **Attitude error** is the true attitude relative to the controller's target (identity unless
  the bag's scenario gives ``target.attitude``): ``q_e = q_ref* ⊗ q``. The *eigenaxis error* is
  its rotation angle ``2 atan2(|q_e,v|, |q_e,4|)``; the *2-1-3 Euler errors* are the three angles
  of ``q_e`` in the 2-1-3 sequence (scipy ``'YXZ'``), as seed 004 measures its settling time.
* **Settling time** to a tolerance: the time after which the error stays inside the band to the
  end of the record (*last exit*, not first entry), linearly interpolated between the last
  sample outside and the first inside; 0 if always inside; ``inf`` if the run ends outside. For
  Euler angles the band must hold on all three axes at once (the max of the absolute angles).
* **Integrated torque** ``∫‖u‖ dt`` and **control energy** ``∫uᵀu dt`` of the applied body
  torque ``u`` (``actuators/torque``): the torque is held over each control period (zero-order
  hold), so the integrals are exact sums ``Σ ‖u_k‖ Δt_k`` with ``Δt_k`` the time to the next
  sample (the last one up to the end of the run). ``‖·‖`` is the Euclidean norm.
* **Peak torque** per body axis ``max |u_i|``; **peak wheel speed** ``max |Ω|`` over all wheels
  (rad/s, relative to the body); **missed steps** from the final ``dynamics/status``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import yaml

from adcs_msgs_py import names as topics
from adcs_sim import bag as bagio
from adcs_sim.attitude import eigenaxis_angle, error_quaternion, euler_213

NS = 1e-9


# --- metrics on arrays ------------------------------------------------------------------------

def settling_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """Time after which ``error`` stays ``<= tol`` to the end (last exit, interpolated)."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(error, dtype=float)
    outside = np.flatnonzero(e > tol)
    if outside.size == 0:
        return float(t[0]) if t.size else math.nan
    i = outside[-1]
    if i == e.size - 1:
        return math.inf
    e0, e1 = e[i], e[i + 1]
    return float(t[i] + (e0 - tol) / (e0 - e1) * (t[i + 1] - t[i]))


def first_entry_time(t: np.ndarray, error: np.ndarray, tol: float) -> float:
    """First time ``error`` reaches ``tol`` (interpolated); ``inf`` if never."""
    e = np.asarray(error, dtype=float)
    inside = np.flatnonzero(e <= tol)
    if inside.size == 0:
        return math.inf
    i = inside[0]
    if i == 0:
        return float(t[0])
    e0, e1 = e[i - 1], e[i]
    return float(t[i - 1] + (e0 - tol) / (e0 - e1) * (t[i] - t[i - 1]))


def zoh_durations(t: np.ndarray, t_end: float) -> np.ndarray:
    """Hold durations of samples at ``t`` (to the next sample, the last to ``t_end``)."""
    t = np.asarray(t, dtype=float)
    return np.diff(np.append(t, max(t_end, t[-1]))) if t.size else t


def integrated_norm(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫‖u‖ dt`` of a zero-order-held signal ``u`` (N, k) sampled at ``t``."""
    return float(np.sum(np.linalg.norm(u, axis=-1) * zoh_durations(t, t_end)))


def integrated_square(t: np.ndarray, u: np.ndarray, t_end: float) -> float:
    """``∫uᵀu dt`` of a zero-order-held signal ``u`` (N, k) sampled at ``t``."""
    return float(np.sum(np.sum(np.asarray(u) ** 2, axis=-1) * zoh_durations(t, t_end)))


# --- a run's time series -------------------------------------------------------------------

@dataclass
class RunData:
    """Time series of one run, as recorded (seconds, SI units)."""

    t: np.ndarray                      # state stamps
    q: np.ndarray                      # (N, 4) true attitude
    w: np.ndarray                      # (N, 3) true body rate
    t_u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    t_wheels: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wheel_names: list = field(default_factory=list)
    wheel_speed: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    wheel_torque: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    missed_steps: int | None = None
    q_ref: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    scenario: dict | None = None

    @property
    def t_end(self) -> float:
        return float(self.t[-1]) if self.t.size else 0.0

    @classmethod
    def from_bag(cls, path) -> 'RunData':
        """Read a bag of the graph (complete or truncated) into arrays."""
        ns = None
        want = {topics.STATE, topics.TRUTH_STATE, topics.APPLIED_TORQUE, topics.WHEELS_STATE,
                topics.DYNAMICS_STATUS}
        state, truth, torque, wheels, missed = [], [], [], [], None
        names: list = []
        for topic, _, msg in bagio.read_messages(path):
            # Topics may be namespaced (/sat1/state): match on the name relative to the namespace.
            if ns is None and topic.endswith('/' + topics.STATE):
                ns = topic[:-len(topics.STATE)]
            rel = topic[len(ns):] if ns and topic.startswith(ns) else topic.lstrip('/')
            if rel not in want:
                continue
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * NS
            if rel in (topics.STATE, topics.TRUTH_STATE):
                o, a = msg.pose.pose.orientation, msg.twist.twist.angular
                (state if rel == topics.STATE else truth).append((stamp, o.x, o.y, o.z, o.w, a.x, a.y, a.z))
            elif rel == topics.APPLIED_TORQUE:
                v = msg.vector
                torque.append((stamp, v.x, v.y, v.z))
            elif rel == topics.WHEELS_STATE:
                names = list(msg.name)
                wheels.append((stamp, *msg.velocity, *msg.effort))
            else:
                for status in msg.status:
                    for kv in status.values:
                        if kv.key == 'missed_steps':
                            missed = int(float(kv.value))
        rows = np.array(truth or state, dtype=float).reshape(-1, 8)
        if rows.shape[0] == 0:
            raise ValueError(f'{path}: no {topics.STATE} messages: not a run of the graph')
        run = cls(t=rows[:, 0], q=rows[:, 1:5], w=rows[:, 5:8], missed_steps=missed)
        if torque:
            arr = np.array(torque, dtype=float)
            run.t_u, run.u = arr[:, 0], arr[:, 1:4]
        if wheels:
            arr = np.array(wheels, dtype=float)
            n = len(names)
            run.t_wheels, run.wheel_names = arr[:, 0], names
            run.wheel_speed, run.wheel_torque = arr[:, 1:1 + n], arr[:, 1 + n:1 + 2 * n]
        scenario_text = bagio.read_metadata(path).get('scenario')
        if scenario_text:
            run.scenario = yaml.safe_load(scenario_text)
            run.q_ref = target_attitude(run.scenario)
        return run


def target_attitude(scenario: dict) -> np.ndarray:
    """The regulation target of a scenario: a controller section's ``target.attitude``, or identity."""
    for name, section in (scenario or {}).items():
        params = (section or {}).get('ros__parameters') or {}
        target = (params.get('target') or {}).get('attitude') if isinstance(params, dict) else None
        if target is not None and str(name).lstrip('/') != 'dynamics':
            q = np.asarray(target, dtype=float)
            return q / np.linalg.norm(q)
    return np.array([0.0, 0.0, 0.0, 1.0])


def run_metrics(run: RunData, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
    """The run's metrics (see the module docstring for each definition)."""
    eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
    qe = error_quaternion(run.q, run.q_ref)
    eigen = np.degrees(eigenaxis_angle(qe))
    euler = np.degrees(np.abs(euler_213(qe)))
    out = {
        'duration_s': run.t_end,
        f'settling_eigenaxis_{eigen_tol_deg:g}deg_s': settling_time(run.t, eigen, eigen_tol_deg),
        f'settling_euler213_{tol_deg:g}deg_s': settling_time(run.t, euler.max(axis=1), tol_deg),
        'settling_euler213_per_axis_s': [settling_time(run.t, euler[:, i], tol_deg) for i in range(3)],
        'final_eigenaxis_error_deg': float(eigen[-1]),
        'integrated_torque_Nms': math.nan, 'control_energy_N2m2s': math.nan,
        'peak_torque_Nm': [math.nan] * 3, 'peak_wheel_speed_rad_s': math.nan,
        'missed_steps': run.missed_steps,
    }
    if run.u.size:
        out['integrated_torque_Nms'] = integrated_norm(run.t_u, run.u, run.t_end)
        out['control_energy_N2m2s'] = integrated_square(run.t_u, run.u, run.t_end)
        out['peak_torque_Nm'] = np.abs(run.u).max(axis=0).tolist()
    if run.wheel_speed.size:
        out['peak_wheel_speed_rad_s'] = float(np.abs(run.wheel_speed).max())
    return out


def format_metrics(metrics: dict) -> str:
    """Human-readable table of :func:`run_metrics`."""
    def fmt(v):
        if isinstance(v, list):
            return '[' + ', '.join(fmt(x) for x in v) + ']'
        if isinstance(v, float):
            return f'{v:.6g}'
        return str(v)
    width = max(len(k) for k in metrics)
    return '\n'.join(f'  {k:<{width}}  {fmt(v)}' for k, v in metrics.items())
