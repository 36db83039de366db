"""The rosbags type store of ROS 2 Jazzy (message definitions, CDR (de)serialisation), loaded once
per process and shared: the CDR codec of the lockstep messages (:mod:`adcs_msgs_py.cdr`) and the
bag code (:mod:`adcs_sim.bag.storage`) both use it. No ROS here: rosbags only, imported on first
use."""
from __future__ import annotations

_TYPESTORE = None


def typestore():
    """The rosbags type store for ROS 2 Jazzy (message definitions and CDR (de)serialisation)."""
    global _TYPESTORE
    if _TYPESTORE is None:
        from rosbags.typesys import Stores, get_typestore
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE
