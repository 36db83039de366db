"""The layering rule: plant, laws, schemas and analysis import no rclpy (Monte Carlo and offline
analysis use them without ROS). Checked in a fresh interpreter, so nothing else pre-imports it."""
from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import ROOT

PURE_MODULES = [
    'adcs_sim.truth.plant', 'adcs_core.attitude', 'adcs_sim.truth.schema', 'adcs_sim.app.analysis',
    'adcs_sim.app.batch', 'adcs_core.faults', 'adcs_sim.truth.sensors', 'adcs_sim.truth.thrusters',
    'adcs_controllers.laws.pd', 'adcs_controllers.laws.allocation', 'adcs_controllers.families',
    'adcs_controllers.laws.inverse_optimal', 'adcs_controllers.laws.underactuated',
    'adcs_controllers.laws.reconfiguration', 'adcs_controllers.laws.motion_to_rest',
    'adcs_controllers.laws.motion_to_spin', 'adcs_controllers.laws.saturation',
    'adcs_controllers.laws.single_axis', 'adcs_controllers.laws.backstepping',
    'adcs_msgs_py.params', 'adcs_msgs_py.names',
]


@pytest.mark.parametrize('module', PURE_MODULES)
def test_module_imports_no_rclpy(module):
    code = f'import sys, {module}; print("rclpy" in sys.modules)'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == 'False', f'{module} pulls in rclpy'
