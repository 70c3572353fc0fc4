"""One FMU alone read as a scenario: ``twin run X.fmu``, as ``fmpy simulate X.fmu`` runs it.

Any FMI 2.0 co-simulation FMU (one the twin built, or any other tool's) becomes the data of a
scenario of one instance, checked by :mod:`twin.config.load` as a TOML file's (``--set`` and
every ``twin run`` option work as for a scenario file):

- its ``DefaultExperiment`` gives the times, as fmpy takes them: the start (0 without one),
  the end (``stopTime``; else one second after the start) and the step (``stepSize``; else
  fmpy's choice for a fixed step, ``10 ** (round(log10(stop - start)) - 3)``); the FMU steps
  at the scenario's step and every step is recorded, so ``--step-size`` and
  ``--output-interval`` change both as they do in fmpy;
- every Real input is driven by a constant at its start value (its column in signals.csv),
  until ``--input-file`` gives it a table; an Integer or Boolean input keeps its start value
  inside the FMU;
- the instance is named after the model (``LowPass`` -> ``low_pass``): its columns are
  ``low_pass.y``; its parameters keep their start values unless ``--set
  fmu.low_pass.parameters.NAME=...`` gives one;
- there is no error model (``[errormodel] evaluate = false``) and no measured experiment to
  compare with: a lone FMU is not the tester.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction
from pathlib import Path
from typing import Any

from twin.config.durations import NS_PER_S
from twin.config.reader import unsafe_name
from twin.errors import ConfigError

__all__ = ["instance_name", "read_fmu_data"]


def instance_name(model_name: str) -> str:
    """A model's name as an instance's (lower_snake): ``LowPass`` -> ``low_pass``."""
    snake = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", model_name)
    snake = re.sub(r"[^a-z0-9_]+", "_", snake.lower()).strip("_")
    snake = re.sub(r"__+", "_", snake)
    return snake if re.fullmatch(r"[a-z][a-z0-9_]*", snake or "") else f"fmu_{snake}".rstrip("_")


def _ns(seconds: float, what: str, source: str) -> int:
    """A DefaultExperiment time in whole nanoseconds (as its decimal text says it)."""
    if not math.isfinite(seconds):
        raise ConfigError(f"DefaultExperiment {what} {seconds!r} is not a finite time", source=source)
    ns = Fraction(repr(float(seconds))) * NS_PER_S
    if ns.denominator != 1:
        raise ConfigError(
            f"DefaultExperiment {what} {seconds!r} s is not a whole number of nanoseconds", source=source
        )
    return int(ns)


def _times(md: Any, source: str) -> tuple[int, int, int]:
    """(start, stop, step) in ns, from the DefaultExperiment as fmpy reads it."""
    experiment = md.defaultExperiment
    start_s = float(experiment.startTime) if experiment and experiment.startTime is not None else 0.0
    stop_s = float(experiment.stopTime) if experiment and experiment.stopTime is not None else start_s + 1.0
    start, stop = _ns(start_s, "startTime", source), _ns(stop_s, "stopTime", source)
    if start < 0:
        raise ConfigError(
            f"DefaultExperiment startTime {start_s!r} s: the twin's clock starts at 0 (give --start-time)",
            source=source,
        )
    if experiment and experiment.stepSize is not None:
        step = _ns(float(experiment.stepSize), "stepSize", source)
    elif stop > start:
        # fmpy's fixed step for an FMU that names none (fmpy.simulation.simulate_fmu)
        step = 10 ** (round(math.log10((stop - start) / NS_PER_S)) - 3) * NS_PER_S
        step = max(1, round(step))
    else:
        step = NS_PER_S // 1000
    return start, stop, step


def read_fmu_data(path: Path) -> dict[str, Any]:
    """The scenario data of the FMU file ``path`` run alone (see the module); one
    :class:`~twin.errors.ConfigError` line naming the file when it is not an FMU the twin runs."""
    from twin.fmu.catalog import variables
    from twin.fmu.description import fmpy_description
    from twin.fmu.external import check

    source = str(path)
    checked = check(path)  # fmpy validate, FMI 2.0 co-simulation, a binary for this platform
    md = fmpy_description(checked.xml)  # the bytes checked, not the file read again
    start, stop, step = _times(md, source)
    model = checked.model_name or path.stem
    name = instance_name(model)
    run_name = path.stem if unsafe_name(path.stem) is None else name
    inputs = {
        var.name: {
            "profile": "constant",
            "value": float(var.start or 0.0),
            "source": f"{path.name}: its start value",
        }
        for var in variables(str(checked.path)).values()
        if var.causality == "input" and var.type == "Real"
    }
    scenario: dict[str, Any] = {
        "name": run_name,
        "description": f"{path.name} alone ({model}): its DefaultExperiment, inputs at their start values",
        "duration": f"{stop} ns",
        "step": f"{step} ns",
    }
    if start:
        scenario["start"] = f"{start} ns"
    held = {
        var.name: f"{path.name} alone: {'an' if var.type[0] in 'AEIOU' else 'a'} {var.type} input keeps its start value"
        for var in variables(str(checked.path)).values()
        if var.causality == "input" and var.type != "Real"
    }
    data: dict[str, Any] = {
        "scenario": scenario,
        "fmu": {name: {"model": str(checked.path), **({"unconnected": held} if held else {})}},
        "errormodel": {"evaluate": False},
    }
    if inputs:
        data["input"] = {name: inputs}
    return data
