"""The ``twin`` console script.

Importing the twin takes a few tenths of a second; a Ctrl-C in that time would end in a
traceback of the import machinery. Here it ends as every other interrupt of the command does:
one line and exit code 130 (nothing has been written yet).
"""

from __future__ import annotations

import sys


def main() -> int:
    """Run ``twin.cli.main`` with an interrupt during its import reported in one line."""
    try:
        from twin.cli import main as cli_main

        return cli_main(own_process=True)  # the process is the command's alone
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return 130
