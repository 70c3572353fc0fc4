"""Test helpers: the paper's scenario as a dict, a tiny TOML writer (tomli_w is not a dependency)."""

from __future__ import annotations

import copy
import datetime as dt
import json
import math
import re
import tomllib
from pathlib import Path
from typing import Any

from twin.config.load import default_scenario_path

PAPER = default_scenario_path()
_PAPER_DATA = tomllib.loads(PAPER.read_text(encoding="utf-8"))


def paper_data() -> dict[str, Any]:
    """A fresh copy of the paper's scenario, the files it names made absolute (so it loads from anywhere)."""
    data = copy.deepcopy(_PAPER_DATA)
    for fmu in data["fmu"].values():
        if "parameter_files" in fmu:
            fmu["parameter_files"] = [str((PAPER.parent / f).resolve()) for f in fmu["parameter_files"]]
    if "spreads" in data.get("uncertainty", {}):
        data["uncertainty"]["spreads"] = str((PAPER.parent / data["uncertainty"]["spreads"]).resolve())
    return data


def _key(k: str) -> str:
    # bare when possible; otherwise a basic string, which a JSON string is
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dt.date | dt.time):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_array_of_tables(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _emit(lines: list[str], table: dict[str, Any], path: list[str]) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, dict) and not _is_array_of_tables(v)}
    tables = {k: v for k, v in table.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in table.items() if _is_array_of_tables(v)}
    if path and (scalars or not (tables or arrays)):
        lines.append(f"\n[{'.'.join(map(_key, path))}]")
    lines.extend(f"{_key(k)} = {_value(v)}" for k, v in scalars.items())
    for k, v in tables.items():
        _emit(lines, v, [*path, k])
    for k, items in arrays.items():
        for item in items:
            lines.append(f"\n[[{'.'.join(map(_key, [*path, k]))}]]")
            lines.extend(f"{_key(ik)} = {_value(iv)}" for ik, iv in item.items())


def dumps(data: dict[str, Any]) -> str:
    """TOML text for ``data`` (tables as [headers], arrays of tables as [[headers]])."""
    lines: list[str] = []
    _emit(lines, data, [])
    return "\n".join(lines).lstrip("\n") + "\n"


def write(path: Path, data: dict[str, Any] | str | bytes) -> Path:
    """Write a scenario (a dict, TOML text or raw bytes) to ``path``."""
    if isinstance(data, bytes):
        path.write_bytes(data)
    else:
        path.write_text(data if isinstance(data, str) else dumps(data), encoding="utf-8")
    return path


def paper_text() -> str:
    """The paper's scenario as text, the files it names made absolute."""
    text = PAPER.read_text(encoding="utf-8")
    for folder in ("calibration", "base", "validation"):
        text = text.replace(f'"{folder}/', f'"{PAPER.parent / folder}/')
    return text
