"""The ``twin`` command: one module per command, each parsing its arguments, calling the
package and printing what it did (:mod:`twin.cli.parser` assembles the one parser).

Exit codes: 0 success, 2 bad input (one line per problem naming file and key, no
traceback), 1 a failure while running, 130/143 interrupted.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None, *, own_process: bool = False) -> int:
    """The ``twin`` command on ``argv`` (default: ``sys.argv[1:]``); its exit code.

    ``own_process`` says the process is the command's alone (the console script and
    ``python -m twin``): a run may then tune it (:mod:`twin.cli.process`). A Ctrl-C while the
    twin imports ends as every other interrupt does: one line, 130.
    """
    try:
        from twin.cli.parser import run_command
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return 130
    return run_command(argv, own_process=own_process)


def console() -> int:
    """The console script ``twin``: :func:`main` in a process of its own."""
    return main(own_process=True)
