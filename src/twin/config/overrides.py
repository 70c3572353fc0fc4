"""``--set KEY=VALUE`` overrides of a scenario's data, applied before it is checked."""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from typing import Any

from twin.config.reader import check_values
from twin.errors import ConfigError, ConfigErrors


def split_key(key: str, source: str = "--set") -> list[str]:
    """Dotted key with optional quoted parts: ``connections."thermal.t_spindle"``."""
    parts, buf, quoted = [], "", False
    for ch in key:
        if ch == '"':
            quoted = not quoted
        elif ch == "." and not quoted:
            parts.append(buf)
            buf = ""
        else:
            buf += ch
    parts.append(buf)
    if quoted or any(not p for p in parts):
        raise ConfigError(f"malformed key {key!r}", source=source)
    return parts


def apply_overrides(data: dict[str, Any], overrides: Sequence[str], source: str = "--set") -> None:
    """Apply ``KEY=VALUE`` overrides in place; VALUE is read as TOML (else as a plain string).

    ``source`` names the overrides in messages (``load_scenario`` adds the file name); every
    bad override is reported at once.
    """
    problems: list[ConfigError] = []
    for item in overrides:
        try:
            _apply_override(data, item, source)
        except ConfigError as exc:
            problems.append(exc)
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)


def _apply_override(data: dict[str, Any], item: str, source: str) -> None:
    if "=" not in item:
        raise ConfigError(f"expected KEY=VALUE, got {item!r}", source=source)
    key, raw = item.split("=", 1)
    parts = split_key(key.strip(), source)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except (RecursionError, ValueError):
        raise ConfigError(
            "the value is nested too deeply or has too many digits", source=source, key=key
        ) from None
    check_values(value, source, key)  # the depth and integer range a file's values have
    node = data
    for p in parts[:-1]:
        child = node.get(p)
        if child is None:
            child = node[p] = {}
        elif not isinstance(child, dict):
            raise ConfigError(f"cannot set {key!r}: '{p}' is not a table", source=source, key=key)
        node = child
    node[parts[-1]] = value
