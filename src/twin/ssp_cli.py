"""``twin export-ssp SCENARIO -o tester.ssp``: a scenario's system as an SSP 1.0 archive."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from twin.errors import ConfigError

__all__ = ["add_parser"]


def _out_path(text: str) -> Path:
    from twin.outputs.run_folder import check_output_file

    out = check_output_file(Path(text), "-o", ".ssp")
    if not out.resolve().parent.is_dir():  # the archive is written beside itself, then renamed
        raise ConfigError(f"no folder {out.resolve().parent}", source="-o")
    return out


def _cmd_export_ssp(args: argparse.Namespace) -> int:
    from twin.cli import _load
    from twin.ssp import export_ssp

    out = _out_path(args.output)  # checked before the scenario's FMUs are built
    scenario = _load(args)
    done = export_ssp(scenario, out)
    for what in done.left_out:
        print(f"twin: export-ssp: not in the archive: {what}", file=sys.stderr)
    print(f"{out}: {done.components} components, {done.connections} connections (SSP 1.0)")
    return 0


def add_parser(sub: Any) -> None:
    """``twin export-ssp``."""
    p = sub.add_parser(
        "export-ssp",
        help="write a scenario's system (FMUs, parameters, connections) as an SSP 1.0 archive",
    )
    p.add_argument("scenario", nargs="?", help="scenario TOML file or a shipped scenario's name")
    p.add_argument("-o", "--output", required=True, metavar="FILE.ssp", help="the archive to write")
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="override a scenario value by its dotted key"
    )
    p.set_defaults(func=_cmd_export_ssp)
