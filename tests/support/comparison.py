"""A recorded run against the one computed now, and the published numbers against ours."""
from __future__ import annotations

from pathlib import Path

import numpy as np

# A committed bag recorded on one CPU, compared with the batch engine on another: numpy dispatches
# sin, cos, arccos, arctan2 ... to SIMD kernels chosen for the CPU (AVX-512 vs AVX2 vs baseline),
# which may differ by an ulp; a closed-loop run carries that to ~1e-11 relative (seen: 3.2e-11 on
# the seed 002 slew). On one machine the graph and the batch engine are equal bit for bit (the
# node-pair tests check that in the same run); across machines, to this tolerance.
CROSS_CPU_RTOL = 1e-9


def assert_recorded_run_equal(actual, recorded) -> None:
    """``actual`` (computed here) equals ``recorded`` (a committed bag's): bit for bit on the CPU
    that recorded it, to :data:`CROSS_CPU_RTOL` on another (see there)."""
    actual, recorded = np.asarray(actual), np.asarray(recorded)
    if not np.array_equal(actual, recorded):
        np.testing.assert_allclose(actual, recorded, rtol=CROSS_CPU_RTOL, atol=1e-15)


def reference_comparison(bags, paper: Path, out: Path) -> str:
    """``comparison.md`` of ``adcs-analyze BAGS --compare --reference PAPER --out OUT`` (which must exit
    0): the published-vs-ours rows every seed's doc table is checked against."""
    from adcs_sim.app.analysis.analyze import main as analyze  # matplotlib behind it: only for these tests
    assert analyze([*map(str, bags), '--compare', '--reference', str(paper), '--out', str(out)]) == 0
    return (out / 'comparison.md').read_text()


def plain_message(value):
    """A deserialised message as nested tuples (numpy arrays as dtype + bytes), comparable with
    ==: message content, not CDR bytes (Fast DDS leaves a serialised message's alignment padding
    uninitialised, so equal messages can differ there)."""
    if hasattr(value, '__dataclass_fields__'):
        return tuple(plain_message(getattr(value, f)) for f in value.__dataclass_fields__)
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(plain_message(v) for v in value)
    return value
