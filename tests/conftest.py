"""Shared fixtures: every ROS test runs on its own domain id, loopback discovery only."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from adcs_sim.domains import DomainLease  # noqa: E402

# Tests use UDP only: a killed Fast DDS process would otherwise leave shared-memory files.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
CONFIG = ROOT / 'config'


@pytest.fixture
def ros_domain(monkeypatch):
    """A leased ROS_DOMAIN_ID (in 100..232, away from the runner's default range), set in os.environ.

    Yields the lease; ``lease.env()`` is the environment for subprocesses of the test.
    """
    lease = DomainLease(100, 232)
    monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        yield lease
    finally:
        lease.release()
