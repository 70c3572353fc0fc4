"""The exchange state of a run: every value that changes while it runs, in one place.

The loops (Python and compiled), the scenario events and the checkpoint all work on this one
:class:`State`. Its buffers are numpy arrays that the compiled stepper reads and writes
through pointers (see :mod:`twin.cosim.native`), so the state is never copied between the two
sides; the input and output buffers are the :class:`~twin.fmu.slot.RealPort` values the FMI
calls use directly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.config.profiles import Signal, constant, profile_function, ramp_from
from twin.config.spec import NS_PER_S, Profile
from twin.cosim.layout import TwinCounters
from twin.cosim.plan import DrivenSpec, InputKind, Plan, PlannedInstance, exact_key
from twin.fmu.slot import RealPort


@dataclass
class Buffers:
    """One instance's exchange buffers (every array has at least one element, for C)."""

    in_port: RealPort  # values: the inputs last set
    out_port: RealPort  # values: the outputs of the last step, pending until they become visible
    delay_buf: np.ndarray  # the value each delayed input takes at its next exchange
    raw: np.ndarray  # the visible outputs without their bias
    cur: np.ndarray  # the visible outputs: raw + bias
    bias: np.ndarray  # bias events added to each output

    @classmethod
    def of(cls, inst: PlannedInstance) -> Buffers:
        in_port = RealPort([i.vr for i in inst.inputs])
        in_port.values[: len(inst.inputs)] = [i.initial for i in inst.inputs]
        n_out = max(len(inst.outputs), 1)
        return cls(
            in_port=in_port,
            out_port=RealPort(inst.out_vrs),
            delay_buf=np.array(
                [i.initial if i.kind == InputKind.DELAYED else 0.0 for i in inst.inputs] or [0.0]
            ),
            raw=np.zeros(n_out),
            cur=np.zeros(n_out),
            bias=np.zeros(n_out),
        )

    def commit(self) -> None:
        """The pending outputs become the visible ones (their bias added)."""
        n = self.out_port.n
        self.raw[:n] = self.out_port.values[:n]
        np.add(self.raw, self.bias, out=self.cur)


class Driven:
    """The functions of time driving the driven inputs, one per column, with the data that
    rebuilds each (a checkpoint keeps the data, not the function)."""

    def __init__(self, profiles: Sequence[Profile], specs: Sequence[DrivenSpec]) -> None:
        self._profiles = profiles
        self.specs: list[DrivenSpec] = []
        self.functions: list[Signal] = []
        for spec in specs:
            self.specs.append(tuple(spec))
            self.functions.append(self._function(tuple(spec)))

    def _function(self, spec: DrivenSpec) -> Signal:
        if spec[0] == "constant":
            return constant(spec[1])
        if spec[0] == "profile":
            return profile_function(self._profiles[int(spec[1])])
        return ramp_from(*map(float, spec[1:]))

    def set(self, column: int, spec: DrivenSpec) -> None:
        """Drive ``column`` by ``spec`` from now on."""
        self.specs[column] = tuple(spec)
        self.functions[column] = self._function(tuple(spec))

    def __len__(self) -> int:
        return len(self.functions)

    def column_keys(self) -> list[object]:
        """Per column, a key two columns share only when they give the same values at every
        tick: a profile's column by the very profile (the object's id, good while it is alive: a
        Monte Carlo's samples share their tester's load and drive profiles, an updated sample
        its prior sample's room; equal copies are not recognized), any other by its spec's
        exact numbers (:func:`~twin.cosim.plan.exact_key`: 0.0 is not -0.0)."""
        return [
            ("profile", id(self._profiles[int(spec[1])])) if spec[0] == "profile" else exact_key(spec)
            for spec in self.specs
        ]

    def matrix(self, k0: int, k1: int, step_ns: int, every: int) -> np.ndarray:
        """The driven values from tick ``k0`` to ``k1 - 1`` at the ticks that read them
        (:func:`driven_ticks`), one row per such tick."""
        return self.at_ticks(driven_ticks(k0, k1, every), step_ns)

    def at_ticks(self, ticks: np.ndarray, step_ns: int) -> np.ndarray:
        """The driven values at the ticks ``ticks`` (int64), one row per tick."""
        t = ticks * step_ns / NS_PER_S
        out = np.empty((len(ticks), max(len(self.functions), 1)))
        for d, fn in enumerate(self.functions):
            out[:, d] = fn(t)
        return out

    def row(self, t_s: float) -> np.ndarray:
        """The driven values at the time ``t_s`` (s)."""
        t = np.array([t_s])
        return np.array([fn(t)[0] for fn in self.functions], dtype=np.float64)


def driven_every(plan: Plan) -> int:
    """The ticks between two that read the driven inputs: an instance reads its driven inputs
    at its own exchanges only, the multiples of its period, so the greatest common divisor of
    the periods of the instances with one (0: none has). The paper replay's FMUs exchange every
    tenth tick: a matrix of every tick's values would be nine tenths rows nobody reads."""
    periods = [i.period_ticks for i in plan.instances if any(p.kind == InputKind.DRIVEN for p in i.inputs)]
    return math.gcd(*periods) if periods else 0


def driven_ticks(k0: int, k1: int, every: int) -> np.ndarray:
    """The ticks from ``k0`` to ``k1 - 1`` that read the driven inputs: the multiples of
    ``every`` (:func:`driven_every`; 0: none, and one row for the loops' sake)."""
    if every <= 0:
        return np.array([k0], dtype=np.int64)
    first = -(-k0 // every) * every
    return np.arange(first, max(k1, first + 1), every, dtype=np.int64)


def driven_row(k: int, k0: int, every: int) -> int:
    """The row of tick ``k``'s driven values in the matrix of a batch from ``k0``
    (:func:`driven_ticks`); a tick that reads none gets the row before it (nothing reads it)."""
    if every <= 0:
        return 0
    return max(0, (k - -(-k0 // every) * every) // every)


@dataclass
class State:
    """Everything a run changes: buffers, visibility ticks, counters, driven inputs."""

    buffers: list[Buffers]
    #: per instance, the tick its pending outputs become visible (-1: nothing pending)
    pending_at: np.ndarray
    counters: Any  # TwinCounters, shared with the compiled stepper
    driven: Driven
    #: how many of the plan's events have been applied
    events_applied: int = 0


def make_state(plan: Plan) -> State:
    """The state before initialization: start values, delays' initial values, no outputs yet."""
    counters = TwinCounters()
    counters.fail_slot = -1
    return State(
        buffers=[Buffers.of(inst) for inst in plan.instances],
        pending_at=np.full(len(plan.instances), -1, dtype=np.int64),
        counters=counters,
        driven=Driven(plan.scenario.profiles, plan.driven),
    )


__all__ = ["Buffers", "Driven", "State", "driven_every", "driven_row", "driven_ticks", "make_state"]
