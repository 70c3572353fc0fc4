"""The frozen scenario specification the master runs.

Built only by :mod:`twin.config.load`, which checks everything first; every time is an
integer number of nanoseconds (never an accumulated float).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

NS_PER_S = 1_000_000_000

ParameterValue = float | int | bool


def _frozen(d: Mapping | None = None) -> Mapping:
    return MappingProxyType(dict(d or {}))


@dataclass(frozen=True)
class Parameter:
    """A parameter value and where it comes from (paper, handbook, estimate, calibrated)."""

    value: ParameterValue
    source: str = ""


@dataclass(frozen=True)
class FMUSpec:
    """One FMU instance: which model, how often it steps, its parameter values."""

    name: str
    model: str
    period_ns: int
    parameters: Mapping[str, Parameter] = field(default_factory=_frozen)


@dataclass(frozen=True)
class Connection:
    """Output ``src`` feeds input ``dst`` ("instance.variable").

    A delayed connection passes the value of the previous exchange (its ``initial`` value at the
    first one): the only way a loop between FMUs is allowed.
    """

    src: str
    dst: str
    delay: bool = False
    initial: float | None = None


ProfileKind = Literal["constant", "ramp", "exponential", "sine", "table"]


@dataclass(frozen=True)
class Profile:
    """A time function driving an FMU input that no connection feeds."""

    target: str
    kind: ProfileKind
    params: Mapping[str, float] = field(default_factory=_frozen)
    table: tuple[tuple[float, float], ...] = ()
    source: str = ""


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
    """Everything one run needs, checked."""

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

    def fmu(self, name: str) -> FMUSpec:
        for f in self.fmus:
            if f.name == name:
                return f
        raise KeyError(name)
