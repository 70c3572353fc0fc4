"""Property-based tests of the scenario loader (issue 6, item 5).

* Values inside the documented ranges never fail: consistent steps, periods, durations and
  output intervals (in any exact spelling: "0.5 s", "500ms", 0.5, ...), seeds in [0, 2^31),
  parameters inside each FMU parameter's [min, max] from modelDescription.xml, profiles and
  events inside their target input's range -> the file loads and the Scenario holds the values.
* Values outside give a clear error: out-of-range parameters, zero/negative durations,
  non-multiples, wrong types, unknown keys -> ConfigErrors whose str() has one line per
  problem, each naming the file and the key; never another exception.
* Anything else (any value of any type at any key, any ``--set``) -> loads or ConfigError.

The base scenario is the paper's, plus one instance of every model it does not use, so every
model's parameters are covered. The loader bugs these properties found (non-ConfigError
exceptions, a wrong refusal, problems spanning two lines) have regression tests at the end.
"""

from __future__ import annotations

import copy
import datetime as dt
import math
import re
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from twin.config.durations import MAX_TICKS
from twin.config.load import (
    MAX_DURATION_NS,
    load_scenario,
    load_scenario_data,
    parse_duration,
)
from twin.config.reader import SAFE_NAME
from twin.config.spec import NS_PER_S
from twin.errors import ConfigError, ConfigErrors
from twin.fmu.build import model_names
from twin.fmu.catalog import variables as model_variables

from ..config.scenario_toml import PAPER, dumps, paper_data, write

COMMON = {
    "deadline": None,
    "derandomize": True,  # the same examples on every run and in CI
    "database": None,
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
}
SOURCE = "prop.toml"
BASE_DIR = PAPER.parent
FAULT_INPUT = "fault_inject"
#: text the test helper writes as valid TOML (its JSON escapes cannot spell surrogate pairs or DEL)
TOML_SAFE = st.characters(max_codepoint=0xFFFF, exclude_categories=["Cs", "Cc"])

# ----------------------------------------------------------------------------- the base scenario


def _snake(model: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "_", model).lower()


_PAPER = paper_data()
#: instance -> model: the paper's instances plus one of every model the paper does not use
INSTANCES: dict[str, str] = {name: spec["model"] for name, spec in _PAPER["fmu"].items()}
INSTANCES.update({_snake(m): m for m in model_names() if m not in INSTANCES.values()})


def base_data() -> dict[str, Any]:
    data = paper_data()
    for inst, model in INSTANCES.items():
        data["fmu"].setdefault(
            inst, {"model": model, "period": "1 s", "unconnected": "spare: nothing feeds it"}
        )
    return data


def _fed(data: dict[str, Any]) -> set[str]:
    out = set()
    for dsts in data.get("connections", {}).values():
        out.update([dsts] if isinstance(dsts, str) else dsts)
    return out


@dataclass(frozen=True)
class Var:
    inst: str
    name: str
    type: str
    causality: str
    lo: float
    hi: float

    @property
    def ref(self) -> str:
        return f"{self.inst}.{self.name}"


def _range(v: Any) -> tuple[float, float]:
    return (v.min, v.max)  # the catalog resolves declared types and missing bounds (+-inf)


def _vars(causality: str) -> list[Var]:
    out = []
    for inst, model in INSTANCES.items():
        for v in model_variables(model).values():
            if v.causality == causality:
                out.append(Var(inst, v.name, v.type, v.causality, *_range(v)))
    return out


PARAMETERS = _vars("parameter")
FED = _fed(_PAPER)
FREE_INPUTS = [v for v in _vars("input") if v.ref not in FED and v.type == "Real"]
FED_INPUTS = [v for v in _vars("input") if v.ref in FED]
OUTPUTS = [v for v in _vars("output") if v.type == "Real"]


def test_base_scenario_loads() -> None:
    scenario = load_scenario_data(base_data(), SOURCE, BASE_DIR)
    assert {f.name: f.model for f in scenario.fmus} == INSTANCES
    assert set(INSTANCES.values()) == set(model_names())


# ----------------------------------------------------------------------------- strategies: durations

UNITS = {
    "ns": 1,
    "us": 10**3,
    "ms": 10**6,
    "s": NS_PER_S,
    "min": 60 * NS_PER_S,
    "h": 3600 * NS_PER_S,
    "d": 86400 * NS_PER_S,
}


def _decimal(q: Fraction) -> str | None:
    """Exact decimal text of q, or None if it has none."""
    if q.denominator == 1:
        return str(q.numerator)
    k = 0
    while (q * 10**k).denominator != 1:
        k += 1
        if k > 30:
            return None
    digits = str(q.numerator * 10**k // q.denominator).rjust(k + 1, "0")
    return f"{digits[:-k]}.{digits[-k:]}"


def duration_spelling(ns: int) -> st.SearchStrategy[Any]:
    """Every exact spelling of ``ns``: "<decimal> <unit>" (with or without a space), whole
    seconds as an integer, seconds as a float when its repr is exact."""
    options: list[st.SearchStrategy[Any]] = []
    for unit, factor in UNITS.items():
        text = _decimal(Fraction(ns, factor))
        if text is not None:
            options.append(st.sampled_from(["", " ", "  "]).map(lambda sep, t=text, u=unit: f"{t}{sep}{u}"))
    if ns % NS_PER_S == 0:
        options.append(st.just(ns // NS_PER_S))
    seconds = ns / NS_PER_S
    if Fraction(repr(seconds)) * NS_PER_S == ns:
        options.append(st.just(seconds))
    return st.one_of(options)


def positive_duration(max_ns: int = 10**15) -> st.SearchStrategy[tuple[int, Any]]:
    return st.integers(1, max_ns).flatmap(lambda ns: st.tuples(st.just(ns), duration_spelling(ns)))


MULTIPLES = [1, 2, 3, 4, 5, 6, 10, 12, 15, 20, 30, 60]


@dataclass
class Expect:
    """What the loaded Scenario must hold."""

    step: int = 0
    duration: int = 0
    interval: int = 0
    drift: int = 0
    seed: int = 0
    name: str = ""
    periods: dict[str, int] = field(default_factory=dict)
    params: dict[tuple[str, str], Any] = field(default_factory=dict)
    profiles: dict[str, tuple[str, dict[str, float], tuple[tuple[float, float], ...]]] = field(
        default_factory=dict
    )
    events: list[tuple[int, str, str, float, int]] = field(default_factory=list)


# ----------------------------------------------------------------------------- strategies: values


def in_range(v: Var) -> st.SearchStrategy[Any]:
    """A TOML value inside the variable's range (Reals also as integers when whole ones fit)."""
    if v.type == "Boolean":
        return st.booleans()
    if v.type == "Integer":
        return st.integers(math.ceil(v.lo), math.floor(v.hi))
    lo, hi = max(v.lo, -1e300), min(v.hi, 1e300)
    floats = st.floats(lo, hi, allow_nan=False, allow_infinity=False)
    ilo, ihi = math.ceil(lo), math.floor(hi)
    return st.one_of(floats, st.integers(int(ilo), int(ihi))) if ilo <= ihi else floats


def _stored(v: Var, raw: Any) -> Any:
    return float(raw) if v.type == "Real" else raw


def _shrink_into(reach: Callable[[float], list[float]], x: float, lo: float, hi: float) -> float:
    """Move x toward 0 (ulp by ulp) until every value of reach(x) lies in [lo, hi]."""
    for _ in range(64):
        if all(lo <= r <= hi for r in reach(x)):
            return x
        x = math.nextafter(x, 0.0)
    return 0.0


@dataclass
class _Profile:
    """A profile being drawn for one input: its TOML table and the parameters it must load as."""

    d: st.DrawFn
    v: Var
    raw: dict[str, Any]
    params: dict[str, float] = field(default_factory=dict)

    def value(self) -> float:
        """A value inside the input's range."""
        return self.d(st.floats(self.v.lo, self.v.hi, allow_nan=False))

    def duration(self, key: str, *, zero_ok: bool = False) -> None:
        """A duration at ``key`` in any exact spelling; loaded as seconds."""
        ns, spelled = self.d(
            st.integers(0 if zero_ok else 1, 10**15).flatmap(
                lambda n: st.tuples(st.just(n), duration_spelling(n))
            )
        )
        self.raw[key] = spelled
        self.params[key] = ns / NS_PER_S


# One function per profile kind: it fills the _Profile and returns the table the loader must
# build (empty but for "table").


def _constant_profile(p: _Profile) -> tuple[tuple[float, float], ...]:
    p.raw["value"] = p.params["value"] = p.value()
    return ()


def _ramp_profile(p: _Profile) -> tuple[tuple[float, float], ...]:
    p.raw["start"] = p.params["start"] = p.value()
    p.raw["end"] = p.params["end"] = p.value()
    p.duration("duration")
    if p.d(st.booleans()):
        p.duration("delay", zero_ok=True)
    return ()


def _exponential_profile(p: _Profile) -> tuple[tuple[float, float], ...]:
    start, end = p.value(), p.value()
    p.duration("time_constant")
    scale = 1.0
    if p.d(st.booleans()):
        p.duration("rise_at")
        scale = 1.0 / -math.expm1(-p.params["rise_at"] / p.params["time_constant"])
    rise = _shrink_into(lambda r: [start, start + r * scale], (end - start) / scale, p.v.lo, p.v.hi)
    p.raw["start"], p.raw["rise"] = start, rise
    p.params.update(start=start, rise=rise)
    return ()


def _sine_profile(p: _Profile) -> tuple[tuple[float, float], ...]:
    lo, hi = p.v.lo, p.v.hi
    a, b = p.value(), p.value()
    mean = a / 2 + b / 2
    if not lo <= mean <= hi:
        mean = a
    amp = _shrink_into(lambda x: [mean - x, mean + x], abs(b - a) / 2, lo, hi)
    p.raw.update(mean=mean, amplitude=amp)
    p.params.update(mean=mean, amplitude=amp)
    p.duration("period")
    if p.d(st.booleans()):
        p.raw["phase"] = p.params["phase"] = p.d(st.floats(-1e6, 1e6))
    return ()


def _table_profile(p: _Profile) -> tuple[tuple[float, float], ...]:
    times = sorted(p.d(st.sets(st.integers(0, 10**15), min_size=2, max_size=6)))
    values = [p.value() for _ in times]
    p.raw["points"] = [[p.d(duration_spelling(t)), x] for t, x in zip(times, values, strict=True)]
    return tuple((t / NS_PER_S, float(x)) for t, x in zip(times, values, strict=True))


PROFILE_KINDS: dict[str, Callable[[_Profile], tuple[tuple[float, float], ...]]] = {
    "constant": _constant_profile,
    "ramp": _ramp_profile,
    "exponential": _exponential_profile,
    "sine": _sine_profile,
    "table": _table_profile,
}


@st.composite
def profile_in_range(d: st.DrawFn, v: Var) -> tuple[dict[str, Any], tuple[str, dict[str, float], tuple]]:
    """A profile whose values stay inside v's range: (TOML table, expected (kind, params, table))."""
    kind = d(st.sampled_from(list(PROFILE_KINDS)))
    p = _Profile(d, v, {"profile": kind})
    table = PROFILE_KINDS[kind](p)
    if d(st.booleans()):
        p.raw["source"] = d(st.text(TOML_SAFE, max_size=10))
    return p.raw, (kind, p.params, table)


@st.composite
def valid_scenarios(d: st.DrawFn) -> tuple[dict[str, Any], Expect]:
    data = base_data()
    exp = Expect()
    sc = data["scenario"]
    # times: periods are multiples of the step, the duration a multiple of every period
    unit = d(st.sampled_from([1, 10**3, 10**6, NS_PER_S, 60 * NS_PER_S]), label="step unit")
    exp.step = unit * d(st.integers(1, 1000), label="step / unit")
    mults = {inst: d(st.sampled_from(MULTIPLES)) for inst in INSTANCES}
    span = exp.step * math.lcm(*mults.values())
    # within a year and within the ticks a run may take (twin.config.durations.MAX_TICKS)
    longest = min(MAX_DURATION_NS, MAX_TICKS * exp.step)
    exp.duration = span * d(st.integers(1, max(1, longest // span)), label="duration / lcm")
    if exp.duration < 2 * exp.step:
        exp.duration = 2 * span
    exp.interval = exp.step * d(st.integers(1, exp.duration // exp.step), label="interval / step")
    exp.drift, drift = d(positive_duration(10**16))
    exp.seed = d(st.integers(0, 2**31 - 1))
    exp.name = d(st.from_regex(SAFE_NAME, fullmatch=True).filter(lambda n: ".." not in n))  # names a folder
    sc.update(
        name=exp.name,
        step=d(duration_spelling(exp.step)),
        duration=d(duration_spelling(exp.duration)),
        output_interval=d(duration_spelling(exp.interval)),
        drift_window=drift,
        seed=exp.seed,
    )
    for inst, m in mults.items():
        exp.periods[inst] = exp.step * m
        data["fmu"][inst]["period"] = d(duration_spelling(exp.step * m))
    # a few parameters of every instance, each inside its declared range
    for inst in INSTANCES:
        own = [v for v in PARAMETERS if v.inst == inst]
        chosen = d(st.lists(st.sampled_from(own), unique_by=lambda v: v.name, max_size=4))
        table = data["fmu"][inst].setdefault("parameters", {})
        for v in chosen:
            raw = d(in_range(v), label=v.ref)
            table[v.name] = {"value": raw, "source": "prop"} if d(st.booleans()) else raw
            exp.params[(inst, v.name)] = _stored(v, raw)
    # profiles on a few free inputs (replacing the paper's), each inside the input's range
    for v in d(st.lists(st.sampled_from(FREE_INPUTS), unique_by=lambda v: v.ref, max_size=4)):
        raw, expected = d(profile_in_range(v), label=f"profile {v.ref}")
        data.setdefault("input", {}).setdefault(v.inst, {})[v.name] = raw
        exp.profiles[v.ref] = expected
    # events: set/ramp a free input inside its range, bias an output, make an FMU fail
    events = []
    for _ in range(d(st.integers(0, 3))):
        at = d(st.integers(0, exp.duration - 1))
        action = d(st.sampled_from(["set", "ramp", "bias", "fault"]))
        ev: dict[str, Any] = {"at": d(duration_spelling(at)), "action": action}
        if action == "fault":
            inst = d(st.sampled_from(sorted(INSTANCES)))
            fault = d(st.sampled_from(["error", "discard", "nan"]))
            ev.update(target=inst, fault=fault)
            exp.events.append(
                (at, "set", f"{inst}.{FAULT_INPUT}", {"error": 1.0, "discard": 2.0, "nan": 3.0}[fault], 0)
            )
        else:
            v = d(st.sampled_from(OUTPUTS if action == "bias" else FREE_INPUTS))
            # up to three biases on one output add up: each a third of the narrowest range
            w = _bias_width(v) / 3
            value = d(st.floats(-w, w) if action == "bias" else st.floats(v.lo, v.hi))
            ev.update(target=v.ref, value=value)
            dur = 0
            if action == "ramp":
                dur, ev["duration"] = d(positive_duration())
            exp.events.append((at, action, v.ref, value, dur))
        events.append(ev)
    if events:
        data["event"] = events
    return data, exp


def _bias_width(v: Var) -> float:
    """The narrowest range a bias on output ``v`` must fit: its own, those of the inputs it feeds."""
    dsts = _PAPER.get("connections", {}).get(v.ref, [])
    refs = [v.ref, *([dsts] if isinstance(dsts, str) else dsts)]
    spans = [x.hi - x.lo for x in [*OUTPUTS, *_vars("input")] if x.ref in refs]
    return min([1e6, *(s for s in spans if math.isfinite(s))])


# ----------------------------------------------------------------------------- (a) inside the ranges


def _load_file(data: dict[str, Any]) -> Any:
    with tempfile.TemporaryDirectory() as tmp:
        return load_scenario(write(Path(tmp) / SOURCE, data))


@settings(max_examples=200, **COMMON)
@given(drawn=valid_scenarios())
def test_values_inside_ranges_load_and_are_kept(drawn: tuple[dict[str, Any], Expect]) -> None:
    data, exp = drawn
    try:
        sc = _load_file(data)
    except ConfigError as exc:
        pytest.fail(f"a scenario inside every documented range was refused:\n{exc}\n\n{dumps(data)}")
    assert (sc.step_ns, sc.duration_ns, sc.output_interval_ns) == (exp.step, exp.duration, exp.interval)
    assert (sc.seed, sc.drift_window_ns, sc.name) == (exp.seed, exp.drift, exp.name)
    assert {f.name: f.period_ns for f in sc.fmus} == exp.periods
    for (inst, name), value in exp.params.items():
        got = sc.fmu(inst).parameters[name].value
        assert got == value and type(got) is type(value), (inst, name, got, value)
    profiles = {p.target: p for p in sc.profiles}
    for target, (kind, params, table) in exp.profiles.items():
        p = profiles[target]
        assert (p.kind, dict(p.params), p.table) == (kind, params, table), target
    got_events = sorted((e.at_ns, e.action, e.target, e.value, e.duration_ns) for e in sc.events)
    assert got_events == sorted(exp.events)
    event(f"{len(exp.params)} parameters, {len(exp.profiles)} profiles, {len(exp.events)} events")


# ----------------------------------------------------------------------------- (b) outside the ranges


@dataclass
class Mutation:
    key: str  # the key the error must name
    apply: Callable[[dict[str, Any]], None]
    what: str
    #: other keys the same mistake may legitimately be reported at too (regexes)
    also: tuple[str, ...] = ()
    #: what must still be valid for this problem to be detectable: step, duration,
    #: model:<inst> (its model is known), spec:<inst> (it is usable: it has a period)
    needs: frozenset[str] = frozenset()
    #: what this mutation makes invalid
    breaks: frozenset[str] = frozenset()


def _setter(*path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def apply(data: dict[str, Any]) -> None:
        node = data
        for p in path[:-1]:
            node = node.setdefault(p, {})
        node[path[-1]] = value

    apply.path = path  # type: ignore[attr-defined]
    return apply


def _deleter(*path: str) -> Callable[[dict[str, Any]], None]:
    def apply(data: dict[str, Any]) -> None:
        node = data
        for p in path[:-1]:
            node = node[p]
        node.pop(path[-1], None)

    apply.path = path  # type: ignore[attr-defined]
    return apply


def _target(m: Mutation) -> tuple[Any, ...]:
    path = m.apply.path  # type: ignore[attr-defined]
    return tuple(path[:3]) if path[0] in ("input", "fmu") else tuple(path[:2])


#: scalars, arrays and tables of every TOML type (what a typo or a wrong paste produces)
toml_scalars = st.one_of(
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(),
    st.text(max_size=12),
    st.dates(),
    st.times(),
    st.datetimes(),
)
toml_values = st.recursive(
    toml_scalars,
    lambda c: st.one_of(st.lists(c, max_size=3), st.dictionaries(st.text(max_size=6), c, max_size=3)),
    max_leaves=6,
)
not_a_number = toml_values.filter(lambda x: isinstance(x, bool) or not isinstance(x, int | float))
not_a_duration_text = st.text(max_size=12).filter(lambda s: _not_duration(s))
unparseable_durations = st.one_of(
    st.sampled_from(
        [
            *("1 parsec", "5 minutes", "", "0.5 ns", "1.25 ns", "-1 s", math.nan, math.inf, -math.inf),
            *("1e400 s", "1e5000 s", "2000000 d", 1e300),  # absurdly long
        ]
    ),
    st.text(max_size=12).filter(lambda s: _unparseable(s)),
    toml_values.filter(lambda x: isinstance(x, bool | list | dict | dt.date | dt.time)),
)
bad_durations = st.one_of(
    unparseable_durations,
    st.integers(max_value=0),
    st.floats(max_value=0.0),
    st.sampled_from(
        [0, "0 s", "0ms", "-1 s", "1 parsec", "5 minutes", "", "0.5 ns", "1.25 ns", math.nan, math.inf]
    ),
    st.floats(min_value=1e-12, max_value=1e-9, exclude_max=True),  # fractions of a nanosecond
    not_a_duration_text,
    toml_values.filter(lambda x: isinstance(x, bool | list | dict | dt.date | dt.time)),
)


def _unparseable(s: str) -> bool:
    try:
        parse_duration(s)
    except ValueError:
        return True
    return False


def _not_duration(s: str) -> bool:
    try:
        return parse_duration(s) <= 0
    except ValueError:
        return True


def _step_ns(data: dict[str, Any]) -> int:
    return parse_duration(data["scenario"]["step"])


#: what to get wrong (profiles and events have many ways each: drawn more often)
MUTATION_KINDS = [
    "step",
    "duration",
    "duration-multiple",
    "interval",
    "interval-multiple",
    "seed",
    "drift",
    "name",
    "description",
    "period",
    "period-multiple",
    "period-divides",
    "parameter-range",
    "parameter-range",
    "parameter-type",
    "parameter-unknown",
    *["profile"] * 6,
    *["event"] * 3,
    "unknown-key",
    "missing",
]


@dataclass(frozen=True)
class _Mutating:
    """What a mutation of one kind is drawn with."""

    d: st.DrawFn
    kind: str
    step: int  # the base scenario's step, ns
    duration: int  # and its duration, ns
    inst: str = ""  # the instance a per-instance mutation is about

    @property
    def spec(self) -> frozenset[str]:
        return frozenset({f"spec:{self.inst}"})  # the instance is usable: its inputs are checked

    @property
    def model(self) -> frozenset[str]:
        return frozenset({f"model:{self.inst}"})  # its model is known: its period and parameters are checked


MutationFn = Callable[[_Mutating], Mutation]

# ---- mistakes in [scenario]


def _scenario_value(
    key: str, values: st.SearchStrategy[Any], breaks: frozenset[str] = frozenset()
) -> MutationFn:
    """A wrong value drawn from ``values`` at scenario.<key>."""
    return lambda m: Mutation(
        f"scenario.{key}", _setter("scenario", key, value=m.d(values)), m.kind, breaks=breaks
    )


def _duration_mutation(m: _Mutating) -> Mutation:
    if m.kind == "duration":
        value = m.d(st.one_of(bad_durations, st.sampled_from(["367 d", "1000 d", 366 * 86400 + 1])))
        needs: frozenset[str] = frozenset()
    else:  # not a multiple of the step
        k = m.d(st.integers(0, 10**6))
        value, needs = f"{k * m.step + m.d(st.integers(1, m.step - 1))} ns", frozenset({"step"})
    return Mutation(
        "scenario.duration",
        _setter("scenario", "duration", value=value),
        m.kind,
        also=(r"fmu\.\w+\.period", r"event\[0\]\.at"),  # an event at 1 s is late for a run of -1 s
        needs=needs,
        breaks=frozenset({"duration"}),
    )


def _interval_multiple(m: _Mutating) -> Mutation:
    step = m.step
    if m.d(st.booleans()):  # longer than the run
        value, needs = f"{m.duration + step * m.d(st.integers(1, 10**6))} ns", frozenset({"duration", "step"})
    else:
        value, needs = (
            f"{step * m.d(st.integers(0, 10**6)) + m.d(st.integers(1, step - 1))} ns",
            frozenset({"step"}),
        )
    return Mutation(
        "scenario.output_interval", _setter("scenario", "output_interval", value=value), m.kind, needs=needs
    )


not_a_string = toml_values.filter(lambda x: not isinstance(x, str))

SCENARIO_MUTATIONS: dict[str, MutationFn] = {
    "step": _scenario_value("step", bad_durations, breaks=frozenset({"step"})),
    "duration": _duration_mutation,
    "duration-multiple": _duration_mutation,
    "interval": _scenario_value("output_interval", bad_durations),
    "interval-multiple": _interval_multiple,
    "seed": _scenario_value(
        "seed", st.one_of(st.integers(max_value=-1), st.integers(min_value=2**31), st.floats(), not_a_number)
    ),
    "drift": _scenario_value("drift_window", bad_durations),
    "name": _scenario_value("name", st.one_of(st.just(""), not_a_string)),
    "description": _scenario_value("description", not_a_string),
}

# ---- mistakes in one [fmu.<inst>]


def _period_mutation(m: _Mutating) -> Mutation:
    value = m.d(bad_durations)
    try:
        parse_duration(value)
        breaks = frozenset()
    except ValueError:
        breaks = m.spec  # an unusable instance: its inputs are no longer checked
    return Mutation(
        f"fmu.{m.inst}.period",
        _setter("fmu", m.inst, "period", value=value),
        m.kind,
        needs=m.model,
        breaks=breaks,
    )


def _period_multiple(m: _Mutating) -> Mutation:
    value = f"{m.step * m.d(st.integers(0, 100)) + m.d(st.integers(1, m.step - 1))} ns"
    return Mutation(
        f"fmu.{m.inst}.period",
        _setter("fmu", m.inst, "period", value=value),
        m.kind,
        needs=m.model | {"step"},
    )


def _period_divides(m: _Mutating) -> Mutation:
    k = m.d(st.sampled_from([k for k in range(2, 2000) if m.duration % (k * m.step)]))
    return Mutation(
        f"fmu.{m.inst}.period",
        _setter("fmu", m.inst, "period", value=f"{k * m.step} ns"),
        m.kind,
        needs=m.model | {"step", "duration"},
    )


def _unknown_parameter(m: _Mutating) -> Mutation:
    others = [o for o in _vars("output") + _vars("input") if o.inst == m.inst]
    name = m.d(
        st.one_of(
            st.sampled_from([o.name for o in others]),
            st.from_regex(r"[a-z][a-z_]{0,15}", fullmatch=True),
        ).filter(lambda n: n not in {p.name for p in PARAMETERS if p.inst == m.inst})
    )
    return Mutation(
        f"fmu.{m.inst}.parameters.{name}",
        _setter("fmu", m.inst, "parameters", name, value=1.0),
        m.kind,
        needs=m.model,
    )


def _parameter_mutation(m: _Mutating) -> Mutation:
    v = m.d(st.sampled_from([p for p in PARAMETERS if p.inst == m.inst]))
    if m.kind == "parameter-unknown":
        return _unknown_parameter(m)
    value = m.d(out_of_range(v) if m.kind == "parameter-range" else wrong_type(v))
    if m.d(st.booleans()):
        value = {"value": value, "source": "prop"}
    return Mutation(
        f"fmu.{m.inst}.parameters.{v.name}",
        _setter("fmu", m.inst, "parameters", v.name, value=value),
        m.kind,
        needs=m.model,
    )


def _unknown_key(m: _Mutating) -> Mutation:
    table = m.d(st.sampled_from(["", "scenario.", f"fmu.{m.inst}."]))
    allowed = {
        "": {"scenario", "fmu", "connections", "delay", "input", "event", "errormodel"},
        "scenario.": {
            "name",
            "description",
            "duration",
            "step",
            "output_interval",
            "start",
            "seed",
            "drift_window",
        },
        f"fmu.{m.inst}.": {"model", "period", "parameters", "parameter_files"},
    }[table]
    name = m.d(st.from_regex(r"[a-z][a-z_]{0,12}", fullmatch=True).filter(lambda n: n not in allowed))
    path = [*table.rstrip(".").split("."), name] if table else [name]
    return Mutation(f"{table}{name}", _setter(*path, value=m.d(toml_values)), m.kind)


def _missing(m: _Mutating) -> Mutation:
    """A required value left out (an output interval or a period left out is the step's)."""
    which = m.d(st.sampled_from(["step", "duration", "model"]))
    if which == "model":
        return Mutation(
            f"fmu.{m.inst}.{which}", _deleter("fmu", m.inst, which), m.kind, breaks=m.spec | m.model
        )
    return Mutation(
        f"scenario.{which}",
        _deleter("scenario", which),
        m.kind,
        breaks=frozenset({which}) if which in ("step", "duration") else frozenset(),
    )


INSTANCE_MUTATIONS: dict[str, MutationFn] = {
    "period": _period_mutation,
    "period-multiple": _period_multiple,
    "period-divides": _period_divides,
    "parameter-range": _parameter_mutation,
    "parameter-type": _parameter_mutation,
    "parameter-unknown": _parameter_mutation,
    "profile": lambda m: m.d(bad_profile()),
    "event": lambda m: m.d(bad_event(m.duration)),
    "unknown-key": _unknown_key,
    "missing": _missing,
}


@st.composite
def mutation(d: st.DrawFn) -> Mutation:
    base = base_data()
    step = _step_ns(base)
    duration = parse_duration(base["scenario"]["duration"])
    kind = d(st.sampled_from(MUTATION_KINDS))
    if kind in SCENARIO_MUTATIONS:
        return SCENARIO_MUTATIONS[kind](_Mutating(d, kind, step, duration))
    # the instance is drawn for every per-instance kind (profiles and events draw their own)
    inst = d(st.sampled_from(sorted(INSTANCES)))
    return INSTANCE_MUTATIONS[kind](_Mutating(d, kind, step, duration, inst))


def test_every_mutation_kind_has_its_strategy() -> None:
    assert set(MUTATION_KINDS) == set(SCENARIO_MUTATIONS) | set(INSTANCE_MUTATIONS)
    assert not set(SCENARIO_MUTATIONS) & set(INSTANCE_MUTATIONS)


def out_of_range(v: Var, *, finite: bool = False) -> st.SearchStrategy[Any]:
    if v.type == "Boolean":
        return wrong_type(v)
    options: list[st.SearchStrategy[Any]] = []
    if v.type == "Integer":
        if math.isfinite(v.hi):
            options.append(st.integers(min_value=int(v.hi) + 1))
        if math.isfinite(v.lo):
            options.append(st.integers(max_value=int(v.lo) - 1))
        return st.one_of(options)
    if not finite:
        options.append(st.sampled_from([math.nan, math.inf, -math.inf]))
    if math.isfinite(v.hi):
        options.append(st.floats(min_value=v.hi, exclude_min=True, allow_infinity=False))
    if math.isfinite(v.lo):
        options.append(st.floats(max_value=v.lo, exclude_max=True, allow_infinity=False))
    return st.one_of(options)


def wrong_type(v: Var) -> st.SearchStrategy[Any]:
    if v.type == "Boolean":
        return toml_values.filter(lambda x: not isinstance(x, bool))
    if v.type == "Integer":
        return toml_values.filter(lambda x: isinstance(x, bool) or not isinstance(x, int))
    return st.one_of(
        not_a_number,
        st.dictionaries(st.sampled_from(["val", "unit", "min"]), toml_scalars, max_size=2),
        st.just({"source": "no value"}),
    )


# One function per way to get an input's profile wrong, given the free input v it is drawn for.


def _input_profile(inst: str, name: str, raw: dict[str, Any], how: str, key: str = "") -> Mutation:
    """The profile ``raw`` at [input.<inst>.<name>], reported at input.<inst>.<name>[.key]."""
    return Mutation(
        f"input.{inst}.{name}" + (f".{key}" if key else ""),
        _setter("input", inst, name, value=raw),
        how,
        needs=frozenset({f"spec:{inst}"}),
    )


def _profile_out_of_range(d: st.DrawFn, v: Var, how: str) -> Mutation:
    return _input_profile(
        v.inst, v.name, {"profile": "constant", "value": d(out_of_range(v, finite=True))}, how
    )


def _profile_sine_reach(d: st.DrawFn, v: Var, how: str) -> Mutation:
    mean = d(st.floats(v.lo, v.hi))  # an amplitude of twice the range leaves it, however it rounds
    amp = d(st.floats(min_value=2 * (v.hi - v.lo), max_value=1e300))
    return _input_profile(
        v.inst, v.name, {"profile": "sine", "mean": mean, "amplitude": amp, "period": "1 min"}, how
    )


def _profile_nan_value(d: st.DrawFn, v: Var, how: str) -> Mutation:
    value = d(st.one_of(st.sampled_from([math.nan, math.inf, -math.inf]), not_a_number))
    return _input_profile(v.inst, v.name, {"profile": "constant", "value": value}, how, "value")


def _profile_zero_duration(d: st.DrawFn, v: Var, how: str) -> Mutation:
    ok_value = st.floats(v.lo, v.hi)
    k = d(st.sampled_from(["duration", "time_constant", "period"]))
    raw = {
        "duration": {"profile": "ramp", "start": d(ok_value), "end": d(ok_value)},
        "time_constant": {"profile": "exponential", "start": d(ok_value), "rise": 0.0},
        "period": {"profile": "sine", "mean": d(ok_value), "amplitude": 0.0},
    }[k]
    raw[k] = d(bad_durations)
    return _input_profile(v.inst, v.name, raw, how, k)


def _profile_unknown_kind(d: st.DrawFn, v: Var, how: str) -> Mutation:
    kind = d(toml_values.filter(lambda x: x not in ("constant", "ramp", "exponential", "sine", "table")))
    return _input_profile(v.inst, v.name, {"profile": kind, "value": 1.0}, how, "profile")


def _profile_missing(d: st.DrawFn, v: Var, how: str) -> Mutation:
    kind, required = d(
        st.sampled_from(
            [
                ("ramp", ["start", "end", "duration"]),
                ("sine", ["mean", "amplitude", "period"]),
                ("exponential", ["start", "rise", "time_constant"]),
            ]
        )
    )
    gone = d(st.sampled_from(required))
    raw = {
        "profile": kind,
        **{
            k: ("1 s" if k in ("duration", "period", "time_constant") else v.lo)
            for k in required
            if k != gone
        },
    }
    return _input_profile(v.inst, v.name, raw, how, gone)


def _profile_unknown_key(d: st.DrawFn, v: Var, how: str) -> Mutation:
    extra = d(
        st.from_regex(r"[a-z][a-z_]{0,10}", fullmatch=True).filter(
            lambda n: n not in {"profile", "value", "source"}
        )
    )
    return _input_profile(v.inst, v.name, {"profile": "constant", "value": v.lo, extra: 1}, how, extra)


def _profile_points(d: st.DrawFn, v: Var, how: str) -> Mutation:
    pts = d(
        st.one_of(
            st.lists(
                st.tuples(st.integers(0, 100), st.floats(v.lo, v.hi)).map(list), max_size=1
            ),  # fewer than two
            st.lists(st.integers(0, 100), min_size=2, max_size=4).map(
                lambda ts: [[t, v.lo] for t in sorted(ts, reverse=True)]
            ),  # not increasing
            st.just([[0, math.nan], [1, v.lo]]),
            st.just([["soon", v.lo], [1, v.lo]]),
            toml_values.filter(lambda x: not isinstance(x, list)),
        )
    )
    return _input_profile(v.inst, v.name, {"profile": "table", "points": pts}, how, "points")


def _profile_fed(d: st.DrawFn, v: Var, how: str) -> Mutation:
    """A profile on an input a connection already feeds."""
    f = d(st.sampled_from(FED_INPUTS))
    return _input_profile(f.inst, f.name, {"profile": "constant", "value": (f.lo + f.hi) / 2}, how)


def _profile_no_such_input(d: st.DrawFn, v: Var, how: str) -> Mutation:
    name = d(
        st.from_regex(r"[a-z][a-z_]{0,10}", fullmatch=True).filter(
            lambda n: n not in model_variables(INSTANCES[v.inst])
        )
    )
    return _input_profile(v.inst, name, {"profile": "constant", "value": 0.0}, how)


def _profile_an_output(d: st.DrawFn, v: Var, how: str) -> Mutation:
    o = d(st.sampled_from([o for o in OUTPUTS if o.inst == v.inst] or OUTPUTS))
    return _input_profile(o.inst, o.name, {"profile": "constant", "value": 0.0}, how)


BAD_PROFILES: dict[str, Callable[[st.DrawFn, Var, str], Mutation]] = {
    "out-of-range": _profile_out_of_range,
    "sine-reach": _profile_sine_reach,
    "nan-value": _profile_nan_value,
    "zero-duration": _profile_zero_duration,
    "unknown-kind": _profile_unknown_kind,
    "missing": _profile_missing,
    "unknown-key": _profile_unknown_key,
    "points": _profile_points,
    "fed": _profile_fed,
    "no-such-input": _profile_no_such_input,
    "an-output": _profile_an_output,
}


@st.composite
def bad_profile(d: st.DrawFn) -> Mutation:
    v = d(st.sampled_from(FREE_INPUTS))
    how = d(st.sampled_from(list(BAD_PROFILES)))
    return BAD_PROFILES[how](d, v, how)


@st.composite
def bad_event(d: st.DrawFn, duration: int) -> Mutation:
    v = d(st.sampled_from(FREE_INPUTS))
    spec = frozenset({f"spec:{v.inst}"})
    ok = {"at": "1 s", "action": "set", "target": v.ref, "value": (v.lo + v.hi) / 2}
    how = d(st.sampled_from(["at", "at-late", "action", "value", "ramp-duration", "target", "fault"]))
    needs = spec
    if how == "at":
        field_, value = (
            "at",
            d(st.one_of(st.integers(max_value=-1), st.floats(max_value=-1.0), unparseable_durations)),
        )
    elif how == "at-late":
        field_, value, needs = "at", f"{duration + d(st.integers(0, 10**12))} ns", spec | {"duration"}
    elif how == "action":
        field_, value = "action", d(toml_values.filter(lambda x: x not in ("set", "ramp", "bias", "fault")))
    elif how == "value":
        field_, value = "value", d(st.one_of(out_of_range(v), not_a_number))
    elif how == "ramp-duration":
        ok["action"] = "ramp"
        field_, value = "duration", d(bad_durations)
    elif how == "target":
        field_, value = (
            "target",
            d(
                st.one_of(
                    toml_values.filter(lambda x: not isinstance(x, str)),
                    st.just("thermal"),
                    st.just("nobody.t_room"),
                    st.sampled_from([o.ref for o in OUTPUTS if o.inst == v.inst]),
                )
            ),
        )
    else:
        ok = {"at": "1 s", "action": "fault", "target": v.inst}
        field_, value = (
            "fault",
            d(toml_values.filter(lambda x: x not in ("error", "discard", "nan"))),
        )
    ev = {**ok, field_: value}
    return Mutation(f"event[0].{field_}", _setter("event", value=[ev]), f"event-{how}", needs=needs)


def _check_config_errors(exc: ConfigErrors, allowed: list[str]) -> None:
    lines = str(exc).split("\n")
    assert len(lines) == len(exc.problems), "one line per problem"
    assert len(set(lines)) == len(lines), f"a problem reported twice:\n{exc}"
    for p, line in zip(exc.problems, lines, strict=True):
        assert p.key, f"a problem without a key: {line}"
        assert line == f"{SOURCE}: {p.key}: {p.message}", line
        assert p.message and "\n" not in p.message
        assert any(re.fullmatch(a, p.key) for a in allowed), f"unexpected problem: {line}\n(all: {exc})"


@settings(max_examples=400, **COMMON)
@given(drawn=st.lists(mutation(), min_size=1, max_size=4, unique_by=_target))
def test_values_outside_give_one_clear_line_per_problem(drawn: list[Mutation]) -> None:
    # leave out a mistake another one hides (no valid step: nothing is a non-multiple of it)
    muts = [m for m in drawn if not any(m.needs & o.breaks for o in drawn if o is not m)]
    assert muts
    data = base_data()
    for m in muts:
        m.apply(data)
    for m in muts:
        event(m.what)
    try:
        load_scenario_data(data, SOURCE, BASE_DIR)
    except ConfigErrors as exc:
        allowed = [re.escape(m.key) for m in muts] + [a for m in muts for a in m.also]
        _check_config_errors(exc, allowed)
        keys = {p.key for p in exc.problems}
        missing = [m for m in muts if m.key not in keys]
        assert not missing, f"not reported: {[(m.key, m.what) for m in missing]}\ngot:\n{exc}"
    except Exception as exc:
        pytest.fail(f"{type(exc).__name__} instead of ConfigErrors: {exc!r}")
    else:
        pytest.fail(f"accepted: {[(m.key, m.what) for m in muts]}")


# ----------------------------------------------------------------------------- anything else


def _paths(x: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    if isinstance(x, dict):
        for k, v in x.items():
            yield (*prefix, k)
            yield from _paths(v, (*prefix, k))
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield (*prefix, i)
            yield from _paths(v, (*prefix, i))


def _fuzz_base() -> dict[str, Any]:
    data = base_data()
    data["event"] = [
        {"at": "1 min", "action": "ramp", "target": "thermal.q_friction", "value": 10.0, "duration": "5 min"},
        {"at": "2 min", "action": "fault", "target": "mechanics", "fault": "nan"},
        {"at": "3 min", "action": "bias", "target": "sensors.probe_meas", "value": 1e-6},
    ]
    data["delay"] = [{"from": "sensors.probe_meas", "to": "mechanics.wear_offset", "initial": 0.0}]
    return data


FUZZ_PATHS = sorted(_paths(_fuzz_base()), key=repr)


@st.composite
def fuzzed(d: st.DrawFn) -> dict[str, Any]:
    data = copy.deepcopy(_fuzz_base())
    for _ in range(d(st.integers(1, 3))):
        path = d(st.sampled_from(FUZZ_PATHS))
        node: Any = data
        try:
            for p in path[:-1]:
                node = node[p]
            if d(st.integers(0, 4)) == 0 and isinstance(node, dict):
                node.pop(path[-1], None)  # a missing value
            else:
                node[path[-1]] = d(st.one_of(toml_values, bad_durations, st.floats(-1e7, 1e7)))
        except (KeyError, IndexError, TypeError):
            continue  # an earlier replacement removed the parent
    return data


@settings(max_examples=500, **COMMON)
@given(data=fuzzed())
def test_any_value_anywhere_loads_or_gives_config_errors(data: dict[str, Any]) -> None:
    try:
        load_scenario_data(data, SOURCE, BASE_DIR)
        event("loaded")
    except ConfigErrors as exc:
        event("refused")
        _check_config_errors(exc, [r".+"])
    except Exception as exc:
        pytest.fail(f"{type(exc).__name__} instead of ConfigErrors: {exc!r}")


OVERRIDE_KEYS = [
    "scenario.duration",
    "scenario.step",
    "scenario.output_interval",
    "scenario.seed",
    "fmu.thermal.period",
    "fmu.mechanics.parameters.sensor_tilt",
    "fmu.sensors.parameters.seed",
    "input.thermal.q_hydraulic.value",
    "input.thermal.t_room.time_constant",
    'connections."thermal.t_base"',
]


@pytest.fixture(scope="module")
def paper_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("prop") / SOURCE, base_data())


@settings(max_examples=150, **COMMON)
@given(
    overrides=st.lists(
        st.tuples(
            st.one_of(st.sampled_from(OVERRIDE_KEYS), st.text(max_size=15)),
            st.one_of(st.text(max_size=15), toml_scalars.map(lambda x: dumps({"v": x})[4:].strip())),
        ).map(lambda kv: f"{kv[0]}={kv[1]}"),
        min_size=1,
        max_size=3,
    )
)
def test_any_set_override_loads_or_gives_config_error(paper_file: Path, overrides: list[str]) -> None:
    try:
        load_scenario(paper_file, overrides)
        event("loaded")
    except ConfigError as exc:
        event("refused")
        problems = exc.problems if isinstance(exc, ConfigErrors) else [exc]
        assert str(exc).split("\n") == [str(p) for p in problems]
        assert all(str(p).startswith(f"{paper_file}: ") for p in problems), str(exc)
    except Exception as exc:
        pytest.fail(f"{type(exc).__name__} instead of a ConfigError for --set {overrides}: {exc!r}")


# ----------------------------------------------------------------------------- regressions


def _t_room(profile: dict[str, Any]) -> Callable[[dict[str, Any]], None]:
    return _setter("input", "thermal", "t_room", value=profile)


def _exponential(**values: Any) -> Callable[[dict[str, Any]], None]:
    return _t_room({"profile": "exponential", "start": 293.15, "rise": 1.0, **values})


@pytest.mark.parametrize(
    ("mutate", "key"),
    [
        # ZeroDivisionError: 1 - exp(-rise_at / time_constant) == 0.0 for rise_at << time_constant
        (_exponential(time_constant="100000000 s", rise_at="1 ns", rise=1e-17), None),
        # OverflowError: ns / NS_PER_S of a profile duration beyond 1.8e308 s
        (
            _t_room({"profile": "ramp", "start": 293.15, "end": 294.0, "duration": "1e400 s"}),
            "input.thermal.t_room.duration",
        ),
        (
            _t_room({"profile": "table", "points": [[0, 293.0], ["1e400 s", 294.0]]}),
            "input.thermal.t_room.points",
        ),
        # TypeError: unhashable type in `fault not in FAULTS`
        (
            _setter(
                "event", value=[{"at": "1 s", "action": "fault", "target": "thermal", "fault": ["error"]}]
            ),
            "event[0].fault",
        ),
        # ValueError (int -> str digit limit) while formatting the message of a huge duration
        (_setter("scenario", "duration", value="1e5000 s"), "scenario.duration"),
        (_setter("scenario", "step", value="1e5000 s"), "scenario.step"),
        (_setter("fmu", "thermal", "period", value="1e5000 s"), "fmu.thermal.period"),
        # 2^53 ns and 2^53 + 1 ns increase strictly, but were compared as one float of seconds
        (
            _t_room(
                {
                    "profile": "table",
                    "points": [["9007199254740992 ns", 293.0], ["9007199254740993 ns", 294.0]],
                }
            ),
            None,
        ),
    ],
    ids=[
        "exp-rise_at-tiny",
        "ramp-1e400s",
        "table-1e400s",
        "fault-list",
        "duration-1e5000s",
        "step-1e5000s",
        "period-1e5000s",
        "table-1ns-apart",
    ],
)
def test_found_by_the_properties(mutate: Callable[[dict[str, Any]], None], key: str | None) -> None:
    """Inputs these properties found escaping as another exception (or wrongly refused):
    now loaded (key None) or refused with one line at ``key``."""
    data = base_data()
    mutate(data)
    try:
        load_scenario_data(data, SOURCE, BASE_DIR)
    except ConfigErrors as exc:
        assert key is not None, f"refused:\n{exc}"
        _check_config_errors(exc, [re.escape(key)])
    else:
        assert key is None, f"accepted, expected a problem at {key}"


@pytest.mark.parametrize(
    "mutate",
    [
        _exponential(time_constant="2 h", rise_at=0),
        _exponential(time_constant=0, rise_at="8 h"),
        _exponential(time_constant=-1, rise_at="8 h"),
        _exponential(time_constant="1 s", rise_at=-1000),
    ],
    ids=["rise_at-0", "time_constant-0", "time_constant-negative", "rise_at-negative"],
)
def test_exponential_nonpositive_duration_gives_config_errors(
    mutate: Callable[[dict[str, Any]], None],
) -> None:
    """Was: 'must be positive' reported, but the value kept in the profile and the range check
    computing with it: 1 / -expm1(0) (ZeroDivisionError) or expm1(28800) (OverflowError)."""
    data = base_data()
    mutate(data)
    with pytest.raises(ConfigErrors) as exc:
        load_scenario_data(data, SOURCE, BASE_DIR)
    _check_config_errors(exc.value, [r"input\.thermal\.t_room\.(rise_at|time_constant)"])


@pytest.mark.parametrize(
    "mutate",
    [
        _setter("fmu", "thermal", "parameters", value={"c\nx": 1.0}),
        _setter("fmu", "sensors", "\n", value=False),
        _setter("connections", "thermal.t_base", value="sen\nsors.t_base"),
        _setter(
            "event", value=[{"at": "1 s", "action": "set", "target": "thermal.q_fr\niction", "value": 1.0}]
        ),
        _setter("fmu", "thermal", "parameter_files", value=["a\nb.toml"]),
    ],
    ids=["parameter-name", "fmu-key", "connection", "event-target", "parameter-file"],
)
def test_line_break_in_a_quoted_name_stays_one_line(mutate: Callable[[dict[str, Any]], None]) -> None:
    """Was: keys (a TOML quoted key may hold "\\n"), variable references and file names quoted
    as they are, so one problem spanned two lines (found by the fuzz and --set properties)."""
    data = base_data()
    mutate(data)
    with pytest.raises(ConfigErrors) as exc:
        load_scenario_data(data, SOURCE, BASE_DIR)
    _check_config_errors(exc.value, [r".+"])


def test_line_break_in_a_set_key_stays_one_line(paper_file: Path) -> None:
    with pytest.raises(ConfigError) as exc:
        load_scenario(paper_file, ["0\n0=1"])
    problems = exc.value.problems if isinstance(exc.value, ConfigErrors) else [exc.value]
    assert str(exc.value).split("\n") == [str(p) for p in problems]
