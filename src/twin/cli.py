"""The ``twin`` command: build the FMUs, run and validate scenarios.

Exit codes: 0 success, 2 bad input (one line per problem naming file and key, no
traceback), 1 a failure while running, 130/143 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from twin import __version__
from twin.errors import ConfigError, TwinError


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad arguments as one line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(message, source=self.prog)


def _cmd_build(args: argparse.Namespace) -> int:
    from twin.fmu.build import build_all

    out = Path(args.out) if args.out else None
    for model, path in build_all(out).items():
        print(f"{model}: {path}")
    return 0


def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="twin", description="Co-simulation digital twin of a spherical plain bearing tester."
    )
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    p = sub.add_parser("build", help="build every FMU in fmus/ (into the cache, or --out DIR)")
    p.add_argument("--out", metavar="DIR", help="write the .fmu files here instead of the cache")
    p.set_defaults(func=_cmd_build)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = make_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        return int(args.func(args))
    except TwinError as exc:
        print(f"twin: {exc}", file=sys.stderr)
        return exc.exit_code


if __name__ == "__main__":
    sys.exit(main())
