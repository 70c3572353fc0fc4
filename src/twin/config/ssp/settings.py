"""The run's settings an SSP archive gives: the default experiment (stop time, start time),
libcosim's fixed step (``com.opensimulationplatform``), and the twin's own settings
(``io.github.twin``): output interval, seed, drift window, wear limit, and the scenario's
``[errormodel]``, ``[uncertainty]`` and ``[reference]`` tables with the files they name.

An archive without libcosim's annotation gives no step: the scenario's step is then missing, and
the check says so (``--step-size``, or ``--set scenario.step=...``, gives one).
"""

from __future__ import annotations

import json
import re
from typing import Any

from twin.config.reader import check_values
from twin.config.ssp.names import NS, OSP_TYPE, TWIN_TYPE, tag_of
from twin.errors import ConfigError

__all__ = ["TABLES", "scenario_table", "twin_tables"]

#: the twin's tables an archive carries, and the file each may name (relative to the SSD)
TABLES = {"errormodel": "coefficients", "uncertainty": "spreads", "reference": None}
#: the attributes of twin:Scenario and the [scenario] key each gives (durations in seconds)
_SCENARIO_ATTRIBUTES = {
    "outputInterval": "output_interval",
    "driftWindow": "drift_window",
    "seed": "seed",
    "wearLimitMm": "wear_limit_mm",
}


def _experiment(r: Any) -> Any:
    return r.root.find("ssd:DefaultExperiment", NS)


def scenario_table(r: Any, system: Any) -> dict[str, Any]:
    """The ``[scenario]`` table of the archive (``r``: the system reader, which collects what it
    refuses): its name, description, duration, step and the twin's settings; what the archive
    does not give stays out, for the check to name."""
    table: dict[str, Any] = {"name": r.root.get("name") or "ssp"}
    description = system.get("description") if system is not None else None
    if description:
        table["description"] = description
    experiment = _experiment(r)
    if experiment is None:
        return table
    start = experiment.get("startTime")
    # the schema makes it an xs:double (INF and NaN included); a twin's run starts at 0 s, so
    # another start would silently shift every profile and event: refused, not ignored
    if start is not None and float(start) != 0.0:
        r.refuse(
            experiment,
            f"startTime {start!r}: a start time other than 0 is not supported (a twin's run starts at 0 s)",
        )
    if experiment.get("stopTime") is not None:
        table["duration"] = f"{experiment.get('stopTime')} s"
    for algorithm in r.known(r.annotation(experiment, OSP_TYPE), {"osp:Algorithm"}):
        for a in (c for c in algorithm if isinstance(c.tag, str)):
            if tag_of(a) != "osp:FixedStepAlgorithm":
                r.refuse(a, "an algorithm other than libcosim's fixed step: the twin steps at a fixed step")
            elif a.get("baseStepSize"):
                table["step"] = f"{a.get('baseStepSize')} s"
    for el in r.known(r.annotation(experiment, TWIN_TYPE), {"twin:Scenario"}):
        _twin_scenario(r, el, table)
    return table


def _twin_scenario(r: Any, el: Any, table: dict[str, Any]) -> None:
    """The twin's settings, passed on as a scenario file writes them, for the same checks (its
    tables, inside it, are :func:`twin_tables`'s)."""
    for c in el:
        if isinstance(c.tag, str) and tag_of(c) != "twin:Tables":
            r.refuse(c, "an annotation (io.github.twin) this version of the twin does not apply")
    for attribute, text in el.attrib.items():
        key = _SCENARIO_ATTRIBUTES.get(attribute)
        if key is None:
            r.refuse(el, f"attribute {attribute!r}: a setting this version of the twin does not apply")
        elif key in ("output_interval", "drift_window"):
            table[key] = f"{text} s"
        elif key == "seed":
            # an integer as a scenario file's seed is, checked where that one is (scenario.seed:
            # an integer in [0, 2^31)); anything else ("abc", "1.5", "²") is passed on as text
            # for that check to refuse. [0-9], not str.isdigit(): that takes "²", int() does not
            table[key] = int(text) if re.fullmatch(r"\s*[+-]?[0-9]{1,30}\s*", text) else text
        else:
            try:
                table[key] = float(text)
            except ValueError:
                table[key] = text  # refused by the [scenario] check, which names the key
    if "output_interval" not in table and "step" in table:
        table["output_interval"] = table["step"]


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a finite number")


def twin_tables(r: Any) -> dict[str, Any]:
    """The scenario's ``[errormodel]``, ``[uncertainty]`` and ``[reference]`` tables from the
    twin's annotation (JSON), a file each names unpacked from the archive (its path made
    absolute, as a base's paths are when a file extends it)."""
    experiment = _experiment(r)
    annotation = r.annotation(experiment, TWIN_TYPE) if experiment is not None else None
    el = annotation.find("twin:Scenario/twin:Tables", NS) if annotation is not None else None
    if el is None:
        return {}
    try:
        tables = json.loads(el.text or "{}", parse_constant=_no_constant)
        check_values(tables, r.a.source, "twin:Tables")
    except (ValueError, ConfigError) as exc:
        r.refuse(el, f"not the twin's tables as JSON: {exc}")
        return {}
    if (
        not isinstance(tables, dict)
        or not set(tables) <= set(TABLES)
        or not all(isinstance(v, dict) for v in tables.values())
    ):
        r.refuse(el, f"expected tables {sorted(TABLES)} as JSON objects")
        return {}
    for name, key in TABLES.items():
        table = tables.get(name)
        if key is None or table is None or not isinstance(table.get(key), str):
            continue
        member = table[key]
        if not r.a.has(member):
            r.refuse(el, f"{name}.{key} names {member!r}, which the archive does not hold")
            continue
        table[key] = str(r.a.file(member))
    return tables
