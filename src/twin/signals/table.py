"""The signal table: one time axis and named columns in SI units.

Column names are ``"<instance>.<variable>"`` for FMU variables (``thermal.t_base``) and
``"errormodel.<name>"`` for quantities the error model derives. Each column carries its unit
and the subsystem it belongs to (used to group series in plots and recordings).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Signal:
    """Metadata of one column."""

    name: str
    unit: str
    subsystem: str
    description: str = ""


@dataclass
class SignalTable:
    """Time (s, float64) and columns (float64 arrays of the same length)."""

    time: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict[str, Signal] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.time = np.asarray(self.time, dtype=np.float64)
        for name, values in self.columns.items():
            self._check(name, values)

    def _check(self, name: str, values: np.ndarray) -> None:
        if values.shape != self.time.shape:
            raise ValueError(f"column '{name}' has shape {values.shape}, time has {self.time.shape}")
        if name not in self.meta:
            raise ValueError(f"column '{name}' has no metadata")

    def add(self, signal: Signal, values: np.ndarray) -> None:
        """Add (or replace) a column."""
        values = np.asarray(values, dtype=np.float64)
        self.meta[signal.name] = signal
        self._check(signal.name, values)
        self.columns[signal.name] = values

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def __len__(self) -> int:
        return int(self.time.shape[0])

    def names(self) -> list[str]:
        return list(self.columns)

    def subset(self, names: Iterable[str]) -> SignalTable:
        """A table of the same time axis with only ``names`` (in that order); arrays are shared."""
        out = SignalTable(self.time)
        for name in names:
            out.add(self.meta[name], self.columns[name])
        return out

    def subsystems(self) -> Mapping[str, list[str]]:
        """Column names grouped by subsystem, in insertion order."""
        groups: dict[str, list[str]] = {}
        for name in self.columns:
            groups.setdefault(self.meta[name].subsystem, []).append(name)
        return groups


@dataclass(frozen=True)
class Block:
    """A chunk of rows on the run's time axis: ``time`` (s) and one array per column name.

    What a recorder hands its sinks while a run goes (see :mod:`twin.outputs.sink`), and what the
    CSV reader hands on (:mod:`twin.signals.csv`).
    """

    time: np.ndarray
    columns: Mapping[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.time.shape[0])

    def rows(self, sl: slice | np.ndarray) -> Block:
        """The rows ``sl`` of every column."""
        return Block(self.time[sl], {k: v[sl] for k, v in self.columns.items()})

    @staticmethod
    def join(blocks: Sequence[Block]) -> Block:
        """The rows of ``blocks`` one after the other (the columns of the first)."""
        if len(blocks) == 1:
            return blocks[0]
        return Block(
            np.concatenate([b.time for b in blocks]),
            {k: np.concatenate([b.columns[k] for b in blocks]) for k in blocks[0].columns},
        )
