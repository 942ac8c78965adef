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


def probe_writable(path) -> None:
    """Raise OSError unless ``path`` can be written: its folder (made if missing) takes a new
    file, and its name fits the file system. Checked before long work, so that the error comes
    at once and names the file asked for, not a temporary one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(prefix=".ols_probe.", dir=path.parent)
    os.close(fd)
    os.unlink(probe)
    if len(os.fsencode(path.name)) > 255:
        raise OSError(36, "File name too long")


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
