"""``[[event]]``: at a time, set or ramp an input, bias an output, or make an FMU fail."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from twin.config.durations import format_duration
from twin.config.endpoints import check_range, endpoint
from twin.config.reader import Problems, array_of_tables
from twin.config.spec import Connection, Event, FMUSpec
from twin.fmu.catalog import variables as model_variables

_EVENT_KEYS = {"at", "action", "target", "value", "duration", "fault"}
_EVENT_ACTIONS = {"set", "ramp", "bias", "fault"}
#: fault events: how the FMU fails (its fault_inject input)
FAULTS = {"error": 1.0, "discard": 2.0, "nan": 3.0}


@dataclass(frozen=True)
class _Scope:
    """What every event is checked against."""

    p: Problems
    fmus: Mapping[str, FMUSpec]
    fed: set[str]  # inputs fed by a connection
    duration_ns: int | None
    #: a run that begins later (scenario.start) cannot apply what came before
    start_ns: int = 0

    def when(self, at: int | None, key: str) -> int | None:
        """``at`` if it lies within the run (a problem if it does not), None if unknown."""
        if at is not None and (at < 0 or (self.duration_ns is not None and at >= self.duration_ns)):
            self.p.add(key + ".at", "must lie within the scenario's duration")
            return None
        if at is not None and at < self.start_ns:
            self.p.add(
                key + ".at",
                f"{format_duration(at)} is before scenario.start ({format_duration(self.start_ns)}): a run "
                "that begins later cannot apply it (start at or before it, or remove the event)",
            )
            return None
        return at


def _fault(s: _Scope, raw: Mapping[str, Any], key: str, at: int | None) -> Event | None:
    """A fault: a set event on the instance's fault_inject input."""
    inst, fault = raw.get("target"), raw.get("fault")
    if not isinstance(inst, str) or inst not in s.fmus:
        s.p.add(
            key + ".target",
            f"a fault targets an FMU instance (one of: {', '.join(sorted(s.fmus))}), got {inst!r}",
        )
        return None
    if not isinstance(fault, str) or fault not in FAULTS:
        s.p.add(key + ".fault", f"expected one of {sorted(FAULTS)}, got {fault!r}")
        return None
    model = s.fmus[inst].model
    if "fault_inject" not in model_variables(model):
        s.p.add(key + ".target", f"model {model} has no fault_inject input")
        return None
    at = s.when(at, key)
    return Event(at, "set", f"{inst}.fault_inject", FAULTS[fault], 0) if at is not None else None


def _target_ok(s: _Scope, raw: Mapping[str, Any], key: str, action: str) -> bool:
    """A bias needs an output, set and ramp an input no connection feeds."""
    causality = "output" if action == "bias" else "input"
    if endpoint(s.p, s.fmus, raw.get("target"), key + ".target", causality) is None:
        return False
    if action != "bias" and raw["target"] in s.fed:
        s.p.add(
            key + ".target", f"input {raw['target']!r} is fed by a connection; {action} needs a free input"
        )
        return False
    return True


def _change(s: _Scope, raw: Mapping[str, Any], key: str, at: int | None, action: str) -> Event | None:
    """A set, ramp or bias event."""
    if "fault" in raw:
        s.p.add(key + ".fault", "only a 'fault' action takes a fault")
    target_ok = _target_ok(s, raw, key, action)
    value = s.p.number(raw, "value", key + ".")
    dur = s.p.duration(raw, "duration", key + ".", required=action == "ramp")
    if action == "ramp" and dur is not None and dur <= 0:
        s.p.add(key + ".duration", "a ramp needs a positive duration")
    at = s.when(at, key)
    if value is None or not target_ok:
        return None
    if action != "bias":
        check_range(s.p, s.fmus, raw["target"], [value], key + ".value")
    return Event(at, action, raw["target"], value, dur or 0) if at is not None else None


def load_events(
    p: Problems,
    data: Mapping[str, Any],
    fmus: Mapping[str, FMUSpec],
    duration_ns: int | None,
    connections: Sequence[Connection],
    start_ns: int = 0,
) -> list[Event]:
    """Every event, checked, in time order (none before ``start_ns``, when the run begins)."""
    scope = _Scope(p, fmus, {c.dst for c in connections}, duration_ns, start_ns)
    out: list[Event] = []
    keys: list[str] = []
    for _i, key, raw in array_of_tables(p, data, "event", ""):
        p.unknown_keys(raw, _EVENT_KEYS, key + ".")
        at = p.duration(raw, "at", key + ".")
        action = raw.get("action")
        if not isinstance(action, str) or action not in _EVENT_ACTIONS:
            p.add(
                key + ".action",
                f"unknown action {action!r} (expected one of: {', '.join(sorted(_EVENT_ACTIONS))})",
            )
            continue
        event = _fault(scope, raw, key, at) if action == "fault" else _change(scope, raw, key, at, action)
        if event is not None:
            out.append(event)
            keys.append(key)
    _check_biases(p, fmus, connections, sorted(zip(out, keys, strict=True), key=lambda ek: ek[0].at_ns))
    return sorted(out, key=lambda e: e.at_ns)


def _spans(
    fmus: Mapping[str, FMUSpec], connections: Sequence[Connection], target: str
) -> list[tuple[float, str]]:
    """(width of the declared range, whose) of an output and of every input it feeds: a bias
    wider than one of them moves every value out of that range."""
    out = []
    for ref in [target, *(c.dst for c in connections if c.src == target)]:
        inst, _, var = ref.partition(".")
        v = model_variables(fmus[inst].model).get(var) if inst in fmus else None
        if v is not None and math.isfinite(v.max - v.min):
            out.append((v.max - v.min, ref))
    return out


def _check_biases(
    p: Problems,
    fmus: Mapping[str, FMUSpec],
    connections: Sequence[Connection],
    events: Sequence[tuple[Event, str]],
) -> None:
    """Biases add up on their output; the sum must stay narrower than the output's declared
    range and that of every input the output feeds (the FMU fed would refuse it mid-run)."""
    total: dict[str, float] = {}
    for e, key in events:
        if e.action != "bias":
            continue
        total[e.target] = total.get(e.target, 0.0) + e.value
        for width, ref in _spans(fmus, connections, e.target):
            if abs(total[e.target]) > width:
                p.add(
                    key + ".value",
                    f"a bias of {total[e.target]!r} on {e.target} is wider than the range of {ref} "
                    f"({width!r}): every value would fall outside it",
                )
                return
