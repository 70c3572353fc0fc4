"""The one validating reader of the files the twin reads: TOML read safely, and a collector of
problems that checks each value as it is taken.

:func:`read_toml` reads a regular file of bounded size, depth and integer range; a
:class:`Problems` bound to the file takes its values (a table, a number in a range, an
integer, a boolean, a list of strings, a duration), each checked as it is taken. Every
problem is kept with the file's name and the dotted key, so all of them are reported at once,
one line each, with a did-you-mean for a misspelt key (like FMPy's validators), as
:class:`~twin.errors.ConfigErrors`. Scenarios, sweep files, held-out files, coefficients and
priors, a lab's LAB.toml and a run's run.json are all read this way.
"""

from __future__ import annotations

import copy
import datetime
import hashlib
import math
import os
import re
import stat
import threading
import tomllib
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.config.durations import parse_duration
from twin.errors import ConfigError, ConfigErrors, did_you_mean

#: TOML integers are 64-bit signed (TOML 1.0); Python's reader accepts any size
INT_LIMIT = 2**63 - 1


def number_problem(v: Any, lo: float = -math.inf, hi: float = math.inf) -> str | None:
    """Why ``v`` is not a finite number in [``lo``, ``hi``] (None when it is one): the one
    number check of every file the twin reads."""
    if not finite_number(v):
        return f"expected a finite number, got {v!r}"
    if lo <= v <= hi:
        return None
    if hi == math.inf:
        return f"expected a finite number >= {lo:g}{' (not negative)' if lo == 0 else ''}, got {v!r}"
    if lo == -math.inf:
        return f"expected a finite number <= {hi:g}, got {v!r}"
    return f"expected a finite number within [{lo:g}, {hi:g}], got {v!r}"


def finite_number(v: Any) -> bool:
    """``v`` is an int or float a float can hold: not a bool, NaN, inf, or an integer beyond 64
    bits (``math.isfinite`` raises OverflowError on an integer beyond the float range)."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return False
    return abs(v) <= INT_LIMIT if isinstance(v, int) else math.isfinite(v)


class Problems:
    """Collects problems with the file name, so all of them are reported at once."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[ConfigError] = []
        #: FMU instances declared but unusable: their problem is reported once, at the instance,
        #: not again at every connection, profile and event naming them (all of them: no [fmu])
        self.broken: set[str] = set()
        self.no_fmus = False

    def add(self, key: str, message: str) -> None:
        """One problem at ``key`` (a repeated one is kept once)."""
        problem = ConfigError(message, source=self.source, key=key)
        if any(e.key == problem.key and e.message == problem.message for e in self.items):
            return  # one line per problem: a list connection repeats its source for each input
        self.items.append(problem)

    def unknown_keys(self, table: Mapping[str, Any], allowed: set[str], prefix: str) -> None:
        """A problem for every key of ``table`` not in ``allowed``."""
        for k in table:
            if k not in allowed:
                hint = ", ".join(sorted(allowed))
                self.add(
                    f"{prefix}{k}", f"unknown key{did_you_mean(str(k), allowed)} (expected one of: {hint})"
                )

    def duration(
        self, table: Mapping[str, Any], key: str, prefix: str, *, required: bool = True
    ) -> int | None:
        """``table[key]`` as nanoseconds, or None (and a problem unless optional and absent)."""
        if key not in table:
            if required:
                self.add(prefix + key, "missing (a duration such as '480 min')")
            return None
        try:
            return parse_duration(table[key])
        except ValueError as exc:
            self.add(prefix + key, str(exc))
            return None

    def number(
        self,
        table: Mapping[str, Any],
        key: str,
        prefix: str,
        *,
        lo: float = -math.inf,
        hi: float = math.inf,
    ) -> float | None:
        """``table[key]`` as a finite float in [``lo``, ``hi``], or None and a problem."""
        if key not in table:
            self.add(prefix + key, "missing (a number)")
            return None
        why = number_problem(table[key], lo, hi)
        if why is not None:
            self.add(prefix + key, why)
            return None
        return float(table[key])

    def integer(
        self, table: Mapping[str, Any], key: str, prefix: str, *, default: int, lo: int, hi: int
    ) -> int:
        """``table[key]`` (``default`` when absent) as an integer in [``lo``, ``hi``]; else
        ``default`` and a problem."""
        v = table.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            self.add(prefix + key, f"expected an integer in [{lo}, {hi}], got {v!r}")
            return default
        return v

    def boolean(self, table: Mapping[str, Any], key: str, prefix: str, *, default: bool) -> bool:
        """``table[key]`` (``default`` when absent) as true or false; else ``default`` and a problem."""
        v = table.get(key, default)
        if not isinstance(v, bool):
            self.add(prefix + key, f"expected true or false, got {v!r}")
            return default
        return v

    def strings(self, table: Mapping[str, Any], key: str, prefix: str) -> tuple[str, ...]:
        """``table[key]`` (none when absent) as a list of strings; else () and a problem."""
        v = table.get(key, [])
        if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
            self.add(prefix + key, "expected a list of strings")
            return ()
        return tuple(v)

    def table(self, data: Mapping[str, Any], key: str, prefix: str = "") -> dict[str, Any]:
        """``data[key]`` when it is a table (``{}`` when absent), else a problem and ``{}``."""
        return table(self, data, key, prefix)

    def check(self) -> None:
        """Raise every problem found so far (one :class:`ConfigError`, or :class:`ConfigErrors`)."""
        if self.items:
            raise self.items[0] if len(self.items) == 1 else ConfigErrors(self.items)


def array_of_tables(
    p: Problems, data: Mapping[str, Any], name: str, hint: str
) -> list[tuple[int, str, dict]]:
    """(index, key, table) of each entry of a ``[[name]]`` array; problems for the rest."""
    raw = data.get(name, [])
    if not isinstance(raw, list):
        p.add(name, f"expected an array of tables [[{name}]]")
        return []
    out = []
    for i, entry in enumerate(raw):
        if isinstance(entry, dict):
            out.append((i, f"{name}[{i}]", entry))
        else:
            p.add(f"{name}[{i}]", f"expected a table{hint}")
    return out


def table(p: Problems, data: Mapping[str, Any], key: str, prefix: str = "") -> dict[str, Any]:
    """``data[key]`` when it is a table (``{}`` when absent), else a problem and ``{}``."""
    v = data.get(key, {})
    if not isinstance(v, dict):
        p.add(prefix + key, f"expected a table, got {type(v).__name__}")
        return {}
    return v


#: the largest TOML file the twin reads (a scenario is a few kB; a parameter file some 10 kB)
MAX_TOML_BYTES = 1_000_000
#: the deepest nesting of tables and arrays a TOML file may have (a scenario needs 5)
MAX_TOML_DEPTH = 32


def _read_regular_file(path: Path, source: str) -> bytes:
    """At most :data:`MAX_TOML_BYTES` of a regular file: a FIFO, device (/dev/zero), socket or
    directory is refused before anything is read from it, so none can hang or exhaust memory."""
    try:
        # O_NONBLOCK: opening a FIFO without a writer would block forever otherwise
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise ConfigError("file not found", source=source) from None
    except IsADirectoryError:
        raise ConfigError("is a directory, expected a TOML file", source=source) from None
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", source=source) from None
    st = os.fstat(fd)
    problem = None
    if stat.S_ISDIR(st.st_mode):
        problem = "is a directory, expected a TOML file"
    elif not stat.S_ISREG(st.st_mode):
        problem = "is not a regular file (a device, FIFO or socket), expected a TOML file"
    elif st.st_size > MAX_TOML_BYTES:
        problem = f"is {st.st_size} bytes, more than the {MAX_TOML_BYTES} a TOML file may have"
    if problem:
        os.close(fd)
        raise ConfigError(problem, source=source)
    with os.fdopen(fd, "rb") as f:
        try:
            data = f.read(MAX_TOML_BYTES + 1)
        except OSError as exc:
            raise ConfigError(f"cannot read: {exc.strerror or exc}", source=source) from None
    if len(data) > MAX_TOML_BYTES:  # it grew while being read
        raise ConfigError(f"is more than the {MAX_TOML_BYTES} bytes a TOML file may have", source=source)
    return data


def check_values(data: Any, source: str, key: str = "") -> None:
    """Depth and integer range of parsed TOML (a file's, a ``--set`` value's at ``key``, a
    sweep point's), walked without recursion: :class:`ConfigError` at the first problem."""
    stack: list[tuple[Any, str, int]] = [(data, key, 0)]
    while stack:
        node, key, depth = stack.pop()
        if depth > MAX_TOML_DEPTH:
            raise ConfigError(
                f"nested more than {MAX_TOML_DEPTH} levels deep", source=source, key=key or None
            )
        if isinstance(node, dict):
            stack.extend((v, f"{key}.{k}" if key else str(k), depth + 1) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, f"{key}[{i}]", depth + 1) for i, v in enumerate(node))
        elif isinstance(node, int) and not isinstance(node, bool) and abs(node) > INT_LIMIT:
            raise ConfigError(
                "integer out of range (TOML integers are 64-bit)", source=source, key=key or None
            )
        elif isinstance(node, str) and "\0" in node:
            # TOML allows "\u0000": a NUL would cut a name at the C side (FMI strings) and
            # is in no file name, unit or column of the twin's
            raise ConfigError("a NUL character (\\u0000) in a string", source=source, key=key or None)
        if isinstance(node, dict) and any("\0" in k for k in node):
            raise ConfigError("a NUL character (\\u0000) in a key", source=source, key=key or None)


#: what :func:`read_toml` parsed and checked, by the SHA-256 of the file's bytes: a sweep's
#: client builds every point's scenario anew from the same parameter files, and tomllib is
#: pure Python while :func:`toml_copy` only copies a tree. Small files only, a few.
_PARSED: OrderedDict[bytes, dict[str, Any]] = OrderedDict()
_PARSED_FILES, _PARSED_FILE_BYTES = 32, 64 * 1024
_PARSED_LOCK = threading.Lock()


def read_toml(path: Path, source: str) -> dict[str, Any]:
    """A TOML file's data; :class:`ConfigError` (naming ``source``) when it cannot be read.

    Only a regular file of at most :data:`MAX_TOML_BYTES` is read; nesting deeper than
    :data:`MAX_TOML_DEPTH` and integers beyond 64 bits are refused, each with one line. The
    file is read every time; bytes already parsed in this process are not parsed again, and
    each caller gets its own copy of the data (scenario data is changed by ``--set``)."""
    raw = _read_regular_file(path, source)
    key = hashlib.sha256(raw).digest()
    with _PARSED_LOCK:  # a worker may run points in several threads
        data = _PARSED.get(key)
        if data is not None:
            _PARSED.move_to_end(key)
    if data is None:
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(f"not UTF-8 text (byte {exc.start})", source=source) from None
        data = parse_toml(text, source)
        if len(raw) > _PARSED_FILE_BYTES:
            return data
        with _PARSED_LOCK:
            _PARSED[key] = data
            while len(_PARSED) > _PARSED_FILES:
                _PARSED.popitem(last=False)
    return toml_copy(data)


#: the scalar types of parsed TOML: immutable, so a copy may share them
_TOML_SCALARS = (str, int, float, bool, datetime.datetime, datetime.date, datetime.time)


def toml_copy(node: Any) -> Any:
    """A copy of TOML data that shares nothing mutable with ``node``: new tables and arrays,
    the same scalars (immutable). What ``copy.deepcopy`` gives without its memo: TOML data
    is a tree, so none is needed (a value of any other type is deep-copied, to stay exact
    for data a caller built)."""
    if isinstance(node, dict):
        return {k: toml_copy(v) for k, v in node.items()}
    if isinstance(node, list):
        return [toml_copy(v) for v in node]
    if node is None or isinstance(node, _TOML_SCALARS):
        return node
    return copy.deepcopy(node)


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """TOML text's data, with the checks of :func:`read_toml`. A leading byte-order mark is
    dropped: Windows editors (Notepad) write one, and tomllib refuses it."""
    try:
        data = tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", source=source) from None
    except RecursionError:
        raise ConfigError(f"nested more than {MAX_TOML_DEPTH} levels deep", source=source) from None
    except ValueError:  # an integer of thousands of digits (Python's int-str limit)
        raise ConfigError(
            "a number with thousands of digits (TOML integers are 64-bit)", source=source
        ) from None
    check_values(data, source)
    return data


#: a name that becomes a folder or file name (a scenario's run folder, a sweep's folder): no
#: separators, no "..", nothing hidden, so a derived path stays inside the output folder
SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def unsafe_name(name: object) -> str | None:
    """Why ``name`` cannot name a folder (None when it can)."""
    if isinstance(name, str) and SAFE_NAME.fullmatch(name) and ".." not in name:
        return None
    return (
        f"{name!r} cannot name a folder: 1-100 letters, digits, '.', '_' or '-', starting with a "
        "letter or digit, no '..'"
    )
