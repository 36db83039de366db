"""The recorder node, its bag writer held shut until a line arrives on stdin (for
tests/test_recorder_backlog.py: a recorder that takes nothing while DDS keeps delivering).

The first message the recorder takes blocks its executor in ``BagWriter.write`` until the test
writes a line; DDS' own threads keep receiving meanwhile. Everything else is the recorder's
``main`` as ``python -m adcs_sim.nodes.recorder`` runs it.
"""
import sys
import threading

from adcs_sim.bag.writer import BagWriter
from adcs_sim.nodes import recorder

OPEN = threading.Event()
threading.Thread(target=lambda: (sys.stdin.readline(), OPEN.set()), daemon=True).start()
_write = BagWriter.write


def gated_write(self, *args, **kwargs):
    OPEN.wait()
    return _write(self, *args, **kwargs)


BagWriter.write = gated_write
recorder.main()
