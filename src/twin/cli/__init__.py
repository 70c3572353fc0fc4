"""The ``twin`` command: one module per command, each parsing its arguments, calling the
package and printing what it did (:mod:`twin.cli.parser` assembles the one parser).

Exit codes: 0 success, 2 bad input (one line per problem naming file and key, no
traceback), 1 a failure while running, 130/143 interrupted.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
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
    """The console script ``twin``: :func:`main` in a process of its own, which ends when the
    command returns. A command a signal ended leaves at once: the interpreter's teardown would
    wait for Dask's threads, and every process it started is ended first. A command that
    returned leaves at once too (:func:`_leave`)."""
    code = main(own_process=True)
    if interrupt.caught() is not None:
        interrupt.park()
        interrupt.end_children()
        _flush()
        os._exit(code)
    _leave(code)
    return code  # a thread of the command still runs: the interpreter waits for it, as usual


def _leave(code: int) -> None:
    """End the process with ``code`` now, unless a (non-daemon) thread of the command still
    runs. By the time a command returns its files are written and closed and its helper
    processes ended; the interpreter's teardown would only free every module (rerun, pyarrow,
    numpy), a tenth of a second or more after a short run. The exit handlers still run first
    (temporary folders, a Dask cluster left open, coverage's data), then the streams are
    flushed. Under a profiler or a debugger the interpreter ends as usual."""
    main_thread = threading.main_thread()
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not main_thread):
        return
    if sys.getprofile() is not None or sys.gettrace() is not None:
        return  # a profiler or debugger (python -m cProfile) writes what it found at the end
    atexit._run_exitfuncs()
    _flush()
    os._exit(code)


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
