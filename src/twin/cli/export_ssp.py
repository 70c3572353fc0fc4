"""``twin export-ssp SCENARIO -o tester.ssp``: a scenario's system as an SSP 1.0 archive."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from twin.cli.common import add_set, flag, optional

NAME = "export-ssp"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME, help="write a scenario's system (FMUs, parameters, connections) as an SSP 1.0 archive"
    )
    optional(p, "scenario", "scenario TOML file or a shipped scenario's name")
    p.add_argument("-o", "--output", required=True, metavar="FILE.ssp", help="the archive to write")
    flag(
        p,
        "--lossy",
        "write the archive even if another master could not run the scenario from it as the twin does "
        "(scheduled events, delayed connections): each thing left out is named",
    )
    add_set(p)
    return p


def command(args: argparse.Namespace) -> int:
    from twin.config.load import find_scenario, load_scenario
    from twin.exchange.ssp import export_ssp
    from twin.outputs.run_folder import check_output_file

    out = check_output_file(
        Path(args.output), "-o", ".ssp", in_a_folder=True
    )  # checked before the scenario's FMUs are built
    done = export_ssp(load_scenario(find_scenario(args.scenario), args.set or []), out, lossy=args.lossy)
    for what in done.left_out:
        print(f"twin: export-ssp: left out (--lossy): {what}", file=sys.stderr)
    print(f"{out}: {done.components} components, {done.connections} connections (SSP 1.0)")
    return 0
