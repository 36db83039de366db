"""adcs_sim/app/scenario/seeding.py gives each campaign run numpy's own generator state, bit for bit:
``PCG64(SeedSequence(seed, spawn_key=(i,))).state`` for seeds of one to five 32-bit words (and 0),
indices up to 2**32 - 1, and the same draws as ``default_rng`` of each run."""
from __future__ import annotations

import numpy as np
import pytest

from adcs_sim.app.scenario.seeding import pcg64_states, run_generators

SEEDS = [0, 1, 20261123, 2**32 - 1, 2**32, 2**64 + 12345, 2**127 + 3, 2**130 + 7,
         123456789012345678901234567890123456789012]


@pytest.mark.parametrize('seed', SEEDS)
def test_states_are_numpys(seed):
    indices = [*range(40), 999, 65535, 2**31, 2**32 - 1]
    expected = [np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(i,))).state for i in indices]
    assert pcg64_states(seed, indices) == expected
    assert pcg64_states(seed, []) == []


def test_draws_are_default_rngs():
    indices = [5, 3, 0, 700]
    got = [(g.random(3).tolist(), g.standard_normal(4).tolist(), g.normal(size=(2,)).tolist())
           for g in run_generators(20261123, indices)]
    want = []
    for i in indices:
        g = np.random.default_rng(np.random.SeedSequence(20261123, spawn_key=(i,)))
        want.append((g.random(3).tolist(), g.standard_normal(4).tolist(), g.normal(size=(2,)).tolist()))
    assert repr(got) == repr(want)


def test_out_of_range_is_refused():
    with pytest.raises(ValueError):
        pcg64_states(1, [2**32])
    with pytest.raises(ValueError):
        pcg64_states(1, [-1])
    with pytest.raises(ValueError):
        pcg64_states(-1, [0])
