"""``twin list``: the shipped scenarios and calibration experiments, with their descriptions."""

from __future__ import annotations

import argparse
from typing import Any

NAME = "list"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME, help="the shipped scenarios and calibration experiments, with their descriptions"
    )
    return p


def command(args: argparse.Namespace) -> int:
    from twin.config.load import shipped_scenarios

    for title, folder, rows in shipped_scenarios():
        if rows:
            print(f"{title} (in {folder}):")
            width = max(len(n) for n, _ in rows)
            for n, d in rows:
                print(f"  {n:<{width}}  {d}")
    return 0
