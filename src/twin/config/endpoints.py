"""FMU variables named in a scenario (``"instance.variable"``), checked against the catalog."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from twin.config.checks import range_problem
from twin.config.reader import Problems
from twin.config.spec import FMUSpec
from twin.fmu.catalog import Variable
from twin.fmu.catalog import variables as model_variables


def endpoint(p: Problems, fmus: Mapping[str, FMUSpec], ref: Any, key: str, causality: str) -> Variable | None:
    """The Real variable ``ref`` names if it exists with ``causality``, else None and a problem."""
    if not isinstance(ref, str) or ref.count(".") != 1:
        p.add(key, f"expected 'instance.variable', got {ref!r}")
        return None
    inst, var = ref.split(".")
    spec = fmus.get(inst)
    if spec is None:
        if not p.no_fmus and inst not in p.broken:
            p.add(key, f"unknown FMU instance '{inst}' in {ref!r} (known: {', '.join(sorted(fmus))})")
        return None
    v = model_variables(spec.model).get(var)
    if v is None:
        p.add(key, f"{spec.model} has no variable '{var}' (in {ref!r})")
        return None
    if v.causality != causality:
        a = "an" if v.causality[0] in "aeiou" else "a"
        p.add(key, f"{ref!r} is {a} {v.causality}, expected an {causality}")
        return None
    if v.type != "Real":
        p.add(key, f"{ref!r} is {v.type}; only Real variables are exchanged")
        return None
    return v


def check_range(
    p: Problems, fmus: Mapping[str, FMUSpec], target: str, values: Sequence[float], key: str
) -> None:
    """Values driven into an input must lie in its declared range (the FMU would refuse them)."""
    inst, var = target.split(".")
    why = range_problem(model_variables(fmus[inst].model)[var], target, values)
    if why is not None:
        p.add(key, why)
