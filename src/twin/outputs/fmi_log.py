"""``fmi.log``: what the FMUs logged during a run (``twin run --fmi-logging``).

One line per message, as the FMU gave it to the logger callback: its instance, its status,
its category and the text (a line break in it shown as ``\\n``)::

    thermal fmi2OK [logAll] fmi2SetupExperiment: start time 0 s
    mechanics fmi2Error [logStatusError] fmi2DoStep: fault injected (error)

The file is in the run folder, not on the terminal: an FMU that logs at every step would bury
the command's own lines, and the log belongs with the run it describes. Each line is flushed
as it comes, so a run that crashes keeps what the FMUs said before.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import IO

from twin.outputs.guard import open_output
from twin.outputs.sink import ClosesOnExit

__all__ = ["FmiLogFile"]


class FmiLogFile(ClosesOnExit):
    """``fmi.log`` at ``path`` (made anew; continued with ``append``: a resumed run's), taking
    messages as a :class:`~twin.cosim.controls.RunControls` ``fmi_log``."""

    def __init__(self, path: Path, *, append: bool = False) -> None:
        self.path = path
        self.messages = 0
        #: a write that failed (a full disk): the log stops there, the run goes on
        self.error: OSError | None = None
        raw = open_output(path, "a" if append else "w")  # never through a planted link
        self._file: IO[str] | None = io.TextIOWrapper(raw, encoding="utf-8", newline="\n")

    def __call__(self, instance: str, status: str, category: str, message: str) -> None:
        if self._file is None:
            return  # a message after the run (an instance freed late) has no file to go to
        text = message.replace("\r", "\\r").replace("\n", "\\n")
        try:
            self._file.write(f"{instance} {status} [{category}] {text}\n")
            self._file.flush()
        except OSError as exc:  # raised here, it would end in the FMU's C code: kept for later
            self.error = exc
            self.close()
            return
        self.messages += 1

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None
