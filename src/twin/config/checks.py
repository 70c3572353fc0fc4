"""The checks of one value against what a model declares: a parameter's type and physical range,
the values an input is driven to.

Shared by the scenario loader (:mod:`twin.config.fmus`, :mod:`twin.config.inputs`, which collect
every problem of a file) and by the scenario's own methods that return changed copies
(:meth:`twin.config.spec.Scenario.with_parameter` and the others, which raise at the first):
each check returns the checked value or the reason it is refused, so both say the same.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from twin.config.reader import did_you_mean, finite_number
from twin.fmu.catalog import Variable
from twin.fmu.catalog import variables as model_variables

__all__ = ["ParameterValue", "parameter_value", "range_problem", "typed_value"]

ParameterValue = float | int | bool

_EXPECTED = {
    "Boolean": "true or false",
    "Integer": "an integer",
    "Enumeration": "an integer (an item's value)",
}


def typed_value(var: Variable, raw: Any) -> tuple[ParameterValue | None, str | None]:
    """``raw`` as a value of the variable's type (floats for Real), or the reason it is not one."""
    if var.type == "Boolean":
        ok = isinstance(raw, bool)
    elif var.type in ("Integer", "Enumeration"):
        ok = not isinstance(raw, bool) and isinstance(raw, int)
    else:
        ok = not isinstance(raw, bool) and isinstance(raw, int | float)
    if not ok:
        return None, f"expected {_EXPECTED.get(var.type, 'a number')}, got {raw!r}"
    if var.type in _EXPECTED:
        return raw, None
    if not finite_number(raw):
        return None, f"expected a finite number, got {raw!r}"
    return float(raw), None


def parameter_value(
    model: str, name: str, raw: Any, variables: Mapping[str, Variable] | None = None
) -> tuple[ParameterValue | None, str | None]:
    """``raw`` as the value of ``model``'s parameter ``name`` (it exists, has the type, lies in
    its physical range), or the reason it cannot be. ``variables``: the model's (looked up
    once by a caller that checks many of its parameters)."""

    variables = model_variables(model) if variables is None else variables
    var = variables.get(name)
    if var is None or var.causality != "parameter":
        known = [n for n, v in variables.items() if v.causality == "parameter"]
        return None, f"{model} has no parameter '{name}'{did_you_mean(name, known)}"
    value, why = typed_value(var, raw)
    if why is not None or value is None:
        return None, why
    if var.type != "Boolean" and not var.min <= value <= var.max:
        unit = f" {var.unit}" if var.unit else ""
        return None, (
            f"{value!r}{unit} is outside the physical range [{var.min!r}, {var.max!r}] of {model}.{var.name}"
        )
    return value, None


def range_problem(var: Variable, target: str, values: Iterable[float]) -> str | None:
    """Why values driven into the input ``target`` (``instance.variable``) would be refused by
    its FMU (the first outside its declared range), or None."""
    bad = [x for x in values if not var.min <= x <= var.max]
    if not bad:
        return None
    unit = f" {var.unit}" if var.unit else ""
    return f"reaches {bad[0]!r}{unit}, outside the range [{var.min!r}, {var.max!r}] of {target}"
