"""adcs_sim: the plant, the simulated clock and the tooling around the ROS graph.

* :mod:`adcs_sim.plant`, :mod:`adcs_sim.attitude` — rigid body, actuators, environment, RK4 (no ROS);
* :mod:`adcs_sim.scenario` — the dynamics / recorder parameter schemas and the plant built from them;
* :mod:`adcs_sim.nodes` — dynamics and recorder nodes;
* :mod:`adcs_sim.runner` (``adcs-run``), :mod:`adcs_sim.analysis` and :mod:`adcs_sim.analyze`
  (``adcs-analyze``), :mod:`adcs_sim.bag` (MCAP bags).
"""
