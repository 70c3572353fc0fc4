"""The one parser of the ``twin`` command, assembled from its commands' modules, and the exit
code of what a command raised."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from twin import __version__
from twin.cli import (
    build,
    calibrate,
    compensate,
    export_ssp,
    geometry,
    heldout,
    identify,
    inspect,
    interrupt,
    resume,
    run,
    scenarios,
    sweep,
    update,
    validate,
)
from twin.cli.common import Parser
from twin.errors import TwinError

#: the commands, in the order ``twin --help`` lists them
COMMANDS = (
    build,
    scenarios,
    run,
    resume,
    validate,
    compensate,
    geometry,
    calibrate,
    identify,
    inspect,
    export_ssp,
    sweep,
    heldout,
    update,
)


def make_parser() -> Parser:
    """The ``twin`` command's parser, one subcommand per module of :data:`COMMANDS`."""
    parser = Parser(
        prog="twin", description="Co-simulation digital twin of a spherical plain bearing tester."
    )
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=Parser)
    for command in COMMANDS:
        command.add_parser(sub).set_defaults(func=command.command)
    return parser


def run_command(argv: Sequence[str] | None = None, *, own_process: bool = False) -> int:
    """Parse ``argv``, run the command, and map what it raised to one line and an exit code:
    bad input 2, a failure 1, an interrupt 130 (SIGINT) or 143 (SIGTERM)."""
    parser = make_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        args.own_process = own_process
        return int(args.func(args))
    except BrokenPipeError:
        # the reader went away (`twin inspect X | head`): nothing left to say, and no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        # Ctrl-C in a program that called twin.cli.main (no watcher: twin.cli.interrupt), or
        # a stretch that gave up on a signal: nothing half-written is left behind by either
        interrupt.say()
        return interrupt.exit_code()
    except Exception as exc:
        if interrupt.caught() is not None:
            # what broke after a signal came broke of the stopping (a killed compiler, a
            # cluster closed under a task): the command was interrupted, not failed
            interrupt.say()
            return interrupt.exit_code()
        if isinstance(exc, TwinError):
            for line in str(exc).splitlines():  # several problems: one line each
                print(f"twin: {line}", file=sys.stderr)
            return exc.exit_code
        if isinstance(exc, OSError):
            # a file the command had to write or read failed it (a full disk while the Monte
            # Carlo writes uncertainty.csv, a folder removed under a run): one line, exit 1
            print(f"twin: {_os_error(exc)}", file=sys.stderr)
            return 1
        raise


def _os_error(exc: OSError) -> str:
    from twin.outputs.sink import DISK_FULL_ERRNOS

    if exc.errno in DISK_FULL_ERRNOS:
        return f"disk full ({exc.strerror}) while writing {exc.filename or 'an output file'}"
    return f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc)
