"""Where FMUs from elsewhere are extracted: one private folder per process, gone with it.

fmpy loads an FMU from an extracted folder. An FMU the twin built loads its library from the
cache instead (:func:`twin.fmu.build.built_library`); any other (a scenario's own ``.fmu``, an
SSP's) is extracted by each twin process into its own folder
``<tmp>/twin-<uid>/pid-<pid>/`` (the parent 0700, this user's only), removed at exit; a
process killed with SIGKILL cannot remove its own, so the next twin process that extracts an
FMU removes the folders of processes that no longer run. ``<tmp>`` is Python's temporary
folder (``TMPDIR``).
"""

from __future__ import annotations

import atexit
import os
import shutil
import stat
import tempfile
from pathlib import Path

from twin.errors import UnsafeCacheError

_MINE: dict[int, Path] = {}  # by pid: a forked child makes its own


def alive(pid: int) -> bool:
    """Whether the process ``pid`` runs (another user's counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def _parent() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else 0
    parent = Path(tempfile.gettempdir()) / f"twin-{uid}"
    parent.mkdir(mode=0o700, exist_ok=True)
    st = parent.lstat()
    if not stat.S_ISDIR(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != uid) or st.st_mode & 0o077:
        raise UnsafeCacheError(
            f"{parent} is not a private folder of this user (FMUs are extracted there): remove it, "
            "or set TMPDIR to a private folder",
            source="TMPDIR",
        )
    return parent


def clean_stale(parent: Path) -> list[Path]:
    """Remove the extraction folders of twin processes that no longer run; returns them."""
    gone = []
    for folder in parent.glob("pid-*"):
        pid = folder.name.removeprefix("pid-")
        if pid.isdigit() and int(pid) != os.getpid() and not alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)
            gone.append(folder)
    return gone


def process_dir() -> Path:
    """This process's private extraction folder (made, and stale ones cleaned, on first use)."""
    pid = os.getpid()
    if pid not in _MINE:
        parent = _parent()
        clean_stale(parent)
        mine = parent / f"pid-{pid}"
        shutil.rmtree(mine, ignore_errors=True)  # a dead process's, with this pid reused
        mine.mkdir(mode=0o700)
        atexit.register(shutil.rmtree, mine, True)
        _MINE[pid] = mine
    return _MINE[pid]


def extraction_dir(prefix: str) -> str:
    """A new folder for one extracted FMU, inside :func:`process_dir`."""
    return tempfile.mkdtemp(prefix=prefix, dir=process_dir())
