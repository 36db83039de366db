"""Allocate a ROS_DOMAIN_ID no other adcs_sim process on this machine is using.

Each run (runner, test, benchmark) takes a domain with an exclusive ``flock`` on a file in the
temp directory and holds it while it runs, so concurrent runs never cross-talk. A process that
dies releases its lock with it. The runner's nodes inherit the lock's file descriptor
(:meth:`DomainLease.fileno`, ``pass_fds``): a ``flock`` belongs to the open file, so the domain is
free again only when the runner *and* the last of its nodes have exited, however they ended.
"""
from __future__ import annotations

import fcntl
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

LOCK_DIR = Path(tempfile.gettempdir()) / 'adcs_sim_domains'
MAX_DOMAIN_ID = 232  # largest id whose DDS ports stay valid on Linux


class DomainLease:
    """An exclusively held domain id; release() or process exit frees it."""

    def __init__(self, first: int = 1, last: int = MAX_DOMAIN_ID) -> None:
        if not 0 <= first <= last <= MAX_DOMAIN_ID:
            raise ValueError(f'domain range must lie in 0..{MAX_DOMAIN_ID}, got {first}..{last}')
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        start = first + os.getpid() % (last - first + 1)  # spread concurrent callers
        ids = list(range(start, last + 1)) + list(range(first, start))
        for domain in ids:
            fd = os.open(LOCK_DIR / f'{domain}.lock', os.O_CREAT | os.O_RDWR, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            self.domain_id, self._fd = domain, fd
            return
        raise RuntimeError(f'no free ROS domain id in {first}..{last}')

    def env(self, base: dict | None = None, allow_network: bool = False) -> dict:
        """Environment for a process of this run: own domain, loopback-only discovery.

        ``allow_network=True`` (``adcs-run --allow-network``, for a graph spread over several
        hosts) lets DDS discover participants on the local subnet instead
        (``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``); nothing else ever widens discovery."""
        env = dict(os.environ if base is None else base)
        env['ROS_DOMAIN_ID'] = str(self.domain_id)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET' if allow_network else 'LOCALHOST'
        env.pop('ROS_LOCALHOST_ONLY', None)   # deprecated; would override the range above
        return env

    def fileno(self) -> int:
        """The lock's file descriptor: a process that inherits it holds the lease until it exits."""
        if self._fd is None:
            raise ValueError('the lease was released')
        return self._fd

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


@contextmanager
def leased_domain(first: int = 1, last: int = MAX_DOMAIN_ID):
    lease = DomainLease(first, last)
    try:
        yield lease
    finally:
        lease.release()
