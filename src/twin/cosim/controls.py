"""What steers a run from outside while it goes, as one value handed down once.

simpy hands each process its ``Environment`` and nothing else; the twin hands every layer of a
run (the command, the pipeline, the master, its simpy processes) one :class:`RunControls`:
whether to stop, where to report progress, when to save the whole twin and where to, where
to say a line to the user, and where the FMUs' own log messages go.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["RunControls"]


def _never() -> str | None:
    return None


def _silent(line: str) -> None:
    return None


@dataclass(frozen=True)
class RunControls:
    """``stop`` is asked between batches: the name of a signal ends the run as "interrupted";
    ``progress(now_ns, duration_ns)`` is told at each hundredth of the run; every
    ``checkpoint_every_ns`` of simulated time ``on_checkpoint`` receives the whole master's
    state (never at the end: the run is complete then); ``echo`` takes a line for the user;
    ``fmi_log(instance, status, category, message)``, when given, takes every message the FMUs
    log, their debug logging switched on (``twin run --fmi-logging``)."""

    stop: Callable[[], str | None] = _never
    progress: Callable[[int, int], None] | None = None
    checkpoint_every_ns: int | None = None
    on_checkpoint: Callable[[dict[str, Any]], None] | None = None
    echo: Callable[[str], None] = _silent
    fmi_log: Callable[[str, str, str, str], None] | None = None

    def stopped(self) -> str | None:
        """The name of the signal that asked the run to stop, or None."""
        return self.stop()

    def saving(self, every_ns: int | None, save: Callable[[dict[str, Any]], None]) -> RunControls:
        """A copy that saves the whole twin with ``save`` every ``every_ns`` (None: never)."""
        return dataclasses.replace(
            self, checkpoint_every_ns=every_ns, on_checkpoint=save if every_ns else None
        )
