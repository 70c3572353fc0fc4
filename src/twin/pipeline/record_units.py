"""A lab's record in the error model's units: its time column, each column's unit, and a check
that the magnitudes are those of a wear tester.

The error model reads SI (temperatures in K, the probe and wear in m, the load in N, the torque
in N.m, the angle in rad). A lab's logger writes what it writes: the probe in mm, the
temperatures in degC, the time in minutes. ``LAB.toml`` says so::

    [errormodel]
    time = "t_min"                                   # the time column (default "time")
    units = { t_min = "min", probe = "mm", T_room = "degC" }

Each unit converts (:func:`twin.units.conversion`, the twin's one unit registry) to the SI unit
of what the column holds; a unit of another dimension (a probe in degC) is refused naming the
column. A record without its units is read as SI, and a column whose typical value is no
magnitude this tester's sensor could read in its SI unit (a probe of 4.805 "m": it was mm) is
refused naming the column and the key that would say its unit, rather than compensated into
nonsense: :data:`PLAUSIBLE`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin.config.reader import Problems
from twin.errormodel.settings import EvaluationConfig
from twin.errors import ConfigError, UnitError
from twin.signals.csv import TIME
from twin.signals.table import Block
from twin.units import conversion

__all__ = ["PLAUSIBLE", "RecordUnits", "record_units"]

#: the SI unit the error model reads each column field in
SI_UNITS: dict[str, str] = {
    "temperatures": "K",
    "reading": "m",
    "true_wear": "m",
    "load": "N",
    "torque": "N.m",
    "angle": "rad",
    "vibration": "m",
}

#: the range, in the SI unit, that a column's median must lie in for a record of this tester.
#: Generous (a lab's tester may be another size), but a unit off by 1000 or a temperature
#: scale mistaken for kelvin falls outside:
#: - temperatures 200-400 K: a lab's air and a tester's bodies (-73 to +127 degC); a record in
#:   degC read as K is 5-40 "K";
#: - the probe and the wear within 50 mm: the paper's probe reads 4.805 mm, gauging probes
#:   span a few mm to 50 mm; 4.805 read as metres is 4.8 m;
#: - the vibration within 10 mm; the angle within 4 pi (a swing is at most a turn or two; a
#:   record in degrees of a +-25 deg swing has a median near 0 and passes, its peaks do not
#:   matter here);
#: - the load within 10 MN and the torque within 100 kN.m: ten times a large bearing tester's.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "temperatures": (200.0, 400.0),
    "reading": (-0.05, 0.05),
    "true_wear": (-0.05, 0.05),
    "vibration": (-0.01, 0.01),
    "angle": (-4 * np.pi, 4 * np.pi),
    "load": (-1e7, 1e7),
    "torque": (-1e5, 1e5),
}


@dataclass(frozen=True)
class _Column:
    key: str  # the [errormodel] key that names it
    field: str  # its Columns field (its SI unit and plausible range)
    unit: str  # the unit the record gives it in ("" = SI)
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class RecordUnits:
    """How a lab's record maps to the error model's units: the time column and its factor to
    seconds, each read column's ``(factor, offset)`` to its SI unit and the key naming it."""

    source: str = "compensate"
    time: str = TIME
    time_factor: float = 1.0
    columns: Mapping[str, _Column] = field(default_factory=dict)

    def to_si(self, block: Block, record: str) -> Block:
        """``block`` in SI; a column whose median is implausible for its sensor is refused
        (checked on every block: a unit mistake shifts the whole column, one sensor's glitch
        does not move a median)."""
        time = block.time * self.time_factor if self.time_factor != 1.0 else block.time
        columns = {}
        for name, values in block.columns.items():
            col = self.columns.get(name)
            if col is None:
                columns[name] = values
                continue
            si = values if (col.factor, col.offset) == (1.0, 0.0) else values * col.factor + col.offset
            if si.size:
                self._check(name, col, float(np.median(si)), record)
            columns[name] = si
        return Block(time, columns)

    def _check(self, name: str, col: _Column, median: float, record: str) -> None:
        lo, hi = PLAUSIBLE[col.field]
        if lo <= median <= hi:
            return
        si = SI_UNITS[col.field]
        given = f"in {col.unit}" if col.unit else f"read as {si}, no unit given"
        raise ConfigError(
            f"column {name!r} ({col.key}): typical value {median:.6g} {si} ({given}) is outside "
            f"{lo:g} to {hi:g} {si}, no reading of this sensor: give its unit in {self.source}, "
            f'[errormodel] units = {{ "{name}" = "..." }}',
            source=record,
        )


def record_units(p: Problems, em: Mapping[str, Any], cfg: EvaluationConfig) -> RecordUnits:
    """The record's units from a LAB.toml ``[errormodel]`` table's ``time`` and ``units``
    (problems into ``p``, one per key)."""
    time = em.get("time", TIME)
    if not isinstance(time, str) or not time.strip():
        p.add("errormodel.time", f"expected the time column's name (a string), got {time!r}")
        time = TIME
    read = _read_columns(cfg)
    given = em.get("units", {})
    if not isinstance(given, Mapping):
        p.add("errormodel.units", f"expected a table column = unit, got {type(given).__name__}")
        given = {}
    columns = {name: _Column(key, fld, "") for name, (key, fld) in read.items()}
    time_factor = 1.0
    for name, unit in given.items():
        key = f"errormodel.units.{name}"
        if not isinstance(unit, str):
            p.add(key, f"expected a unit (a string such as 'mm' or 'degC'), got {unit!r}")
        elif name == time:
            time_factor = _seconds(p, key, unit)
        elif name not in read:
            known = ", ".join(sorted([time, *read]))
            p.add(key, f"no column the error model reads is named {name!r} (it reads {known})")
        else:
            col_key, fld = read[name]
            factor, offset = _conversion(p, key, unit, SI_UNITS[fld])
            columns[name] = _Column(col_key, fld, unit, factor, offset)
    return RecordUnits(p.source, time, time_factor, columns)


def _read_columns(cfg: EvaluationConfig) -> dict[str, tuple[str, str]]:
    """Every column the error model reads: its ``[errormodel]`` key and its Columns field."""
    out = {col: (f"errormodel.temperatures.{pt}", "temperatures") for pt, col in cfg.temperatures.items()}
    for fld in ("reading", "true_wear", "load", "torque", "angle", "vibration"):
        for col in cfg.names(fld):
            out[col] = (f"errormodel.{fld}", fld)
    return out


def _conversion(p: Problems, key: str, unit: str, si: str) -> tuple[float, float]:
    try:
        return conversion(unit, si)
    except UnitError as exc:
        p.add(key, f"{exc.message}: the column holds {si}")
        return 1.0, 0.0


def _seconds(p: Problems, key: str, unit: str) -> float:
    """The factor from the time column's ``unit`` to seconds (a duration, counting forward)."""
    factor, offset = _conversion(p, key, unit, "s")
    if offset or not factor > 0:
        p.add(key, f"{unit!r} is not a duration counting time forward")
        return 1.0
    return factor
