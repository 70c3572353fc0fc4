"""An input file: a CSV whose columns drive FMU inputs, as ``fmpy simulate --input-file`` reads one.

The file is ``time,<column>,...`` (the twin's one CSV reader, :class:`twin.signals.csv.CsvReader`:
UTF-8, times in seconds, increasing). A column is named ``instance.variable`` (the twin's
columns: a run's signals.csv can drive another run), or ``variable`` alone when the scenario
has one FMU instance; each must name a Real input no connection feeds. Each column becomes a
``table`` profile of that input (:meth:`twin.config.spec.Scenario.with_input`, checked as a
scenario file's: the input's range), in place of what drove it; a column of one row is a
constant. Between rows the value is interpolated linearly, before the first row it is the
first value and after the last the last; a time given twice is a jump, the later value holding
from that time on: fmpy's reading of an input file for a continuous input, at the
communication points.

Units: a column's unit comes from its header (``thermal.t_room [degC]``) or from the sidecar
``<stem>.units.json`` beside the file (``{"thermal.t_room": {"unit": "degC"}}``, the twin's own
format); its values are converted to the input's unit with :func:`twin.units.conversion`.
Without a unit a column is taken in the input's unit.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from twin.config.spec import Profile, Scenario
from twin.errors import ConfigError, ConfigErrors, did_you_mean

__all__ = ["drive_from_file", "read_inputs"]

#: a header holding its unit: ``name [unit]``
_WITH_UNIT = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\[\]]*)\]$")
#: the largest input file read: a table profile holds every row in memory, about 100 bytes
#: each (some two million rows of one column)
MAX_INPUT_BYTES = 64 << 20


def _sidecar_units(path: Path) -> dict[str, str]:
    """The units a ``<stem>.units.json`` beside the file gives, by column."""
    side = path.with_suffix(".units.json")
    if not side.is_file():
        return {}
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"unreadable units sidecar: {exc}", source=str(side)) from None
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise ConfigError("expected an object: column -> {unit, ...}", source=str(side))
    return {k: str(v["unit"]) for k, v in data.items() if isinstance(v.get("unit"), str) and v["unit"]}


def read_inputs(path: Path) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, str]]]:
    """(times, {column: (values, unit)}) of an input file; one line naming the file and the
    line (or column) on a bad file."""
    from twin.signals.csv import CsvReader, Flag

    source = str(path)
    if path.is_file() and path.stat().st_size > MAX_INPUT_BYTES:
        raise ConfigError(f"larger than {MAX_INPUT_BYTES >> 20} MB", source=source)

    def refuse(flag: Flag) -> None:
        raise ConfigError(f"line {flag.line}: {flag.reason}", source=source)

    reader = CsvReader(path, ({}, ""), None, on_flag=refuse)
    reader.measured, reader.jumps = False, True  # any finite number; a time twice is a jump
    try:
        blocks = list(reader.blocks())
    finally:
        reader.close()
    from twin.signals.table import Block

    names = reader.names[1:]
    if not names:
        raise ConfigError("line 1: no column after 'time' (nothing to drive)", source=source)
    data = Block.join(blocks) if blocks else None
    if data is None or len(data.time) == 0:
        raise ConfigError("no rows after the header", source=source)
    units = _sidecar_units(path)
    columns: dict[str, tuple[np.ndarray, str]] = {}
    for header in names:
        values = np.asarray(data.columns[header], dtype=np.float64)
        m = _WITH_UNIT.match(header)
        name, unit = (m["name"], m["unit"].strip()) if m else (header, units.get(header, ""))
        if not np.isfinite(values).all():
            raise ConfigError(f"column {header!r}: a value that is not a finite number", source=source)
        if name in columns:
            raise ConfigError(f"line 1: column {name!r} appears twice", source=source)
        columns[name] = (values, unit)
    return np.asarray(data.time, dtype=np.float64), columns


def _inputs(scenario: Scenario) -> dict[str, str]:
    """Every Real input of the scenario's instances no connection feeds, by its column name,
    with its unit (a lone instance's also by the variable's name alone)."""
    from twin.fmu.catalog import variables

    fed = {c.dst for c in scenario.connections}
    out: dict[str, str] = {}
    for spec in scenario.fmus:
        for name, var in variables(spec.model).items():
            target = f"{spec.name}.{name}"
            if var.causality == "input" and var.type == "Real" and target not in fed:
                out[target] = var.unit
    return out


def _target(name: str, scenario: Scenario, inputs: Mapping[str, str]) -> str | None:
    """The input a column names (``variable`` alone: the lone instance's), or None."""
    if "." not in name and len(scenario.fmus) == 1:
        name = f"{scenario.fmus[0].name}.{name}"
    return name if name in inputs else None


def _in_unit(values: np.ndarray, unit: str, target: str, to: str) -> np.ndarray:
    """``values`` (in ``unit``) in the input's unit ``to``."""
    if not unit or unit == to:
        return values
    if not to:
        raise ConfigError(f"in {unit!r}, but {target} declares no unit to convert to")
    from twin.units import conversion

    factor, offset = conversion(unit, to)
    return values * factor + offset


def drive_from_file(scenario: Scenario, path: Path) -> Scenario:
    """``scenario`` with every input the file ``path`` names driven by its column (see the
    module); every problem of the file at once, one line each naming the file and the column."""
    times, columns = read_inputs(path)
    inputs = _inputs(scenario)
    problems: list[ConfigError] = []
    for name, (values, unit) in columns.items():
        target = _target(name, scenario, inputs)
        if target is None:
            why = _unknown(name, scenario, inputs)
            problems.append(ConfigError(why, source=str(path), key=f"column {name!r}"))
            continue
        try:
            scaled = _in_unit(values, unit, target, inputs[target])
            scenario = scenario.with_input(_profile(target, times, scaled, f"{path.name}: column {name}"))
        except ConfigError as exc:  # a unit that does not convert, a value out of the input's range
            problems.append(ConfigError(exc.message or str(exc), source=str(path), key=f"column {name!r}"))
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)
    return scenario


def _profile(target: str, times: np.ndarray, values: np.ndarray, source: str) -> Profile:
    """A table through the rows, or a constant for a file of one row."""
    from types import MappingProxyType

    if len(times) == 1:
        return Profile(target, "constant", MappingProxyType({"value": float(values[0])}), (), source)
    return Profile.of_table(target, times, values, source)


def _unknown(name: str, scenario: Scenario, inputs: Mapping[str, str]) -> str:
    """Why a column drives nothing, with a close match."""
    from twin.fmu.catalog import variables

    short = {t.split(".", 1)[1]: t for t in inputs} if len(scenario.fmus) == 1 else {}
    known = [*inputs, *short]
    column = name
    if "." not in name and len(scenario.fmus) == 1:
        name = f"{scenario.fmus[0].name}.{name}"
    instance, _, var = name.partition(".")
    spec = next((f for f in scenario.fmus if f.name == instance), None)
    if spec is not None and var in variables(spec.model):
        v = variables(spec.model)[var]
        if v.causality != "input":
            return f"{name} is an {v.causality}, not an input: only inputs are driven"
        if v.type != "Real":
            return f"{name} is a {v.type} input: the twin drives Real inputs only"
        return f"input {name} is fed by a connection"
    hint = did_you_mean(name, known)
    listed = ", ".join(sorted(inputs)[:8]) + (", ..." if len(inputs) > 8 else "")
    return f"no free input named {column!r}{hint} (columns are 'instance.variable' of: {listed or 'none'})"
