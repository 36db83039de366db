"""Reject, count and warn: how a node survives a bad message.

A node wraps each conversion of an incoming message in :meth:`RejectCounter.accept`; an
:class:`~adcs_msgs_py.conversions.InvalidMessage` is counted per topic and logged as a throttled
warning, and the callback simply returns. Nothing downstream ever sees a NaN.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import TypeVar

from adcs_msgs_py.conversions import InvalidMessage

T = TypeVar('T')

WARN_THROTTLE_S = 5.0


class RejectCounter:
    """Per-topic count of rejected messages, with a throttled warning through a ROS logger."""

    def __init__(self, logger, throttle_s: float = WARN_THROTTLE_S) -> None:
        self._logger = logger
        self._throttle_s = throttle_s
        self.counts: Counter[str] = Counter()

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def reject(self, topic: str, reason: str) -> None:
        """Count a rejected message on ``topic`` and warn (throttled)."""
        self.counts[topic] += 1
        self._logger.warning(
            f'rejected message on {topic!r} ({self.counts[topic]} so far): {reason}',
            throttle_duration_sec=self._throttle_s)

    def accept(self, topic: str, convert: Callable[[], T]) -> T | None:
        """Run ``convert()``; on InvalidMessage count and warn, and return None."""
        try:
            return convert()
        except InvalidMessage as exc:
            self.reject(topic, str(exc))
            return None
