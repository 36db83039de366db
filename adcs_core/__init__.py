"""The kernel: pure math and conventions that every layer shares (numpy only; no ROS, no plant,
no law). Quaternion and rotation algebra (:mod:`adcs_core.attitude`), orbit geometry and the orbit
frame (:mod:`adcs_core.orbit`), inertia matrices and their checks (:mod:`adcs_core.inertia`), actuator
fault states and the fault-schedule bookkeeping (:mod:`adcs_core.faults`).

Everything takes an optional leading batch axis; products are summed in a fixed order so that a
run's numbers do not depend on the other runs of its batch.
"""
