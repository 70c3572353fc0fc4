"""``twin build``: build every FMU in fmus/ (into the cache, or ``--out DIR``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

NAME = "build"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="build every FMU in fmus/ (into the cache, or --out DIR)")
    p.add_argument("--out", metavar="DIR", help="write the .fmu files here instead of the cache")
    return p


def command(args: argparse.Namespace) -> int:
    from twin.fmu.build import build_all

    for model, path in build_all(Path(args.out) if args.out else None).items():
        print(f"{model}: {path}")
    return 0
