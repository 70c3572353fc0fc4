"""``summary.json``: the run's numbers (drift, error parts, residuals, indexes, timings, versions).

Keys keep the insertion order of the dict the caller builds (the order a reader expects:
scenario first, results, then timings), rather than being sorted. NaN and infinities,
which JSON does not have, become ``null``; numpy scalars and arrays become plain numbers
and lists. The file is written atomically (temporary file in the same folder, then
:func:`os.replace`), so a reader never sees half a summary and a crash keeps the old one.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import enum
import functools
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path, PurePath
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.files import write_text_atomic
from twin.outputs.sink import OutcomeSink

if TYPE_CHECKING:
    from twin.outputs.sink import Outcome

__all__ = ["SummarySink", "summary_text", "to_jsonable", "write_summary"]


def to_jsonable(obj: Any, _where: str = "$") -> Any:
    """``obj`` as plain JSON types: non-finite floats -> None, numpy -> Python, paths -> str.

    Mappings (keys must be strings), lists, tuples, numpy arrays, dataclass instances,
    enums, paths and dates are converted recursively; any other type raises ``TypeError``
    naming where it sits (``$.timings.step``).
    """
    return _jsonable(obj, _where)


# One converter per type, chosen by the type's method resolution order: ``bool`` before
# ``int`` (a bool is an int), numpy's float64 as a float, an IntEnum as its int.
@functools.singledispatch
def _jsonable(obj: Any, where: str) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return _jsonable({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}, where)
    raise TypeError(f"{where}: cannot write a {type(obj).__name__} to JSON")


@_jsonable.register(type(None))
@_jsonable.register(bool)
@_jsonable.register(str)
def _as_is(obj: bool | str | None, where: str) -> Any:
    return obj


@_jsonable.register(int)
@_jsonable.register(np.integer)
def _int(obj: int | np.integer, where: str) -> int:
    return int(obj)


@_jsonable.register(np.bool_)
def _bool(obj: np.bool_, where: str) -> bool:
    return bool(obj)


@_jsonable.register(float)
@_jsonable.register(np.floating)
def _float(obj: float | np.floating, where: str) -> float | None:
    value = float(obj)
    return value if math.isfinite(value) else None


@_jsonable.register(np.ndarray)
def _array(obj: np.ndarray, where: str) -> Any:
    return _jsonable(obj.tolist(), where)


@_jsonable.register(Mapping)
def _mapping(obj: Mapping[Any, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in obj.items():
        if not isinstance(key, str):
            raise TypeError(f"{where}: key {key!r} is a {type(key).__name__}, JSON keys must be str")
        out[key] = _jsonable(value, f"{where}.{key}")
    return out


@_jsonable.register(list)
@_jsonable.register(tuple)
def _sequence(obj: list[Any] | tuple[Any, ...], where: str) -> list[Any]:
    return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj)]


@_jsonable.register(enum.Enum)
def _enum(obj: enum.Enum, where: str) -> Any:
    return _jsonable(obj.value, where)


@_jsonable.register(PurePath)
def _path(obj: PurePath, where: str) -> str:
    return str(obj)


@_jsonable.register(dt.date)  # a datetime is a date
def _date(obj: dt.date, where: str) -> str:
    return obj.isoformat()


@_jsonable.register(np.generic)  # the numpy scalars not above, e.g. np.str_
def _numpy_scalar(obj: np.generic, where: str) -> Any:
    return _jsonable(obj.item(), where)


def summary_text(data: Mapping[str, Any]) -> str:
    """``data`` as the text of a summary file: JSON, indent 2, insertion order, NaN/Inf as null."""
    return json.dumps(to_jsonable(data), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def write_summary(path: str | os.PathLike[str], data: Mapping[str, Any]) -> Path:
    """Write ``data`` as JSON (indent 2, insertion order, NaN/Inf as null) atomically to ``path``."""
    return write_text_atomic(path, summary_text(data), sync=True)


class SummarySink(OutcomeSink):
    """``summary.json`` as a sink: written when the run's outcome is known, from its summary.

    Put it last among a run's sinks: a reader takes the file's presence as "the run is over",
    and the summary's timings then count the writing of every other file. A run that broke
    while writing its outputs gets a short one saying so instead
    (:func:`twin.pipeline.stages._failed_writing`).
    """

    def __init__(self, path: Path) -> None:
        self.path = path

    def write_outcome(self, outcome: Outcome) -> None:
        write_summary(self.path, outcome.summary())
