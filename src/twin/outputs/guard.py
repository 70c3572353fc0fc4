"""Output folders and files written in place, never through a link planted there.

A file written in place (a run's signals.csv as it grows, its lock, fmi.log) is opened by
:func:`open_output` with ``O_NOFOLLOW``: a link there is refused with one line (exit 2), as is
anything but a regular file (a FIFO would block, a device would swallow the run).
:func:`refuse_links` says the same for a whole folder's outputs before anything runs, and
:func:`output_dir` makes a folder that is not a link. A file written whole goes through
:mod:`twin.files` (a temporary file renamed over it).
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import IO, Literal

from twin.errors import ConfigError
from twin.files import NOFOLLOW

__all__ = ["open_output", "output_dir", "read_text_capped", "refuse_links"]

_LINK = "is a symbolic link: the twin writes no file through a link (remove it, or choose another folder)"


def _link_error(path: Path) -> ConfigError:
    return ConfigError(_LINK, source=str(path))


def refuse_links(folder: Path, names: Iterable[str]) -> None:
    """Refuse (one line, exit 2) when one of the files ``names`` in ``folder`` is a symbolic
    link: said before a command runs, not found when it writes there."""
    for name in names:
        if (folder / name).is_symlink():
            raise _link_error(folder / name)


def output_dir(path: Path, option: str | None = None) -> Path:
    """Make the folder ``path`` (and its parents) unless it is there; a symbolic link in its
    place (a runs/ folder pointing elsewhere) is refused, not followed, and a file there or a
    folder that cannot be made is one line (naming ``option`` when the user named the
    folder). The parents are the user's choice (a link among them is the user's own)."""
    where = f"{option} {path}" if option else str(path)
    if path.is_symlink():
        raise _link_error(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise ConfigError("is a file, expected a folder", source=where) from None
    except OSError as exc:
        raise ConfigError(f"cannot be made: {exc.strerror}", source=where) from None
    if path.is_symlink() or not path.is_dir():
        raise ConfigError("is not a folder", source=where)
    return path


def open_output(path: str | os.PathLike[str], mode: Literal["w", "a", "r+"] = "w") -> IO[bytes]:
    """Open ``path`` for writing in binary, never through a link: "w" empties it, "a" appends,
    "r+" keeps it (read and write, a run's lock); made when missing. A symbolic link, a FIFO or
    a device in its place is refused with one line (:class:`~twin.errors.ConfigError`)."""
    path = Path(path)
    access = os.O_RDWR if mode == "r+" else os.O_WRONLY
    flags = access | os.O_CREAT | NOFOLLOW | os.O_NONBLOCK  # a FIFO does not block
    if mode == "a":
        flags |= os.O_APPEND
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as exc:
        if exc.errno == errno.ELOOP or path.is_symlink():
            raise _link_error(path) from None
        if exc.errno == errno.ENXIO:  # a FIFO nobody reads
            raise ConfigError("is not a regular file", source=str(path)) from None
        exc.filename = exc.filename or str(path)
        raise
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ConfigError("is not a regular file", source=str(path))
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
        if mode == "w":
            os.ftruncate(fd, 0)
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, {"w": "wb", "a": "ab", "r+": "r+b"}[mode])


def read_text_capped(path: Path, limit: int) -> str:
    """A small file the twin wrote itself (summary.json), read as UTF-8 without following a
    link and at most ``limit`` bytes (ValueError beyond it, OSError when it cannot be read)."""
    fd = os.open(path, os.O_RDONLY | NOFOLLOW | os.O_NONBLOCK)
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ValueError(f"{path} is not a regular file")
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{path} holds more than {limit} bytes")
    return data.decode("utf-8")
