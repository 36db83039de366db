"""Basilisk child of benchmarks/montecarlo_speed.py (runs in the throwaway bsk venv only).

The PD slew of ``config/microsat_pd_slew.yaml`` in Basilisk, one run after another: hub with
three reaction wheels (RK4, the scenario's integration step), simpleNav, attTrackingError to the
identity, mrpFeedback (PD, no integral term) and rwMotorTorque at the control period, for the
scenario's duration. Each run is built, initialised and executed (what a campaign of separate
Basilisk runs does); prints one JSON line {"s_per_run": ..., "cpu_s_per_run": ..., "runs": ...} (wall and CPU time).
"""
import json
import sys
import time

from Basilisk.architecture import messaging
from Basilisk.fswAlgorithms import attTrackingError, mrpFeedback, rwMotorTorque
from Basilisk.simulation import reactionWheelStateEffector, simpleNav, spacecraft, svIntegrators
from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW


def dynamics(sim, a, sigma0):
    sc = spacecraft.Spacecraft()
    sc.hub.mHub = 50.0
    J = a['inertia']
    sc.hub.IHubPntBc_B = [[J[0], 0.0, 0.0], [0.0, J[1], 0.0], [0.0, 0.0, J[2]]]
    sc.hub.sigma_BNInit = [[v] for v in sigma0]
    factory = simIncludeRW.rwFactory()
    for axis in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        factory.create('custom', axis, Omega=0.0, Js=a['spin_inertia'], u_max=a['max_torque'],
                       Omega_max=a['max_speed'] * 60.0 / (2.0 * 3.141592653589793))
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    factory.addToSpacecraft('wheels', wheels, sc)
    sc.setIntegrator(svIntegrators.svIntegratorRK4(sc))
    sim.AddModelToTask('dyn', wheels, 2)
    sim.AddModelToTask('dyn', sc, 1)
    return sc, wheels, factory


def one_run(a, sigma0):
    sim = SimulationBaseClass.SimBaseClass()
    sim.CreateNewProcess('p').addTask(sim.CreateNewTask('dyn', macros.sec2nano(a['max_step'])))
    sim.CreateNewProcess('f').addTask(sim.CreateNewTask('fsw', macros.sec2nano(a['period'])))
    sc, wheels, factory = dynamics(sim, a, sigma0)
    nav = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    ref = messaging.AttRefMsg().write(messaging.AttRefMsgPayload())
    err = attTrackingError.attTrackingError()
    err.attNavInMsg.subscribeTo(nav.attOutMsg)
    err.attRefInMsg.subscribeTo(ref)
    veh = messaging.VehicleConfigMsgPayload()
    veh.ISCPntB_B = [v for row in ([a['inertia'][0], 0, 0], [0, a['inertia'][1], 0], [0, 0, a['inertia'][2]])
                     for v in row]
    veh_msg = messaging.VehicleConfigMsg().write(veh)
    rw_params = factory.getConfigMessage()
    pd = mrpFeedback.mrpFeedback()
    pd.K, pd.Ki, pd.P = a['K'], -1.0, a['P']
    pd.guidInMsg.subscribeTo(err.attGuidOutMsg)
    pd.vehConfigInMsg.subscribeTo(veh_msg)
    pd.rwParamsInMsg.subscribeTo(rw_params)
    pd.rwSpeedsInMsg.subscribeTo(wheels.rwSpeedOutMsg)
    alloc = rwMotorTorque.rwMotorTorque()
    alloc.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    alloc.rwParamsInMsg.subscribeTo(rw_params)
    alloc.vehControlInMsg.subscribeTo(pd.cmdTorqueOutMsg)
    wheels.rwMotorCmdInMsg.subscribeTo(alloc.rwMotorTorqueOutMsg)
    for model in (nav, err, pd, alloc):
        sim.AddModelToTask('fsw', model)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(a['duration']))
    sim.ExecuteSimulation()
    return sc.scStateOutMsg.read().sigma_BN


def main() -> None:
    a = json.loads(sys.argv[1])
    one_run(a, a['sigma0'][0])  # warm up (imports, first allocations)
    t0, c0 = time.perf_counter(), time.process_time()
    final = [one_run(a, sigma0) for sigma0 in a['sigma0']]
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    worst = max(sum(v * v for v in s) ** 0.5 for s in final)
    print(json.dumps({'s_per_run': dt / len(a['sigma0']), 'cpu_s_per_run': cpu / len(a['sigma0']),
                      'runs': len(a['sigma0']), 'final_mrp_norm_max': worst}))


if __name__ == '__main__':
    main()
