"""``twin build``: build every FMU in fmus/ (into the cache, or ``--out DIR``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

NAME = "build"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME,
        help="build the FMUs in fmus/: into the cache those whose sources changed, or every one "
        "into --out DIR",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        help="build every FMU and write the .fmu files here (default: the cache, where an FMU "
        "whose sources are unchanged since its last build is found, not built again)",
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.fmu.build import build_all
    from twin.outputs.run_folder import check_output_folder

    out = Path(args.out) if args.out else None
    if out is not None:  # a file or /proc named: one line, exit 2, before anything is built
        check_output_folder(out, "--out")
    for model, path in build_all(out).items():
        print(f"{model}: {path}")
    return 0
