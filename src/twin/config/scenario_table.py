"""The ``[scenario]`` table: name, timing (step, duration, output interval), seed."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.config.durations import MAX_DURATION_NS, format_duration
from twin.config.reader import Problems, finite_number, table, unsafe_name
from twin.config.spec import NS_PER_S

_SCENARIO_KEYS = {
    "name",
    "description",
    "duration",
    "step",
    "output_interval",
    "seed",
    "drift_window",
    "wear_limit_mm",
}


@dataclass(frozen=True)
class ScenarioTable:
    """The checked ``[scenario]`` table; a time is None when it has a problem."""

    name: str
    description: str
    step_ns: int | None
    duration_ns: int | None
    output_interval_ns: int | None
    seed: int
    drift_window_ns: int
    wear_limit_mm: float | None = None


def _check_duration(p: Problems, duration: int, step: int | None) -> None:
    if duration <= 0:
        p.add("scenario.duration", "must be positive")
    elif duration > MAX_DURATION_NS:
        p.add("scenario.duration", f"{format_duration(duration)} is absurdly long (at most 366 d)")
    elif step and duration % step:
        p.add("scenario.duration", f"{format_duration(duration)} is not a multiple of scenario.step")
    elif step and duration < 2 * step:
        p.add("scenario.duration", "too short: needs at least two steps")


def _check_interval(p: Problems, interval: int, step: int | None) -> None:
    if interval <= 0:
        p.add("scenario.output_interval", "must be positive")
    elif step and interval % step:
        p.add("scenario.output_interval", f"{format_duration(interval)} is not a multiple of scenario.step")


def _timing(p: Problems, sc: Mapping[str, Any]) -> tuple[int | None, int | None, int | None]:
    """(step, duration, output interval), each checked alone and against the others."""
    step = p.duration(sc, "step", "scenario.")
    duration = p.duration(sc, "duration", "scenario.")
    interval = p.duration(sc, "output_interval", "scenario.")
    if step is not None and step <= 0:
        p.add("scenario.step", "must be positive")
        step = None
    elif step is not None and duration is not None and 0 < duration < step:
        # one line naming both: the other times would otherwise all be "not a multiple" of the
        # step or "do not divide" the duration too
        p.add(
            "scenario.duration",
            f"{format_duration(duration)} is shorter than scenario.step ({format_duration(step)})",
        )
        if interval is not None and interval <= 0:
            p.add("scenario.output_interval", "must be positive")
        return None, None, interval
    n_problems = len(p.items)
    if duration is not None:
        _check_duration(p, duration, step)
    if interval is not None:
        _check_interval(p, interval, step)
    duration_ok = duration is not None and len(p.items) == n_problems
    if duration_ok and interval and interval > 0 and interval > duration:
        p.add("scenario.output_interval", "is longer than scenario.duration: nothing would be recorded")
    return step, duration, interval


def _drift_window(p: Problems, sc: Mapping[str, Any]) -> int:
    # longer than the run is allowed: the short calibration runs inherit the base's 5 min, and
    # the drift is then taken over the whole run
    drift_window = p.duration(sc, "drift_window", "scenario.", required=False)
    if drift_window is not None and drift_window <= 0:
        p.add("scenario.drift_window", "must be positive")
    return drift_window if drift_window is not None else 300 * NS_PER_S


def _seed(p: Problems, sc: Mapping[str, Any]) -> int:
    seed = sc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
        p.add("scenario.seed", f"expected an integer in [0, 2^31), got {seed!r}")
        return 0
    return int(seed)


def _wear_limit(p: Problems, sc: Mapping[str, Any]) -> float | None:
    """An endurance test's wear limit (mm): drawn in wear.png; None when not given."""
    if "wear_limit_mm" not in sc:
        return None
    value = sc["wear_limit_mm"]
    if isinstance(value, bool) or not finite_number(value) or not 0 < value <= 10:
        p.add("scenario.wear_limit_mm", f"expected a wear depth in mm, > 0 and <= 10, got {value!r}")
        return None
    return float(value)


def load_scenario_table(p: Problems, data: Mapping[str, Any], source: str) -> ScenarioTable:
    """The ``[scenario]`` table of ``data`` (problems go to ``p``)."""
    sc = table(p, data, "scenario")
    if "scenario" not in data:
        p.add("scenario", "missing [scenario] table")
    p.unknown_keys(sc, _SCENARIO_KEYS, "scenario.")
    name = sc.get("name", Path(source).stem)
    why = unsafe_name(name)
    if why is not None:  # the name becomes the run folder's: runs/<name>
        p.add("scenario.name", why if "name" in sc else f"{why} (the file's name; set scenario.name)")
        name = "scenario"
    step, duration, interval = _timing(p, sc)
    drift_window = _drift_window(p, sc)
    seed = _seed(p, sc)
    description = sc.get("description", "")
    if not isinstance(description, str):
        p.add("scenario.description", "expected a string")
        description = ""
    wear_limit = _wear_limit(p, sc)
    return ScenarioTable(name, description, step, duration, interval, seed, drift_window, wear_limit)
