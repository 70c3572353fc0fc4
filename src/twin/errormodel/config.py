"""The error model's configuration: which columns hold what, and what is known of the tester.

:func:`evaluation_config` builds it for a scenario, :func:`errormodel_config` from known
coefficients and an ``[errormodel]`` table (a scenario's or a lab's TOML), and
:func:`input_columns` names the recorded columns the error model reads (the only ones a run
keeps in memory).
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from twin.config.spec import NS_PER_S, Scenario
from twin.errormodel.evaluate import EvaluationConfig
from twin.errormodel.factors import FACTORS, PARTS
from twin.errormodel.sources import (
    COLUMN_FIELDS,
    DEFAULT_READING,
    DEFAULT_TEMPERATURES,
    DEFAULT_TRUE_WEAR,
    MechanicalCoefficients,
    ThermalGeometry,
)
from twin.errors import ConfigError
from twin.fmu.catalog import variables as model_variables

_GEOMETRY_FROM = {"FixtureMechanics", "SensorsDAQ"}


def model_defaults() -> dict[str, float]:
    """The FixtureMechanics and SensorsDAQ parameters' declared values (their sources are in
    the modelDescription.xml): the error model's default knowledge of the tester."""
    values: dict[str, float] = {}
    for model in sorted(_GEOMETRY_FROM):
        for name, v in model_variables(model).items():
            if v.causality == "parameter" and v.type == "Real" and v.start is not None:
                values[name] = float(v.start)
    return values


def evaluation_config(scenario: Scenario) -> EvaluationConfig:
    """Error-model configuration of a scenario.

    Geometry and the probe's zero drift default to the values the scenario gives its
    FixtureMechanics and SensorsDAQ instances (the instrument's data sheet and the fixture's
    drawings, in a lab); ``[errormodel]`` may override any of them, the temperature columns
    (``temperatures = { point = "column" }``), the reading and the true-wear column.
    """
    values = model_defaults()
    for spec in scenario.fmus:
        if spec.model in _GEOMETRY_FROM:
            values.update({k: float(p.value) for k, p in spec.parameters.items()})
    em = {k: p.value for k, p in scenario.errormodel.items()}
    return errormodel_config(values, em, scenario.source_path, scenario.drift_window_ns / NS_PER_S)


def errormodel_config(
    values: dict[str, float], em: dict[str, Any], source: str, window_s: float
) -> EvaluationConfig:
    """An :class:`EvaluationConfig` from known coefficients and an ``[errormodel]`` table."""
    em = dict(em)
    columns = _pop_columns(em, source)
    factors = em.pop("factors", list(PARTS))
    if not isinstance(factors, list) or not set(factors) <= set(PARTS) or not factors:
        raise ConfigError(f"expected a list from {list(PARTS)}", source=source, key="errormodel.factors")
    geometry_overrides = em.pop("geometry", {})
    if em:
        raise ConfigError(f"unknown key(s) {sorted(em)}", source=source, key="errormodel")
    _check_geometry(geometry_overrides, source)
    _check_columns(columns, source)
    values.update(geometry_overrides)
    mechanics = None
    if all(f.name in values for f in fields(MechanicalCoefficients)):
        mechanics = MechanicalCoefficients.from_parameters(values, source=source)
    return EvaluationConfig(
        geometry=ThermalGeometry.from_parameters(values, source=source),
        mechanics=mechanics,
        factors=tuple(factors),
        **{k: v for k, v in columns.items() if k in _sensor_fields()},
        temperatures=columns["temperatures"],
        reading=str(columns["reading"]),
        true_wear=str(columns["true_wear"]) if columns["true_wear"] else None,
        window_s=window_s,
    )


def _sensor_fields() -> list[str]:
    """The optional instruments' column fields (load, torque, angle, vibration), as the factors
    declare them, in the order of :class:`~twin.errormodel.sources.Columns`."""
    declared = {s for f in FACTORS for s in f.sensors}
    return [name for name in COLUMN_FIELDS if name in declared]


def _pop_columns(em: dict[str, Any], source: str) -> dict[str, Any]:
    """Take the column names out of an ``[errormodel]`` table: the temperatures (merged over
    the twin's), the reading, the true wear and those of the optional instruments given."""
    temperatures = dict(DEFAULT_TEMPERATURES)
    if "temperatures" in em:
        if not isinstance(em["temperatures"], dict):
            raise ConfigError("expected a table point = column", source=source, key="errormodel.temperatures")
        temperatures.update(em.pop("temperatures"))
    return {
        "temperatures": temperatures,
        "reading": em.pop("reading", DEFAULT_READING),
        "true_wear": em.pop("true_wear", DEFAULT_TRUE_WEAR),
        **{k: em.pop(k) for k in _sensor_fields() if k in em},
    }


def _check_columns(columns: dict[str, Any], source: str) -> None:
    sensors = _sensor_fields()
    if not all(isinstance(v, str) for k, v in columns.items() if k in sensors):
        raise ConfigError(f"{', '.join(sensors)} must be column names", source=source, key="errormodel")
    reading, true_wear = columns["reading"], columns["true_wear"]
    if not isinstance(reading, str) or not (true_wear is None or isinstance(true_wear, str)):
        raise ConfigError("reading and true_wear must be column names", source=source, key="errormodel")
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in columns["temperatures"].items()):
        raise ConfigError(
            "temperatures must map point names to column names",
            source=source,
            key="errormodel.temperatures",
        )


def _check_geometry(overrides: Any, source: str) -> None:
    """Check ``[errormodel] geometry``: a table of numbers naming known coefficients."""
    if not isinstance(overrides, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in overrides.values()
    ):
        raise ConfigError("expected a table of numbers", source=source, key="errormodel.geometry")
    known = {f.name for f in fields(ThermalGeometry)} | {f.name for f in fields(MechanicalCoefficients)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ConfigError(f"unknown geometry value(s) {unknown}", source=source, key="errormodel.geometry")


def input_columns(cfg: EvaluationConfig) -> set[str]:
    """The columns the error model and the plot read: the only ones a run keeps in memory.

    Those of every factor, switched on or not (the temperatures and the sensors' presence are
    reported either way), and the true wear.
    """
    names = {name for f in FACTORS for field in (*f.columns, *f.sensors) for name in cfg.names(field)}
    return names | set(cfg.names("true_wear"))
