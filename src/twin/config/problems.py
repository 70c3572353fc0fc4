"""Collecting a scenario file's problems, and reading its TOML and its tables.

Every problem is kept with the file name and the dotted key, so all of them are reported at
once, one line each (like FMPy's validators), as :class:`~twin.errors.ConfigErrors`.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.config.durations import parse_duration
from twin.errors import ConfigError


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
        if any(e.key == key and e.message == message for e in self.items):
            return  # one line per problem: a list connection repeats its source for each input
        self.items.append(ConfigError(message, source=self.source, key=key))

    def unknown_keys(self, table: Mapping[str, Any], allowed: set[str], prefix: str) -> None:
        """A problem for every key of ``table`` not in ``allowed``."""
        for k in table:
            if k not in allowed:
                hint = ", ".join(sorted(allowed))
                self.add(f"{prefix}{k}", f"unknown key (expected one of: {hint})")

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

    def number(self, table: Mapping[str, Any], key: str, prefix: str) -> float | None:
        """``table[key]`` as a finite float, or None and a problem."""
        v = table.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float):
            self.add(prefix + key, f"expected a number, got {v!r}" if key in table else "missing (a number)")
            return None
        if not math.isfinite(v):
            self.add(prefix + key, f"expected a finite number, got {v!r}")
            return None
        return float(v)


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


def read_toml(path: Path, source: str) -> dict[str, Any]:
    """A TOML file's data; :class:`ConfigError` (naming ``source``) when it cannot be read."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", source=source) from None
    except IsADirectoryError:
        raise ConfigError("is a directory, expected a TOML file", source=source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc.__class__.__name__}: {exc}", source=source) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", source=source) from None


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
