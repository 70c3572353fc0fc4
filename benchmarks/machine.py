"""What every benchmark script shares: the machine line it prints, and the table it writes into
the docs (``--write-docs``: ``docs/performance/<script>.md``, included by docs/performance.md).

It imports neither numpy nor the twin until a table is written: bench_compensate.py measures
its children's peak memory with ``os.wait4``, which a large parent would raise (Linux counts a
child's peak from its parent's at the fork).
"""

from __future__ import annotations

import contextlib
import os
import platform
import shlex
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "performance"

#: the libraries whose versions a figure depends on, in the machine line
LIBRARIES = ("numpy", "pyarrow", "libcosimpy", "distributed")


def _version(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "not installed"


def _first(path: str, key: str) -> str:
    """The value of the first ``key: value`` line of a /proc file, or ''."""
    with contextlib.suppress(OSError):
        for line in Path(path).read_text().splitlines():
            if line.startswith(key):
                return line.split(":", 1)[1].strip()
    return ""


#: what the figures depend on: a change here (not committed) marks the commit "-dirty"; the
#: tables in docs/performance/ a benchmark has just written do not
CODE = ("src", "fmus", "scenarios", "benchmarks", "pyproject.toml")


def commit() -> str:
    """The checkout's commit, ``-dirty`` when the code measured differs from it, or ''."""
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        git = ["git", "-C", str(ROOT)]
        head = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        if head.returncode != 0:
            return ""
        changed = subprocess.run([*git, "status", "--porcelain", "--", *CODE], capture_output=True, text=True)
        return head.stdout.strip() + ("-dirty" if changed.stdout.strip() else "")
    return ""


def machine() -> dict[str, str]:
    """CPU, cores, memory, operating system, Python, the libraries' and the twin's versions."""
    mem = _first("/proc/meminfo", "MemTotal")
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 0
    commit_ = commit()
    twin = _version("twin")
    return {
        "cpu": _first("/proc/cpuinfo", "model name") or platform.processor() or "unknown",
        "cores": f"{os.cpu_count()} logical ({usable} usable)",
        "memory": f"{int(mem.split()[0]) / 1024**2:.1f} GB" if mem else "unknown",
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        **{lib: _version(lib) for lib in LIBRARIES},
        "twin": f"{twin} ({commit_})" if commit_ else twin,
    }


def machine_line(info: dict[str, str] | None = None) -> str:
    """The machine on one line, as the tables' header gives it."""
    m = info or machine()
    libs = ", ".join(f"{lib} {m[lib]}" for lib in LIBRARIES)
    return (
        f"{m['cpu']}, {m['cores']} cores, {m['memory']} RAM; {m['os']}; Python {m['python']}, {libs}; "
        f"twin {m['twin']}"
    )


def print_machine(info: dict[str, str] | None = None) -> dict[str, str]:
    """Print the machine, one item a line; returns it."""
    m = info or machine()
    for key, value in m.items():
        print(f"   {key:11s} {value}")
    return m


def command(argv: Sequence[str] | None = None) -> str:
    """The command line that ran this script, as a reader would type it."""
    script = Path(sys.argv[0]).resolve()
    with contextlib.suppress(ValueError):
        script = script.relative_to(ROOT)
    args = sys.argv[1:] if argv is None else list(argv)
    return shlex.join(["python", script.as_posix(), *args])


def write_docs(
    script: str, table: str, info: dict[str, str], argv: Sequence[str] | None = None, name: str | None = None
) -> Path:
    """``table`` (Markdown) into ``docs/performance/<script>.md`` (``<name>.md`` if given: a
    script that writes two tables) under a one-line header: which command wrote it, on what
    machine, when. Written atomically (the docs' build reads it)."""
    from twin.files import write_text_atomic

    header = f"Written by `{command(argv)}` on {time.strftime('%Y-%m-%d')}; machine: {machine_line(info)}."
    path = DOCS / f"{name or Path(script).stem}.md"
    write_text_atomic(path, f"{header}\n\n{table.rstrip()}\n")
    print(f"\nwrote {path.relative_to(ROOT)}")
    return path
