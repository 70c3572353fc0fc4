"""The error model's configuration: which columns hold what, and what is known of the tester.

:func:`evaluation_config` builds it for a scenario, :func:`errormodel_config` from an
``[errormodel]`` table (a scenario's or a lab's TOML), and :func:`input_columns` names the
recorded columns the error model reads (the only ones a run keeps in memory).

What is known of the tester, its coefficients, comes from a coefficients file only
(:mod:`twin.errormodel.coefficients`, written by ``twin identify`` from calibration
experiments): ``[errormodel] coefficients = "calibration/identified.toml"`` names it relative to
the TOML that says so, or gives the same table inline; without it the committed file of the
nominal twin is used. The FMUs' parameters never enter: the twin's truth and the lab's model
of it are kept apart.
"""

from __future__ import annotations

from collections.abc import Mapping, Set
from pathlib import Path
from typing import Any

from twin.config.reader import Problems
from twin.config.spec import NS_PER_S, Scenario
from twin.errormodel.coefficients import (
    Coefficients,
    default_path,
    load_coefficients,
    parse_coefficients,
)
from twin.errormodel.factors import FACTORS, PARTS
from twin.errormodel.settings import EvaluationConfig
from twin.errormodel.sources import (
    COLUMN_FIELDS,
    DEFAULT_READING,
    DEFAULT_TEMPERATURES,
    DEFAULT_TRUE_WEAR,
    EXTRA_TEMPERATURES,
    MechanicalCoefficients,
    ThermalCoefficients,
)
from twin.errors import ConfigError, ConfigErrors, did_you_mean


def model_defaults() -> dict[str, float]:
    """The committed coefficients of the nominal twin (``twin identify``), by name: what the
    error model uses when nothing names a coefficients file."""
    return load_coefficients(default_path()).values()


def coefficients_for(em: Mapping[str, Any], source: str) -> Coefficients | None:
    """The coefficients an ``[errormodel]`` table names: ``coefficients = "file.toml"``
    (relative to ``source``'s folder) or an inline table of them; ``None`` if it names none."""
    spec = em.get("coefficients")
    if spec is None:
        return None
    if isinstance(spec, str):
        path = Path(source).resolve().parent / spec
        try:
            return load_coefficients(path)
        except ConfigError as exc:
            if exc.source != str(path) or exc.key is not None:
                raise  # a problem inside the file: its own name and key say where
            # the file itself cannot be read (missing, a folder): say so where it is named
            raise ConfigError(
                f"{spec}: {exc.message}", source=source, key="errormodel.coefficients"
            ) from None
    if isinstance(spec, Mapping):
        return parse_coefficients({"coefficients": spec}, f"{source}: errormodel")
    raise ConfigError(
        "expected a file name or a table of coefficients", source=source, key="errormodel.coefficients"
    )


def evaluation_config(scenario: Scenario) -> EvaluationConfig:
    """Error-model configuration of a scenario.

    The coefficients come from the file ``[errormodel] coefficients`` names (relative to the
    scenario file), else from the committed default; ``[errormodel]`` may also set the
    temperature columns (``temperatures = { point = "column" }``), the reading, the true-wear
    column and the factors. ``evaluate = false`` says the scenario is not the tester (one FMU
    alone, another tool's system): no error model, no plots, the run's signals only.
    """
    em = {k: p.value for k, p in scenario.errormodel.items()}
    return errormodel_config(None, em, scenario.source_path, scenario.drift_window_ns / NS_PER_S)


def errormodel_config(
    values: Mapping[str, float] | None,
    em: Mapping[str, Any],
    source: str,
    window_s: float,
    also: tuple[str, ...] = (),
) -> EvaluationConfig:
    """An :class:`EvaluationConfig` from an ``[errormodel]`` table, every problem of it at once
    (one line each). Its coefficients are those the table names (``coefficients``), else
    ``values``, else (``None``) the committed ones. ``also``: the table's keys the caller reads
    itself (LAB.toml's ``drift_window``), named among the keys a misspelt one could mean."""
    p = Problems(source)
    p.unknown_keys(
        em,
        {
            "coefficients",
            "temperatures",
            "reading",
            "true_wear",
            "factors",
            "evaluate",
            *_sensor_fields(),
            *also,
        },
        "errormodel.",
    )
    named = coefficients_for(em, source)
    if named is not None:
        values = named.values()
    elif values is None:
        values = model_defaults()
    temperatures = _temperatures(p, em)
    columns = {
        "reading": _column(p, em, "reading", DEFAULT_READING),
        "true_wear": _column(p, em, "true_wear", DEFAULT_TRUE_WEAR),
        **{k: _column(p, em, k, "") for k in _sensor_fields() if k in em},
    }
    factors = _factors(p, em.get("factors", list(PARTS)))
    evaluate = em.get("evaluate", True)
    if not isinstance(evaluate, bool):
        p.add("errormodel.evaluate", f"expected true or false, got {evaluate!r}")
    p.check()
    return EvaluationConfig(
        thermal=ThermalCoefficients.from_values(values, source=source),
        mechanics=MechanicalCoefficients.from_values(values, source=source),
        factors=tuple(factors),
        **{k: v for k, v in columns.items() if k in _sensor_fields()},
        temperatures=temperatures,
        reading=str(columns["reading"]),
        true_wear=str(columns["true_wear"]) if columns["true_wear"] else None,
        window_s=window_s,
        evaluate=evaluate,
    )


def _sensor_fields() -> list[str]:
    """The optional instruments' column fields (load, torque, angle, vibration), as the factors
    declare them, in the order of :class:`~twin.errormodel.sources.Columns`."""
    declared = {s for f in FACTORS for s in f.sensors}
    return [name for name in COLUMN_FIELDS if name in declared]


def _column_problem(value: Any) -> str | None:
    """Why ``value`` cannot name a data column (a string, not empty, not ``time``)."""
    if not isinstance(value, str):
        return f"expected a column name (a string), got {type(value).__name__}"
    if not value.strip() or value == "time":
        what = "an empty name" if not value.strip() else "'time', the time axis"
        return f"expected a data column's name, got {what}"
    return None


def _column(p: Problems, em: Mapping[str, Any], key: str, default: str | None) -> str | None:
    """The column ``em[key]`` names (``default`` without one); a problem when it names none."""
    value = em.get(key, default)
    if key == "true_wear" and value is None:
        return None
    why = _column_problem(value)
    if why is not None:
        p.add(f"errormodel.{key}", why)
        return default
    return value


def _temperatures(p: Problems, em: Mapping[str, Any]) -> dict[str, str]:
    """The temperature columns by measuring point: the table's merged over the twin's."""
    temperatures = dict(DEFAULT_TEMPERATURES)
    given = em.get("temperatures", {})
    if not isinstance(given, dict):
        p.add("errormodel.temperatures", f"expected a table point = column, got {type(given).__name__}")
        return temperatures
    for point, column in given.items():
        key = f"errormodel.temperatures.{point}"
        known = {**DEFAULT_TEMPERATURES, **EXTRA_TEMPERATURES}
        if point not in known:  # a misspelt point would be read as nothing
            p.add(
                key,
                f"unknown measuring point{did_you_mean(str(point), known)} (the points: {', '.join(known)})",
            )
        elif (why := _column_problem(column)) is not None:
            p.add(key, why)
        else:
            temperatures[point] = column
    return temperatures


def _factors(p: Problems, factors: Any) -> list[str]:
    """The ``factors`` list: names of :data:`PARTS`, each once, at least one."""
    ok = isinstance(factors, list) and factors and all(isinstance(f, str) and f in PARTS for f in factors)
    if not ok:
        p.add("errormodel.factors", f"expected a list from {list(PARTS)}")
        return list(PARTS)
    twice = sorted({f for f in factors if factors.count(f) > 1})
    if twice:
        p.add("errormodel.factors", f"{twice} given twice")
    return list(factors)


def input_columns(cfg: EvaluationConfig) -> set[str]:
    """The columns the error model and the plot read: the only ones a run keeps in memory.

    Those of every factor, switched on or not (the temperatures and the sensors' presence are
    reported either way), and the true wear. None for a run that does not evaluate it.
    """
    if not cfg.evaluate:
        return set()
    names = {name for f in FACTORS for field in (*f.columns, *f.sensors) for name in cfg.names(field)}
    return names | set(cfg.names("true_wear"))


def _named_columns(em: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(key, column) of every column an ``[errormodel]`` table names explicitly."""
    named = [(f"errormodel.{k}", em[k]) for k in ("reading", "true_wear", *_sensor_fields()) if k in em]
    temps = em.get("temperatures")
    if isinstance(temps, Mapping):
        named += [(f"errormodel.temperatures.{p}", c) for p, c in temps.items()]
    return [(k, c) for k, c in named if isinstance(c, str)]


def _column_hint(column: str, recorded: set[str]) -> str:
    """A close match, else the recorded columns of the instance named, else the instances."""
    close = did_you_mean(column, recorded)
    if close:
        return close
    inst = column.split(".", 1)[0]
    same = sorted(c for c in recorded if c.startswith(inst + "."))
    if same:
        more = f", ... ({len(same)} in all)" if len(same) > 8 else ""
        return f" ({inst} records: {', '.join(same[:8])}{more})"
    return (
        f" (columns are 'instance.variable' of: {', '.join(sorted({c.split('.', 1)[0] for c in recorded}))})"
    )


def check_recorded_columns(scenario: Scenario, recorded: Set[str]) -> None:
    """Every column the scenario's ``[errormodel]`` names is one the run records (``recorded``:
    an output or a driven input of one of its FMU instances): a misspelt column would otherwise
    let the run complete without an error model. Checked before the run
    (:func:`twin.pipeline.prepare.prepare`)."""
    em = {k: p.value for k, p in scenario.errormodel.items()}
    problems = [
        ConfigError(
            f"column {column!r} is not recorded by this scenario{_column_hint(column, set(recorded))}",
            source=scenario.source_path,
            key=key,
        )
        for key, column in _named_columns(em)
        if column not in recorded
    ]
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)
