"""Files written atomically: a temporary file beside the target, renamed over it only when the
writing succeeded, so a crash or a full disk never leaves a half-written file behind."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


def default_mode() -> int:
    """Permissions of a newly created file under the current umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextmanager
def atomic_path(path, mode=None):
    """Yield a temporary path beside ``path`` to write; on success it becomes ``path`` (with
    ``mode``, default: as a new file would get), on failure it is removed."""
    path = Path(path)
    # ".<name>.XXXXXXXX.tmp" must fit the file system's 255-byte names too: long names are cut.
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name[:200]}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, default_mode() if mode is None else mode)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
