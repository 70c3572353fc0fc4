"""The ``[scenario]`` table: name, timing (start, step, duration, output interval), seed.

The scenario's clock starts at 0 and ends at ``duration``; a run may begin later, at ``start``
(``twin run --start-time``), on the grid of the step and the output interval, and then covers
``start`` to ``duration``. The output interval is the step unless given.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.config.durations import MAX_DURATION_NS, MAX_TICKS, format_duration
from twin.config.reader import Problems, finite_number, table, unsafe_name
from twin.config.spec import NS_PER_S

_SCENARIO_KEYS = {
    "name",
    "description",
    "duration",
    "start",
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
    #: when the run begins (the FMUs' start time): 0, or later within the scenario's clock
    start_ns: int = 0


def _check_duration(p: Problems, duration: int, step: int | None) -> None:
    if duration <= 0:
        p.add("scenario.duration", "must be positive")
    elif duration > MAX_DURATION_NS:
        p.add("scenario.duration", f"{format_duration(duration)} is absurdly long (at most 366 d)")
    elif step and duration % step:
        p.add("scenario.duration", f"{format_duration(duration)} is not a multiple of scenario.step")
    elif step and duration < 2 * step:
        p.add("scenario.duration", "too short: needs at least two steps")
    elif step and duration // step > MAX_TICKS:
        p.add(
            "scenario.step",
            f"{format_duration(step)} over {format_duration(duration)} is {duration // step:.3g} steps, "
            f"more than the {MAX_TICKS:.0e} a run may take: a longer step (or a shorter run)",
        )


def _check_interval(p: Problems, interval: int, step: int | None) -> None:
    if interval <= 0:
        p.add("scenario.output_interval", "must be positive")
    elif step and interval % step:
        p.add("scenario.output_interval", f"{format_duration(interval)} is not a multiple of scenario.step")


def _check_start(p: Problems, start: int, step: int | None, duration: int | None) -> bool:
    """A run that begins later begins on the step's grid, at least two steps before the end."""
    n_problems = len(p.items)
    if start < 0:
        p.add("scenario.start", "must not be negative (the scenario's clock starts at 0)")
    elif step and start % step:
        p.add("scenario.start", f"{format_duration(start)} is not a multiple of scenario.step")
    elif duration is not None and start >= duration:
        p.add(
            "scenario.start",
            f"{format_duration(start)} is not before scenario.duration ({format_duration(duration)}), the end",
        )
    elif duration is not None and step and duration - start < 2 * step:
        p.add("scenario.start", f"{format_duration(start)} leaves less than two steps before the end")
    return len(p.items) == n_problems


def _timing(p: Problems, sc: Mapping[str, Any]) -> tuple[int | None, int | None, int | None, int]:
    """(step, duration, output interval, start), each checked alone and against the others."""
    step = p.duration(sc, "step", "scenario.")
    duration = p.duration(sc, "duration", "scenario.")
    interval = p.duration(sc, "output_interval", "scenario.", required=False)
    start = p.duration(sc, "start", "scenario.", required=False) or 0
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
        return None, None, interval, start
    if interval is None and "output_interval" not in sc:
        interval = step  # every step recorded, as fmpy records every communication point
    n_problems = len(p.items)
    if duration is not None:
        _check_duration(p, duration, step)
    if interval is not None:
        _check_interval(p, interval, step)
    if duration is not None and len(p.items) == n_problems:
        _check_window(p, start, step, duration, interval)
    elif start < 0:
        _check_start(p, start, step, None)
    return step, duration, interval, start


def _check_window(p: Problems, start: int, step: int | None, duration: int, interval: int | None) -> None:
    """The run's window, ``start`` to ``duration``: begun on the grids of the step and of the
    output interval (rows are recorded on its grid from 0: a run begun off it would lose its
    first row), and long enough for a row."""
    if start and not _check_start(p, start, step, duration):
        return
    if start and interval and interval > 0 and start % interval:
        p.add(
            "scenario.start",
            f"{format_duration(start)} is not a multiple of scenario.output_interval ({format_duration(interval)})",
        )
    elif interval and interval > 0 and interval > duration - start:
        run = "scenario.duration" if not start else "the run (scenario.start to scenario.duration)"
        p.add("scenario.output_interval", f"is longer than {run}: nothing would be recorded")


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
    step, duration, interval, start = _timing(p, sc)
    drift_window = _drift_window(p, sc)
    seed = _seed(p, sc)
    description = sc.get("description", "")
    if not isinstance(description, str):
        p.add("scenario.description", "expected a string")
        description = ""
    wear_limit = _wear_limit(p, sc)
    return ScenarioTable(name, description, step, duration, interval, seed, drift_window, wear_limit, start)
