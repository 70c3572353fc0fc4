"""``[input.<instance>.<variable>]``: profiles (time functions) driving the free inputs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any

from twin.config.durations import parse_duration
from twin.config.endpoints import check_range, endpoint
from twin.config.reader import Problems, finite_number, table
from twin.config.spec import (
    NS_PER_S,
    PROFILE_DURATIONS,
    PROFILE_PARAMS,
    Connection,
    FMUSpec,
    Profile,
    table_times_ok,
)


def _points(p: Problems, pts: Any, key: str) -> tuple[tuple[float, float], ...]:
    """A table profile's ``[[time, value], ...]`` as (seconds, value) pairs; () on a problem."""
    ok = isinstance(pts, list) and len(pts) >= 2 and all(isinstance(q, list) and len(q) == 2 for q in pts)
    if not ok:
        p.add(key, "expected [[time, value], ...] with at least two points")
        return ()
    try:
        times_ns = [parse_duration(q[0]) for q in pts]
    except ValueError as exc:
        p.add(key, str(exc))
        return ()
    values = [q[1] for q in pts]
    if not all(finite_number(v) for v in values):
        p.add(key, "values must be finite numbers")
        return ()
    # compared as exact nanoseconds: two times 1 ns apart may be one float second
    if not table_times_ok(times_ns):
        p.add(key, "times must increase (a time given twice is a jump; never three times)")
        return ()
    return tuple(zip((t / NS_PER_S for t in times_ns), map(float, values), strict=True))


def _seconds(p: Problems, raw: Mapping[str, Any], k: str, key: str) -> float | None:
    """A profile's duration parameter in seconds (only a delay may be zero)."""
    ns = p.duration(raw, k, key + ".")
    if ns is None:
        return None
    if ns <= 0 and k != "delay":
        p.add(f"{key}.{k}", "must be positive")
        return None
    if ns < 0:
        p.add(f"{key}.{k}", "must not be negative")
        return None
    return ns / NS_PER_S


def _values(
    p: Problems, raw: Mapping[str, Any], key: str, kind: str
) -> tuple[dict[str, float], tuple[tuple[float, float], ...]]:
    """(parameters, table points) of a profile of ``kind``."""
    required, optional = PROFILE_PARAMS[kind]
    params: dict[str, float] = {}
    points: tuple[tuple[float, float], ...] = ()
    for k in sorted(required | optional):
        if k not in raw:
            if k in required:
                p.add(f"{key}.{k}", f"missing (needed by the '{kind}' profile)")
        elif k == "points":
            points = _points(p, raw[k], f"{key}.points")
        else:
            v = _seconds(p, raw, k, key) if k in PROFILE_DURATIONS else p.number(raw, k, key + ".")
            if v is not None:
                params[k] = v
    return params, points


def _kind(p: Problems, raw: Mapping[str, Any], key: str) -> str | None:
    kind = raw.get("profile")
    if kind is None:
        p.add(key + ".profile", f"missing (one of: {', '.join(PROFILE_PARAMS)})")
        return None
    if not isinstance(kind, str) or kind not in PROFILE_PARAMS:
        p.add(key + ".profile", f"unknown profile {kind!r} (expected one of: {', '.join(PROFILE_PARAMS)})")
        return None
    return kind


def _profile(
    p: Problems, fmus: Mapping[str, FMUSpec], fed: set[str], target: str, raw: Any
) -> Profile | None:
    """The profile of input ``target``, or None when it has a problem that stops its check."""
    key = f"input.{target}"
    if not isinstance(raw, dict):
        p.add(key, "expected a table with 'profile' and its parameters")
        return None
    if endpoint(p, fmus, target, key, "input") is None:
        return None
    if target in fed:
        p.add(key, f"input {target!r} is fed by a connection; it cannot also have a profile")
    kind = _kind(p, raw, key)
    if kind is None:
        return None
    required, optional = PROFILE_PARAMS[kind]
    p.unknown_keys(raw, required | optional | {"profile", "source"}, key + ".")
    params, points = _values(p, raw, key, kind)
    profile = Profile(target, kind, MappingProxyType(params), points, str(raw.get("source", "")))
    if required <= set(params) | ({"points"} if points else set()):
        check_range(p, fmus, target, profile.extremes(), key)
    return profile


def load_profiles(
    p: Problems, data: Mapping[str, Any], fmus: Mapping[str, FMUSpec], connections: Sequence[Connection]
) -> list[Profile]:
    """Every input profile, checked: a free Real input, known parameters, values in range."""
    out = []
    fed = {c.dst for c in connections}
    for inst, per_var in table(p, data, "input").items():
        if not isinstance(per_var, dict):
            p.add(f"input.{inst}", "expected a table [input.<instance>.<variable>]")
            continue
        for var, raw in per_var.items():
            profile = _profile(p, fmus, fed, f"{inst}.{var}", raw)
            if profile is not None:
                out.append(profile)
    return out
