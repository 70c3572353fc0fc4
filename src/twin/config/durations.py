"""Durations in scenario files: exact integer nanoseconds from ``"480 min"`` or ``0.1``."""

from __future__ import annotations

import math
import re
from fractions import Fraction
from typing import Any

#: nanoseconds per second: every time of the twin is an integer number of nanoseconds
NS_PER_S = 1_000_000_000

#: longest run accepted: a year of simulated time
MAX_DURATION_NS = 366 * 24 * 3600 * NS_PER_S
#: most master steps a run may take (scenario.duration / scenario.step): a year at 0.1 s is
#: 3.2e8, the shipped scenarios take at most 1.5e6. The bound is on the count, not the step,
#: so a short run may step finely (an FMU of fast dynamics); but a typo's 1 ns step over
#: 8 hours would be 2.9e13 ticks, days of stepping and terabytes of signals.csv, not a run
MAX_TICKS = 10**9

UNITS_NS = {
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


def _number_of_seconds(value: int | float) -> Fraction:
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"expected a finite duration, got {value!r}")
    return Fraction(repr(float(value)) if isinstance(value, float) else value) * NS_PER_S


#: a duration's number has at most this many characters ("28800.000000001" has 15): longer
#: ones are typos or attacks, and an exact Fraction of thousands of digits hits Python's
#: int-str limit (ValueError deep inside) or takes seconds
_MAX_DIGITS = 40


def _text(value: str) -> Fraction:
    if len(value.strip()) > _MAX_DIGITS + 4:
        raise ValueError(f"a duration of {len(value)} characters: at most {_MAX_DIGITS} digits and a unit")
    m = _DURATION_RE.match(value)
    if not m or m.group(2) not in UNITS_NS:
        raise ValueError(
            f"expected a duration like '480 min' or '0.1 s' (units {', '.join(UNITS_NS)}), got {value!r}"
        )
    # a quick float look first: an exact Fraction of '1e10000000' takes seconds to build
    if not math.isfinite(float(m.group(1))) or float(m.group(1)) * UNITS_NS[m.group(2)] > 2 * _ABSURD_NS:
        raise ValueError(f"{value!r} is absurdly long (more than 1000 years)")
    return Fraction(m.group(1)) * UNITS_NS[m.group(2)]


def parse_duration(value: Any) -> int:
    """A duration as integer nanoseconds: a number of seconds or a string like ``"480 min"``.

    Exact (rational arithmetic), so ``"0.1 s"`` is 100_000_000 ns, never 99_999_999.
    Raises ``ValueError`` with a short reason.
    """
    if isinstance(value, bool):
        raise ValueError(f"expected a duration, got {value!r}")
    if isinstance(value, int | float):
        ns = _number_of_seconds(value)
    elif isinstance(value, str):
        ns = _text(value)
    else:
        raise ValueError(f"expected a duration, got {type(value).__name__}")
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
        if ns % UNITS_NS[unit] == 0:
            return f"{ns // UNITS_NS[unit]} {unit}"
    return f"{ns} ns"
