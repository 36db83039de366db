"""Seeded lost and late command messages on the lockstep link (pure; no rclpy).

The dynamics node's ``link_faults.*`` parameters make a given fraction of the steps lose the
controllers' commands (``drop``) or get them after the step's deadline (``delay``). Which steps
is drawn once from ``numpy.random.default_rng(seed)`` (one uniform number per step: ``u < drop``
is lost, ``drop <= u < drop + delay`` is late), so a run is as deterministic as without faults:
two runs with the same seed lose the same steps, whatever the machine's timing.

What a lost or late command does is the lockstep rule for a command that is not there in time:
the step is a **missed step** and the declared ``lockstep.timeout_policy`` (hold / zero)
applies. A late command then arrives during the next step, stamped for the previous one, and is
counted stale and ignored; a lost one never arrives. The dynamics node receives the real message
before it discards it (so the controller and the recorder see the same traffic as without the
fault, and nothing waits out a wall-clock timeout).

Commands, not states, are what the link loses: the state topic is also what the recorder
records, and for the plant a lost state (no answer) and a lost answer are the same missed step.
"""
from __future__ import annotations

import numpy as np

OK, DROP, DELAY = 0, 1, 2
FATE_NAMES = {DROP: 'lost', DELAY: 'late'}


class LinkFaults:
    """Per-step fate of the commands: :data:`OK`, :data:`DROP` or :data:`DELAY`."""

    def __init__(self, seed: int, drop: float, delay: float, n_steps: int) -> None:
        if not (0.0 <= drop <= 1.0 and 0.0 <= delay <= 1.0 and drop + delay <= 1.0):
            raise ValueError(f'link fault fractions must be in [0, 1] with drop + delay <= 1, '
                             f'got drop={drop}, delay={delay}')
        self.active = drop > 0 or delay > 0
        u = np.random.default_rng(seed).random(n_steps) if self.active else np.ones(n_steps)
        self.fates = np.where(u < drop, DROP, np.where(u < drop + delay, DELAY, OK)).astype(np.int8)
        self.dropped = 0
        self.delayed = 0

    def fate(self, k: int) -> int:
        return int(self.fates[k]) if self.active and k < self.fates.size else OK

    def count(self, fate: int) -> None:
        if fate == DROP:
            self.dropped += 1
        elif fate == DELAY:
            self.delayed += 1
