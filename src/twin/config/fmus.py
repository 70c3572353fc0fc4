"""The ``[fmu.<instance>]`` tables: which model, how often it steps (its ``period``, default
``scenario.step``), its parameter values.

Parameter values come from ``parameter_files`` (each a TOML file with a ``[parameters]``
table, relative to the scenario) and then the table's own ``parameters``, the later winning;
each is checked against the model's declared type and physical range. ``units`` gives a unit
to an input or output its FMU declares none for (``units = { u = "degC" }``), so that a
connection can convert to or from it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from twin.config.checks import parameter_value
from twin.config.durations import format_duration
from twin.config.reader import Problems, did_you_mean, finite_number, read_toml, table
from twin.config.spec import FMUSpec, Parameter
from twin.errors import ConfigError
from twin.fmu.catalog import model_names
from twin.fmu.catalog import variables as model_variables
from twin.units import UnitError, parse

_FMU_KEYS = {"model", "period", "parameters", "parameter_files", "unconnected", "units"}


def _unwrap(p: Problems, raw: Any, key: str) -> tuple[Any, str, float | None] | None:
    """(value, source, standard error) of a parameter given as a value or as ``{ value,
    source }``; a calibrated value may also carry its ``std_error`` (a positive number: the
    run's Monte Carlo draws it)."""
    if not isinstance(raw, dict):
        return raw, "", None
    extra = set(raw) - {"value", "source", "std_error"}
    if extra:
        p.add(
            key, f"unknown key(s) {sorted(extra)} (a parameter is a value or {{ value, source, std_error }})"
        )
        return None
    se = raw.get("std_error", 1.0)
    if not finite_number(se) or not se > 0:
        p.add(key + ".std_error", f"must be a finite number > 0, got {se!r}")
        return None
    if "value" not in raw:
        p.add(key, "missing 'value'")
        return None
    return raw["value"], str(raw.get("source", "")), float(se) if "std_error" in raw else None


def _parameter_value(p: Problems, model: str, name: str, raw: Any, key: str) -> Parameter | None:
    unwrapped = _unwrap(p, raw, key)
    if unwrapped is None:
        return None
    value, why = parameter_value(model, name, unwrapped[0])
    if why is not None or value is None:
        p.add(key, why or "")
        return None
    return Parameter(value, unwrapped[1], unwrapped[2])


def _parameter_file(p: Problems, path: Path, key: str) -> dict[str, tuple[Any, str]]:
    """The ``[parameters]`` of one parameter file as name -> (value, where it is written)."""
    try:
        fdata = read_toml(path, str(path))
    except ConfigError as exc:
        p.add(key, str(exc))
        return {}
    params = fdata.get("parameters", {})
    if not isinstance(params, dict):
        p.add(key, f"{path}: parameters: expected a [parameters] table")
        return {}
    return {k: (v, f"{path.name}: parameters.{k}") for k, v in params.items()}


def _given_parameters(
    p: Problems, raw: Mapping[str, Any], prefix: str, base_dir: Path
) -> dict[str, tuple[Any, str]]:
    """Every parameter value given to an instance: its files in order, then its own table."""
    merged: dict[str, tuple[Any, str]] = {}
    files = raw.get("parameter_files", [])
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        p.add(prefix + "parameter_files", "expected a list of file names")
        files = []
    for f in files:
        merged.update(_parameter_file(p, (base_dir / f).resolve(), prefix + "parameter_files"))
    own = raw.get("parameters", {})
    if not isinstance(own, dict):
        p.add(prefix + "parameters", "expected a table")
        own = {}
    merged.update({k: (v, f"{prefix}parameters.{k}") for k, v in own.items()})
    return merged


def _parameters(p: Problems, model: str, given: Mapping[str, tuple[Any, str]]) -> dict[str, Parameter]:
    variables = model_variables(model)
    params: dict[str, Parameter] = {}
    for k, (v, where) in given.items():
        var = variables.get(k)
        if var is None or var.causality != "parameter":
            known = [n for n, v in variables.items() if v.causality == "parameter"]
            p.add(where, f"{model} has no parameter '{k}'{did_you_mean(k, known)}")
            continue
        param = _parameter_value(p, model, k, v, where)
        if param is not None:
            params[k] = param
    return params


def _model_of(p: Problems, name: str, raw: Any, known: list[str], base_dir: Path) -> str | None:
    """The model an instance table names (one of the twin's, or an FMU file's resolved path),
    or None (and a problem) when it names none we have."""
    if not isinstance(raw, dict):
        p.add(f"fmu.{name}", "expected a table")
        return None
    if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
        p.add(f"fmu.{name}", "instance names are lower_snake (letters, digits, _)")
    prefix = f"fmu.{name}."
    p.unknown_keys(raw, _FMU_KEYS, prefix)
    if "model" not in raw:
        p.add(prefix + "model", f"missing (one of: {', '.join(known)}, or an FMU file)")
        return None
    if isinstance(raw["model"], str) and raw["model"].endswith(".fmu"):
        return _external(p, raw["model"], prefix, base_dir)
    if raw["model"] not in known:
        p.add(prefix + "model", f"unknown model {raw['model']!r} (known: {', '.join(known)})")
        return None
    return str(raw["model"])


def _external(p: Problems, given: str, prefix: str, base_dir: Path) -> str | None:
    """An FMU file named by path (relative to the scenario file), checked as fmpy validates;
    its resolved path is the model's name from here on."""
    from twin.fmu import external

    try:
        return str(external.check(base_dir / given).path)
    except ConfigError as exc:
        p.add(prefix + "model", f"{given}: {exc.message}")
        return None


def _period(p: Problems, raw: Mapping[str, Any], prefix: str, step_ns: int | None) -> int | None:
    """How often the instance steps: its ``period``, else every ``scenario.step`` (so that
    ``twin run --step-size`` sets the step of an FMU that names no period of its own)."""
    if "period" not in raw:
        return step_ns
    period = p.duration(raw, "period", prefix)
    if period is not None and period <= 0:
        p.add(prefix + "period", "must be positive")
    elif period is not None and step_ns and period % step_ns:
        p.add(
            prefix + "period",
            f"{format_duration(period)} is not a multiple of scenario.step ({format_duration(step_ns)})",
        )
    return period


def _units(p: Problems, model: str, raw: Mapping[str, Any], prefix: str) -> dict[str, str]:
    """``units = { variable = "unit" }``: a unit for each Real input or output that the FMU
    declares none for (pint must know it). A variable with a unit of its own keeps it: a
    connection converts from or to that unit."""
    given = raw.get("units", {})
    if not isinstance(given, dict):
        p.add(prefix + "units", 'expected a table such as { u = "degC" }')
        return {}
    variables = model_variables(model)
    out = {}
    for var, unit in given.items():
        key = f"{prefix}units.{var}"
        v = variables.get(var)
        if v is None or v.causality not in ("input", "output") or v.type != "Real":
            exchanged = [n for n, x in variables.items() if x.causality in ("input", "output")]
            p.add(key, f"{model} has no Real input or output '{var}'{did_you_mean(var, exchanged)}")
        elif v.unit:
            p.add(
                key, f"{model} declares '{v.unit}' for {var}: a unit is given only where the FMU gives none"
            )
        elif not isinstance(unit, str) or not unit.strip():
            p.add(key, f'expected a unit such as "degC", got {unit!r}')
        else:
            try:
                parse(unit)
            except UnitError as exc:
                p.add(key, exc.message)
                continue
            out[var] = unit.strip()
    return out


def _instance(
    p: Problems, name: str, raw: Any, known: list[str], base_dir: Path, step_ns: int | None
) -> FMUSpec | None:
    """One instance, or None when it is unusable (its problems are in ``p``)."""
    model = _model_of(p, name, raw, known, base_dir)
    if model is None:
        return None
    prefix = f"fmu.{name}."
    period = _period(p, raw, prefix, step_ns)
    params = _parameters(p, model, _given_parameters(p, raw, prefix, base_dir))
    unconnected = _unconnected(p, model, raw, prefix)
    units = _units(p, model, raw, prefix)
    if period is None:
        return None
    return FMUSpec(
        name=name,
        model=model,
        period_ns=period,
        parameters=MappingProxyType(params),
        unconnected=MappingProxyType(unconnected),
        units=MappingProxyType(units),
    )


def _unconnected(p: Problems, model: str, raw: Mapping[str, Any], prefix: str) -> dict[str, str]:
    """``unconnected = { <input> = "why it stays at its start value" }``: inputs of the model,
    each with a reason (the scenario says it means them to be left alone); or one reason for
    every input of the instance that nothing feeds (``unconnected = "a test rig of two FMUs"``)."""
    given = raw.get("unconnected", {})
    inputs = [n for n, v in model_variables(model).items() if v.causality == "input"]
    if isinstance(given, str) and given.strip():
        return dict.fromkeys(inputs, given)
    if not isinstance(given, dict):
        p.add(
            prefix + "unconnected",
            'expected { <input> = "why it stays at its start value" }, or one reason for all its inputs',
        )
        return {}
    out = {}
    for name, why in given.items():
        key = f"{prefix}unconnected.{name}"
        if name not in inputs:
            p.add(key, f"{model} has no input '{name}'{did_you_mean(name, inputs)}")
        elif not isinstance(why, str) or not why.strip():
            p.add(key, "expected the reason it stays at its start value (a text)")
        else:
            out[name] = why
    return out


def load_fmus(p: Problems, data: Mapping[str, Any], base_dir: Path, step_ns: int | None) -> list[FMUSpec]:
    """The ``[fmu.*]`` instances that can be used; the others are marked broken in ``p``."""
    fmus_raw = table(p, data, "fmu")
    if not fmus_raw:
        p.add("fmu", "at least one [fmu.<name>] table is needed")
        p.no_fmus = True
    known = model_names()
    out = []
    for name, raw in fmus_raw.items():
        spec = _instance(p, name, raw, known, base_dir, step_ns)
        if spec is None:
            p.broken.add(name)
        else:
            out.append(spec)
    return out
