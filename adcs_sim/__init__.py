"""adcs_sim: the plant, the simulated clock and the tooling around the ROS graph.

* :mod:`adcs_sim.truth.plant`, :mod:`adcs_core.attitude` — rigid body, actuators, environment, RK4 (no ROS);
* :mod:`adcs_sim.truth.schema` — the dynamics / recorder parameter schemas and the plant built from them;
* :mod:`adcs_sim.nodes` — dynamics and recorder nodes;
* :mod:`adcs_sim.app.graph.runner` (``adcs-run``), :mod:`adcs_sim.app.analysis.metrics` and
  :mod:`adcs_sim.app.analysis.analyze` (``adcs-analyze``), :mod:`adcs_sim.bag` (MCAP bags).
"""
