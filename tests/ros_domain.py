"""A ROS domain for this test process: one no other test process of this host holds."""

import fcntl
import os
import tempfile
from pathlib import Path

_held: list = []


def free_domain() -> int:
    """A ROS domain (1 to 100) that no other test process of this host holds (xdist's workers,
    another checkout's suite): each holds a lock on its domain's file for as long as it lives."""
    for k in range(100):
        domain = 1 + (os.getpid() + k) % 100
        try:  # (a file another user made: not ours to take)
            lock = open(Path(tempfile.gettempdir()) / f"sotdrake-tests-ros-domain-{domain}.lock", "a")
        except OSError:
            continue
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _held.append(lock)
        return domain
    return 1 + os.getpid() % 100
