"""``twin inspect X.fmu|MODEL``: an FMU's variables, as ``fmpy info`` lists them.

For any FMI 2.0 FMU by path, or one of the twin's models by name (read from its
``modelDescription.xml`` in ``fmus/``): name, causality, variability, type, unit, start, min, max
and description, one line each.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.errors import ConfigError

__all__ = ["add_parser"]


def _description(target: str) -> Any:
    from fmpy import read_model_description

    from twin.config.reader import did_you_mean
    from twin.fmu.catalog import model_names, sources_dir

    path = Path(target)
    if not path.exists() and path.suffix != ".fmu" and len(path.parts) == 1:
        names = model_names()
        if target not in names:
            raise ConfigError(
                f"no FMU file or model named {target!r}{did_you_mean(target, names)}", source="inspect"
            )
        path = sources_dir() / target / "modelDescription.xml"
    if not path.is_file() and not path.is_dir():
        if path.exists():  # /dev/zero, a FIFO: reading one could block or never end
            raise ConfigError(
                "is not a regular file (a device, FIFO or socket), expected an FMU", source=str(path)
            )
        raise ConfigError("file not found", source=str(path))
    try:
        return read_model_description(str(path), validate=False)
    except (AttributeError, TypeError, KeyError, IndexError):
        # fmpy reads the document's attributes unchecked (validate=False): one it lacks ends in
        # "'NoneType' object has no attribute ...", which says nothing of the file
        raise ConfigError(
            "not a readable FMI model description: modelDescription.xml lacks an element or "
            'attribute FMI requires (its root must be <fmiModelDescription fmiVersion="2.0" ...>)',
            source=str(path),
        ) from None
    except Exception as exc:  # fmpy raises several kinds for a file that is not an FMU
        raise ConfigError(
            f"not a readable FMI model description: {exc}".splitlines()[0], source=str(path)
        ) from None


def _text(value: Any) -> str:
    return "" if value is None else str(value)


def _cmd_inspect(args: argparse.Namespace) -> int:
    md = _description(args.target)
    cs = "co-simulation" if md.coSimulation is not None else ""
    me = "model exchange" if md.modelExchange is not None else ""
    kinds = ", ".join(k for k in (cs, me) if k)
    print(
        f"{md.modelName}: FMI {md.fmiVersion} ({kinds}), {len(md.modelVariables)} variables, GUID {md.guid}"
    )
    if md.description:
        print(f"  {md.description}")
    rows = [("name", "causality", "variability", "type", "unit", "start", "min", "max", "description")]
    for v in md.modelVariables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        lo = v.min if v.min is not None else (v.declaredType.min if v.declaredType is not None else None)
        hi = v.max if v.max is not None else (v.declaredType.max if v.declaredType is not None else None)
        rows.append(
            (v.name, v.causality, v.variability, v.type, _text(unit), _text(v.start), _text(lo), _text(hi),
             (v.description or "")[: args.width])
        )  # fmt: skip
    widths = [max(len(r[i]) for r in rows) for i in range(8)]
    for r in rows:
        print("  " + "  ".join(c.ljust(w) for c, w in zip(r[:8], widths, strict=True)) + "  " + r[8])
    return 0


def add_parser(sub: Any) -> None:
    """``twin inspect``."""
    p = sub.add_parser("inspect", help="list an FMU's variables (causality, type, unit, start, min, max)")
    p.add_argument("target", help="an FMI 2.0 .fmu file, or a model of the twin (e.g. FixtureMechanics)")
    p.add_argument("--width", type=int, default=60, help="characters of each description shown (default 60)")
    p.set_defaults(func=_cmd_inspect)
