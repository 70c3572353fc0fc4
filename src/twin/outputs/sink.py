"""The one interface every output of a run implements.

A run tells each of its sinks four things, in this order (the events of libcosim's observer,
cut to what a file needs):

``open(signals)``
    the recorded columns, before the first row (a sink that writes rows makes its header);
``write(block)``
    rows as the run records them, in chunks (:class:`~twin.signals.table.Block`), while the
    co-simulation goes: a killed run keeps every row a sink has written;
``close(outcome)``
    the run is over: its :class:`Outcome` (the table with the error model's columns, and the
    summary) for the sinks that write what comes after the rows (the error model's CSV, the
    plot, the summary); every sink finishes its file;
``fail(error)``
    the run broke with an exception nothing else handled: keep what is written, release the
    file, write nothing new.

A sink whose file another process makes (the plots) begins it early (:meth:`Sink.begin`,
asked before any sink closes). A run with no rows to stream (``twin compensate`` on a CSV)
goes straight to ``close``. A sink that can continue its file after a resumed run says
where its file stands (:meth:`Sink.checkpoint`, saved in the run's checkpoint).

Adding an output is one class with these four methods in its own module, and a line in
:mod:`twin.outputs.run_folder` that names its file and puts it in the run's list.
"""

from __future__ import annotations

import errno
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, ClassVar, Self

if TYPE_CHECKING:
    from twin.signals.table import Block, Signal, SignalTable

__all__ = ["DISK_FULL_ERRNOS", "ClosesOnExit", "Outcome", "OutcomeSink", "Sink"]

#: the errors of a full disk or a file-size limit: a sink failing on one writes nothing more
DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})


class Outcome:
    """What a finished run hands its sinks when they close.

    ``table`` holds the columns kept in memory (those the error model reads) plus the error
    model's, ``columns`` names the error model's (in the order they are written); both are
    empty (``None``, ``()``) when the error model did not run. :meth:`summary` makes the
    summary on its first call, so its timings count every file written before it.
    """

    def __init__(
        self,
        table: SignalTable | None,
        columns: tuple[str, ...],
        summarize: Callable[[], Mapping[str, Any]],
    ) -> None:
        self.table = table
        self.columns = columns
        self._summarize = summarize
        self._summary: Mapping[str, Any] | None = None

    def summary(self) -> Mapping[str, Any]:
        """The run's summary (the content of summary.json); the same on every call."""
        if self._summary is None:
            self._summary = self._summarize()
        return self._summary


class Sink(ABC):
    """One output of a run (see the module docstring for when each method is called).

    ``path`` is its file (named in the run's timings and in what an interrupted run left
    out); a ``skippable`` sink only draws what the others hold (the plots): a run stopped
    after its co-simulation leaves it out unless it has begun.
    """

    path: Path
    skippable: ClassVar[bool] = False

    @abstractmethod
    def open(self, signals: list[Signal]) -> None:
        """The recorded columns, before the first block."""

    @abstractmethod
    def write(self, block: Block) -> None:
        """Rows of every recorded column, in time order."""

    @abstractmethod
    def close(self, outcome: Outcome) -> None:
        """The run is over: finish the file (idempotent)."""

    @abstractmethod
    def fail(self, error: BaseException) -> None:
        """The run broke: keep what is written and release the file (also after close)."""

    def begin(self, outcome: Outcome) -> bool:
        """The outcome is known, before any sink closes: True when this sink has begun its
        file now (another process draws it while the files before it are written), to be
        finished by :meth:`close`. By default nothing begins early."""
        return False

    def checkpoint(self) -> dict[str, Any]:
        """Where its file stands, saved in a run's checkpoint so that a resumed run continues
        it (empty: a file written anew, or written only at the end)."""
        return {}


class OutcomeSink(Sink):
    """Base of the sinks that write only when the run is over, from its outcome (the error
    model's CSV, the plot, the summary): the streamed rows are not theirs, and a run that
    broke leaves them nothing begun to release. Subclasses implement :meth:`write_outcome`,
    called on the first :meth:`close` only.
    """

    _done = False

    def open(self, signals: list[Signal]) -> None:
        """Nothing to prepare: the file is written whole at the end."""
        return  # deliberately nothing (see the docstring)

    def write(self, block: Block) -> None:
        """The streamed rows are not this file's."""
        return  # deliberately nothing (see the docstring)

    def close(self, outcome: Outcome) -> None:
        if not self._done:
            self.write_outcome(outcome)
            self._done = True

    def fail(self, error: BaseException) -> None:
        """Nothing was begun before the outcome: nothing to release, nothing written."""
        return  # deliberately nothing (see the docstring)

    @abstractmethod
    def write_outcome(self, outcome: Outcome) -> None:
        """Write this sink's file from the run's outcome."""


class ClosesOnExit(ABC):
    """A ``with`` block closes the object: for writers whose ``close()`` is idempotent."""

    @abstractmethod
    def close(self) -> None:
        """Finish and release the file; calling it again does nothing."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
