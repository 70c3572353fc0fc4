"""``twin calibrate [SCENARIO]``: fit the thermal network to the paper's measured temperature rises."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.cli.common import optional

NAME = "calibrate"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="fit the thermal network to the paper's measured temperature rises")
    optional(
        p,
        "scenario",
        "scenario file or shipped name whose thermal network is calibrated (default: the paper's)",
    )
    # one target or the other: --write with --out once wrote --out and left the committed
    # file as it was, without a word
    target = p.add_mutually_exclusive_group()
    target.add_argument(
        "--out",
        metavar="FILE",
        help="parameter file to write (default: runs/calibrate/ under the name of the scenario's "
        "calibration file, e.g. runs/calibrate/li2017-thermal-network.toml)",
    )
    target.add_argument(
        "--write",
        action="store_true",
        help="replace the calibration file the scenario includes instead (for the shipped scenarios: the "
        "repository's, which needs the editable install `pip install -e .`)",
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.calibration.thermal import calibrate_file
    from twin.config.load import find_scenario
    from twin.outputs.run_folder import check_output_file

    # checked before the fits (seconds): a parameter file .toml, its report beside it as .json
    out = check_output_file(Path(args.out), "--out", ".toml") if args.out is not None else None
    # a file, or a shipped scenario's name as every other command takes it
    path = calibrate_file(find_scenario(args.scenario), out, write=args.write)
    print(f"calibrated thermal network written to {path}")
    return 0
