"""The one way the twin compiles C: cmake, and a cache keyed by a hash of the sources.

Everything the twin builds (the FMUs of :mod:`twin.fmu.build`, the master's compiled
stepper) goes through :func:`run_cmake` and :func:`cached`, so a fresh clone or a fresh
``pip install`` builds on first use and a changed source file is rebuilt, never served stale.
:func:`build_cached_library` is the whole recipe for a CMake project that builds one shared
library::

    from importlib.resources import files
    from twin.fmu.toolchain import build_cached_library, folder_files

    library = build_cached_library("twin_stepper", folder_files(files("twin.cosim") / "native"))

The cache lives in ``TWIN_CACHE_DIR`` or ``$XDG_CACHE_HOME/twin/fmus``; an entry is written
under a temporary name and renamed into place, so a concurrent reader never sees half a file.

A cached binary is loaded into this process (the FMUs' and the stepper's shared libraries run
their constructors when loaded), so the cache is trusted only as far as it is private and
checked: it is created 0700 and refused when another user owns it or group or others may write
into it (:class:`~twin.errors.UnsafeCacheError`); every entry has a ``.sha256`` file written
when it was built, and an entry whose bytes do not match it (or that has none: a file somebody
put there) is never returned: it is built anew over it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

from twin.errors import BuildError, ToolMissingError, UnsafeCacheError
from twin.files import write_text_atomic

#: environment variable naming the cache folder
CACHE_ENV = "TWIN_CACHE_DIR"
#: file name suffix of a shared library on this platform
LIBRARY_SUFFIX = {"win32": ".dll", "darwin": ".dylib"}.get(sys.platform, ".so")


def cache_dir() -> Path:
    """Where built files are kept: ``TWIN_CACHE_DIR`` or ``$XDG_CACHE_HOME/twin/fmus``, as an
    absolute path (fmpy changes the working directory while it loads a library)."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).absolute()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return (Path(base) / "twin" / "fmus").absolute()


def private_cache_dir() -> Path:
    """:func:`cache_dir`, created 0700 when missing; :class:`UnsafeCacheError` when it is not a
    folder of this user's that only this user may write into."""
    folder = cache_dir()
    if not folder.exists():
        folder.mkdir(parents=True, exist_ok=True)
        os.chmod(folder, 0o700)
    st = folder.stat()
    fix = f"(chmod 700 {folder}, or set {CACHE_ENV} to a private folder)"
    if not stat.S_ISDIR(st.st_mode):
        raise UnsafeCacheError(f"the FMU cache {folder} is not a folder {fix}", source=CACHE_ENV)
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise UnsafeCacheError(f"the FMU cache {folder} belongs to another user {fix}", source=CACHE_ENV)
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise UnsafeCacheError(
            f"the FMU cache {folder} is writable by others (mode {stat.S_IMODE(st.st_mode):o}) {fix}",
            source=CACHE_ENV,
        )
    return folder


def digest_file(path: Path) -> Path:
    """Where the SHA-256 of a cached binary is kept: ``<file>.sha256`` beside it."""
    return path.with_name(path.name + ".sha256")


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def record_digest(path: Path, sha256: str | None = None) -> None:
    """Write ``path``'s SHA-256 beside it (atomically), as the cache's record of what it built."""
    write_text_atomic(digest_file(path), (sha256 or file_sha256(path)) + "\n")


def verified(path: Path) -> bool:
    """Whether ``path`` is a cached binary whose bytes match the SHA-256 recorded at its build."""
    try:
        expected = digest_file(path).read_text(encoding="ascii").strip()
        return path.is_file() and file_sha256(path) == expected
    except (OSError, UnicodeDecodeError):
        return False


#: what the build needs besides cmake: (what it is, the commands that provide it (the first
#: found is used), its environment variable, the Debian package that installs it). fmpy's
#: CMakeLists enables C and C++ (cmake stops with "Configuring incomplete" without a C++
#: compiler, the cause only in its log), and cmake's default generator runs make
_TOOLS = (
    ("a C compiler", ("cc", "gcc", "clang"), "CC", "gcc"),
    ("a C++ compiler", ("c++", "g++", "clang++"), "CXX", "g++"),
)


def _which_tool(commands: tuple[str, ...], env: str | None) -> str | None:
    if env and os.environ.get(env):
        return os.environ[env]
    return next((path for c in commands if (path := shutil.which(c))), None)


def _generator() -> tuple[str | None, str | None]:
    """The build tool cmake's generator runs and the ``-G`` to ask for it: make for cmake's
    default, ninja where make is missing (or ``CMAKE_GENERATOR=Ninja`` asks for it); (None,
    the package to install) when neither is there."""
    wanted = os.environ.get("CMAKE_GENERATOR", "")
    if wanted and "ninja" not in wanted.lower() and "makefiles" not in wanted.lower():
        return wanted, None  # a generator the user chose and knows: cmake checks its tool
    ninja, make = shutil.which("ninja"), shutil.which("make") or shutil.which("gmake")
    if "ninja" in wanted.lower():
        return (ninja, None) if ninja else (None, "ninja-build")
    if make:
        return make, None
    if ninja and not wanted:
        return ninja, "Ninja"
    return None, "make"


def find_tools() -> tuple[str, str]:
    """The C compiler and cmake, once every tool the build needs is there (a C and a C++
    compiler, make or ninja, cmake); else :class:`ToolMissingError`, one line naming each
    missing tool and the Debian package that installs it."""
    found: dict[str, str] = {}
    missing: list[tuple[str, str]] = []  # (what, package)
    for what, commands, env, package in _TOOLS:
        path = _which_tool(commands, env)
        if path:
            found[env] = path
        else:
            missing.append((f"{what} ({commands[1]}, or set {env})", package))
    build_tool, package = _generator()
    if build_tool is None:
        named = "ninja (CMAKE_GENERATOR=Ninja)" if package == "ninja-build" else "make or ninja"
        missing.append((named, package or "make"))
    if missing:
        whats = " and ".join(w for w, _ in missing)
        packages = " ".join(p for _, p in missing)
        raise ToolMissingError(
            f"cannot build the FMUs: {whats} not found: install "
            f"{'it' if len(missing) == 1 else 'them'} (Debian: apt-get install -y {packages})",
            source="build",
        )
    cmake = shutil.which("cmake")
    if not cmake:
        raise ToolMissingError(
            "cmake not found: pip install cmake (it is a dependency of twin) or apt-get install -y cmake",
            source="build",
        )
    return found["CC"], cmake


def generator_flags() -> list[str]:
    """``-G Ninja`` where make is missing and ninja is there (cmake's default needs make)."""
    tool, generator = _generator()
    return ["-G", generator] if tool and generator else []


def progress(line: str) -> None:
    """One line of progress on standard error, flushed, terminal or not: a first build of the
    FMUs takes seconds each, and a log of a batch job shows what the time went to."""
    print(f"twin: {line}", file=sys.stderr, flush=True)


def content_hash(files: Mapping[str, bytes], salt: str = "") -> str:
    """16 hex digits of a SHA-256 over ``salt`` and every (name, content) pair in order."""
    h = hashlib.sha256(salt.encode())
    for name, data in files.items():
        h.update(name.encode() + b"\0" + data + b"\0")
    return h.hexdigest()[:16]


#: the cache's record of source content hashes by their files' stat keys (hash_by_stats)
SOURCE_HASHES = "source-hashes.json"
#: a stat key is recorded only when every file of it is older than this (seconds): a file
#: rewritten within the file system's clock tick keeps its modification time (git's "racy
#: clean" case), and one being written now may change again
SETTLED_S = 2.0
#: the record keeps the last this many keys (one per version of a model's sources, per checkout)
RECORDED_HASHES = 256
_DIGEST = re.compile(r"[0-9a-f]{16}")
#: the records as this process read (and added to) them, by cache folder
_recorded: dict[Path, dict[str, str]] = {}


def hash_by_stats(stats: Sequence[tuple[Any, ...]], salt: str, compute: Callable[[], str]) -> str:
    """The content hash ``compute()`` of the files whose stat keys (path, size, modification
    and change time, inode) are ``stats``, kept in the cache folder (:data:`SOURCE_HASHES`) by
    a SHA-256 of the keys and ``salt``, so that a fresh process hashes no source whose files
    did not change since. Where the key says nothing about the content (a file changed within
    :data:`SETTLED_S`), it is computed and not recorded. A record that cannot be read or
    written is computed around. The record only names which build to look up: what is loaded
    is still checked against the SHA-256 recorded at its build (:func:`cached`)."""
    key = hashlib.sha256(repr((salt, tuple(stats))).encode()).hexdigest()[:32]
    record = private_cache_dir() / SOURCE_HASHES
    if record not in _recorded:
        _recorded[record] = _read_hashes(record)
    found = _recorded[record].get(key)
    if found is not None:
        return found
    digest = compute()
    settled = time.time_ns() - int(SETTLED_S * 1e9)
    if all(s[2] < settled and s[3] < settled for s in stats):
        known = {**_read_hashes(record), key: digest}  # with what other processes added meanwhile
        _recorded[record] = dict(list(known.items())[-RECORDED_HASHES:])
        with contextlib.suppress(OSError):
            write_text_atomic(record, json.dumps(_recorded[record], indent=0) + "\n")
    return digest


def _read_hashes(record: Path) -> dict[str, str]:
    """The record of :func:`hash_by_stats` (empty when missing or unreadable; an entry that is
    not a key and 16 hex digits is left out)."""
    try:
        data = json.loads(record.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {k: v for k, v in data.items() if isinstance(v, str) and _DIGEST.fullmatch(v)}


def folder_files(folder: Path | Traversable) -> dict[str, bytes]:
    """The files directly in ``folder`` (a path or a package resource), by name, sorted."""
    entries = sorted((p for p in folder.iterdir() if p.is_file()), key=lambda p: p.name)
    return {p.name: p.read_bytes() for p in entries if not p.name.startswith(".")}


#: held while cmake is started; :func:`no_more_builds` closes it for good
_STARTS = threading.Lock()
_builds_closed = False


def no_more_builds() -> None:
    """From now on :func:`run_cmake` starts no process (it raises :class:`BuildError` at once).

    A command that a signal ends kills every process it started (:func:`twin.cli.interrupt.end_children`)
    while its main thread runs on: a build between two FMUs could start the next one's cmake
    after the last look for processes, and that cmake (and its make and compilers) outlived
    the command. Closed first, every cmake started is there to be found. Waits for a start
    under way."""
    global _builds_closed
    with _STARTS:
        _builds_closed = True


def run_cmake(source: Path, build: Path, what: str, defines: Mapping[str, str] | None = None) -> None:
    """Configure ``source`` into ``build`` and build its ``install`` target.

    Raises :class:`ToolMissingError` without a compiler or cmake and :class:`BuildError`
    naming ``what`` with the tail of the compiler output when a step fails, or at once once
    the command is ending (:func:`no_more_builds`).
    """
    cc, cmake = find_tools()
    flags = [f"-D{k}={v}" for k, v in (defines or {}).items()]
    steps = {
        "configure": [cmake, "-S", str(source), "-B", str(build), *generator_flags(), *flags],
        "build": [cmake, "--build", str(build), "--target", "install"],
    }
    for step, cmd in steps.items():
        with _STARTS:
            if _builds_closed:
                raise BuildError(f"building {what}: not started, the command is ending")
            proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        with proc:
            out, err = proc.communicate()
        if proc.returncode != 0:
            raise _build_failure(what, step, cc, out + err)


def _build_failure(what: str, step: str, cc: str, output: str) -> BuildError:
    """One line for a failed build, the whole compiler output in a log file it names: a
    compiler that cannot compile a test program says what to install."""
    log = private_cache_dir() / "last-build-error.log"
    try:
        log.write_text(f"building {what} failed ({step})\n{output}", encoding="utf-8")
        where = f"; the full output is in {log}"
    except OSError:
        where = ""
    if (
        "not able to compile a simple test program" in output
        or "No CMAKE_C_COMPILER could be found" in output
    ):
        return BuildError(
            f"the C compiler {cc} cannot compile a test program: install a working one "
            f"(Debian: apt-get install -y gcc) or set CC{where}"
        )
    first = next((ln.strip() for ln in output.splitlines() if "error" in ln.lower()), "see the log")
    return BuildError(f"building {what} failed ({step}): {first}{where}")


#: the scratch folders of builds in the cache: ``.scratch-<pid>-<name>-<random>``
SCRATCH = ".scratch-"


def clean_scratch(folder: Path) -> list[Path]:
    """Remove the scratch folders in ``folder`` of builds whose process no longer runs (a
    build that an interruption ended: its command leaves without the interpreter's teardown,
    and a SIGKILL leaves one too); returns them. A running build's folder is left alone."""
    from twin.fmu.workdir import alive

    gone = []
    for scratch in folder.glob(f"{SCRATCH}*"):
        pid = scratch.name.removeprefix(SCRATCH).split("-", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not alive(int(pid)):
            shutil.rmtree(scratch, ignore_errors=True)
            gone.append(scratch)
    return gone


#: an entry of other sources is pruned once nobody used it for this long: several checkouts
#: (versions of the twin, worktrees) may share the cache, and deleting another's entry as soon
#: as this one builds its own made the other's next run rebuild, or fail mid-way
PRUNE_AFTER_S = 7 * 86400.0


def cached(name: str, digest: str, suffix: str, make: Callable[[Path], Path], *, prune: bool = True) -> Path:
    """The cache entry ``<name>-<digest><suffix>``, made by ``make(scratch_dir)`` when missing.

    ``make`` returns the file it built inside the scratch folder (removed afterwards). Each use
    stamps the entry's time; with ``prune``, the other entries of ``name`` (other sources) that
    nobody used for :data:`PRUNE_AFTER_S` are deleted once the new one is in.
    """
    target = private_cache_dir() / f"{name}-{digest}{suffix}"
    if verified(target):
        _used(target)
        return target
    # missing, or a file whose bytes are not what this cache built: build it anew over it
    clean_scratch(target.parent)
    with tempfile.TemporaryDirectory(prefix=f"{SCRATCH}{os.getpid()}-{name}-", dir=target.parent) as tmp:
        built = make(Path(tmp))
        sha256 = file_sha256(built)
        os.replace(built, target)  # atomic: the scratch folder is on the same disk
    record_digest(target, sha256)
    if prune:
        now = time.time()
        for stale in target.parent.glob(f"{name}-*{suffix}"):
            try:
                st = stale.stat()
                unused = now - max(st.st_atime, st.st_mtime) > PRUNE_AFTER_S
            except OSError:
                continue  # gone already (another process pruned it)
            if stale != target and unused:
                stale.unlink(missing_ok=True)
                digest_file(stale).unlink(missing_ok=True)
    return target


def _used(entry: Path) -> None:
    """Stamp ``entry``'s access time (its modification time stays its build's): it is in use
    (see :data:`PRUNE_AFTER_S`)."""
    # a cache we may read but not stamp: its entries are then pruned by their build time
    with contextlib.suppress(OSError):
        os.utime(entry, ns=(time.time_ns(), entry.stat().st_mtime_ns))


def build_cached_library(name: str, files: Mapping[str, bytes], *, salt: str = "") -> Path:
    """A shared library built by cmake from ``files``, cached by a hash of their contents.

    ``files`` maps relative paths to contents: a ``CMakeLists.txt`` and its sources. The
    project must install a library whose file name contains ``name`` into
    ``${TWIN_OUT_DIR}``; it is built in Release mode. Old entries are kept (several checkouts
    may share the cache, each with its own sources). ``salt`` changes the key without
    changing a file (bump it when the way of building changes).
    """

    def make(scratch: Path) -> Path:
        find_tools()  # a missing tool is the one thing said, before the progress line
        progress(f"building the {name} library (first use of its sources)")
        source, out = scratch / "source", scratch / "out"
        for rel, data in files.items():
            (source / rel).parent.mkdir(parents=True, exist_ok=True)
            (source / rel).write_bytes(data)
        defines = {"CMAKE_BUILD_TYPE": "Release", "TWIN_OUT_DIR": str(out)}
        run_cmake(source, scratch / "build", f"the {name} library", defines)
        built = sorted(out.glob(f"*{name}*"))
        if not built:
            raise BuildError(
                f"building the {name} library installed nothing named *{name}* into TWIN_OUT_DIR"
            )
        return built[0]

    return cached(name, content_hash(files, salt), LIBRARY_SUFFIX, make, prune=False)
