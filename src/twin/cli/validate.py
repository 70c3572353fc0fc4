"""``twin validate SCENARIO``: every check ``twin run`` makes, nothing run."""

from __future__ import annotations

import argparse
from typing import Any

from twin.cli.common import add_experiment, add_set, experiment

NAME = "validate"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="check a scenario without running it")
    p.add_argument(
        "scenario", help="scenario TOML file, SSP archive (.ssp), one FMU (.fmu) or shipped scenario's name"
    )
    add_set(p)
    add_experiment(p)
    p.add_argument(
        "--record",
        nargs="+",
        action="extend",
        metavar="VAR",
        help="the columns signals.csv would hold (default: as twin run's, every Real output, then "
        "each input a profile or an event drives)",
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.pipeline import RunOptions, prepare
    from twin.validation import reports

    options = RunOptions(
        reports=reports,
        experiment=experiment(args),
        record=tuple(args.record) if args.record is not None else None,
    )
    with prepare(args.scenario, args.set or [], options) as prepared:
        sc = prepared.scenario
        print(
            f"{sc.source_path}: ok ({sc.name}: {len(sc.fmus)} FMUs, {len(sc.connections)} connections, "
            f"{len(sc.profiles)} profiles, {len(sc.events)} events)"
        )
    return 0
