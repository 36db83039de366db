"""Basilisk child of benchmarks/plant_step.py (runs in the throwaway bsk venv, not the project's).

A rigid hub with three reaction wheels on its principal axes (Basilisk's spacecraft +
reactionWheelStateEffector, RK4 integrator), constant motor torques from a stand-alone message;
``steps`` integration steps of ``h`` seconds timed around ``ExecuteSimulation``. Prints one JSON
line: {"us_per_step": ..., "steps": ...}.
"""
import json
import sys
import time

from Basilisk.architecture import messaging
from Basilisk.simulation import reactionWheelStateEffector, spacecraft, svIntegrators
from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW


def build(inertia, h):
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess('dyn')
    proc.addTask(sim.CreateNewTask('task', macros.sec2nano(h)))
    sc = spacecraft.Spacecraft()
    sc.hub.mHub = 100.0
    sc.hub.IHubPntBc_B = [[inertia[0], 0.0, 0.0], [0.0, inertia[1], 0.0], [0.0, 0.0, inertia[2]]]
    sc.hub.sigma_BNInit = [[0.1], [0.2], [-0.1]]
    sc.hub.omega_BN_BInit = [[0.01], [-0.02], [0.03]]
    factory = simIncludeRW.rwFactory()
    for axis in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        factory.create('custom', axis, Omega=100.0, Js=0.01, u_max=0.02, Omega_max=5000.0)
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    factory.addToSpacecraft('wheels', wheels, sc)
    sc.setIntegrator(svIntegrators.svIntegratorRK4(sc))
    payload = messaging.ArrayMotorTorqueMsgPayload()
    payload.motorTorque = [0.01, -0.005, 0.002]
    cmd = messaging.ArrayMotorTorqueMsg().write(payload)
    wheels.rwMotorCmdInMsg.subscribeTo(cmd)
    sim.AddModelToTask('task', wheels, 2)
    sim.AddModelToTask('task', sc, 1)
    sim.InitializeSimulation()
    return sim, (cmd, wheels, sc, factory)


def main() -> None:
    args = json.loads(sys.argv[1])
    h, steps = float(args['h']), int(args['steps'])
    sim, keep = build(args['inertia'], h)
    sim.ConfigureStopTime(macros.sec2nano(h * 10))
    sim.ExecuteSimulation()  # warm up
    t0 = time.perf_counter()
    sim.ConfigureStopTime(macros.sec2nano(h * (10 + steps)))
    sim.ExecuteSimulation()
    dt = time.perf_counter() - t0
    print(json.dumps({'us_per_step': 1e6 * dt / steps, 'steps': steps}))


if __name__ == '__main__':
    main()
