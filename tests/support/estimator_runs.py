"""Estimator runs the estimation tests and the figures of docs/determination.md share: a bag of one
MEKF run as the recorder would hold it (:func:`write_run_bag`) and the batch engine flying the PD slew
on an MEKF (:func:`batch`), its sensors the test source :class:`support.estimation_truth.StateSensors`."""
from __future__ import annotations

import numpy as np
from support.estimation_truth import StateSensors, Truth, perturbed
from support.scenarios import make_scenario

from adcs_controllers.estimators.families import MEKF
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.files import validate_scenario

OMEGA = np.array([0.01, -0.02, 0.005])
SECTION = {'gyro.sigma_v': 1e-5, 'gyro.sigma_u': 1e-7, 'star_tracker.sigma': [1e-4] * 3,
           'initial.attitude_sigma': [0.01] * 3, 'initial.bias_sigma': [1e-4] * 3}


def write_run_bag(path, steps=200):
    """A bag of one estimator run as the recorder would hold it: estimate/state and estimator/status
    from the MEKF family on its own truth, truth/state from that truth. Returns the family's outputs."""
    from rclpy.serialization import serialize_message

    from adcs_msgs_py import conversions as cv
    from adcs_msgs_py import conversions_determination as cd
    from adcs_sim.bag.writer import BagWriter
    q0 = np.array([[0.2, 0.1, -0.3, 0.9]]) / np.linalg.norm([0.2, 0.1, -0.3, 0.9])
    truth = Truth(1, 4, 1.0, OMEGA, 1e-5, 1e-7, q0=q0, beta0=[1e-4, -2e-4, 5e-5], batch=False)
    est = MEKF.build(MEKF.schema.validate({**SECTION, 'initial.attitude': list(perturbed(q0, np.array([[0.01, 0.0, -0.01]]))[0])}))
    bag = BagWriter(path)
    for name, type_name in (('/estimate/state', 'nav_msgs/msg/Odometry'), ('/truth/state', 'nav_msgs/msg/Odometry'),
                            ('/estimator/status', 'diagnostic_msgs/msg/DiagnosticArray')):
        bag.add_topic(name, type_name, [])
    out = []
    for _ in range(steps):
        q_true, beta = truth.q_true[0], truth.beta[0].copy()
        m = truth.step()
        e, status = est.step(m)
        bag.write('/truth/state', serialize_message(cv.state_to_msg(m.t_ns, q_true, OMEGA)))
        bag.write('/estimate/state', serialize_message(cd.estimate_to_msg(e)))
        values = {k: (v.item() if isinstance(v, np.ndarray | np.generic) else v) for k, v in status.items()}
        bag.write('/estimator/status', serialize_message(cv.status_to_msg(m.t_ns, 'mekf_estimator', values)))
        out.append((e, status, q_true, beta))
    bag.close()
    return out


Q0 = [0.3062, 0.1768, 0.1768, 0.9186]
SIGMA_V, SIGMA_U, SIGMA_ST = 1e-5, 1e-7, 1e-4
BIAS0 = np.radians([0.1, -0.05, 0.08])     # a 0.1 deg/s-class gyro bias
# StateSensors' gyro samples the rate at t_k (an instantaneous sample, not the truth model's
# rate-integrating gyro): the trapezoidal rule is the propagation that fits it.
MEKF_SECTION = {'sensors': ['gyro', 'star_tracker'], 'gyro.propagation': 'average', 'gyro.sigma_v': SIGMA_V, 'gyro.sigma_u': SIGMA_U,
                'star_tracker.sigma': [SIGMA_ST] * 3, 'initial.attitude': Q0,
                'initial.attitude_sigma': [0.05] * 3, 'initial.bias_sigma': [0.003] * 3}


def batch(tmp_path, n_runs=1, duration=300.0, feedback='estimate', seeds=None, **over):
    # the dynamics section fits the sensors the estimator uses (the scenario check); the test source
    # StateSensors stands in for their readings
    scenario = make_scenario(tmp_path, {'dynamics': {'duration': duration, 'sensors.gyro.enabled': True,
                                                     'sensors.star_tracker.enabled': True},
                                        'mekf_estimator': {**MEKF_SECTION, **over},
                                        'pd_controller': {'feedback': feedback}})
    v = validate_scenario(scenario)
    runs = [{name: NODES[name].schema.validate(p) for name, p in v.items()} for _ in range(n_runs)]
    seeds = list(range(n_runs)) if seeds is None else seeds
    return BatchSimulation.from_runs(runs, StateSensors(seeds, 1.0, SIGMA_V, SIGMA_U, SIGMA_ST, BIAS0))
