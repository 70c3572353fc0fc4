"""A run's experiment as a co-simulation engineer sets it on the command line, in fmpy's and
cosim-cli's words: ``--start-time``, ``--stop-time``, ``--step-size``, ``--output-interval``,
``--input-file``.

Each time is a ``[scenario]`` value of the scenario, set before the scenario is checked (as
``--set`` sets one, so every check of a file's value is made of it, and a file without a step,
such as an SSP archive without libcosim's annotation, takes the one given here):

- ``--start-time T``: ``start``, the FMUs' start time and the master's first tick;
- ``--stop-time T``: ``duration``, the end (the scenario's clock starts at 0);
- ``--step-size T``: ``step``, the master's tick (an FMU without a ``period`` steps at it);
- ``--output-interval T``: ``output_interval``, how often a row is recorded.

A time is a number of seconds (``10``, ``0.1``, ``1e-3``, as fmpy takes it) or a duration with
its unit (``"10 min"``, ``"0.1 s"``), exact to the nanosecond. The input file
(:mod:`twin.config.input_file`) then drives the inputs it names with tables, replacing what
drove them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin.config.durations import format_duration, parse_duration
from twin.errors import ConfigError, ConfigErrors

if TYPE_CHECKING:
    from twin.config.spec import Scenario

__all__ = ["FLAGS", "Experiment", "parse_time"]

#: each time of the experiment: (its flag, the [scenario] key it sets)
FLAGS: Mapping[str, tuple[str, str]] = {
    "start": ("--start-time", "start"),
    "stop": ("--stop-time", "duration"),
    "step": ("--step-size", "step"),
    "output_interval": ("--output-interval", "output_interval"),
}


def parse_time(text: str, flag: str) -> int:
    """A flag's time as nanoseconds: plain seconds (``"10"``, ``"0.1"``, ``"1e-3"``) or a
    duration with its unit (``"10 min"``); not negative. One :class:`ConfigError` naming the
    flag otherwise."""
    try:
        seconds = float(text)
    except ValueError:
        seconds = None
    try:
        if seconds is None:
            ns = parse_duration(text)
        elif not math.isfinite(seconds):
            raise ValueError(f"expected a finite time, got {text!r}")
        else:
            ns = parse_duration(seconds)
    except ValueError as exc:
        raise ConfigError(str(exc), source=flag) from None
    if ns < 0:
        raise ConfigError(
            f"{text!r}: a time must not be negative (the twin's clock starts at 0)", source=flag
        )
    return ns


@dataclass(frozen=True)
class Experiment:
    """The command line's times (as typed, None: the scenario's) and input file (a path, None:
    none). A value: ``run.json`` keeps it (:meth:`to_json`), so ``twin resume`` runs the same
    experiment."""

    start: str | None = None
    stop: str | None = None
    step: str | None = None
    output_interval: str | None = None
    input_file: str | None = None

    def times(self) -> dict[str, int]:
        """The times given, by ``[scenario]`` key, in ns; each checked alone and stop after
        start (every problem at once, one line each naming its flag)."""
        problems: list[ConfigError] = []
        out: dict[str, int] = {}
        for name, (flag, key) in FLAGS.items():
            text = getattr(self, name)
            if text is None:
                continue
            try:
                ns = parse_time(text, flag)
            except ConfigError as exc:
                problems.append(exc)
                continue
            if ns == 0 and name != "start":
                problems.append(ConfigError(f"{text!r}: must be positive", source=flag))
                continue
            out[key] = ns
        if "start" in out and "duration" in out and out["duration"] <= out["start"]:
            problems.append(
                ConfigError(
                    f"{format_duration(out['duration'])} is not after --start-time "
                    f"({format_duration(out['start'])})",
                    source="--stop-time",
                )
            )
        if problems:
            raise problems[0] if len(problems) == 1 else ConfigErrors(problems)
        return out

    def set_times(self, data: dict[str, Any]) -> None:
        """Set the times given in a scenario's data (before it is checked), as ``--set`` would:
        exact nanoseconds, so the loader's checks (multiples of the step, events within the
        run) are made of them and name the ``[scenario]`` key."""
        times = self.times()
        if not times:
            return
        table = data.get("scenario")
        if not isinstance(table, dict):
            table = data["scenario"] = {}  # the loader says what else it lacks
        for key, ns in times.items():
            table[key] = f"{ns} ns"

    def drive(self, scenario: Scenario) -> Scenario:
        """``scenario`` with the inputs the input file names driven by its tables."""
        if self.input_file is None:
            return scenario
        from twin.config.input_file import drive_from_file

        return drive_from_file(scenario, Path(self.input_file))

    def to_json(self) -> dict[str, str]:
        """What was given, for ``run.json`` (the input file's path absolute)."""
        data = {k: v for k, v in asdict(self).items() if v is not None}
        if self.input_file is not None:
            data["input_file"] = str(Path(self.input_file).resolve())
        return data

    @classmethod
    def from_json(cls, data: Any, source: str) -> Experiment:
        """The experiment ``run.json`` keeps (an object of strings); one line when malformed."""
        if data is None:
            return cls()
        names = {f.name for f in fields(cls)}
        if not isinstance(data, dict) or not all(k in names and isinstance(v, str) for k, v in data.items()):
            raise ConfigError(
                f"malformed: expected an object of strings with keys from {sorted(names)}",
                source=source,
                key="experiment",
            )
        return cls(**data)
