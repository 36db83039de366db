"""The two step objects of issue 32 (adcs_sim/truth/step.py, adcs_controllers/step.py): one run is a
batch of one, bit for bit, and the fault rule ("the latest snapshot stamped <= t_k, once") is the
FaultTracker's for both, whether it is fed off the wire snapshot by snapshot or given the schedule."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from adcs_controllers.step import EstimationStep, FlightStep
from adcs_core.faults import FaultState, FaultTracker
from adcs_msgs_py.measurements import received_attitude
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.truth.step import TruthStep

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def sections(name: str) -> dict:
    raw = load_params_file(str(CONFIG / name))
    return {s: NODES[s].schema.validate(p) for s, p in raw.items() if s in NODES}


def test_schedule_held_or_received_gives_the_same_snapshots_at_the_same_steps():
    """Snapshots stamped 0, 1.5 s and 3 s; steps every second: the 1.5 s one applies at 2 s (not at
    1 s), each once, the same for a tracker given the schedule and one fed in any arrival order."""
    a, b = {'w': FaultState('failed', 0.0, 1.5)}, {'w': FaultState('recovered', 0.0, 3.0)}
    schedule = [(0, {'w': FaultState('nominal')}), (1_500_000_000, a), (3_000_000_000, b)]
    held, wire = FaultTracker(), FaultTracker()
    held.hold(schedule)
    for i in (2, 0, 1):   # off the wire, out of order, before t = 0
        wire.add(schedule[i][0], i, 3, schedule[i][1])
    for tracker in (held, wire):
        got = [tracker.due(k * 1_000_000_000) for k in range(5)]
        assert got == [schedule[0][1], None, a, b, None]
        assert tracker.late == 0
    held.rewind()
    assert held.due(2_000_000_000) == a   # a new run: the snapshot due then, nothing before


def test_truth_step_alone_is_the_batch_of_one():
    """uosat12_gsmn's truth model with state noise (and its fault schedule): five steps of the
    node's object (scalar seeds) and of a batch of one give the same bits."""
    s = sections('uosat12_gsmn.yaml')
    d = {**s['dynamics'], 'noise.attitude_std': 1e-4, 'noise.rate_std': 1e-5, 'noise.seed': 7}
    schedule = [(0, {}), (2_000_000_000, {'rw_z': FaultState('failed', 0.0, 2.0)})]
    one, batch = TruthStep(d, warm=False), TruthStep(d, n_runs=1, warm=False)
    for step in (one, batch):
        step.add_schedule(schedule)
    x1, xb = one.initial_state(), batch.initial_state()
    assert_array_equal(x1, xb[0])
    rng = np.random.default_rng(3)
    for k in range(5):
        t = k * one.period
        applied = one.apply_due_faults(k * one.period_ns), batch.apply_due_faults(k * one.period_ns)
        assert (applied[0] is None) == (applied[1] is None) == (k != 0 and k != 2)
        (q1, w1, _), (qb, wb, _) = one.measure(k, t, x1), batch.measure(k, t, xb)
        assert_array_equal(q1, qb[0])
        assert_array_equal(w1, wb[0])
        torque = rng.uniform(-0.01, 0.01, one.wheels.count)
        c1, cb = one.plant.zero_commands(), batch.plant.zero_commands()
        c1['wheels'] = one.wheels.command_from(torque, np.zeros(one.wheels.count, bool))
        cb['wheels'] = batch.wheels.command_from(torque[None], np.zeros((1, one.wheels.count), bool))
        (x1, u1), (xb, ub) = one.integrate(t, x1, c1), batch.integrate(t, xb, cb)
        assert_array_equal(x1, xb[0])
        assert_array_equal(u1, ub[0])
        assert one.failure(t, x1, u1) is None
    assert list(one.wheels.modes) == list(batch.wheels.modes) and 'failed' in one.wheels.modes


def test_flight_step_one_run_is_the_batch_of_one():
    """uosat12_gsmn's controller: the node's call on the decoded (received) attitude and the batch's
    call on the sent one give the same commands, through the wheel failure at 500 s."""
    s = sections('uosat12_gsmn.yaml')
    name = next(n for n in s if NODES[n].role == 'controller')
    family = NODES[name].family
    one, batch = FlightStep.build(name, family, s[name]), FlightStep.build(name, family, s[name])
    schedule = [(0, {}), (500_000_000_000, {'rw_z': FaultState('failed', 0.0, 500.0)})]
    one.faults.hold(schedule)
    batch.faults.hold(schedule)
    rng = np.random.default_rng(5)
    for t_ns in (0, 499_000_000_000, 500_000_000_000, 501_000_000_000):
        q = rng.normal(size=4)
        q *= (1.0 + 1e-9) / np.sqrt(q @ q)   # sent slightly off unit norm
        w = rng.normal(scale=0.01, size=3)
        a = one.step(t_ns, received_attitude(q), w)
        b = batch.step(t_ns, q[None], w[None], batch=True)
        assert a.output == b.output
        assert_array_equal(np.asarray(a.values), np.asarray(b.values)[0])
    assert one.actuation.usable() == batch.actuation.usable() and 'rw_z' not in one.actuation.usable()


@pytest.mark.parametrize('bad', [np.nan, np.inf])
def test_truth_step_names_a_non_finite_state(bad):
    s = sections('microsat_pd_slew.yaml')
    step = TruthStep(s['dynamics'], warm=False)
    x = step.initial_state()
    x[5] = bad
    text = step.failure(0.0, x, np.zeros(3))
    assert text.startswith(f'the plant state is no longer finite at t = {step.period:g} s') and 'rate' in text


def test_estimation_step_makes_the_message_round_trip_only_for_a_batch():
    """A star tracker quaternion sent off unit norm reaches the estimator normalised, as its message
    would; a decoded reading is taken as it is."""
    seen = []

    class Probe:
        def step(self, m):
            seen.append(m.star_tracker.value.copy())
            from adcs_msgs_py.measurements import Estimate
            n = m.star_tracker.value.shape[:-1]
            return Estimate(m.t_ns, m.star_tracker.value, np.zeros(n + (3,)), np.zeros(n + (3,)),
                            np.zeros(n + (6, 6)), np.zeros(n + (3, 3))), {}

    from adcs_msgs_py.measurements import Measurements, Reading
    q = np.array([[0.1, 0.2, 0.3, 0.9]])
    m = Measurements(0, star_tracker=Reading(q, np.zeros((1, 3, 3)), np.array([True])))
    step = EstimationStep('probe', Probe())
    step.step(m, batch=True)
    step.step(m)
    assert_array_equal(seen[0], received_attitude(q))
    assert_array_equal(seen[1], q)
