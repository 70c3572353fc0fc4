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
        help="scenarios folder (default: the one the twin runs: the repository's from an editable "
        "install; a plain install's own copy is refused)",
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.calibration.geometry import MODELS, derived_file, write_derived_files
    from twin.config.load import check_not_installed_copy, scenarios_dir

    folder = Path(args.scenarios) if args.scenarios else scenarios_dir()
    option = (
        "--scenarios" if args.scenarios else "the scenarios folder (default; --scenarios DIR names another)"
    )
    # each file it writes (where it lands: a folder or a base/ linked into the copy lands there)
    for model in MODELS:
        check_not_installed_copy(derived_file(folder, model), option)
    for path in write_derived_files(folder):
        print(f"derived parameters written to {path}")
    return 0
