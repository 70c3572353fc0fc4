"""The stepping loop: runs a batch of ticks of the plan over the exchange state.

Two implementations behind one small interface, :class:`Stepping` (libcosim's "algorithm"):
the compiled stepper (``twin.cosim.native``, ``loop="fast"``) and
:class:`PythonLoop` here (``loop="python"``), which does the same ticks in plain Python on the
same arrays; a test checks that both give byte-identical signals.

Order within a tick ``k`` at ``t = k * step``: (1) the outputs that become visible at ``k``
are committed, (2) the inputs of the instances due at ``k`` are gathered and set, (3) the row
of an output tick is recorded, (4) the due instances step from ``t`` to ``t + period`` and
their outputs become pending (visible at ``k + period``: Jacobi exchange, zero-order hold).
Scenario events are applied between batches (:mod:`twin.cosim.events`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, Protocol

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.plan import ColumnKind, InputKind, Plan, PlannedInput, PlannedInstance
from twin.cosim.state import Buffers, State, driven_every, driven_row
from twin.errors import ConfigError, FMUError
from twin.fmu.slot import FMUSlot

Loop = Literal["fast", "python"]
LOOPS: tuple[Loop, ...] = ("fast", "python")


class Solver(Protocol):
    """An algebraic loop iterated at its instances' communication points
    (:class:`twin.cosim.loops.LoopSolver`)."""

    instances: tuple[int, ...]
    period_ticks: int

    def solve(self, drow: np.ndarray, t: float, *, exchange: bool) -> int: ...


class Stepping(Protocol):
    """Runs ticks of a plan over its state."""

    def ticks(self, k0: int, k1: int, driven: np.ndarray, rows: np.ndarray) -> None:
        """Run the ticks ``k0`` to ``k1 - 1``.

        ``driven`` holds one row of driven values per tick that reads them
        (:func:`twin.cosim.state.driven_ticks`); each recorded row goes to
        ``rows[counters.rows]`` and counts in ``counters.rows``. Raises
        :class:`~twin.errors.FMUError` when an FMU fails (the state is then at that tick).
        """
        ...


class Gather:
    """Sets the input buffer of one instance from its sources (the switch of ``stepper.c``).

    A connection reads the visible output of its source, a driven input its column of the
    driven row; a delayed input takes the value of the previous exchange, and with
    ``exchange`` (every exchange but initialization, where its source may not be initialized
    yet) keeps its source's visible value for the next one. The inputs are grouped by kind
    once, so an exchange is two short loops and one numpy assignment.
    """

    def __init__(self, inst: PlannedInstance, buffers: Sequence[Buffers]) -> None:
        self.buf = buffers[inst.index]
        by_kind: dict[InputKind, list[tuple[int, PlannedInput]]] = {kind: [] for kind in InputKind}
        for j, i in enumerate(inst.inputs):
            by_kind[i.kind].append((j, i))
        # the source buffers are never reallocated (a restore writes into them): keep them
        self.connected = [(j, buffers[i.src].cur, i.idx) for j, i in by_kind[InputKind.CONNECTION]]
        self.delayed = [(j, buffers[i.src].cur, i.idx) for j, i in by_kind[InputKind.DELAYED]]
        # the few transformed connections, applied after the plain copy (as stepper.c does)
        self.affine = [(j, i.factor, i.offset) for j, i in enumerate(inst.inputs) if _affine(i)]
        self.affine_delayed = [
            (j, f, o) for j, f, o in self.affine if inst.inputs[j].kind == InputKind.DELAYED
        ]
        self.affine_connected = [
            (j, f, o) for j, f, o in self.affine if inst.inputs[j].kind == InputKind.CONNECTION
        ]
        self.driven_at = np.array([j for j, _ in by_kind[InputKind.DRIVEN]], dtype=np.intp)
        self.driven_column = np.array([i.src for _, i in by_kind[InputKind.DRIVEN]], dtype=np.intp)

    def __call__(self, drow: np.ndarray, *, exchange: bool) -> None:
        vals, delay_buf = self.buf.in_port.values, self.buf.delay_buf
        self.connect()
        for j, cur, idx in self.delayed:
            vals[j] = delay_buf[j]
            if exchange:
                delay_buf[j] = cur[idx]
        if exchange:
            for j, f, o in self.affine_delayed:
                delay_buf[j] = delay_buf[j] * f + o
        self.drive(drow)

    def connect(self) -> None:
        """The connected inputs alone: each takes its source's visible value, transformed (what
        an algebraic loop's iteration repeats, :mod:`twin.cosim.loops`)."""
        vals = self.buf.in_port.values
        for j, cur, idx in self.connected:
            vals[j] = cur[idx]
        for j, f, o in self.affine_connected:
            vals[j] = vals[j] * f + o

    def drive(self, drow: np.ndarray) -> None:
        """The driven inputs alone: each takes its column of ``drow``."""
        self.buf.in_port.values[self.driven_at] = drow[self.driven_column]


def _affine(i: PlannedInput) -> bool:
    return i.kind != InputKind.DRIVEN and (i.factor != 1.0 or i.offset != 0.0)


def row_values(plan: Plan, state: State) -> list[float]:
    """The recorded columns now: visible outputs and the driven inputs last set."""
    b = state.buffers
    return [
        b[c.instance].cur[c.idx] if c.kind == ColumnKind.OUTPUT else b[c.instance].in_port.values[c.idx]
        for c in plan.columns
    ]


def non_finite(inst: PlannedInstance, slot: FMUSlot, buf: Buffers, j: int) -> FMUError:
    """The error for an output that is NaN or infinite although the step reported success."""
    value = buf.out_port.values[j]
    return FMUError(
        inst.name,
        "fmi2GetReal",
        slot.time,
        f"output '{inst.outputs[j]}' is {value} after fmi2DoStep returned fmi2OK",
    )


def final_tick(
    plan: Plan, state: State, solvers: Sequence[Solver] = ()
) -> tuple[np.ndarray, np.ndarray] | None:
    """The end of the run, tick ``n_ticks``: its outputs become visible (an algebraic loop's
    solved there too), the driven inputs take their values, and its row (times, rows) is
    returned if it is an output tick. No FMU steps."""
    n = plan.n_ticks
    for i, buf in enumerate(state.buffers):
        if state.pending_at[i] == n:
            buf.commit()
    t_s = n * plan.step_ns / NS_PER_S
    values = state.driven.row(t_s)
    for solver in solvers:
        solver.solve(values, t_s, exchange=False)
    for inst in plan.instances:
        Gather(inst, state.buffers).drive(values)
    if n % plan.out_every:
        return None
    return np.array([t_s]), np.array([row_values(plan, state)]).reshape(1, len(plan.columns))


class _Unit:
    """One instance as the Python loop steps it (``looped``: on an algebraic loop, whose solver
    sets its inputs)."""

    def __init__(self, inst: PlannedInstance, slot: FMUSlot, state: State, looped: bool = False) -> None:
        self.looped = looped
        self.inst = inst
        self.slot = slot
        self.buf = state.buffers[inst.index]
        self.gather = Gather(inst, state.buffers)
        self.period_ticks = inst.period_ticks
        self.h = inst.period_ns / NS_PER_S


class PythonLoop:
    """The ticks in plain Python: the same arithmetic as ``native/stepper.c``, through
    :class:`~twin.fmu.slot.FMUSlot`'s calls (slower; for checking the compiled stepper).

    It also runs the plans with algebraic loops: at a tick where a loop's instances are due,
    its ``solvers`` set their inputs (iterated to convergence) before the other instances
    gather theirs, so those see the loop's converged outputs."""

    def __init__(
        self, plan: Plan, state: State, slots: Sequence[FMUSlot], solvers: Sequence[Solver] = ()
    ) -> None:
        self.plan = plan
        self.state = state
        self.solvers = list(solvers)
        looped = {i for s in self.solvers for i in s.instances}
        self.units = [
            _Unit(inst, slot, state, inst.index in looped)
            for inst, slot in zip(plan.instances, slots, strict=True)
        ]
        self.driven_every = driven_every(plan)

    def ticks(self, k0: int, k1: int, driven: np.ndarray, rows: np.ndarray) -> None:
        plan, c = self.plan, self.state.counters
        step, out_every, n_cols = plan.step_ns, plan.out_every, len(plan.columns)
        for k in range(k0, k1):
            t = k * step / NS_PER_S
            self._commit(k)
            due = [u for u in self.units if k % u.period_ticks == 0]
            drow = driven[driven_row(k, k0, self.driven_every)]
            for solver in self.solvers:
                if k % solver.period_ticks == 0:
                    solver.solve(drow, t, exchange=True)
            for u in due:
                if u.looped:
                    continue
                u.gather(drow, exchange=True)
                u.slot.time = t  # an error in fmi2SetReal names this time
                u.slot.write(u.buf.in_port)
            if k % out_every == 0:
                rows[c.rows, :n_cols] = row_values(plan, self.state)
                c.rows += 1
            for u in due:
                self._step(u, k, t)
            c.macro_steps += 1

    def _commit(self, k: int) -> None:
        pending_at = self.state.pending_at
        for i, u in enumerate(self.units):
            if pending_at[i] == k:
                u.buf.commit()
                pending_at[i] = -1

    def _step(self, u: _Unit, k: int, t: float) -> None:
        u.slot.do_step(t, u.h)
        u.slot.read(u.buf.out_port)
        values = u.buf.out_port.values[: len(u.inst.outputs)]
        if not np.isfinite(values).all():
            u.slot.time = t
            raise non_finite(u.inst, u.slot, u.buf, int(np.flatnonzero(~np.isfinite(values))[0]))
        self.state.pending_at[u.inst.index] = k + u.period_ticks
        self.state.counters.fmu_steps += 1


def check_loop(loop: str) -> Loop:
    """``loop`` if it names a loop; a :class:`~twin.errors.ConfigError` otherwise."""
    if loop not in LOOPS:
        raise ConfigError(f"unknown master loop {loop!r} (expected one of: {', '.join(LOOPS)})", key="loop")
    return loop  # type: ignore[return-value]


__all__ = [
    "LOOPS",
    "Gather",
    "Loop",
    "PythonLoop",
    "Solver",
    "Stepping",
    "check_loop",
    "final_tick",
    "non_finite",
    "row_values",
]
