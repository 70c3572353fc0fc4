"""The scenario: a frozen, checked value the master runs, and the copies a study makes of it.

Built from a file by :mod:`twin.config.load`, which checks everything first; every time is an
integer number of nanoseconds (never an accumulated float). A study (a sweep's points, the
testers as built, a Monte Carlo's samples, a calibration's trials) changes a scenario by its
methods, each of which returns a checked copy (as mosaik builds a world in code): no text is
written to be parsed back.

::

    tester = scenario.with_parameter("mechanics", "alpha_long_pole", 1.21e-5, source="drawn")
    warmer = tester.with_value("input.thermal.t_room.rise", 9.9).with_seed(7)
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from twin.config.checks import ParameterValue, parameter_value, range_problem
from twin.config.durations import NS_PER_S, parse_duration
from twin.config.reader import number_problem
from twin.errors import ConfigError
from twin.fmu.catalog import variables as model_variables

__all__ = [
    "NS_PER_S",
    "PROFILE_DURATIONS",
    "PROFILE_PARAMS",
    "SEED_KEY",
    "Connection",
    "Event",
    "FMUSpec",
    "Parameter",
    "ParameterValue",
    "Profile",
    "Scenario",
    "table_times_ok",
]

#: the key a study sets a run's seed by (:meth:`Scenario.with_value`)
SEED_KEY = "scenario.seed"


def _frozen(d: Mapping | None = None) -> Mapping:
    return MappingProxyType(dict(d or {}))


@dataclass(frozen=True)
class Parameter:
    """A parameter value and where it comes from (paper, handbook, estimate, calibrated)."""

    value: ParameterValue
    source: str = ""
    #: one standard error of a calibrated value (its parameter file gives it): what the run's
    #: Monte Carlo draws it by
    std_error: float | None = None


@dataclass(frozen=True)
class FMUSpec:
    """One FMU instance: which model, how often it steps, its parameter values.

    ``units`` gives a unit to inputs and outputs its FMU declares none for (variable -> unit),
    so that a connection can convert to or from them (:mod:`twin.config.connections`).
    """

    name: str
    model: str
    period_ns: int
    parameters: Mapping[str, Parameter] = field(default_factory=_frozen)
    #: inputs meant to stay at their start values, each with the reason (``unconnected``)
    unconnected: Mapping[str, str] = field(default_factory=_frozen)
    units: Mapping[str, str] = field(default_factory=_frozen)

    def unit(self, variable: str) -> str:
        """The unit of ``variable``: the one this instance gives it, else its FMU's ("": none)."""
        declared = self.units.get(variable)
        if declared is not None:
            return declared
        v = model_variables(self.model).get(variable)
        return v.unit if v is not None else ""


@dataclass(frozen=True)
class Connection:
    """Output ``src`` feeds input ``dst`` ("instance.variable").

    A delayed connection passes the value of the previous exchange (its ``initial`` value at the
    first one). The input receives ``factor * output + offset`` (a unit conversion, or an SSP
    LinearTransformation); the identity leaves the value untouched, bit for bit.
    ``convert_units`` False: factor and offset are the whole map from the output's unit to the
    input's (an SSP connection with suppressUnitConversion, or one whose unit conversion the
    SSP reader already folded into them), so the two units are not compared.
    """

    src: str
    dst: str
    delay: bool = False
    initial: float | None = None
    factor: float = 1.0
    offset: float = 0.0
    convert_units: bool = True

    @property
    def affine(self) -> bool:
        """Whether the input receives anything but the output's own value."""
        return self.factor != 1.0 or self.offset != 0.0


ProfileKind = Literal["constant", "ramp", "exponential", "sine", "table"]

#: each profile's parameters: kind -> (required, optional)
PROFILE_PARAMS: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    "constant": (frozenset({"value"}), frozenset()),
    "ramp": (frozenset({"start", "end", "duration"}), frozenset({"delay"})),
    "exponential": (frozenset({"start", "rise", "time_constant"}), frozenset({"rise_at"})),
    "sine": (frozenset({"mean", "amplitude", "period"}), frozenset({"phase"})),
    "table": (frozenset({"points"}), frozenset()),
}
#: the parameters that are durations (seconds in :attr:`Profile.params`)
PROFILE_DURATIONS = frozenset({"duration", "delay", "time_constant", "rise_at", "period"})


@dataclass(frozen=True)
class Profile:
    """A time function driving an FMU input that no connection feeds (times in seconds)."""

    target: str
    kind: ProfileKind
    params: Mapping[str, float] = field(default_factory=_frozen)
    table: tuple[tuple[float, float], ...] = ()
    source: str = ""

    @classmethod
    def of_table(cls, target: str, times_s: Any, values: Any, source: str = "") -> Profile:
        """A ``table`` profile through the points (``times_s``, ``values``)."""
        points = tuple((float(t), float(v)) for t, v in zip(times_s, values, strict=True))
        return cls(target, "table", _frozen(), points, source)

    def extremes(self) -> list[float]:
        """The values it can reach (its extremes), for the range check."""
        q = self.params
        if self.kind == "constant":
            return [q["value"]]
        if self.kind == "ramp":
            return [q["start"], q["end"]]
        if self.kind == "exponential":
            scale = 1.0 / -math.expm1(-q["rise_at"] / q["time_constant"]) if "rise_at" in q else 1.0
            return [q["start"], q["start"] + q["rise"] * scale]
        if self.kind == "sine":
            return [q["mean"] - q["amplitude"], q["mean"] + q["amplitude"]]
        return [v for _, v in self.table]

    def problem(self) -> str | None:
        """Why it cannot drive an input (a parameter missing or not finite, a table whose
        times do not increase), or None."""
        if self.kind not in PROFILE_PARAMS:
            return f"unknown profile {self.kind!r} (expected one of: {', '.join(PROFILE_PARAMS)})"
        required, optional = PROFILE_PARAMS[self.kind]
        missing = sorted(required - set(self.params) - ({"points"} if self.table else set()))
        unknown = sorted(set(self.params) - required - optional)
        if missing or unknown:
            return f"the '{self.kind}' profile needs {sorted(required)}" + (
                f", not {unknown}" if unknown else ""
            )
        if not all(math.isfinite(v) for v in self.params.values()):
            return "its parameters must be finite numbers"
        if self.kind == "table" and not table_times_ok([t for t, _ in self.table]):
            return "a table needs at least two points, times increasing (a time given twice is a jump)"
        return None

    def with_param(self, name: str, value: Any) -> Profile:
        """A copy with its parameter ``name`` set: a number (seconds for a duration, which may
        also be a duration's text such as ``"2 h"``)."""
        required, optional = PROFILE_PARAMS.get(self.kind, (frozenset(), frozenset()))
        if name not in (required | optional) - {"points"}:
            known = ", ".join(sorted((required | optional) - {"points"})) or "none"
            raise ConfigError(
                f"the '{self.kind}' profile has no parameter '{name}' (its parameters: {known})",
                key=f"input.{self.target}.{name}",
            )
        return dataclasses.replace(
            self, params=_frozen({**self.params, name: _profile_number(self, name, value)})
        )


def table_times_ok(times: Any) -> bool:
    """Whether ``times`` can be a table profile's: at least two, the last after the first,
    never decreasing, none given more than twice. A time given twice is a jump: the later value holds from that time on
    (``numpy.interp``), as fmpy applies an input file's jump at a communication point."""
    times = list(times)
    if len(times) < 2 or times[-1] <= times[0] or any(b < a for a, b in itertools.pairwise(times)):
        return False
    return not any(a == c for a, c in zip(times, times[2:], strict=False))


def _profile_number(profile: Profile, name: str, value: Any) -> float:
    key = f"input.{profile.target}.{name}"
    if name in PROFILE_DURATIONS:
        try:
            return parse_duration(value) / NS_PER_S
        except ValueError as exc:
            raise ConfigError(str(exc), key=key) from None
    why = number_problem(value)
    if why is not None:
        raise ConfigError(why, key=key)
    return float(value)


EventAction = Literal["set", "ramp", "bias"]


@dataclass(frozen=True)
class Event:
    """At ``at_ns``: set an input, ramp it over ``duration_ns``, or bias an output by ``value``."""

    at_ns: int
    action: EventAction
    target: str
    value: float
    duration_ns: int = 0


@dataclass(frozen=True)
class Scenario:
    """Everything one run needs, checked.

    ``errormodel``, ``uncertainty`` and ``reference`` are the scenario file's tables of those
    names as written: what the error model is set to, what the run's Monte Carlo draws, the
    measured experiment it replays; each is checked once, where it is used
    (:func:`twin.pipeline.prepare.prepare`).
    """

    name: str
    description: str
    source_path: str
    duration_ns: int
    step_ns: int
    output_interval_ns: int
    seed: int
    fmus: tuple[FMUSpec, ...]
    connections: tuple[Connection, ...] = ()
    profiles: tuple[Profile, ...] = ()
    events: tuple[Event, ...] = ()
    drift_window_ns: int = 300 * NS_PER_S
    errormodel: Mapping[str, Parameter] = field(default_factory=_frozen)
    #: an endurance test's wear limit (mm), drawn in wear.png; None for other tests
    wear_limit_mm: float | None = None
    uncertainty: Mapping[str, Any] = field(default_factory=_frozen)
    reference: Mapping[str, Any] = field(default_factory=_frozen)
    #: when the run begins: the FMUs' start time and the master's first tick (0, or later
    #: within the scenario's clock, which ends at ``duration_ns``)
    start_ns: int = 0

    def fmu(self, name: str) -> FMUSpec:
        for f in self.fmus:
            if f.name == name:
                return f
        raise KeyError(name)

    def profile(self, target: str) -> Profile:
        """The profile driving the input ``target`` (``instance.variable``)."""
        for p in self.profiles:
            if p.target == target:
                return p
        raise ConfigError(f"no profile drives {target}", source=self.source_path, key=f"input.{target}")

    # -- changed copies ------------------------------------------------------------------

    def with_parameter(self, instance: str, name: str, value: Any, source: str = "") -> Scenario:
        """A copy with the parameter ``name`` of the FMU instance ``instance`` set to ``value``,
        checked as the loader checks it (the model has it, of its type, in its physical range)."""
        return self.with_parameters(instance, {name: value}, source)

    def with_parameters(self, instance: str, values: Mapping[str, Any], source: str = "") -> Scenario:
        """A copy with several parameters of one instance set (see :meth:`with_parameter`)."""
        spec = self._instance(instance)
        params = dict(spec.parameters)
        variables = model_variables(spec.model)
        for name, raw in values.items():
            var = variables.get(name)
            # a drawn value (a float for a Real parameter, in its range) is what a Monte Carlo
            # sets for each drawn parameter of each sample: it takes the short way, to the value
            # parameter_value would return (float(raw) is raw); anything else its full check
            if (
                type(raw) is float
                and var is not None
                and var.type == "Real"
                and var.causality == "parameter"
                and var.min <= raw <= var.max
                and math.isfinite(raw)
            ):
                value: ParameterValue | None = raw
            else:
                value, why = parameter_value(spec.model, name, raw, variables)
                if why is not None or value is None:
                    raise ConfigError(
                        why or "", source=self.source_path, key=f"fmu.{instance}.parameters.{name}"
                    )
            params[name] = Parameter(value, source)
        changed = dataclasses.replace(spec, parameters=_frozen(params))
        return dataclasses.replace(self, fmus=tuple(changed if f.name == instance else f for f in self.fmus))

    def with_input(self, profile: Profile) -> Scenario:
        """A copy whose input ``profile.target`` is driven by ``profile`` (in place of the
        profile driving it, if one does): a free Real input, every value in its range."""
        key = f"input.{profile.target}"
        var = self._free_input(profile.target, key)
        why = profile.problem() or range_problem(var, profile.target, profile.extremes())
        if why is not None:
            raise ConfigError(why, source=self.source_path, key=key)
        if any(p.target == profile.target for p in self.profiles):
            profiles = tuple(profile if p.target == profile.target else p for p in self.profiles)
        else:
            profiles = (*self.profiles, profile)
        return dataclasses.replace(self, profiles=profiles)

    def with_seed(self, seed: int) -> Scenario:
        """A copy with the scenario seed ``seed`` (an integer in [0, 2^31))."""
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
            raise ConfigError(
                f"expected an integer in [0, 2^31), got {seed!r}", source=self.source_path, key=SEED_KEY
            )
        return dataclasses.replace(self, seed=seed)

    def with_value(self, key: str, value: Any) -> Scenario:
        """A copy with what ``key`` names set to ``value``: the keys a study varies, as a sweep
        file writes them: ``fmu.<instance>.parameters.<name>``, ``input.<instance>.<variable>.
        <parameter>`` (one parameter of the profile driving that input) or ``scenario.seed``."""
        parts = key.split(".")
        if key == SEED_KEY:
            return self.with_seed(value)
        if len(parts) == 4 and parts[0] == "fmu" and parts[2] == "parameters":
            return self.with_parameter(parts[1], parts[3], value)
        if len(parts) == 4 and parts[0] == "input":
            target = f"{parts[1]}.{parts[2]}"
            return self.with_input(self.profile(target).with_param(parts[3], value))
        raise ConfigError(
            "a study varies fmu.<instance>.parameters.<name>, input.<instance>.<variable>.<parameter> "
            f"or {SEED_KEY}",
            source=self.source_path,
            key=key,
        )

    def nominal(self, key: str) -> float | None:
        """The value ``key`` (as :meth:`with_value` takes it) has here: a parameter's (its
        model's start value where the scenario gives none), a profile's, the seed; None when
        it has no numeric value."""
        parts = key.split(".")
        if key == SEED_KEY:
            return float(self.seed)
        if len(parts) == 4 and parts[0] == "fmu" and parts[2] == "parameters":
            spec = next((f for f in self.fmus if f.name == parts[1]), None)
            if spec is None:
                return None
            if parts[3] in spec.parameters:
                return float(spec.parameters[parts[3]].value)
            var = model_variables(spec.model).get(parts[3])
            start = var.start if var is not None else None
            return float(start) if isinstance(start, int | float) else None
        if len(parts) == 4 and parts[0] == "input":
            profile = next((p for p in self.profiles if p.target == f"{parts[1]}.{parts[2]}"), None)
            value = profile.params.get(parts[3]) if profile is not None else None
            return float(value) if value is not None else None
        return None

    def _instance(self, instance: str) -> FMUSpec:
        try:
            return self.fmu(instance)
        except KeyError:
            known = ", ".join(f.name for f in self.fmus)
            raise ConfigError(
                f"unknown FMU instance '{instance}' (known: {known})",
                source=self.source_path,
                key=f"fmu.{instance}",
            ) from None

    def _free_input(self, target: str, key: str) -> Any:
        instance, _, name = target.partition(".")
        var = model_variables(self._instance(instance).model).get(name)
        if var is None or var.causality != "input" or var.type != "Real":
            raise ConfigError(f"{target!r} is not a Real input of its FMU", source=self.source_path, key=key)
        if any(c.dst == target for c in self.connections):
            raise ConfigError(f"input {target!r} is fed by a connection", source=self.source_path, key=key)
        return var
