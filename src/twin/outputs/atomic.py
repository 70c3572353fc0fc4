"""Files written whole or not at all: a hidden temporary file beside the target, renamed.

A reader (or a run that resumes) then sees the old file or the new one, never a cut one: a
full disk, a kill or a failing writer leaves at most the hidden ``.<name>.<pid>.<random>.tmp``
file, which the writer removes when it can and a new run in the folder removes when it starts
(:meth:`twin.outputs.run_folder.RunFolder.start`).
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from pathlib import Path

__all__ = ["write_atomic"]


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], None]) -> Path:
    """Have ``write`` write the temporary file it is given, then rename it to ``path``; returns
    ``path``. On any failure the temporary file is removed and the error raised again (an
    ``OSError`` naming ``path`` when it named no file: a full disk's error names none)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            exc.filename = exc.filename or str(path)
        raise
    return path
