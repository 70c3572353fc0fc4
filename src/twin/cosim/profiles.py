"""Time functions that drive FMU inputs: the scenario's profiles and its set/ramp events."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from twin.config.spec import Profile

Signal = Callable[[float], float]


def profile_function(p: Profile) -> Signal:
    """The value of a profile at time ``t`` (s)."""
    q = p.params
    if p.kind == "constant":
        v = q["value"]
        return lambda t: v
    if p.kind == "ramp":
        start, end, dur, delay = q["start"], q["end"], q["duration"], q.get("delay", 0.0)
        return lambda t: start + (end - start) * min(max((t - delay) / dur, 0.0), 1.0)
    if p.kind == "exponential":
        # first-order approach start -> start + rise; with rise_at, scaled so that the full
        # rise is reached exactly at that time (the paper gives the rise after 480 min)
        start, rise, tau = q["start"], q["rise"], q["time_constant"]
        scale = 1.0 / (1.0 - math.exp(-q["rise_at"] / tau)) if "rise_at" in q else 1.0
        return lambda t: start + rise * scale * (1.0 - math.exp(-max(t, 0.0) / tau))
    if p.kind == "sine":
        mean, amp, period, phase = q["mean"], q["amplitude"], q["period"], q.get("phase", 0.0)
        return lambda t: mean + amp * math.sin(2.0 * math.pi * t / period + phase)
    if p.kind == "table":
        times = np.array([a for a, _ in p.table])
        values = np.array([b for _, b in p.table])
        return lambda t: float(np.interp(t, times, values))
    raise ValueError(f"unknown profile kind {p.kind!r}")  # the loader rejects these first


def ramp_from(value0: float, value1: float, t0: float, duration: float) -> Signal:
    """Linear ramp from ``value0`` at ``t0`` to ``value1`` after ``duration``, then constant."""
    return lambda t: value0 + (value1 - value0) * min(max((t - t0) / duration, 0.0), 1.0)
