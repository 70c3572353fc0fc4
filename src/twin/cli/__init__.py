"""The ``twin`` command: one module per command, each parsing its arguments, calling the
package and printing what it did (:mod:`twin.cli.parser` assembles the one parser).

Exit codes: 0 success, 2 bad input (one line per problem naming file and key, no
traceback), 1 a failure while running, 130/143 interrupted.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Sequence

from twin.cli import interrupt


def main(argv: Sequence[str] | None = None, *, own_process: bool = False) -> int:
    """The ``twin`` command on ``argv`` (default: ``sys.argv[1:]``); its exit code.

    ``own_process`` says the process is the command's alone (the console script and
    ``python -m twin``): a run may then tune it (:mod:`twin.cli.process`), and the first
    SIGINT or SIGTERM ends it whatever it does (:mod:`twin.cli.interrupt`, installed before
    the twin imports). Whatever a command raises after a signal came is part of its stopping:
    the one line says "interrupted", the exit code is the signal's.
    """
    try:
        if own_process:
            interrupt.install()
        else:
            interrupt.reset()
        from twin.cli.parser import run_command
    except KeyboardInterrupt:  # before the watcher took the signals, or a program's own Ctrl-C
        interrupt.record(signal.SIGINT)
        interrupt.say()
        return 130
    code = run_command(argv, own_process=own_process)
    if interrupt.caught() is not None:  # a command that finished after the signal came
        interrupt.say()
        code = interrupt.exit_code()
    return code


def console() -> int:
    """The console script ``twin``: :func:`main` in a process of its own. A command a signal
    ended leaves at once: the interpreter's teardown would wait for Dask's threads, and every
    process it started is ended first."""
    code = main(own_process=True)
    if interrupt.caught() is not None:
        interrupt.park()
        interrupt.end_children()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        os._exit(code)
    return code
