"""``twin geometry``: derive the FMUs' lengths, capacities and conductances from the drawing."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

NAME = "geometry"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME, help="derive the FMUs' lengths, capacities and conductances from base/tester-geometry.toml"
    )
    p.add_argument(
        "--scenarios",
        metavar="DIR",
        help="scenarios folder (default: the repository's; a plain install's own copy is refused)",
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.calibration.geometry import write_derived_files
    from twin.config.load import check_not_installed_copy, scenarios_dir

    folder = Path(args.scenarios) if args.scenarios else scenarios_dir()
    check_not_installed_copy(folder, "--scenarios")  # its default included
    for path in write_derived_files(folder):
        print(f"derived parameters written to {path}")
    return 0
