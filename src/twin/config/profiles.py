"""Time functions that drive FMU inputs: the scenario's profiles and its set/ramp events.

Each function takes an array of times (s) and returns the values, so the master evaluates a
whole batch of ticks with one numpy call.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from twin.config.spec import Profile

Signal = Callable[[np.ndarray], np.ndarray]


def constant(value: float) -> Signal:
    v = float(value)
    return lambda t: np.full(np.shape(t), v)


def profile_function(p: Profile) -> Signal:
    """The values of a profile at the times ``t`` (s)."""
    q = p.params
    if p.kind == "constant":
        return constant(q["value"])
    if p.kind == "ramp":
        start, end, dur, delay = q["start"], q["end"], q["duration"], q.get("delay", 0.0)
        return lambda t: start + (end - start) * np.clip((t - delay) / dur, 0.0, 1.0)
    if p.kind == "exponential":
        # first-order approach start -> start + rise; with rise_at, scaled so that the full
        # rise is reached exactly at that time (the paper gives the rise after 480 min)
        start, rise, tau = q["start"], q["rise"], q["time_constant"]
        scale = 1.0 / -math.expm1(-q["rise_at"] / tau) if "rise_at" in q else 1.0
        return lambda t: start + rise * scale * -np.expm1(-np.maximum(t, 0.0) / tau)
    if p.kind == "sine":
        mean, amp, period, phase = q["mean"], q["amplitude"], q["period"], q.get("phase", 0.0)
        return lambda t: mean + amp * np.sin(2.0 * np.pi * t / period + phase)
    if p.kind == "table":
        times = np.array([a for a, _ in p.table])
        values = np.array([b for _, b in p.table])
        return lambda t: np.interp(t, times, values)
    raise ValueError(f"unknown profile kind {p.kind!r}")  # the loader rejects these first


def ramp_from(value0: float, value1: float, t0: float, duration: float) -> Signal:
    """Linear ramp from ``value0`` at ``t0`` to ``value1`` after ``duration``, then constant."""
    return lambda t: value0 + (value1 - value0) * np.clip((t - t0) / duration, 0.0, 1.0)
