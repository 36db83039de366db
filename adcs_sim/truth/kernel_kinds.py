"""The compiled plant kernel's actuator kinds (:mod:`adcs_sim.truth.kernel`), without numba.

Each actuator class names its kind (``kernel_kind``) when its module is imported; the kernel module
itself, which imports numba (0.4-0.7 s), is loaded only when a plant is built
(:class:`adcs_sim.truth.plant.Plant`), so validating a scenario (``adcs-run`` before it starts the
graph, the schema and parameter tools) does not pay for it.
"""
WHEELS, TORQUERS, THRUSTERS = 0, 1, 2
