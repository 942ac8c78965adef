"""An exclusive lock on a bake directory, so that two bakes into one folder never interleave
their renames: the second waits, then sees the first one's bake (and refuses to replace a
different one without --overwrite). POSIX advisory locks (fcntl.flock); where fcntl is missing
(Windows) the lock is a no-op and the manifest still keeps a mixed folder from passing as a bake."""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".ols_bake.lock"


@contextmanager
def locked(directory):
    try:
        import fcntl
    except ImportError:          # pragma: no cover - Windows
        yield
        return
    fd = os.open(Path(directory) / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)              # closing releases the lock
