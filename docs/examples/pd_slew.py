"""The PD slew of seed 004 (config/microsat_pd_slew.yaml) from Python: through the ROS 2 node
graph and through the batch engine, and the two runs are the same, bit for bit.

    .venv/bin/python docs/examples/pd_slew.py [--duration 120] [--out DIR]

The graph run starts the recorder, the dynamics node and the PD controller as processes on a
freshly leased ROS_DOMAIN_ID with discovery limited to this machine (as ``adcs-run`` does) and
reads the bag back; the batch run is numpy only. Exits non-zero (AssertionError) if they differ.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from adcs_sim.app.api import Scenario


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=120.0, help='simulated seconds (the paper: 600)')
    parser.add_argument('--out', type=Path, default=None, help='output folder of the graph run (default: temporary)')
    args = parser.parse_args(argv)

    # Load and validate the scenario, shortened: a bad override stops here, naming the key.
    slew = Scenario.load('microsat_pd_slew.yaml', {'dynamics.duration': args.duration})
    print(f'{slew.source.name}: {slew["dynamics.duration"]:g} s, kp = {slew["pd_controller.kp"]}, '
          f'kd = {slew["pd_controller.kd"]}')

    batch = slew.run_batch()[0]                     # the batch engine: numpy, no ROS
    with tempfile.TemporaryDirectory(prefix='pd_slew_') as tmp:
        graph = slew.run_graph(args.out or Path(tmp) / 'run')   # the ROS 2 graph, recorded to a bag

    # Same time grid and the same states, torques and wheel speeds, bit for bit.
    g, b = graph.data, batch.data
    for name in ('t', 'q', 'w', 't_u', 'u', 'wheel_speed'):
        assert np.array_equal(getattr(g, name), getattr(b, name)), f'{name} differs between graph and batch'
    assert g.wheel_names == b.wheel_names
    mg, mb = graph.metrics(), batch.metrics()
    for key in ('settling_euler213_0.5deg_s', 'settling_eigenaxis_0.5deg_s', 'integrated_torque_Nms',
                'final_eigenaxis_error_deg'):
        assert mg[key] == mb[key], key
    print(f'graph and batch equal bit for bit over {g.t.size} states: '
          f'final eigenaxis error {mb["final_eigenaxis_error_deg"]:.4g} deg, '
          f'integrated torque {mb["integrated_torque_Nms"]:.6g} N m s')

    try:   # pandas is optional
        frame = batch.dataframe()
        print(frame[['eigenaxis_error_deg', 'u_x', 'wheel_speed.rw_x']].iloc[::max(1, len(frame) // 4)])
    except ImportError:
        print('(pandas not installed: no DataFrame)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
