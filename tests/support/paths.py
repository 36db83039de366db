"""The repository's folders, for the tests."""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config'
BAGS = ROOT / 'bags'
TESTS = ROOT / 'tests'
SCRIPTS = TESTS / 'support' / 'scripts'   # programs the tests run as subprocesses
# The nodes' Fast DDS profile (adcs_msgs_py.node.FASTDDS_PROFILE, named here without importing rclpy)
FASTDDS_PROFILE = ROOT / 'adcs_msgs_py' / 'fastdds_profile.xml'
