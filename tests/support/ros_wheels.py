"""Which modules are the ROS wheels' (rclpy, the message packages, the middleware and its tools),
told by name so that it works where they are not installed; and a finder that refuses them, to
check what runs without them (``tests/test_suite_layout.py``)."""
from __future__ import annotations

import importlib.metadata
import importlib.util
import sys

# Top-level module names of the ROS 2 wheels (ros-* distributions) and their dependencies of the
# same origin: exact names, and prefixes / suffixes of families.
ROS_NAMES = frozenset({'rclpy', 'rcl', 'rcutils', 'rcpputils', 'rpyutils', 'fastcdr', 'fastrtps', 'tracetools',
                       'builtin_interfaces', 'domain_coordinator', 'foonathan_memory_vendor', 'libyaml_vendor',
                       'spdlog_vendor'})
ROS_PREFIXES = ('rcl_', 'rmw', 'rosidl', 'ament_', 'ros_', 'fastrtps_', 'rosgraph_')
ROS_SUFFIXES = ('_msgs', '_interfaces')


def is_ros_module(name: str | None) -> bool:
    """Whether module ``name`` (dotted) belongs to the ROS wheels."""
    top = (name or '').split('.')[0]
    return top in ROS_NAMES or top.startswith(ROS_PREFIXES) or top.endswith(ROS_SUFFIXES)


def ros_available() -> bool:
    """Whether rclpy can be found (not imported: nothing of ROS is loaded by asking)."""
    try:
        return importlib.util.find_spec('rclpy') is not None
    except (ImportError, ValueError):
        return False


def installed_ros_modules() -> set[str]:
    """Top-level names installed by the ``ros-*`` distributions of this environment."""
    found = set()
    for dist in importlib.metadata.distributions():
        if (dist.metadata['Name'] or '').lower().replace('_', '-').startswith('ros-'):
            for f in dist.files or ():
                top = f.parts[0]
                if top.endswith('.py'):
                    found.add(top[:-3])
                elif '.' not in top and '-' not in top and top not in ('..', 'bin', 'include', 'lib', 'share'):
                    found.add(top)
    return found


class RefuseRos:
    """A meta-path finder that refuses every ROS module, as if the wheels were not installed."""

    def find_spec(self, name, path=None, target=None):
        if is_ros_module(name):
            raise ModuleNotFoundError(f'No module named {name!r} (the ROS wheels are refused)', name=name)
        # anything else: None, the next finder's


def refuse_ros() -> None:
    """Refuse the ROS wheels from now on in this process (modules already imported stay)."""
    if not any(isinstance(f, RefuseRos) for f in sys.meta_path):
        sys.meta_path.insert(0, RefuseRos())
