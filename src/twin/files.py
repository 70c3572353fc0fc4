"""Files written whole or not at all, and never through a link planted where they go.

A file written whole goes through a hidden temporary file beside the target, created
exclusively (``O_EXCL | O_NOFOLLOW``, a unique name), then renamed over the target: a symbolic
link in the target's place is replaced, never followed. (A file written in place, and the
folders outputs go to, are guarded by :mod:`twin.outputs.guard`.)

A reader (or a run that resumes) then sees the old file or the new one, never a cut one: a
full disk, a kill or a failing writer leaves at most the hidden ``.<name>.<pid>.<random>.tmp``
file, which the writer removes when it can and a new run in the folder removes when it starts
(:meth:`twin.outputs.run_folder.RunFolder.start`). Every file the twin writes whole goes
through :func:`write_atomic`.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from pathlib import Path

__all__ = [
    "NOFOLLOW",
    "temporary_name",
    "write_atomic",
    "write_bytes_atomic",
    "write_text_atomic",
]

#: open flags that never follow a link and never leak into a child process
NOFOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)


def temporary_name(path: Path) -> Path:
    """The hidden temporary file a write of ``path`` goes through (unique per writer)."""
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], None]) -> Path:
    """Have ``write`` write the temporary file it is given (created empty and exclusively
    here, so that nothing planted can stand at its name), then rename it to ``path``, which
    replaces a link there rather than following it; returns ``path``. On any failure the
    temporary file is removed and the error raised again (an ``OSError`` naming ``path`` when
    it named no file: a full disk's error names none)."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | NOFOLLOW, 0o666))
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            exc.filename = exc.filename or str(path)
        raise
    return path


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes, *, sync: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically; with ``sync`` its bytes are on disk before the
    rename makes them visible. The file gets the umask's permissions (not a private 0o600)."""

    def write(tmp: Path) -> None:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | NOFOLLOW)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            if sync:
                f.flush()
                os.fsync(f.fileno())

    return write_atomic(path, write)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, sync: bool = False) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically (:func:`write_bytes_atomic`)."""
    return write_bytes_atomic(path, text.encode("utf-8"), sync=sync)
