"""Load a scenario file (TOML) into a checked, frozen :class:`~twin.config.spec.Scenario`.

Every problem in a file is collected and reported at once, one line each naming the file
and the dotted key (like FMPy's validators), as :class:`~twin.errors.ConfigErrors`.
Connections are checked before any run (as mosaik does): endpoints exist, an output feeds
an input, units agree, no input is fed twice, and loops between FMUs go through an explicit
delay with an initial value.
"""

from __future__ import annotations

import itertools
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from fractions import Fraction
from functools import cache
from pathlib import Path
from types import MappingProxyType
from typing import Any

from twin.config.spec import (
    NS_PER_S,
    Connection,
    Event,
    FMUSpec,
    Parameter,
    Profile,
    Scenario,
)
from twin.errors import ConfigError, ConfigErrors

#: longest run accepted: a year of simulated time
MAX_DURATION_NS = 366 * 24 * 3600 * NS_PER_S

_UNITS_NS = {
    "ns": 1,
    "us": 1_000,
    "ms": 1_000_000,
    "s": NS_PER_S,
    "min": 60 * NS_PER_S,
    "h": 3600 * NS_PER_S,
    "d": 86400 * NS_PER_S,
}
#: no duration in a scenario can be longer than this (and beyond it numbers stop being sane)
_ABSURD_NS = 1000 * 366 * 86400 * NS_PER_S
_DURATION_RE = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?)\s*([a-z]+)\s*$")

_TOP_KEYS = {"scenario", "fmu", "connections", "delay", "input", "event", "errormodel"}
_SCENARIO_KEYS = {"name", "description", "duration", "step", "output_interval", "seed", "drift_window"}
_FMU_KEYS = {"model", "period", "parameters", "parameter_files"}
_PROFILE_PARAMS: dict[str, tuple[set[str], set[str]]] = {
    # kind: (required, optional)
    "constant": ({"value"}, set()),
    "ramp": ({"start", "end", "duration"}, {"delay"}),
    "exponential": ({"start", "rise", "time_constant"}, {"rise_at"}),
    "sine": ({"mean", "amplitude", "period"}, {"phase"}),
    "table": ({"points"}, set()),
}
_PROFILE_DURATIONS = {"duration", "delay", "time_constant", "rise_at", "period"}
_EVENT_KEYS = {"at", "action", "target", "value", "duration", "fault"}
_EVENT_ACTIONS = {"set", "ramp", "bias", "fault"}
#: fault events: how the FMU fails (its fault_inject input)
FAULTS = {"error": 1.0, "discard": 2.0, "nan": 3.0}


def parse_duration(value: Any) -> int:
    """A duration as integer nanoseconds: a number of seconds or a string like ``"480 min"``.

    Exact (rational arithmetic), so ``"0.1 s"`` is 100_000_000 ns, never 99_999_999.
    Raises ``ValueError`` with a short reason.
    """
    if isinstance(value, bool):
        raise ValueError(f"expected a duration, got {value!r}")
    if isinstance(value, int | float):
        if not math.isfinite(value):
            raise ValueError(f"expected a finite duration, got {value!r}")
        frac, unit = Fraction(repr(float(value)) if isinstance(value, float) else value), NS_PER_S
    elif isinstance(value, str):
        m = _DURATION_RE.match(value)
        if not m or m.group(2) not in _UNITS_NS:
            raise ValueError(
                f"expected a duration like '480 min' or '0.1 s' (units {', '.join(_UNITS_NS)}), got {value!r}"
            )
        # a quick float look first: an exact Fraction of '1e10000000' takes seconds to build
        if not math.isfinite(float(m.group(1))) or float(m.group(1)) * _UNITS_NS[m.group(2)] > 2 * _ABSURD_NS:
            raise ValueError(f"{value!r} is absurdly long (more than 1000 years)")
        frac, unit = Fraction(m.group(1)), _UNITS_NS[m.group(2)]
    else:
        raise ValueError(f"expected a duration, got {type(value).__name__}")
    ns = frac * unit
    if ns.denominator != 1:
        raise ValueError(f"{value!r} is not a whole number of nanoseconds")
    if ns > _ABSURD_NS:
        raise ValueError(f"{value!r} is absurdly long (more than 1000 years)")
    return int(ns)


def format_duration(ns: int) -> str:
    """Shortest exact text for a duration, for messages."""
    if ns == 0:
        return "0 s"
    for unit in ("d", "h", "min", "s", "ms", "us"):
        if ns % _UNITS_NS[unit] == 0:
            return f"{ns // _UNITS_NS[unit]} {unit}"
    return f"{ns} ns"


# ----------------------------------------------------------------------------- model metadata


@cache
def model_variables(model: str) -> Mapping[str, Any]:
    """The ``modelDescription.xml`` variables of a model in ``fmus/`` by name (no build needed)."""
    from fmpy import read_model_description

    from twin.fmu.build import fmu_sources_dir

    md = read_model_description(str(fmu_sources_dir() / model / "modelDescription.xml"))
    return {v.name: v for v in md.modelVariables}


def variable_unit(v: Any) -> str:
    """Declared unit of an FMI variable (directly or through its declared type)."""
    if getattr(v, "unit", None):
        return str(v.unit)
    declared = getattr(v, "declaredType", None)
    return str(declared.unit) if declared is not None and declared.unit else ""


def _known_models() -> list[str]:
    from twin.fmu.build import model_names

    return model_names()


# ----------------------------------------------------------------------------- --set overrides


def _split_key(key: str, source: str = "--set") -> list[str]:
    """Dotted key with optional quoted parts: ``connections."thermal.t_spindle"``."""
    parts, buf, quoted = [], "", False
    for ch in key:
        if ch == '"':
            quoted = not quoted
        elif ch == "." and not quoted:
            parts.append(buf)
            buf = ""
        else:
            buf += ch
    parts.append(buf)
    if quoted or any(not p for p in parts):
        raise ConfigError(f"malformed key {key!r}", source=source)
    return parts


def apply_overrides(data: dict[str, Any], overrides: Sequence[str], source: str = "--set") -> None:
    """Apply ``KEY=VALUE`` overrides in place; VALUE is read as TOML (else as a plain string).

    ``source`` names the overrides in messages (``load_scenario`` adds the file name); every
    bad override is reported at once.
    """
    problems: list[ConfigError] = []
    for item in overrides:
        try:
            _apply_override(data, item, source)
        except ConfigError as exc:
            problems.append(exc)
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)


def _apply_override(data: dict[str, Any], item: str, source: str) -> None:
    if "=" not in item:
        raise ConfigError(f"expected KEY=VALUE, got {item!r}", source=source)
    key, raw = item.split("=", 1)
    parts = _split_key(key.strip(), source)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    node = data
    for p in parts[:-1]:
        child = node.get(p)
        if child is None:
            child = node[p] = {}
        elif not isinstance(child, dict):
            raise ConfigError(f"cannot set {key!r}: '{p}' is not a table", source=source, key=key)
        node = child
    node[parts[-1]] = value


# ----------------------------------------------------------------------------- the loader


class _Problems:
    """Collects problems with the file name, so all of them are reported at once."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[ConfigError] = []
        #: FMU instances declared but unusable: their problem is reported once, at the instance,
        #: not again at every connection, profile and event naming them (all of them: no [fmu])
        self.broken: set[str] = set()
        self.no_fmus = False

    def add(self, key: str, message: str) -> None:
        if any(e.key == key and e.message == message for e in self.items):
            return  # one line per problem: a list connection repeats its source for each input
        self.items.append(ConfigError(message, source=self.source, key=key))

    def unknown_keys(self, table: Mapping[str, Any], allowed: set[str], prefix: str) -> None:
        for k in table:
            if k not in allowed:
                hint = ", ".join(sorted(allowed))
                self.add(f"{prefix}{k}", f"unknown key (expected one of: {hint})")

    def duration(
        self, table: Mapping[str, Any], key: str, prefix: str, *, required: bool = True
    ) -> int | None:
        if key not in table:
            if required:
                self.add(prefix + key, "missing (a duration such as '480 min')")
            return None
        try:
            return parse_duration(table[key])
        except ValueError as exc:
            self.add(prefix + key, str(exc))
            return None

    def number(self, table: Mapping[str, Any], key: str, prefix: str) -> float | None:
        v = table.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float):
            self.add(prefix + key, f"expected a number, got {v!r}" if key in table else "missing (a number)")
            return None
        if not math.isfinite(v):
            self.add(prefix + key, f"expected a finite number, got {v!r}")
            return None
        return float(v)


def _array_of_tables(
    p: _Problems, data: Mapping[str, Any], name: str, hint: str
) -> list[tuple[int, str, dict]]:
    """(index, key, table) of each entry of a ``[[name]]`` array; problems for the rest."""
    raw = data.get(name, [])
    if not isinstance(raw, list):
        p.add(name, f"expected an array of tables [[{name}]]")
        return []
    out = []
    for i, entry in enumerate(raw):
        if isinstance(entry, dict):
            out.append((i, f"{name}[{i}]", entry))
        else:
            p.add(f"{name}[{i}]", f"expected a table{hint}")
    return out


def _table(p: _Problems, data: Mapping[str, Any], key: str, prefix: str = "") -> dict[str, Any]:
    v = data.get(key, {})
    if not isinstance(v, dict):
        p.add(prefix + key, f"expected a table, got {type(v).__name__}")
        return {}
    return v


def _read_toml(path: Path, source: str) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", source=source) from None
    except IsADirectoryError:
        raise ConfigError("is a directory, expected a TOML file", source=source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc.__class__.__name__}: {exc}", source=source) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", source=source) from None


def _declared_range(var: Any) -> tuple[float, float]:
    """[min, max] of an FMI variable, directly or through its declared type (unbounded if none)."""
    declared = getattr(var, "declaredType", None)
    lo = var.min if var.min is not None else (declared.min if declared is not None else None)
    hi = var.max if var.max is not None else (declared.max if declared is not None else None)
    return (float(lo) if lo is not None else -math.inf, float(hi) if hi is not None else math.inf)


def _parameter_value(p: _Problems, model: str, var: Any, raw: Any, key: str) -> Parameter | None:
    source = ""
    if isinstance(raw, dict):
        extra = set(raw) - {"value", "source"}
        if extra:
            p.add(key, f"unknown key(s) {sorted(extra)} (a parameter is a value or {{ value, source }})")
            return None
        if "value" not in raw:
            p.add(key, "missing 'value'")
            return None
        source = str(raw.get("source", ""))
        raw = raw["value"]
    if var.type == "Boolean":
        if not isinstance(raw, bool):
            p.add(key, f"expected true or false, got {raw!r}")
            return None
        return Parameter(raw, source)
    if var.type == "Integer":
        if isinstance(raw, bool) or not isinstance(raw, int):
            p.add(key, f"expected an integer, got {raw!r}")
            return None
        value: float | int = raw
    else:
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            p.add(key, f"expected a number, got {raw!r}")
            return None
        value = float(raw)
        if not math.isfinite(value):
            p.add(key, f"expected a finite number, got {raw!r}")
            return None
    lo, hi = _declared_range(var)
    if not lo <= value <= hi:
        unit = variable_unit(var)
        p.add(
            key,
            f"{value!r} {unit} is outside the physical range [{lo!r}, {hi!r}] of {model}.{var.name}".replace(
                "  ", " "
            ),
        )
        return None
    return Parameter(value, source)


def _load_fmus(p: _Problems, data: Mapping[str, Any], base_dir: Path, step_ns: int | None) -> list[FMUSpec]:
    fmus_raw = _table(p, data, "fmu")
    if not fmus_raw:
        p.add("fmu", "at least one [fmu.<name>] table is needed")
        p.no_fmus = True
    known = _known_models()
    out = []
    for name, raw in fmus_raw.items():
        prefix = f"fmu.{name}."
        if not isinstance(raw, dict):
            p.add(f"fmu.{name}", "expected a table")
            p.broken.add(name)
            continue
        if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
            p.add(f"fmu.{name}", "instance names are lower_snake (letters, digits, _)")
        p.unknown_keys(raw, _FMU_KEYS, prefix)
        model = raw.get("model")
        if "model" not in raw:
            p.add(prefix + "model", f"missing (one of: {', '.join(known)})")
            p.broken.add(name)
            continue
        if model not in known:
            p.add(prefix + "model", f"unknown model {model!r} (known: {', '.join(known)})")
            p.broken.add(name)
            continue
        period = p.duration(raw, "period", prefix)
        if period is not None:
            if period <= 0:
                p.add(prefix + "period", "must be positive")
            elif step_ns and period % step_ns:
                p.add(
                    prefix + "period",
                    f"{format_duration(period)} is not a multiple of scenario.step ({format_duration(step_ns)})",
                )
        variables = model_variables(model)
        merged: dict[str, tuple[Any, str]] = {}
        files = raw.get("parameter_files", [])
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            p.add(prefix + "parameter_files", "expected a list of file names")
            files = []
        for f in files:
            fpath = (base_dir / f).resolve()
            try:
                fdata = _read_toml(fpath, str(fpath))
            except ConfigError as exc:
                p.add(prefix + "parameter_files", str(exc))
                continue
            params = fdata.get("parameters", {})
            if not isinstance(params, dict):
                p.add(prefix + "parameter_files", f"{fpath}: parameters: expected a [parameters] table")
                continue
            for k, v in params.items():
                merged[k] = (v, f"{fpath.name}: parameters.{k}")
        params_raw = raw.get("parameters", {})
        if not isinstance(params_raw, dict):
            p.add(prefix + "parameters", "expected a table")
            params_raw = {}
        for k, v in params_raw.items():
            merged[k] = (v, f"{prefix}parameters.{k}")
        params: dict[str, Parameter] = {}
        for k, (v, where) in merged.items():
            var = variables.get(k)
            if var is None or var.causality != "parameter":
                p.add(where, f"{model} has no parameter '{k}'")
                continue
            param = _parameter_value(p, model, var, v, where)
            if param is not None:
                params[k] = param
        if period is not None:
            out.append(FMUSpec(name=name, model=model, period_ns=period, parameters=MappingProxyType(params)))
        else:
            p.broken.add(name)
    return out


def _endpoint(p: _Problems, fmus: Mapping[str, FMUSpec], ref: Any, key: str, causality: str) -> Any | None:
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


def _load_connections(p: _Problems, data: Mapping[str, Any], fmus: Mapping[str, FMUSpec]) -> list[Connection]:
    out: list[Connection] = []
    conns = _table(p, data, "connections")
    for src, dsts in conns.items():
        key = f'connections."{src}"'
        if isinstance(dsts, str):
            dsts = [dsts]
        if isinstance(dsts, dict):
            p.add(
                key, f'expected an input name or a list of them (quote the output: "{src}.<variable>" = ...)'
            )
            continue
        if not isinstance(dsts, list) or not all(isinstance(d, str) for d in dsts):
            p.add(key, "expected an input name or a list of them")
            continue
        for dst in dsts:
            out.append(Connection(src, dst))
    for _i, key, raw in _array_of_tables(p, data, "delay", " with from, to, initial"):
        p.unknown_keys(raw, {"from", "to", "initial"}, key + ".")
        initial = p.number(raw, "initial", key + ".")
        if isinstance(raw.get("from"), str) and isinstance(raw.get("to"), str) and initial is not None:
            out.append(Connection(raw["from"], raw["to"], delay=True, initial=initial))
        elif not (isinstance(raw.get("from"), str) and isinstance(raw.get("to"), str)):
            p.add(key, "needs 'from' and 'to' as 'instance.variable'")
    fed: dict[str, str] = {}
    for c in out:
        key = f'connections."{c.src}"' if not c.delay else "delay"
        vs = _endpoint(p, fmus, c.src, key, "output")
        vd = _endpoint(p, fmus, c.dst, key, "input")
        if vs is not None and vd is not None and variable_unit(vs) != variable_unit(vd):
            p.add(
                key, f"unit mismatch: {c.src} is in '{variable_unit(vs)}', {c.dst} in '{variable_unit(vd)}'"
            )
        if c.dst in fed:
            p.add(key, f"input {c.dst!r} is already fed by {fed[c.dst]!r}")
        fed[c.dst] = c.src
    _check_loops(p, out)
    return out


def _check_loops(p: _Problems, connections: Sequence[Connection]) -> None:
    """Loops between instances must contain a delayed connection (no algebraic loops)."""
    graph: dict[str, set[str]] = {}
    for c in connections:
        if not c.delay and "." in c.src and "." in c.dst:
            a, b = c.src.split(".")[0], c.dst.split(".")[0]
            graph.setdefault(a, set()).add(b)
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return [*stack[stack.index(m) :], m]
            if m not in state and (cycle := visit(m)):
                return cycle
        state[n] = 2
        stack.pop()
        return None

    for n in sorted(graph):
        if n not in state and (cycle := visit(n)):
            p.add(
                "connections",
                "algebraic loop " + " -> ".join(cycle) + ": break it with a [[delay]] (from, to, initial)",
            )
            return


def _load_profiles(
    p: _Problems, data: Mapping[str, Any], fmus: Mapping[str, FMUSpec], connections: Sequence[Connection]
) -> list[Profile]:
    out = []
    fed = {c.dst for c in connections}
    inputs = _table(p, data, "input")
    for inst, per_var in inputs.items():
        if not isinstance(per_var, dict):
            p.add(f"input.{inst}", "expected a table [input.<instance>.<variable>]")
            continue
        for var, raw in per_var.items():
            key = f"input.{inst}.{var}"
            target = f"{inst}.{var}"
            if not isinstance(raw, dict):
                p.add(key, "expected a table with 'profile' and its parameters")
                continue
            if _endpoint(p, fmus, target, key, "input") is None:
                continue
            if target in fed:
                p.add(key, f"input {target!r} is fed by a connection; it cannot also have a profile")
            kind = raw.get("profile")
            if kind is None:
                p.add(key + ".profile", f"missing (one of: {', '.join(_PROFILE_PARAMS)})")
                continue
            if not isinstance(kind, str) or kind not in _PROFILE_PARAMS:
                p.add(
                    key + ".profile",
                    f"unknown profile {kind!r} (expected one of: {', '.join(_PROFILE_PARAMS)})",
                )
                continue
            required, optional = _PROFILE_PARAMS[kind]
            p.unknown_keys(raw, required | optional | {"profile", "source"}, key + ".")
            params: dict[str, float] = {}
            table: tuple[tuple[float, float], ...] = ()
            for k in sorted(required | optional):
                if k not in raw:
                    if k in required:
                        p.add(f"{key}.{k}", f"missing (needed by the '{kind}' profile)")
                    continue
                if k == "points":
                    pts = raw[k]
                    ok = (
                        isinstance(pts, list)
                        and len(pts) >= 2
                        and all(isinstance(q, list) and len(q) == 2 for q in pts)
                    )
                    if not ok:
                        p.add(f"{key}.points", "expected [[time, value], ...] with at least two points")
                        continue
                    try:
                        times_ns = [parse_duration(q[0]) for q in pts]
                    except ValueError as exc:
                        p.add(f"{key}.points", str(exc))
                        continue
                    values = [q[1] for q in pts]
                    if any(
                        isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
                        for v in values
                    ):
                        p.add(f"{key}.points", "values must be finite numbers")
                        continue
                    # compared as exact nanoseconds: two times 1 ns apart may be one float second
                    if any(b <= a for a, b in itertools.pairwise(times_ns)):
                        p.add(f"{key}.points", "times must increase strictly")
                        continue
                    table = tuple(zip((t / NS_PER_S for t in times_ns), map(float, values), strict=True))
                elif k in _PROFILE_DURATIONS:
                    ns = p.duration(raw, k, key + ".")
                    if ns is not None:
                        if ns <= 0 and k != "delay":
                            p.add(f"{key}.{k}", "must be positive")
                        elif ns < 0:
                            p.add(f"{key}.{k}", "must not be negative")
                        else:
                            params[k] = ns / NS_PER_S
                else:
                    v = p.number(raw, k, key + ".")
                    if v is not None:
                        params[k] = v
            profile = Profile(target, kind, MappingProxyType(params), table, str(raw.get("source", "")))
            if required <= set(params) | ({"points"} if table else set()):
                _check_range(p, fmus, target, _profile_extremes(profile), key)
            out.append(profile)
    return out


def _profile_extremes(pr: Profile) -> list[float]:
    """The values a profile can reach (its extremes), for the range check."""
    q = pr.params
    if pr.kind == "constant":
        return [q["value"]]
    if pr.kind == "ramp":
        return [q["start"], q["end"]]
    if pr.kind == "exponential":
        scale = 1.0 / -math.expm1(-q["rise_at"] / q["time_constant"]) if "rise_at" in q else 1.0
        return [q["start"], q["start"] + q["rise"] * scale]
    if pr.kind == "sine":
        return [q["mean"] - q["amplitude"], q["mean"] + q["amplitude"]]
    return [v for _, v in pr.table]


def _check_range(
    p: _Problems, fmus: Mapping[str, FMUSpec], target: str, values: Sequence[float], key: str
) -> None:
    """Values driven into an input must lie in its declared range (the FMU would refuse them)."""
    inst, var = target.split(".")
    v = model_variables(fmus[inst].model)[var]
    lo, hi = _declared_range(v)
    bad = [x for x in values if not lo <= x <= hi]
    if bad:
        unit = variable_unit(v)
        p.add(
            key,
            f"reaches {bad[0]!r} {unit}, outside the range [{lo!r}, {hi!r}] of {target}".replace("  ", " "),
        )


def _load_events(
    p: _Problems,
    data: Mapping[str, Any],
    fmus: Mapping[str, FMUSpec],
    duration_ns: int | None,
    connections: Sequence[Connection],
) -> list[Event]:
    fed = {c.dst for c in connections}
    out = []
    for _i, key, raw in _array_of_tables(p, data, "event", ""):
        p.unknown_keys(raw, _EVENT_KEYS, key + ".")
        at = p.duration(raw, "at", key + ".")
        action = raw.get("action")
        if not isinstance(action, str) or action not in _EVENT_ACTIONS:
            p.add(
                key + ".action",
                f"unknown action {action!r} (expected one of: {', '.join(sorted(_EVENT_ACTIONS))})",
            )
            continue
        if action == "fault":
            # make an FMU fail at a given time: a set event on its fault_inject input
            inst, fault = raw.get("target"), raw.get("fault")
            if not isinstance(inst, str) or inst not in fmus:
                p.add(
                    key + ".target",
                    f"a fault targets an FMU instance (one of: {', '.join(sorted(fmus))}), got {inst!r}",
                )
                continue
            if not isinstance(fault, str) or fault not in FAULTS:
                p.add(key + ".fault", f"expected one of {sorted(FAULTS)}, got {fault!r}")
                continue
            if "fault_inject" not in model_variables(fmus[inst].model):
                p.add(key + ".target", f"model {fmus[inst].model} has no fault_inject input")
                continue
            if at is not None and (at < 0 or (duration_ns is not None and at >= duration_ns)):
                p.add(key + ".at", "must lie within the scenario's duration")
            elif at is not None:
                out.append(Event(at, "set", f"{inst}.fault_inject", FAULTS[fault], 0))
            continue
        if "fault" in raw:
            p.add(key + ".fault", "only a 'fault' action takes a fault")
        causality = "output" if action == "bias" else "input"
        target_ok = _endpoint(p, fmus, raw.get("target"), key + ".target", causality) is not None
        if target_ok and action != "bias" and raw["target"] in fed:
            p.add(
                key + ".target",
                f"input {raw['target']!r} is fed by a connection; {action} needs a free input",
            )
            target_ok = False
        value = p.number(raw, "value", key + ".")
        dur = p.duration(raw, "duration", key + ".", required=action == "ramp")
        if action == "ramp" and dur is not None and dur <= 0:
            p.add(key + ".duration", "a ramp needs a positive duration")
        dur = dur or 0
        if at is not None and (at < 0 or (duration_ns is not None and at >= duration_ns)):
            p.add(key + ".at", "must lie within the scenario's duration")
        if value is not None and target_ok and action != "bias":
            _check_range(p, fmus, raw["target"], [value], key + ".value")
        if at is not None and value is not None and target_ok:
            out.append(Event(at, action, raw["target"], value, dur))
    return sorted(out, key=lambda e: e.at_ns)


def load_scenario_data(data: dict[str, Any], source: str, base_dir: Path) -> Scenario:
    """Check an already-parsed scenario; raises :class:`ConfigErrors` listing every problem."""
    p = _Problems(source)
    p.unknown_keys(data, _TOP_KEYS, "")
    sc = _table(p, data, "scenario")
    if "scenario" not in data:
        p.add("scenario", "missing [scenario] table")
    p.unknown_keys(sc, _SCENARIO_KEYS, "scenario.")
    name = sc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name:
        p.add("scenario.name", "expected a non-empty string")
        name = Path(source).stem
    step = p.duration(sc, "step", "scenario.")
    duration = p.duration(sc, "duration", "scenario.")
    interval = p.duration(sc, "output_interval", "scenario.")
    if step is not None and step <= 0:
        p.add("scenario.step", "must be positive")
        step = None
    n_problems = len(p.items)
    if duration is not None:
        if duration <= 0:
            p.add("scenario.duration", "must be positive")
        elif duration > MAX_DURATION_NS:
            p.add("scenario.duration", f"{format_duration(duration)} is absurdly long (at most 366 d)")
        elif step and duration % step:
            p.add("scenario.duration", f"{format_duration(duration)} is not a multiple of scenario.step")
        elif step and duration < 2 * step:
            p.add("scenario.duration", "too short: needs at least two steps")
    if interval is not None:
        if interval <= 0:
            p.add("scenario.output_interval", "must be positive")
        elif step and interval % step:
            p.add(
                "scenario.output_interval", f"{format_duration(interval)} is not a multiple of scenario.step"
            )
    duration_ok = duration is not None and len(p.items) == n_problems
    if duration_ok and interval and interval > 0 and interval > duration:
        p.add("scenario.output_interval", "is longer than scenario.duration: nothing would be recorded")
    drift_window = p.duration(sc, "drift_window", "scenario.", required=False)
    if drift_window is not None and drift_window <= 0:
        p.add("scenario.drift_window", "must be positive")
    seed = sc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
        p.add("scenario.seed", f"expected an integer in [0, 2^31), got {seed!r}")
        seed = 0
    description = sc.get("description", "")
    if not isinstance(description, str):
        p.add("scenario.description", "expected a string")
        description = ""

    fmus = _load_fmus(p, data, base_dir, step)
    for f in fmus:
        if duration and duration > 0 and f.period_ns > 0 and duration % f.period_ns:
            p.add(f"fmu.{f.name}.period", f"{format_duration(f.period_ns)} does not divide scenario.duration")
    by_name = {f.name: f for f in fmus}
    connections = _load_connections(p, data, by_name)
    profiles = _load_profiles(p, data, by_name, connections)
    events = _load_events(p, data, by_name, duration, connections)
    errormodel = _table(p, data, "errormodel")

    if p.items:
        raise ConfigErrors(p.items)
    assert step is not None and duration is not None and interval is not None
    return Scenario(
        name=name,
        description=description,
        source_path=source,
        duration_ns=duration,
        step_ns=step,
        output_interval_ns=interval,
        seed=int(seed),
        fmus=tuple(fmus),
        connections=tuple(connections),
        profiles=tuple(profiles),
        events=tuple(events),
        drift_window_ns=drift_window if drift_window is not None else 300 * NS_PER_S,
        errormodel=MappingProxyType({k: Parameter(v) for k, v in errormodel.items()}),
    )


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``over`` on top of ``base``: tables merge key by key, anything else is replaced.

    An input's profile table is replaced whole: a sine does not inherit a constant's value.
    """
    out = dict(base)
    for k, v in over.items():
        mergeable = isinstance(v, dict) and isinstance(out.get(k), dict) and "profile" not in v
        out[k] = _merge(out[k], v) if mergeable else v
    return out


def read_scenario_data(path: Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A scenario file's data with its ``extends`` chain resolved.

    ``extends = "base/tester-system.toml"`` (relative to the file) takes that file as the
    starting point; the file's own tables merge over it key by key. A base's
    ``parameter_files`` stay relative to the base.
    """
    data = _read_toml(path, str(path))
    parent = data.pop("extends", None)
    if parent is None:
        return data
    if not isinstance(parent, str):
        raise ConfigError(f"expected a file name, got {parent!r}", source=str(path), key="extends")
    base_path = (path.resolve().parent / parent).resolve()
    if base_path in _seen or base_path == path.resolve():
        raise ConfigError(f"circular extends through {base_path.name}", source=str(path), key="extends")
    base = read_scenario_data(base_path, (*_seen, path.resolve()))
    # a base's parameter files are named relative to the base's folder
    for spec in base.get("fmu", {}).values():
        if isinstance(spec, dict) and isinstance(spec.get("parameter_files"), list):
            spec["parameter_files"] = [
                str((base_path.parent / f).resolve()) if isinstance(f, str) else f
                for f in spec["parameter_files"]
            ]
    return _merge(base, data)


def load_scenario(path: str | Path, overrides: Sequence[str] = ()) -> Scenario:
    """Read (resolving ``extends``), override (``--set``) and check a scenario file."""
    path = Path(path)
    data = read_scenario_data(path)
    apply_overrides(data, overrides, f"{path}: --set")
    return load_scenario_data(data, str(path), path.resolve().parent)


def default_scenario_path() -> Path:
    """The paper's thermal experiment: ``scenarios/li2017-thermal-experiment.toml``."""
    return scenarios_dir() / "li2017-thermal-experiment.toml"


def scenarios_dir() -> Path:
    """The ``scenarios/`` folder of the source tree this package runs from."""
    from twin.fmu.build import fmu_sources_dir

    return fmu_sources_dir().parent / "scenarios"
