"""The generators of many campaign runs at once: ``default_rng(SeedSequence(seed, spawn_key=(i,)))``'s
states without building each run's ``SeedSequence`` (numpy only).

A campaign's run ``i`` draws from ``np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))``
(:mod:`adcs_sim.app.campaign.plan`). Building a ``SeedSequence`` and a ``PCG64`` costs ~25 us a run (its
entropy is coerced to words in Python), more than the run's draws. :func:`pcg64_states` computes
the very same PCG64 states for many runs: numpy's ``SeedSequence`` algorithm (its ``mix_entropy``
over the seed's 32-bit words padded to the pool size and the spawn key, then ``generate_state(4,
uint64)``; ``bit_generator.pyx``) with the run index as the only word that differs, in uint32
arithmetic over all the runs at once, and ``PCG64``'s seeding (``pcg64_set_seed``: the 128-bit
``srandom`` of PCG, ``state = 0; inc = 2 seq + 1; step; state += initstate; step``) in Python
integers. :func:`run_generators` yields one ``Generator`` given each run's state in turn (a
``Generator`` over PCG64 keeps no state of its own). ``tests/test_seeding.py`` compares the states
and the draws with numpy's own for many seeds and indices.
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np

POOL_SIZE = 4                      # SeedSequence's default pool (4 words of 32 bits)
INIT_A, MULT_A = 0x43b0d7e5, 0x931e8875
INIT_B, MULT_B = 0x8b51f9dd, 0x58f38ded
MIX_MULT_L, MIX_MULT_R = 0xca01f9dd, 0x4973f715
XSHIFT = 16
MASK32, MASK128 = 0xFFFFFFFF, (1 << 128) - 1
PCG_MULT = (2549297995355413924 << 64) + 4865540595714422341   # PCG_DEFAULT_MULTIPLIER_128
MAX_RUN_INDEX = MASK32             # the run index is the spawn key's one 32-bit word


def _words(n: int) -> list[int]:
    """numpy's _int_to_uint32_array: little-endian 32-bit words of n >= 0 ([0] for 0)."""
    out = [n & MASK32]
    n >>= 32
    while n:
        out.append(n & MASK32)
        n >>= 32
    return out


def _hashmix(value, h: list):
    """SeedSequence's hashmix (uint32; h[0] the running hash constant, updated)."""
    value = value ^ h[0]
    h[0] = (h[0] * MULT_A) & MASK32
    value = (value * np.uint32(h[0])) if isinstance(value, np.ndarray) else (value * h[0]) & MASK32
    return value ^ (value >> XSHIFT)


def _mix(x, y):
    """SeedSequence's mix (uint32)."""
    result = (np.uint32(MIX_MULT_L) * x - np.uint32(MIX_MULT_R) * y) if isinstance(x, np.ndarray) \
        else (MIX_MULT_L * x - MIX_MULT_R * y) & MASK32
    return result ^ (result >> XSHIFT)


def _pools(seed: int, indices: np.ndarray) -> list[np.ndarray]:
    """The entropy pool (4 words, each an array over the runs) of SeedSequence(seed, spawn_key=(i,))."""
    entropy = _words(seed)
    entropy += [0] * (POOL_SIZE - len(entropy))       # padded: a spawn key follows
    h = [INIT_A]
    mixer = [_hashmix(entropy[i], h) for i in range(POOL_SIZE)]
    for src in range(POOL_SIZE):
        for dst in range(POOL_SIZE):
            if src != dst:
                mixer[dst] = _mix(mixer[dst], _hashmix(mixer[src], h))
    pool = [np.full(indices.size, m, dtype=np.uint32) for m in mixer]
    for word in entropy[POOL_SIZE:]:                  # a seed of more than 4 words
        for dst in range(POOL_SIZE):
            pool[dst] = _mix(pool[dst], np.uint32(_hashmix(word, h)))
    spawn = indices.astype(np.uint32)
    for dst in range(POOL_SIZE):                      # the spawn key: the run index, one word
        pool[dst] = _mix(pool[dst], _hashmix(spawn, h))
    return pool


def pcg64_states(seed: int, indices) -> list[dict]:
    """``np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(i,))).state`` of each run index i
    (ints in [0, 2**32): one word of spawn key)."""
    indices = np.asarray(indices, dtype=np.int64)
    if indices.size and not (0 <= indices.min() and indices.max() <= MAX_RUN_INDEX) or seed < 0:
        raise ValueError('run indices must be in [0, 2**32) and the seed >= 0')
    h, words = INIT_B, []
    with np.errstate(over='ignore'):   # uint32 arithmetic: modulo 2**32, as numpy's C
        pool = _pools(int(seed), indices)
        for i in range(8):                            # generate_state(4, uint64): 8 words of 32 bits
            value = pool[i % POOL_SIZE] ^ np.uint32(h)
            h = (h * MULT_B) & MASK32
            value = value * np.uint32(h)
            words.append(value ^ (value >> XSHIFT))
    lo = [(w[1].astype(np.uint64) << np.uint64(32)) | w[0].astype(np.uint64) for w in (words[0:2], words[2:4],
                                                                                       words[4:6], words[6:8])]
    states = []
    for s0, s1, i0, i1 in zip(*(v.tolist() for v in lo)):
        inc = ((((i0 << 64) + i1) << 1) | 1) & MASK128
        state = inc                                   # state 0, one step: 0 * PCG_MULT + inc
        state = ((state + ((s0 << 64) + s1)) * PCG_MULT + inc) & MASK128
        states.append({'bit_generator': 'PCG64', 'state': {'state': state, 'inc': inc},
                       'has_uint32': 0, 'uinteger': 0})
    return states


def run_generators(seed: int, indices) -> Iterator[np.random.Generator]:
    """One Generator, in run ``indices[j]``'s state at the j-th step: the generator of each run
    (use it before the next one; :func:`pcg64_states`)."""
    rng = np.random.Generator(np.random.PCG64())
    for state in pcg64_states(seed, indices):
        rng.bit_generator.state = state
        yield rng
