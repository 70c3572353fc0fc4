"""The error model's configuration: which columns hold what, and what is known of the tester.

:func:`evaluation_config` builds it for a scenario, :func:`errormodel_config` from known
coefficients and an ``[errormodel]`` table (a scenario's or a lab's TOML), and
:func:`input_columns` names the recorded columns the error model reads (the only ones a run
keeps in memory).
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from twin.config.load import model_variables
from twin.config.spec import NS_PER_S, Scenario
from twin.errormodel.evaluate import PARTS, EvaluationConfig
from twin.errormodel.sources import (
    DEFAULT_READING,
    DEFAULT_TEMPERATURES,
    MechanicalCoefficients,
    ThermalGeometry,
)
from twin.errors import ConfigError

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
    temperatures = dict(DEFAULT_TEMPERATURES)
    if "temperatures" in em:
        if not isinstance(em["temperatures"], dict):
            raise ConfigError("expected a table point = column", source=source, key="errormodel.temperatures")
        temperatures.update(em.pop("temperatures"))
    reading = em.pop("reading", DEFAULT_READING)
    true_wear = em.pop("true_wear", "mechanics.wear_depth_true")
    columns = {k: em.pop(k) for k in ("load", "torque", "angle", "vibration") if k in em}
    factors = em.pop("factors", list(PARTS))
    if not isinstance(factors, list) or not set(factors) <= set(PARTS) or not factors:
        raise ConfigError(f"expected a list from {list(PARTS)}", source=source, key="errormodel.factors")
    geometry_overrides = em.pop("geometry", {})
    if em:
        raise ConfigError(f"unknown key(s) {sorted(em)}", source=source, key="errormodel")
    if not isinstance(geometry_overrides, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in geometry_overrides.values()
    ):
        raise ConfigError("expected a table of numbers", source=source, key="errormodel.geometry")
    known = {f.name for f in fields(ThermalGeometry)} | {f.name for f in fields(MechanicalCoefficients)}
    unknown = sorted(set(geometry_overrides) - known)
    if unknown:
        raise ConfigError(f"unknown geometry value(s) {unknown}", source=source, key="errormodel.geometry")
    if not all(isinstance(v, str) for v in columns.values()):
        raise ConfigError(
            "load, torque, angle, vibration must be column names",
            source=source,
            key="errormodel",
        )
    if not isinstance(reading, str) or not (true_wear is None or isinstance(true_wear, str)):
        raise ConfigError("reading and true_wear must be column names", source=source, key="errormodel")
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in temperatures.items()):
        raise ConfigError(
            "temperatures must map point names to column names",
            source=source,
            key="errormodel.temperatures",
        )
    values.update(geometry_overrides)
    mechanics = None
    if all(f.name in values for f in fields(MechanicalCoefficients)):
        mechanics = MechanicalCoefficients.from_parameters(values, source=source)
    return EvaluationConfig(
        geometry=ThermalGeometry.from_parameters(values, source=source),
        mechanics=mechanics,
        factors=tuple(factors),
        **columns,
        temperatures=temperatures,
        reading=str(reading),
        true_wear=str(true_wear) if true_wear else None,
        window_s=window_s,
    )


def input_columns(cfg: EvaluationConfig) -> set[str]:
    """The columns the error model and the plot read: the only ones a run keeps in memory."""
    names = {*cfg.temperatures.values(), cfg.reading, cfg.load, cfg.torque, cfg.angle, cfg.vibration}
    if cfg.true_wear:
        names.add(cfg.true_wear)
    return names
