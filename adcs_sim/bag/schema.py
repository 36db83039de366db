"""The ``recorder`` section of a scenario (pure, no ROS; the node is :mod:`adcs_sim.nodes.recorder`)."""
from __future__ import annotations

from adcs_msgs_py.blocks import startup_params
from adcs_msgs_py.params import Param, Schema, positive

RECORDER_SCHEMA = Schema('recorder', [
    Param('output', 'string', default='', doc='bag folder to create (empty: runs/<timestamp>)'),
    Param('scenario_file', 'string', default='',
          doc='scenario file embedded in the bag as metadata (the runner sets it)'),
    Param('topics', 'string_array', default=['all'],
          doc="topics to record; 'all': every topic of the interface plus any discovered"),
    Param('chunk_size', 'int', default=65536, check=positive,
          doc='MCAP chunk size (bytes): smaller loses less on a crash'),
    Param('flush_period', 'double', default=0.5, check=positive,
          doc='wall seconds between flushes of the open chunk to disk'),
    Param('discovery_period', 'double', default=1.0, check=positive,
          doc='wall seconds between looks for new topics to record'),
    *startup_params(),
], doc='records every topic of the graph to a rosbag2 MCAP bag')
