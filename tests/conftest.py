"""Fixtures and hooks of the suite: every ROS test on its own domain id, loopback discovery only;
the markers; the kernels compiled once before the tests.

No ROS here at import (``tests/test_suite_layout.py`` checks it): the ROS fixtures import rclpy and
the domain lease when they run, so that the pure tests run without the ROS wheels. Helpers live in
``tests/support/`` (``from support.scenarios import make_scenario``); no test module imports another.

Markers (registered in pyproject.toml, ``--strict-markers``):

* ``graph``: the test uses a ROS context or graph, or starts ROS processes. Given here to every test
  that uses :data:`ROS_FIXTURES` (directly or through another fixture), and by ``pytestmark`` in the
  modules that build ROS objects or start the graph without them;
* ``slow``: one of the longest tests (~3 s or more alone on the 2-core machine), left out of the inner loop;
* ``paper``: reproduces a number or figure of a seed paper.

``pytest -m "not graph and not slow"`` is the inner loop. Without the ROS wheels, a test module that
imports them at module level is skipped at collection, its reason naming the module.
"""
from __future__ import annotations

import itertools
import os
import sys

import pytest
from support.paths import FASTDDS_PROFILE, ROOT
from support.processes import Spawner
from support.ros_wheels import is_ros_module, ros_available

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# Asks Fast DDS for UDP only. rmw_fastrtps's LOCALHOST discovery range sets its own transports and
# adds shared memory anyway (test_recorder.remove_if_orphaned cleans what a SIGKILLed node leaves).
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
# adcs_msgs_py.node.network_hygiene_defaults() without importing rclpy: the same Fast DDS profile as
# the nodes, for in-process graphs (test_suite_layout checks that the two paths agree)
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(FASTDDS_PROFILE))

# A test using one of these (or a fixture that does) runs ROS: marked ``graph``.
ROS_FIXTURES = frozenset({'ros_domain', 'two_contexts', 'spawn'})


@pytest.fixture
def spawn():
    """A :class:`~support.processes.Spawner`; at teardown, passed or failed, every process it started
    or adopted is killed with its process group and descendants (a failing test leaves no runner and
    no node behind for the rest of the suite)."""
    spawner = Spawner()
    try:
        yield spawner
    finally:
        spawner.cleanup()




_LEASES = itertools.count()   # leases taken by this process (ros_domain)


@pytest.fixture
def ros_domain(monkeypatch):
    """A leased ROS_DOMAIN_ID (in 100..232, away from the runner's default range), set in os.environ.

    Yields the lease; ``lease.env()`` is the environment for subprocesses of the test.
    """
    from adcs_sim.app.graph.domains import DomainLease  # ros-domain-coordinator: a ROS wheel
    # Each lease of this process starts from another id (a step coprime with the 133 ids): a test
    # never meets in its domain a participant an earlier test of this process left alive (one still
    # waiting to be collected). With the default start every lease of a process began at the same
    # id, and a later test's writers once waited on an earlier test's recorder readers, 5 s a step.
    lease = DomainLease(100, 232, prefer=100 + (os.getpid() + 37 * next(_LEASES)) % 133)
    monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        yield lease
    finally:
        lease.release()


@pytest.fixture
def two_contexts(ros_domain):
    """Two rclpy contexts (two DDS participants, as two processes of the graph) on a leased
    domain, initialised; shut down at teardown."""
    import rclpy
    from rclpy.context import Context
    from support.ros_graph import close_graph
    pair = (Context(), Context())
    for ctx in pair:
        rclpy.init(args=[], context=ctx)
    try:
        yield pair
    finally:
        for ctx in pair:
            close_graph(rclpy, ctx)


def pytest_collection_modifyitems(config, items):
    """``graph`` on every test that uses a ROS fixture (its fixture closure: through other fixtures too)."""
    for item in items:
        if ROS_FIXTURES & set(getattr(item, 'fixturenames', ())):
            item.add_marker(pytest.mark.graph)


class _Module(pytest.Module):
    """A test module that, when the ROS wheels are missing, is skipped if it imports them at module level."""

    def _getobj(self):
        try:
            return super()._getobj()
        except self.CollectError as exc:
            cause = exc.__cause__
            if isinstance(cause, ImportError) and is_ros_module(cause.name) and not ros_available():
                pytest.skip(f'needs the ROS wheels (imports {cause.name})', allow_module_level=True)
            raise


def pytest_pycollect_makemodule(module_path, parent):
    if module_path.name != 'conftest.py':
        return _Module.from_parent(parent, path=module_path)
    return None


def pytest_sessionstart(session):
    """Compile every numba kernel (``adcs_sim.app.batch.kernels.compile_all``: loads them on a warm cache)
    once, before any test, in this process only: an xdist worker, or a node the tests start, then
    loads the machine code from numba's cache instead of compiling it (twice in parallel, and inside
    a test's time). Not for ``--collect-only``, nor in the workers (``workerinput``)."""
    config = session.config
    if hasattr(config, 'workerinput') or config.option.collectonly:
        return
    from adcs_sim.app.batch.kernels import compile_all, summary
    reporter = config.pluginmanager.get_plugin('terminalreporter')
    verbose = config.option.verbose > 0
    write = reporter.write_line if reporter is not None else print
    times = compile_all(progress=write if verbose else None)
    if not verbose:
        write(summary(times))
