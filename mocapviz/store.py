"""Files on disk written so that a reader never sees a half-written one.

atomic_write   bytes -> a temporary file with a unique name beside the target, fsync'ed, renamed into place
               (two writers never share a temporary file; a killed writer leaves the previous file intact).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


def atomic_write(target: str | os.PathLike, data: bytes) -> None:
    """Replace ``target`` by ``data`` atomically: a unique temporary file in the same folder, fsync, rename.

    Raises
    ------
    OSError
        The folder does not exist or is not writable (the temporary file is removed).
    """
    target = Path(target)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
