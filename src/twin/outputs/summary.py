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
import json
import math
import os
import uuid
from collections.abc import Mapping
from pathlib import Path, PurePath
from typing import Any

import numpy as np

__all__ = ["to_jsonable", "write_json_atomic", "write_summary"]


def to_jsonable(obj: Any, _where: str = "$") -> Any:
    """``obj`` as plain JSON types: non-finite floats -> None, numpy -> Python, paths -> str.

    Mappings (keys must be strings), lists, tuples, numpy arrays, dataclass instances,
    enums, paths and dates are converted recursively; any other type raises ``TypeError``
    naming where it sits (``$.timings.step``).
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, (bool, np.bool_)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist(), _where)
    if isinstance(obj, Mapping):
        out: dict[str, Any] = {}
        for key, value in obj.items():
            if not isinstance(key, str):
                raise TypeError(f"{_where}: key {key!r} is a {type(key).__name__}, JSON keys must be str")
            out[key] = to_jsonable(value, f"{_where}.{key}")
        return out
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, f"{_where}[{i}]") for i, v in enumerate(obj)]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}, _where)
    if isinstance(obj, enum.Enum):
        return to_jsonable(obj.value, _where)
    if isinstance(obj, PurePath):
        return str(obj)
    if isinstance(obj, (dt.datetime, dt.date)):
        return obj.isoformat()
    if isinstance(obj, np.generic):  # e.g. np.str_
        return to_jsonable(obj.item(), _where)
    raise TypeError(f"{_where}: cannot write a {type(obj).__name__} to JSON")


def write_json_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    # os.open with mode 0o666 honours the umask, unlike tempfile's private 0o600 files,
    # so the summary gets the same permissions as the other outputs of the run.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())  # data on disk before the rename makes it visible
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_summary(path: str | os.PathLike[str], data: Mapping[str, Any]) -> Path:
    """Write ``data`` as JSON (indent 2, insertion order, NaN/Inf as null) atomically to ``path``."""
    text = json.dumps(to_jsonable(data), indent=2, ensure_ascii=False, allow_nan=False)
    return write_json_atomic(path, text + "\n")
