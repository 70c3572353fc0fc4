"""``twin inspect X.fmu|MODEL``: an FMU's variables, as ``fmpy info`` lists them.

For any FMI 2.0 FMU by path, or one of the twin's models by name (read from its
``modelDescription.xml`` in ``fmus/``): name, causality, variability, type, unit, start, min, max
and description, one line each.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

NAME = "inspect"


def _width(text: str) -> int:
    """Characters of description: 0 leaves the column out, a negative one is no width."""
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a number of characters (0 or more), got {text!r}")
    return n


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="list an FMU's variables (causality, type, unit, start, min, max)")
    p.add_argument("target", help="an FMI 2.0 .fmu file, or a model of the twin (e.g. FixtureMechanics)")
    p.add_argument(
        "--width", type=_width, default=60, help="characters of each description shown (default 60; 0: none)"
    )
    return p


def _text(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isinf(value)):
        return ""
    return str(value)


def command(args: argparse.Namespace) -> int:
    from twin.fmu.catalog import inspectable

    md = inspectable(args.target)
    print(
        f"{md.model_name}: FMI {md.fmi_version} ({', '.join(md.kinds)}), {len(md.variables)} variables, GUID {md.guid}"
    )
    if md.text:
        print(f"  {md.text}")
    rows = [("name", "causality", "variability", "type", "unit", "start", "min", "max", "description")]
    for v in md.variables.values():
        rows.append(
            (v.name, v.causality, v.variability, v.type, v.unit, _text(v.start), _text(v.min), _text(v.max),
             v.description[: args.width])
        )  # fmt: skip
    widths = [max(len(r[i]) for r in rows) for i in range(8)]
    for r in rows:
        print("  " + "  ".join(c.ljust(w) for c, w in zip(r[:8], widths, strict=True)) + "  " + r[8])
    return 0
