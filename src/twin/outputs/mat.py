"""``signals.mat``: signals.csv as a MATLAB file (``twin run --format mat``), by
:func:`scipy.io.savemat`.

Written when the run is over, from ``signals.csv`` read back (the same rows and values, bit
for bit: the CSV holds each float's shortest exact text). MATLAB names cannot hold a dot, so a
column ``instance.variable`` becomes the field ``variable`` of a struct ``instance``, which
MATLAB reads as the column's own name (``load signals.mat; plot(time, thermal.t_base)``):

- ``time``: the time column (s), a column vector;
- one struct per instance, one field per recorded column of it, a column vector each; a
  variable's name that is no MATLAB name (an external FMU's ``der(x)``, ``a.b``, ``x[1]``) has
  every other character made ``_``, an ``x`` put before a first character that is not a
  letter, is cut to 63 characters, and gets ``_2``, ``_3``, ... when two names of one instance
  map to the same field;
- ``names`` and ``mat_names``: the CSV's column names (time first) and each one's name in the
  file (``low_pass.y``), so the mapping is in the file itself.

``scipy.io.loadmat(path, simplify_cells=True)`` gives ``m["low_pass"]["y"]``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from twin.files import write_atomic
from twin.outputs.sink import Outcome, OutcomeSink

__all__ = ["MAT_RESERVED", "SignalsMatSink", "mat_names", "mat_problem", "write_signals_mat"]

#: the file's own variables: no instance may be named so
MAT_RESERVED = frozenset({"time", "names", "mat_names"})
#: MATLAB's longest name (namelengthmax)
_LONGEST = 63


def _field(name: str) -> str:
    """``name`` made a MATLAB name (see the module)."""
    field = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not field[:1].isalpha() or not field[:1].isascii():
        field = "x" + field
    return field[:_LONGEST]


def mat_problem(instances: Iterable[str]) -> str | None:
    """Why instances so named cannot be structs of a MAT file (a reserved or too long name),
    or None."""
    for name in instances:
        if name in MAT_RESERVED:
            return f"an instance named {name!r} would clash with the MAT file's {name!r} variable"
        if len(name) > _LONGEST or _field(name) != name:
            return f"the instance name {name!r} is no MATLAB name (at most {_LONGEST} characters)"
    return None


def mat_names(columns: Sequence[str]) -> dict[str, tuple[str, str]]:
    """Each ``instance.variable`` column's (struct, field) in the file, in column order."""
    out: dict[str, tuple[str, str]] = {}
    taken: dict[str, set[str]] = {}
    for column in columns:
        instance, _, variable = column.partition(".")
        used = taken.setdefault(instance, set())
        field = base = _field(variable)
        k = 2
        while field in used:
            suffix = f"_{k}"
            field = base[: _LONGEST - len(suffix)] + suffix
            k += 1
        used.add(field)
        out[column] = (instance, field)
    return out


def write_signals_mat(csv_path: Path, mat_path: Path) -> Path:
    """``mat_path`` from the signals CSV ``csv_path`` (see the module), written atomically."""
    from scipy.io import savemat

    from twin.outputs.csv import read_signals_csv

    table = read_signals_csv(csv_path)
    columns = table.names()
    mapping = mat_names(columns)
    data: dict[str, Any] = {"time": np.asarray(table.time, dtype=np.float64)}
    for column, (instance, field) in mapping.items():
        data.setdefault(instance, {})[field] = np.asarray(table[column], dtype=np.float64)
    data["names"] = np.array(["time", *columns], dtype=object)
    data["mat_names"] = np.array(["time", *(f"{i}.{f}" for i, f in mapping.values())], dtype=object)

    def save(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object: savemat would add ".mat" to a name
            savemat(f, data, oned_as="column", long_field_names=True, do_compression=True)

    return write_atomic(mat_path, save)


class SignalsMatSink(OutcomeSink):
    """``signals.mat``, written from ``signals.csv`` (``csv_path``) once the run is over: the
    CSV's sink closes before it (:meth:`twin.outputs.run_folder.RunFolder.run_sinks`)."""

    def __init__(self, path: Path, csv_path: Path) -> None:
        self.path = path
        self.csv_path = csv_path

    def write_outcome(self, outcome: Outcome) -> None:
        write_signals_mat(self.csv_path, self.path)
