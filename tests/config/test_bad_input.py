"""Bad input: a corpus of malformed scenarios, each a small mutation of the paper's scenario.

Every case must give exit code 2, no traceback, and one line per problem of the form
``twin: FILE: KEY: message`` naming the file, the dotted key and what is wrong.
"""

from __future__ import annotations

import datetime as dt
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from twin.cli import main

from .scenario_toml import paper_data, paper_text, write

Mutation = Callable[[dict[str, Any]], None]


def _path(key: str | tuple[str, ...]) -> tuple[str, ...]:
    return tuple(key.split(".")) if isinstance(key, str) else key


def setv(key: str | tuple[str, ...], value: Any) -> Mutation:
    """Set a (dotted or tuple) key, creating tables on the way."""

    def mutate(data: dict[str, Any]) -> None:
        *parents, last = _path(key)
        node = data
        for p in parents:
            node = node.setdefault(p, {})
        node[last] = value

    return mutate


def delv(key: str | tuple[str, ...]) -> Mutation:
    def mutate(data: dict[str, Any]) -> None:
        *parents, last = _path(key)
        node = data
        for p in parents:
            node = node[p]
        del node[last]

    return mutate


def both(*mutations: Mutation) -> Mutation:
    def mutate(data: dict[str, Any]) -> None:
        for m in mutations:
            m(data)

    return mutate


def event(**fields: Any) -> Mutation:
    """Add one [[event]] (a valid 'set' of the hydraulic heat, changed by ``fields``)."""
    ev = {"at": "60 min", "action": "set", "target": "thermal.q_hydraulic", "value": 500.0, **fields}
    return setv("event", [{k: v for k, v in ev.items() if v is not None}])


def text(old: str, new: str) -> Callable[[], str]:
    """The paper's file as text with one replacement (for syntax errors)."""

    def make() -> str:
        t = paper_text()
        assert old in t, old
        return t.replace(old, new, 1)

    return make


@dataclass(frozen=True)
class Case:
    id: str
    key: str | None  # the dotted key the message names (None: a problem with the whole file)
    word: str  # a distinctive word of the message
    mutate: Mutation | None = None  # edit the paper's scenario ...
    content: Callable[[], str | bytes] | None = None  # ... or give the file's content
    sets: tuple[str, ...] = ()  # --set overrides
    lines: int | None = 1  # expected number of problems (None: follow-on problems allowed)


ROOM_FROM_SENSOR = (
    delv("input.thermal.t_room"),
    setv(("connections", "sensors.t_room_meas"), "thermal.t_room"),
)

CASES = [
    # --- TOML syntax
    Case("syntax-unclosed-string", None, "syntax", content=text('name = "li2017', 'name = "li2017\n')),
    Case("syntax-missing-value", None, "syntax", content=text('step = "1 s"', "step =")),
    Case("syntax-unquoted-duration", None, "syntax", content=text('step = "1 s"', "step = 1 s")),
    Case("syntax-duplicate-key", None, "overwrite", content=text("seed = 2017", "seed = 2017\nseed = 1")),
    Case(
        "syntax-duplicate-table",
        None,
        "twice",
        content=lambda: paper_text() + '\n[fmu.thermal]\nmodel = "X"\n',
    ),
    Case("syntax-unclosed-header", None, "syntax", content=text("[fmu.sensors]", "[fmu.sensors")),
    Case(
        "syntax-unclosed-array", None, "syntax", content=lambda: paper_text() + '\n[[delay]]\nfrom = ["a"\n'
    ),
    Case("syntax-bad-escape", None, "syntax", content=text('name = "li2017', 'name = "li\\q2017')),
    # --- unreadable files (content built in the test)
    Case("file-missing", None, "not found"),
    Case("file-is-directory", None, "directory"),
    Case(
        "file-bad-utf8",
        None,
        "UTF-8",
        content=lambda: paper_text().encode() + b"\n# caf\xe9\xff\n",
    ),
    Case("file-empty", "scenario", "missing", content=lambda: "", lines=4),
    # --- unknown keys
    Case("unknown-top-level", "solver", "unknown", setv("solver.method", "rk4")),
    Case("unknown-scenario-key", "scenario.stop_time", "unknown", setv("scenario.stop_time", "480 min")),
    Case("unknown-fmu-key", "fmu.thermal.perid", "unknown", setv("fmu.thermal.perid", "10 s")),
    Case(
        "unknown-profile-key",
        "input.thermal.q_hydraulic.amplitude",
        "unknown",
        setv("input.thermal.q_hydraulic.amplitude", 1.0),
    ),
    Case("unknown-event-key", "event[0].when", "unknown", event(when="now")),
    Case(
        "unknown-delay-key",
        "delay[0].gain",
        "unknown",
        both(
            *ROOM_FROM_SENSOR[:1],
            setv(
                "delay",
                [{"from": "sensors.t_room_meas", "to": "thermal.t_room", "initial": 293.15, "gain": 1}],
            ),
        ),
    ),
    # --- wrong types
    Case("seed-string", "scenario.seed", "integer", setv("scenario.seed", "2017")),
    Case("seed-float", "scenario.seed", "integer", setv("scenario.seed", 20.17)),
    Case("seed-too-big", "scenario.seed", "integer", setv("scenario.seed", 2**31)),
    Case("name-number", "scenario.name", "cannot name a folder", setv("scenario.name", 5)),
    # --- names that would put the run folder elsewhere (runs/<name>)
    Case("name-parent", "scenario.name", "cannot name a folder", setv("scenario.name", "../../x")),
    Case("name-absolute", "scenario.name", "cannot name a folder", setv("scenario.name", "/tmp/x")),
    Case("name-separator", "scenario.name", "cannot name a folder", setv("scenario.name", "a/b")),
    Case("name-dotdot", "scenario.name", "cannot name a folder", setv("scenario.name", "..")),
    Case("name-hidden", "scenario.name", "cannot name a folder", setv("scenario.name", ".x")),
    Case("name-empty", "scenario.name", "cannot name a folder", setv("scenario.name", "")),
    Case("name-too-long", "scenario.name", "cannot name a folder", setv("scenario.name", "x" * 101)),
    Case("name-newline", "scenario.name", "cannot name a folder", setv("scenario.name", "a\nb")),
    Case("name-nul", "scenario.name", "a NUL character", setv("scenario.name", "a\x00b")),
    Case("name-backslash", "scenario.name", "cannot name a folder", setv("scenario.name", "..\\x")),
    Case("description-list", "scenario.description", "string", setv("scenario.description", ["a"])),
    Case("duration-bool", "scenario.duration", "duration", setv("scenario.duration", True)),
    Case("duration-date", "scenario.duration", "date", setv("scenario.duration", dt.date(2017, 1, 1))),
    Case("duration-table", "scenario.duration", "dict", setv("scenario.duration", {"min": 480})),
    Case("scenario-not-table", "scenario", "table", setv("scenario", 5), lines=3),
    Case("model-number", "fmu.thermal.model", "unknown model", setv("fmu.thermal.model", 5)),
    Case(
        "parameter-files-table",
        "fmu.thermal.parameter_files",
        "list",
        setv("fmu.thermal.parameter_files", {"a": "x.toml"}),
    ),
    Case("parameters-list", "fmu.thermal.parameters", "table", setv("fmu.thermal.parameters", [1, 2])),
    Case("fmu-string", "fmu", "table", setv("fmu", "thermal"), lines=2),
    Case("delay-table", "delay", "array", setv("delay", {"from": "a.b", "to": "c.d", "initial": 0.0})),
    Case("event-table", "event", "array", setv("event", {"at": "1 min"})),
    Case(
        "profile-value-string",
        "input.thermal.q_hydraulic.value",
        "number",
        setv("input.thermal.q_hydraulic.value", "300 W"),
    ),
    Case(
        "profile-value-nan",
        "input.thermal.q_hydraulic.value",
        "finite",
        setv("input.thermal.q_hydraulic.value", float("nan")),
    ),
    Case("profile-not-table", "input.thermal.q_hydraulic", "table", setv("input.thermal.q_hydraulic", 300.0)),
    Case(
        "profile-kind-list",
        "input.thermal.q_hydraulic.profile",
        "unknown profile",
        setv("input.thermal.q_hydraulic.profile", ["constant"]),
    ),
    Case(
        "connection-target-number",
        'connections."thermal.t_clamp"',
        "input name",
        setv(("connections", "thermal.t_clamp"), 5),
    ),
    Case(
        "connection-unquoted-output",
        'connections."thermal"',
        "quote",
        both(
            delv(("connections", "thermal.t_clamp")),
            setv(("connections", "thermal", "t_clamp"), "mechanics.t_clamp"),
        ),
    ),
    # --- missing values
    Case("missing-duration", "scenario.duration", "missing", delv("scenario.duration")),
    Case("missing-step", "scenario.step", "missing", delv("scenario.step")),
    Case("missing-model", "fmu.sensors.model", "missing", delv("fmu.sensors.model")),
    # a run that begins later (twin run --start-time) begins on the grids, before the end
    Case(
        "start-off-the-step", "scenario.start", "multiple of scenario.step", setv("scenario.start", "1.5 s")
    ),
    Case("start-after-the-end", "scenario.start", "is not before", setv("scenario.start", "9 h")),
    Case("start-negative", "scenario.start", "negative", setv("scenario.start", -10)),
    Case(
        "start-off-the-rows", "scenario.start", "output_interval", setv("scenario.start", "5 s"), lines=None
    ),
    Case(
        "start-off-a-period",
        "fmu.thermal.period",
        "scenario.start",
        both(setv("scenario.start", "5 s"), setv("scenario.output_interval", "1 s")),
        lines=3,  # every FMU of the paper's exchanges every 10 s: each one's period is named
    ),
    Case(
        "missing-profile-parameter",
        "input.thermal.t_room.time_constant",
        "missing",
        delv("input.thermal.t_room.time_constant"),
    ),
    Case(
        "missing-profile-kind",
        "input.thermal.q_hydraulic.profile",
        "missing",
        delv("input.thermal.q_hydraulic.profile"),
    ),
    Case("missing-fmus", "fmu", "at least one", setv("fmu", {})),
    Case(
        "missing-delay-initial",
        "delay[0].initial",
        "missing",
        both(ROOM_FROM_SENSOR[0], setv("delay", [{"from": "sensors.t_room_meas", "to": "thermal.t_room"}])),
    ),
    # --- times: zero, negative, not multiples, too short, too long, not whole nanoseconds
    Case("step-zero", "scenario.step", "positive", setv("scenario.step", "0 s")),
    Case("step-negative", "scenario.step", "positive", setv("scenario.step", -1)),
    Case("step-unknown-unit", "scenario.step", "expected a duration", setv("scenario.step", "1 sec")),
    Case("step-negative-string", "scenario.step", "expected a duration", setv("scenario.step", "-1 s")),
    Case("step-sub-nanosecond", "scenario.step", "nanoseconds", setv("scenario.step", "0.5 ns")),
    Case("period-zero", "fmu.thermal.period", "positive", setv("fmu.thermal.period", "0 s")),
    Case("period-negative", "fmu.thermal.period", "positive", setv("fmu.thermal.period", -10)),
    Case(
        "period-not-multiple-of-step", "fmu.thermal.period", "multiple", setv("fmu.thermal.period", "1.5 s")
    ),
    Case("period-not-dividing-duration", "fmu.thermal.period", "divide", setv("fmu.thermal.period", "7 s")),
    Case("output-interval-zero", "scenario.output_interval", "positive", setv("scenario.output_interval", 0)),
    Case(
        "output-interval-not-multiple",
        "scenario.output_interval",
        "multiple",
        setv("scenario.output_interval", "2.5 s"),
    ),
    Case("duration-zero", "scenario.duration", "positive", setv("scenario.duration", "0 s")),
    Case(
        "wear-limit-negative",
        "scenario.wear_limit_mm",
        "wear depth in mm",
        setv("scenario.wear_limit_mm", -0.152),
    ),
    Case(
        "wear-limit-string",
        "scenario.wear_limit_mm",
        "wear depth in mm",
        setv("scenario.wear_limit_mm", "0.152 mm"),
    ),
    Case(
        "wear-limit-bool", "scenario.wear_limit_mm", "wear depth in mm", setv("scenario.wear_limit_mm", True)
    ),
    Case("wear-limit-absurd", "scenario.wear_limit_mm", "<= 10", setv("scenario.wear_limit_mm", 1e300)),
    Case(
        "duration-not-multiple-of-step",
        "scenario.duration",
        "multiple",
        setv("scenario.duration", "28800.5 s"),
        lines=4,
    ),
    # and each of the three 10 s periods that does not divide it
    Case("duration-too-short", "scenario.duration", "too short", setv("scenario.duration", "1 s"), lines=4),
    Case("duration-absurdly-long", "scenario.duration", "absurdly", setv("scenario.duration", "367 d")),
    Case("duration-absurdly-long-seconds", "scenario.duration", "absurdly", setv("scenario.duration", 1e12)),
    Case("drift-window-zero", "scenario.drift_window", "positive", setv("scenario.drift_window", "0 min")),
    # --- models and instances
    Case("unknown-model", "fmu.thermal.model", "unknown model", setv("fmu.thermal.model", "ThermalNetwrk")),
    Case(
        "instance-name-not-snake",
        "fmu.Extra",
        "lower_snake",
        setv("fmu.Extra", {"model": "SensorsDAQ", "period": "1 s", "unconnected": "a spare DAQ"}),
    ),
    # --- connections
    Case(
        "connection-unknown-instance",
        'connections."thermo.t_clamp"',
        "unknown FMU instance",
        both(
            delv(("connections", "thermal.t_clamp")),
            setv(("connections", "thermo.t_clamp"), "mechanics.t_clamp"),
        ),
    ),
    Case(
        "connection-unknown-variable",
        'connections."thermal.t_clampp"',
        "no variable",
        both(
            delv(("connections", "thermal.t_clamp")),
            setv(("connections", "thermal.t_clampp"), "mechanics.t_clamp"),
        ),
    ),
    Case(
        "connection-not-instance-dot-variable",
        'connections."thermal"',
        "instance.variable",
        both(
            delv(("connections", "thermal.t_clamp")),
            setv(("connections", "thermal"), "mechanics.t_clamp"),
        ),
    ),
    Case(
        "connection-output-to-output",
        'connections."thermal.t_oil"',
        "expected an input",
        setv(("connections", "thermal.t_oil"), "mechanics.dz_spindle"),
    ),
    Case(
        "connection-input-to-input",
        'connections."thermal.t_room"',
        "expected an output",
        both(
            delv(("connections", "thermal.t_clamp")),
            setv(("connections", "thermal.t_room"), "mechanics.t_clamp"),
        ),
    ),
    Case(
        "connection-unit-mismatch",
        'connections."thermal.t_oil"',
        "unit mismatch",
        both(
            delv(("connections", "mechanics.probe_true")),
            setv(("connections", "thermal.t_oil"), "sensors.probe_true"),
        ),
    ),
    Case(
        "connection-input-fed-twice",
        'connections."thermal.t_oil"',
        "already fed",
        setv(("connections", "thermal.t_oil"), "mechanics.t_clamp"),
    ),
    Case(
        "connection-and-profile",
        "input.mechanics.t_clamp",
        "cannot also have a profile",
        setv("input.mechanics.t_clamp", {"profile": "constant", "value": 293.15}),
    ),
    Case("algebraic-loop", "connections", "algebraic loop", both(*ROOM_FROM_SENSOR)),
    # --- parameters
    Case(
        "parameter-negative-capacity",
        "fmu.thermal.parameters.c_base",
        "physical range",
        setv("fmu.thermal.parameters.c_base", -1),
    ),
    Case(
        "parameter-share-above-one",
        "fmu.thermal.parameters.hyd_share_base",
        "physical range",
        setv("fmu.thermal.parameters.hyd_share_base", 1.5),
    ),
    Case(
        "parameter-unknown",
        "fmu.thermal.parameters.c_foo",
        "no parameter",
        setv("fmu.thermal.parameters.c_foo", 1.0),
    ),
    Case(
        "parameter-is-an-input",
        "fmu.thermal.parameters.t_room",
        "no parameter",
        setv("fmu.thermal.parameters.t_room", 293.15),
    ),
    Case(
        "parameter-boolean-given-number",
        "fmu.thermal.parameters.start_at_room",
        "true or false",
        setv("fmu.thermal.parameters.start_at_room", 1),
    ),
    Case(
        "parameter-integer-given-float",
        "fmu.sensors.parameters.seed",
        "integer",
        setv("fmu.sensors.parameters.seed", 1.5),
    ),
    Case(
        "parameter-real-given-string",
        "fmu.mechanics.parameters.l_clamp",
        "number",
        setv("fmu.mechanics.parameters.l_clamp", "5 cm"),
    ),
    Case(
        "parameter-table-extra-key",
        "fmu.thermal.parameters.c_base",
        "unknown key",
        setv("fmu.thermal.parameters.c_base", {"value": 1.0, "unit": "J/K"}),
    ),
    Case(
        "parameter-table-without-value",
        "fmu.thermal.parameters.c_base",
        "missing 'value'",
        setv("fmu.thermal.parameters.c_base", {"source": "handbook"}),
    ),
    Case(
        "parameter-file-missing",
        "fmu.thermal.parameter_files",
        "not found",
        setv("fmu.thermal.parameter_files", ["no-such-parameters.toml"]),
    ),
    # --- events
    Case("event-at-end", "event[0].at", "within", event(at="480 min")),
    Case("event-after-end", "event[0].at", "within", event(at="9 h")),
    Case("event-unknown-action", "event[0].action", "unknown action", event(action="jump")),
    Case("event-action-list", "event[0].action", "unknown action", event(action=["set"])),
    Case("event-ramp-without-duration", "event[0].duration", "missing", event(action="ramp")),
    Case("event-ramp-zero-duration", "event[0].duration", "positive", event(action="ramp", duration="0 s")),
    Case("event-missing-value", "event[0].value", "missing", event(value=None)),
    Case(
        "event-set-on-fed-input",
        "event[0].target",
        "fed by a connection",
        event(target="mechanics.t_clamp"),
    ),
    Case("event-bias-on-input", "event[0].target", "expected an output", event(action="bias")),
    # --- profiles
    Case(
        "profile-unknown-kind",
        "input.thermal.q_hydraulic.profile",
        "unknown profile",
        setv("input.thermal.q_hydraulic.profile", "square"),
    ),
    Case(
        "profile-ramp-zero-duration",
        "input.mechanics.angle.duration",
        "positive",
        setv("input.mechanics.angle", {"profile": "ramp", "start": 0.0, "end": 1.0, "duration": "0 s"}),
    ),
    Case(
        "profile-ramp-negative-delay",
        "input.mechanics.angle.delay",
        "negative",
        setv(
            "input.mechanics.angle",
            {"profile": "ramp", "start": 0.0, "end": 1.0, "duration": "1 h", "delay": -60},
        ),
    ),
    Case(
        "profile-table-not-increasing",
        "input.thermal.q_friction.points",
        "increase",
        setv(
            "input.thermal.q_friction", {"profile": "table", "points": [[0, 0.0], ["2 h", 1.0], ["1 h", 2.0]]}
        ),
    ),
    Case(
        "profile-table-time-thrice",  # twice is a jump (as in fmpy's input files), thrice is not
        "input.thermal.q_friction.points",
        "increase",
        setv(
            "input.thermal.q_friction",
            {"profile": "table", "points": [[0, 0.0], ["1 h", 1.0], [3600, 2.0], ["60 min", 3.0]]},
        ),
    ),
    Case(
        "profile-table-one-point",
        "input.thermal.q_friction.points",
        "two points",
        setv("input.thermal.q_friction", {"profile": "table", "points": [[0, 0.0]]}),
    ),
    Case(
        "profile-table-nan-value",
        "input.thermal.q_friction.points",
        "finite",
        setv("input.thermal.q_friction", {"profile": "table", "points": [[0, 0.0], ["1 h", float("nan")]]}),
    ),
    Case(
        "profile-on-unknown-instance",
        "input.hydraulics.q",
        "unknown FMU instance",
        setv("input.hydraulics.q", {"profile": "constant", "value": 1.0}),
    ),
    Case(
        "profile-on-output",
        "input.thermal.t_oil",
        "expected an input",
        setv("input.thermal.t_oil", {"profile": "constant", "value": 300.0}),
    ),
    # --- error model
    Case("errormodel-unknown-key", "errormodel.gain", "unknown key", setv("errormodel.gain", 2.0)),
    # --- --set
    Case("set-without-equals", "--set", "KEY=VALUE", sets=("scenario.step",)),
    Case("set-into-non-table", "--set: scenario.step.x", "not a table", sets=("scenario.step.x=1",)),
    Case("set-malformed-key", "--set", "malformed", sets=('connections."thermal.t_oil=1',)),
    Case("set-empty-key-part", "--set", "malformed", sets=("scenario..step=1",)),
    Case("set-makes-step-zero", "scenario.step", "positive", sets=('scenario.step="0 s"',)),
    Case("set-makes-duration-absurd", "scenario.duration", "absurdly", sets=("scenario.duration=400 d",)),
    Case("set-unknown-key", "scenario.stop", "unknown", sets=("scenario.stop=1",)),
    Case(
        "set-quoted-key-feeds-twice",
        'connections."thermal.t_oil"',
        "already fed",
        sets=('connections."thermal.t_oil"="mechanics.t_clamp"',),
    ),
    Case("set-replaces-table-with-number", "fmu.thermal", "expected a table", sets=("fmu.thermal=3",)),
]


# ----------------------------------------------------------------------------- issue 13: the classes
# Each class of bad input, not only one example of it: numbers a float cannot hold or no run can
# use, times that are zero, negative, absurd or inconsistent, values outside a variable's declared
# range (modelDescription min/max: the FMU would refuse them mid-run), misspelt error-model
# columns. Each: exit 2, one line naming the file and the key.


def _range(inst: str, var: str) -> tuple[float, float]:
    """The declared [min, max] of an instance's variable in the paper's scenario."""
    from twin.fmu.catalog import variables

    model = paper_data()["fmu"][inst]["model"]
    v = variables(model)[var]
    return v.min, v.max


def above(inst: str, var: str) -> float:
    _, hi = _range(inst, var)
    return hi + max(1.0, abs(hi))


def below(inst: str, var: str) -> float:
    lo, _ = _range(inst, var)
    return lo - max(1.0, abs(lo))


def profile(target: str, **fields: Any) -> Mutation:
    inst, var = target.split(".")
    return setv(("input", inst, var), fields)


def bias(*values: float, target: str = "thermal.t_bearing") -> Mutation:
    evs = [
        {"at": f"{10 * (i + 1)} min", "action": "bias", "target": target, "value": v}
        for i, v in enumerate(values)
    ]
    return setv("event", evs)


def room_delay(initial: float) -> Mutation:
    return both(
        ROOM_FROM_SENSOR[0],
        setv("delay", [{"from": "sensors.t_room_meas", "to": "thermal.t_room", "initial": initial}]),
    )


def seed_text(literal: str) -> Callable[[], str]:
    return text("seed = 2017", f"seed = {literal}")


def param_text(literal: str) -> Callable[[], str]:
    # into the paper's own [fmu.thermal.parameters] (a second table of that name is a TOML error)
    return lambda: text("[fmu.thermal.parameters]\n", f"[fmu.thermal.parameters]\nc_base = {literal}\n")()


C_BASE = "fmu.thermal.parameters.c_base"
NAN, INF = float("nan"), float("inf")

CLASS_CASES = [
    # --- numbers no float holds, or no finite number
    Case("num-param-nan", C_BASE, "finite", setv(C_BASE, NAN)),
    Case("num-param-inf", C_BASE, "finite", setv(C_BASE, INF)),
    Case("num-param-minus-inf", C_BASE, "finite", setv(C_BASE, -INF)),
    Case("num-param-1e999", C_BASE, "finite", content=param_text("1e999")),
    Case("num-param-int-beyond-float", C_BASE, "64-bit", content=param_text("9" * 400)),
    Case("num-param-int-beyond-64-bit", C_BASE, "64-bit", setv(C_BASE, 2**64)),
    Case("num-param-int-5000-digits", None, "digits", content=param_text("1" * 5000)),
    Case("num-param-negative-int-5000-digits", None, "digits", content=param_text("-" + "7" * 5000)),
    Case("num-seed-int-beyond-float", "scenario.seed", "64-bit", content=seed_text("1" * 330)),
    Case(
        "num-std-error-inf",
        C_BASE + ".std_error",
        "finite",
        setv(C_BASE, {"value": 1000.0, "std_error": INF}),
    ),
    Case(
        "num-std-error-nan",
        C_BASE + ".std_error",
        "finite",
        setv(C_BASE, {"value": 1000.0, "std_error": NAN}),
    ),
    Case("num-std-error-zero", C_BASE + ".std_error", "> 0", setv(C_BASE, {"value": 1000.0, "std_error": 0})),
    Case(
        "num-profile-inf",
        "input.thermal.q_hydraulic.value",
        "finite",
        setv("input.thermal.q_hydraulic.value", INF),
    ),
    Case(
        "num-profile-int-beyond-64-bit",
        "input.thermal.q_hydraulic.value",
        "64-bit",
        setv("input.thermal.q_hydraulic.value", -(2**70)),
    ),
    Case("num-event-value-nan", "event[0].value", "finite", event(value=NAN)),
    Case("num-event-value-minus-inf", "event[0].value", "finite", event(value=-INF)),
    Case("num-delay-initial-inf", "delay[0].initial", "finite", room_delay(INF)),
    Case(
        "num-table-point-inf",
        "input.thermal.q_friction.points",
        "finite",
        profile("thermal.q_friction", profile="table", points=[[0, 0.0], ["1 h", INF]]),
    ),
    # --- durations, steps, periods: zero, negative, not finite, absurd, inconsistent
    Case("time-duration-1e30-seconds", "scenario.duration", "absurdly", setv("scenario.duration", 1e30)),
    Case("time-duration-1e30-text", "scenario.duration", "absurdly", setv("scenario.duration", "1e30 s")),
    Case("time-duration-nan", "scenario.duration", "finite", setv("scenario.duration", NAN)),
    Case("time-duration-inf", "scenario.duration", "finite", setv("scenario.duration", INF)),
    Case("time-duration-negative", "scenario.duration", "positive", setv("scenario.duration", -28800)),
    Case("time-duration-int64-max", "scenario.duration", "absurdly", setv("scenario.duration", 2**63 - 1)),
    Case(
        "time-duration-5000-digits",
        "scenario.duration",
        "characters",
        setv("scenario.duration", "1" * 5000 + " s"),
    ),
    Case(
        "time-duration-5000-decimals",
        "scenario.duration",
        "characters",
        setv("scenario.duration", "0." + "0" * 5000 + "1 s"),
    ),
    Case(
        "time-step-longer-than-duration",
        "scenario.duration",
        "shorter than scenario.step",
        setv("scenario.step", "10 h"),
    ),
    Case(
        "time-step-equal-to-duration",
        "scenario.duration",
        "too short",
        setv("scenario.step", "480 min"),
        lines=None,
    ),
    Case("time-step-nan", "scenario.step", "finite", setv("scenario.step", NAN)),
    Case("time-step-inf", "scenario.step", "finite", setv("scenario.step", INF)),
    Case("time-step-1e-300", "scenario.step", "nanoseconds", setv("scenario.step", 1e-300)),
    Case("time-step-absurd", "scenario.step", "absurdly", setv("scenario.step", "1e20 h")),
    Case(
        "time-output-interval-longer-than-duration",
        "scenario.output_interval",
        "longer than scenario.duration",
        setv("scenario.output_interval", "9 h"),
    ),
    Case(
        "time-output-interval-negative",
        "scenario.output_interval",
        "positive",
        setv("scenario.output_interval", -10),
    ),
    Case(
        "time-output-interval-nan",
        "scenario.output_interval",
        "finite",
        setv("scenario.output_interval", NAN),
    ),
    Case("time-period-inf", "fmu.thermal.period", "finite", setv("fmu.thermal.period", INF)),
    Case("time-period-absurd", "fmu.thermal.period", "absurdly", setv("fmu.thermal.period", "1e30 s")),
    Case(
        "time-period-longer-than-duration", "fmu.thermal.period", "divide", setv("fmu.thermal.period", "9 h")
    ),
    Case("time-drift-window-nan", "scenario.drift_window", "finite", setv("scenario.drift_window", NAN)),
    Case(
        "time-drift-window-absurd",
        "scenario.drift_window",
        "absurdly",
        setv("scenario.drift_window", "1e30 s"),
    ),
    Case(
        "time-profile-time-constant-nan",
        "input.thermal.t_room.time_constant",
        "finite",
        setv("input.thermal.t_room.time_constant", NAN),
    ),
    Case(
        "time-profile-sine-period-zero",
        "input.thermal.q_friction.period",
        "positive",
        profile("thermal.q_friction", profile="sine", mean=10.0, amplitude=1.0, period=0),
    ),
    Case(
        "time-profile-ramp-duration-absurd",
        "input.mechanics.angle.duration",
        "absurdly",
        profile("mechanics.angle", profile="ramp", start=0.0, end=1.0, duration="1e300 s"),
    ),
    Case(
        "time-table-time-nan",
        "input.thermal.q_friction.points",
        "finite",
        profile("thermal.q_friction", profile="table", points=[[0, 0.0], [NAN, 1.0]]),
    ),
    Case("time-event-at-inf", "event[0].at", "finite", event(at=INF)),
    Case("time-event-at-absurd", "event[0].at", "absurdly", event(at="1e30 s")),
    Case("time-event-at-negative", "event[0].at", "within", event(at=-60)),
    Case(
        "time-event-ramp-negative-duration",
        "event[0].duration",
        "positive",
        event(action="ramp", duration=-60),
    ),
    # --- values outside the declared [min, max] of their variable (modelDescription.xml)
    Case("range-param-above-max", C_BASE, "physical range", setv(C_BASE, above("thermal", "c_base"))),
    Case(
        "range-conductance-below-min",
        "fmu.thermal.parameters.g_base_room",
        "physical range",
        setv("fmu.thermal.parameters.g_base_room", below("thermal", "g_base_room")),
    ),
    Case(
        "range-mechanics-param-above-max",
        "fmu.mechanics.parameters.liner_creep_time",
        "physical range",
        setv("fmu.mechanics.parameters.liner_creep_time", above("mechanics", "liner_creep_time")),
    ),
    Case(
        "range-mechanics-param-below-min",
        "fmu.mechanics.parameters.solver_step",
        "physical range",
        setv("fmu.mechanics.parameters.solver_step", {"value": 0.0, "source": "typo"}),
    ),
    Case(
        "range-sensors-param-above-max",
        "fmu.sensors.parameters.probe_nonlinearity",
        "physical range",
        setv("fmu.sensors.parameters.probe_nonlinearity", above("sensors", "probe_nonlinearity")),
    ),
    Case(
        "range-integer-param-above-max",
        "fmu.sensors.parameters.seed",
        "physical range",
        setv("fmu.sensors.parameters.seed", 2**40),
    ),
    Case(
        "range-integer-param-negative",
        "fmu.sensors.parameters.seed",
        "physical range",
        setv("fmu.sensors.parameters.seed", -1),
    ),
    Case(
        "range-constant-above",
        "input.thermal.q_hydraulic",
        "outside the range",
        setv("input.thermal.q_hydraulic.value", 2e6),
    ),
    Case(
        "range-constant-below",
        "input.thermal.q_hydraulic",
        "outside the range",
        setv("input.thermal.q_hydraulic.value", -1.0),
    ),
    Case(
        "range-room-in-celsius",
        "input.thermal.t_room",
        "outside the range",
        setv("input.thermal.t_room.start", 20.0),
    ),
    Case(
        "range-ramp-end",
        "input.mechanics.angle",
        "outside the range",
        profile("mechanics.angle", profile="ramp", start=0.0, end=10.0, duration="1 h"),
    ),
    Case(
        "range-sine-swing",
        "input.thermal.q_friction",
        "outside the range",
        profile("thermal.q_friction", profile="sine", mean=10.0, amplitude=20.0, period="1 h"),
    ),
    Case(
        "range-table-value",
        "input.thermal.q_friction",
        "outside the range",
        profile("thermal.q_friction", profile="table", points=[[0, 0.0], ["1 h", -5.0]]),
    ),
    Case(
        "range-exponential-rise",
        "input.thermal.t_room",
        "outside the range",
        setv("input.thermal.t_room.rise", 500.0),
    ),
    Case("range-event-set", "event[0].value", "outside the range", event(value=-1.0)),
    Case(
        "range-event-ramp",
        "event[0].value",
        "outside the range",
        event(action="ramp", duration="5 min", value=2e6),
    ),
    Case("range-delay-initial-celsius", "delay[0].initial", "outside the range", room_delay(20.0)),
    Case(
        "range-delay-initial-above",
        "delay[0].initial",
        "outside the range",
        room_delay(above("thermal", "t_room")),
    ),
    Case("range-bias-wider-than-fed-input", "event[0].value", "wider", bias(500.0)),
    Case(
        "range-bias-wider-than-own-range",
        "event[0].value",
        "wider",
        bias(-400.0, target="sensors.t_base_meas"),
    ),
    Case("range-biases-add-up", "event[1].value", "wider", bias(200.0, 200.0)),
    # --- the error model's columns, checked against what the scenario records
    Case(
        "em-reading-misspelt",
        "errormodel.reading",
        "did you mean",
        setv("errormodel.reading", "sensors.probe_mea"),
    ),
    Case(
        "em-reading-unknown-instance",
        "errormodel.reading",
        "not recorded",
        setv("errormodel.reading", "daq.probe_meas"),
    ),
    Case(
        "em-reading-no-close-match",
        "errormodel.reading",
        "sensors records",
        setv("errormodel.reading", "sensors.zzz"),
    ),
    Case("em-reading-empty", "errormodel.reading", "empty name", setv("errormodel.reading", "")),
    Case("em-reading-number", "errormodel.reading", "a column name", setv("errormodel.reading", 5)),
    Case(
        "em-true-wear-misspelt",
        "errormodel.true_wear",
        "not recorded",
        setv("errormodel.true_wear", "mechanics.wear"),
    ),
    Case("em-load-misspelt", "errormodel.load", "did you mean", setv("errormodel.load", "sensors.load_mes")),
    Case(
        "em-angle-misspelt",
        "errormodel.angle",
        "did you mean",
        setv("errormodel.angle", "sensors.angel_meas"),
    ),
    Case(
        "em-temperature-column-misspelt",
        "errormodel.temperatures.base",
        "did you mean",
        setv("errormodel.temperatures", {"base": "sensors.t_bas_meas"}),
    ),
    Case(
        "em-temperature-column-of-truth",
        "errormodel.temperatures.room",
        "not recorded",
        setv("errormodel.temperatures", {"room": "thermal.t_room_true"}),
    ),
    Case(
        "em-temperature-point-misspelt",
        "errormodel.temperatures.bsae",
        "did you mean 'base'",
        setv("errormodel.temperatures", {"bsae": "sensors.t_base_meas"}),
    ),
    Case("em-temperatures-list", "errormodel.temperatures", "table", setv("errormodel.temperatures", ["a"])),
    Case(
        "em-factor-misspelt",
        "errormodel.factors",
        "expected a list",
        setv("errormodel.factors", ["thermall"]),
    ),
    Case("em-factors-empty", "errormodel.factors", "expected a list", setv("errormodel.factors", [])),
    Case("em-factors-string", "errormodel.factors", "expected a list", setv("errormodel.factors", "thermal")),
    Case(
        "em-unknown-key",
        "errormodel.readings",
        "did you mean 'reading'",
        setv("errormodel.readings", "sensors.probe_meas"),
    ),
    Case(
        "em-coefficients-number", "errormodel.coefficients", "file name", setv("errormodel.coefficients", 5)
    ),
    # --- the same classes through --set
    Case(
        "set-int-beyond-float-in-a-table",
        "--set: input.thermal.q_friction.points[1][1]",
        "64-bit",
        sets=('input.thermal.q_friction={profile="table", points=[[0, 1.0], [1, ' + "9" * 400 + "]]}",),
    ),
    Case("set-5000-digits", "--set: scenario.seed", "digits", sets=("scenario.seed=" + "9" * 5000,)),
    Case(
        "set-nested-5000-deep",
        "--set: scenario.seed",
        "nested",
        sets=("scenario.seed=" + "[" * 5000 + "]" * 5000,),
    ),
    Case(
        "set-nested-40-deep",
        "--set: scenario.seed" + "[0]" * 33,
        "nested",
        sets=("scenario.seed=" + "[" * 40 + "]" * 40,),
    ),
    Case("set-parameter-nan", C_BASE, "finite", sets=(f"{C_BASE}=nan",)),
    Case("set-parameter-out-of-range", C_BASE, "physical range", sets=(f"{C_BASE}=-5.0",)),
    Case("set-step-longer-than-duration", "scenario.duration", "shorter", sets=('scenario.step="9 h"',)),
    Case(
        "set-errormodel-column-misspelt",
        "errormodel.reading",
        "did you mean",
        sets=('errormodel.reading="sensors.probe"',),
    ),
]
CASES += CLASS_CASES


def build(case: Case, tmp_path: Path) -> Path:
    path = tmp_path / f"{case.id}.toml"
    if case.id == "file-missing":
        return path
    if case.id == "file-is-directory":
        path.mkdir()
        return path
    if case.content is not None:
        return write(path, case.content())
    data = paper_data()
    if case.mutate is not None:
        case.mutate(data)
    return write(path, data)


def check_report(stderr: str, path: Path, key: str | None, word: str, lines: int | None) -> list[str]:
    """The contract: one line per problem, each ``twin: FILE: ...``; one names ``key`` and says ``word``."""
    assert "Traceback" not in stderr
    out = stderr.strip().splitlines()
    assert out, "nothing on stderr"
    for line in out:
        assert line.startswith("twin: "), line
        assert path.name in line, line
    hits = [ln for ln in out if (key is None or f"{key}: " in ln) and word.lower() in ln.lower()]
    assert hits, f"no line names {key!r} with {word!r}:\n{stderr}"
    if lines is not None:
        assert len(out) == lines, stderr
    return out


def test_corpus_is_large_and_ids_unique() -> None:
    assert len(CASES) >= 40
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_scenario_is_rejected_with_one_line_per_problem(case: Case, tmp_path: Path, capsys) -> None:
    path = build(case, tmp_path)
    argv = ["validate", str(path)]
    for s in case.sets:
        argv += ["--set", s]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    check_report(captured.err, path, case.key, case.word, case.lines)


@pytest.mark.parametrize("inst", ["thermal", "mechanics", "sensors"])
def test_every_parameter_outside_its_declared_range_is_one_line(inst: str) -> None:
    """The class, not examples: every numeric parameter of each paper instance, just beyond its
    modelDescription min and max, is refused before the run naming the key and the range."""
    import math

    from twin.config.load import load_scenario_data
    from twin.errors import ConfigErrors
    from twin.fmu.catalog import variables

    model = paper_data()["fmu"][inst]["model"]
    checked = 0
    for v in variables(model).values():
        if v.causality != "parameter" or v.type == "Boolean":
            continue
        for bound, step in ((v.min, -1), (v.max, +1)):
            if not math.isfinite(bound):
                continue
            value = bound + step * max(1.0, abs(bound)) if v.type == "Real" else int(bound) + step
            data = paper_data()
            data["fmu"][inst].setdefault("parameters", {})[v.name] = value
            with pytest.raises(ConfigErrors) as exc:
                load_scenario_data(data, "s.toml", Path("."))
            key = f"fmu.{inst}.parameters.{v.name}"
            assert str(exc.value).split("\n") == [str(exc.value.problems[0])], str(exc.value)
            assert exc.value.problems[0].key == key and repr(bound) in exc.value.problems[0].message
            checked += 1
    assert checked >= 30


def test_the_unmutated_paper_scenario_passes(tmp_path: Path, capsys) -> None:
    """The corpus's base is valid: each case fails for its mutation only."""
    path = write(tmp_path / "paper.toml", paper_data())
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def test_the_same_loop_with_a_delay_is_accepted(tmp_path: Path, capsys) -> None:
    data = paper_data()
    del data["input"]["thermal"]["t_room"]
    data["delay"] = [{"from": "sensors.t_room_meas", "to": "thermal.t_room", "initial": 293.15}]
    path = write(tmp_path / "delayed-loop.toml", data)
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err
    assert "ok" in capsys.readouterr().out


def test_three_independent_problems_are_reported_at_once(tmp_path: Path, capsys) -> None:
    data = paper_data()
    data["scenario"]["step"] = "0 s"
    data["fmu"]["thermal"]["parameters"] = {"c_base": -1}
    data["input"]["thermal"]["q_hydraulic"]["profile"] = "square"
    path = write(tmp_path / "three.toml", data)
    assert main(["validate", str(path)]) == 2
    out = check_report(capsys.readouterr().err, path, "scenario.step", "positive", 3)
    assert any("fmu.thermal.parameters.c_base: " in ln and "range" in ln for ln in out)
    assert any("input.thermal.q_hydraulic.profile: " in ln and "square" in ln for ln in out)


def test_every_bad_set_is_reported_at_once(tmp_path: Path, capsys) -> None:
    path = write(tmp_path / "sets.toml", paper_data())
    assert main(["validate", str(path), "--set", "nothing", "--set", "scenario.step.x=1"]) == 2
    out = check_report(capsys.readouterr().err, path, "--set", "KEY=VALUE", 2)
    assert "not a table" in out[1]


# ----------------------------------------------------------------------------- validate and run agree

#: one case of each class: twin run must refuse them before anything runs, with validate's line
SHARED_CASES = [
    "num-param-int-beyond-float",
    "num-profile-inf",
    "time-step-longer-than-duration",
    "time-duration-5000-digits",
    "range-delay-initial-celsius",
    "range-bias-wider-than-fed-input",
    "range-integer-param-above-max",
    "em-reading-misspelt",
    "em-temperature-point-misspelt",
    "em-factor-misspelt",
    "set-int-beyond-float-in-a-table",
    "parameter-file-missing",
]


@pytest.mark.parametrize("case_id", SHARED_CASES)
def test_run_refuses_what_validate_refuses_with_the_same_line(case_id: str, tmp_path: Path, capsys) -> None:
    case = next(c for c in CASES if c.id == case_id)
    path = build(case, tmp_path)
    sets = [a for s in case.sets for a in ("--set", s)]
    assert main(["validate", str(path), *sets]) == 2
    validate_err = capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["run", str(path), "--quiet", "--out", str(out), *sets]) == 2
    captured = capsys.readouterr()
    assert captured.err == validate_err
    check_report(captured.err, path, case.key, case.word, case.lines)
    assert not out.exists()  # refused before the run folder was made


# ----------------------------------------------------------------------------- the real entry point

SUBPROCESS_CASES = ["syntax-unquoted-duration", "connection-unit-mismatch", "parameter-negative-capacity"]


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "twin", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        check=False,
        timeout=120,
    )


@pytest.mark.parametrize("case_id", SUBPROCESS_CASES)
def test_validate_from_the_command_line_exits_2(case_id: str, tmp_path: Path) -> None:
    case = next(c for c in CASES if c.id == case_id)
    path = build(case, tmp_path)
    proc = _run(["validate", str(path)], tmp_path)
    assert proc.returncode == 2, proc.stderr
    check_report(proc.stderr, path, case.key, case.word, case.lines)


def test_run_fails_at_validation_and_writes_nothing(tmp_path: Path) -> None:
    case = next(c for c in CASES if c.id == "step-zero")
    path = build(case, tmp_path)
    out = tmp_path / "out"
    proc = _run(["run", str(path), "--quiet", "--out", str(out)], tmp_path)
    assert proc.returncode == 2, proc.stderr
    check_report(proc.stderr, path, case.key, case.word, case.lines)
    assert proc.stdout == ""
    assert not out.exists()
