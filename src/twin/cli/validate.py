"""``twin validate SCENARIO``: every check ``twin run`` makes, nothing run."""

from __future__ import annotations

import argparse
from typing import Any

from twin.cli.common import add_set

NAME = "validate"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="check a scenario without running it")
    p.add_argument("scenario", help="scenario TOML file, SSP archive (.ssp) or shipped scenario's name")
    add_set(p)
    return p


def command(args: argparse.Namespace) -> int:
    from twin.pipeline import RunOptions, prepare
    from twin.validation import reports

    with prepare(args.scenario, args.set or [], RunOptions(reports=reports)) as prepared:
        sc = prepared.scenario
        print(
            f"{sc.source_path}: ok ({sc.name}: {len(sc.fmus)} FMUs, {len(sc.connections)} connections, "
            f"{len(sc.profiles)} profiles, {len(sc.events)} events)"
        )
    return 0
