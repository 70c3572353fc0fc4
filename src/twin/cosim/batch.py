"""Runs of one system stepped together by the compiled stepper: a Monte Carlo's samples.

A Monte Carlo's samples are one scenario with other parameter values, seeds and driven
profiles: the same instances, connections, periods and recorded columns (one
:func:`structure`). Run one by one, every sample pays the master's Python around its FMU work
(simpy's clock, a profile matrix and a row buffer per batch of ticks, the recorder) for a few
milliseconds of stepping. Stepped together, the copies' instances are one array of slots for
the stepper's one call per batch of ticks: copy ``c``'s instance ``i`` is slot ``c * M + i``,
its connections read the slots of its own copy and its driven inputs the columns of its own
copy. The copies share nothing and each one's FMUs are called in the same order with the same
values as alone, so every copy's rows are bit for bit those of its run alone
(tests/cosim/test_batch.py).

What a batch does not do, it refuses (:func:`unbatchable`): scenario events, algebraic loops
(the Python loop's). A copy whose FMUs fail in their set-up or while stepping
is not run on: the caller runs it alone (:attr:`BatchRuns.alone`), where the master reports
the failure as it would anyway, with everything recorded up to it.
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.instances import close_slots, fmu_files, initialize, open_slots
from twin.cosim.layout import Status, TwinColumn, TwinCounters, TwinSlot, entry
from twin.cosim.master import RunResult
from twin.cosim.native import NativeLoop, stepper
from twin.cosim.plan import BATCH_TICKS, InputKind, Plan
from twin.cosim.state import State, driven_every, driven_ticks, make_state
from twin.cosim.stepping import final_tick
from twin.errors import RunError
from twin.fmu.pool import SlotPool
from twin.fmu.slot import FMUSlot
from twin.signals.table import SignalTable

__all__ = ["Batch", "BatchRuns", "run_batch", "structure", "unbatchable"]


def structure(plan: Plan) -> tuple[object, ...]:
    """What runs stepped together must share: the clock, every instance's model, period,
    inputs' sources and outputs, the driven columns' count and the recorded columns."""
    instances = tuple(
        (i.name, i.model, i.period_ticks, i.outputs, tuple((p.kind, p.src, p.idx) for p in i.inputs))
        for i in plan.instances
    )
    columns = tuple((c.instance, c.kind, c.idx, c.meta.name) for c in plan.columns)
    sc = plan.scenario
    return (
        sc.step_ns,
        sc.start_ns,
        sc.duration_ns,
        sc.output_interval_ns,
        len(plan.driven),
        instances,
        columns,
    )


def unbatchable(plan: Plan) -> str | None:
    """Why ``plan`` cannot be stepped with others (None: it can)."""
    if plan.events:
        return "it has scenario events (applied between batches of ticks, per run)"
    if plan.loops:
        return "it has algebraic loops (the Python loop iterates them)"
    return None


@dataclass
class BatchRuns:
    """The results of the copies that ran (by their index in the batch) and the indices of
    those left to run alone (their set-up or a step failed)."""

    results: dict[int, RunResult] = field(default_factory=dict)
    alone: list[int] = field(default_factory=list)


@dataclass
class _Copy:
    index: int
    plan: Plan
    state: State
    slots: list[FMUSlot]
    loop: NativeLoop
    #: after the run: the rows of every copy and this copy's place among them, and its
    #: macro steps and FMU steps
    rows: tuple[_Rows, int] | None = None
    counters: tuple[int, int] = (0, 0)


class Batch:
    """Runs of ``plans`` (one :func:`structure`, none :func:`unbatchable`) stepped together, in
    three parts so that a caller may step one batch while it works on another:
    :meth:`open` loads and initializes every copy (Python), :meth:`step` runs every tick (the
    compiled stepper: the interpreter's lock is released while it runs), :meth:`results` gives
    each completed copy's result with the ``keep`` columns of every row. :meth:`close` gives
    the instances back to ``pool`` (a pool that keeps as many idle instances per FMU as a batch
    has copies reuses them all); a batch is a context manager that closes."""

    def __init__(self, plans: Sequence[Plan], keep: Collection[str], pool: SlotPool | None = None) -> None:
        if plans:
            first = structure(plans[0])
            for plan in plans:
                why = unbatchable(plan)
                if why is not None or structure(plan) != first:
                    raise ValueError(
                        f"plan of {plan.scenario.name!r} cannot join the batch: {why or 'another structure'}"
                    )
        self.plans, self.pool = list(plans), pool
        self.kept = [j for j, c in enumerate(plans[0].columns) if c.meta.name in keep] if plans else []
        self.copies: list[_Copy] = []
        self.alone: list[int] = []
        self.setup_s = self.step_s = 0.0
        self._attempted = False
        self._failed: int | None = None  # the copy whose FMU failed in the last attempt
        self._files: dict[str, Path] | None = None  # each model's .fmu (found at open)

    def open(self) -> Batch:
        """Load and initialize every copy; a copy an FMU refuses goes to :attr:`alone`."""
        start = time.perf_counter()
        if self.plans:
            # the copies share their models (structure): each file is found once for them all
            try:
                self._files = fmu_files(self.plans[0])
            except RunError:
                self._files = None  # each copy finds it again, fails and runs alone (its error told)
        for index, plan in enumerate(self.plans):
            copy = _open(index, plan, self.pool, self._files)
            if copy is None:
                self.alone.append(index)
            else:
                self.copies.append(copy)
        self.setup_s = time.perf_counter() - start
        return self

    def step(self) -> None:
        """Every tick of every copy: one attempt (:meth:`attempt`, the part another thread may
        run), then, while a copy's FMU failed, that copy goes to :attr:`alone` and the others
        start again without it (its instances cannot be rewound to the tick the batch stopped
        at; a failure is rare). The retries open instances: in the thread that owns the pool."""
        if not self._attempted:
            self.attempt()
        while self._failed is not None:
            failed, self._failed = self._failed, None
            self.alone.append(self.copies[failed].index)
            for c in self.copies:
                close_slots(c.slots)
                c.slots = []
            reopened = []
            for c in (c for i, c in enumerate(self.copies) if i != failed):
                again = _open(c.index, c.plan, self.pool, self._files)
                if again is None:
                    self.alone.append(c.index)
                else:
                    reopened.append(again)
            self.copies = reopened
            self.attempt()

    def attempt(self) -> None:
        """Step every copy to the end once, the compiled stepper's ticks and nothing of the
        pool's (so a thread of its own may run it); a copy whose FMU failed is noted for
        :meth:`step`."""
        start = time.perf_counter()
        self._attempted = True
        self._failed = _step(self.copies, self.kept) if self.copies else None
        self.step_s += time.perf_counter() - start

    def results(self) -> BatchRuns:
        """The completed copies' results and the copies left to run alone (after :meth:`step`)."""
        n = max(len(self.plans), 1)
        out = BatchRuns(alone=sorted(self.alone))
        for copy in self.copies:
            out.results[copy.index] = _result(
                copy, self.kept, (self.setup_s + self.step_s) / n, self.setup_s / n
            )
        return out

    def close(self) -> None:
        """Give every copy's instances back to the pool (idempotent)."""
        for copy in self.copies:
            close_slots(copy.slots, self.pool)
            copy.slots = []

    def __enter__(self) -> Batch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_batch(plans: Sequence[Plan], keep: Collection[str], pool: SlotPool | None = None) -> BatchRuns:
    """Step the runs of ``plans`` together (:class:`Batch`: open, step, results, close)."""
    with Batch(plans, keep, pool) as batch:
        batch.open().step()
        return batch.results()


def _open(index: int, plan: Plan, pool: SlotPool | None, files: Mapping[str, Path] | None) -> _Copy | None:
    """Copy ``index``'s instances loaded and initialized (None: an FMU refused)."""
    # what an FMU's refusal raises; anything else is a bug and goes up
    try:
        slots = open_slots(plan, pool, files=files)
    except RunError:
        return None
    try:
        state = make_state(plan)
        initialize(plan, state, slots)
        return _Copy(index, plan, state, slots, NativeLoop(plan, state, slots))
    except RunError:
        close_slots(slots)
        return None


class _Rows:
    """Every recorded row of every copy (the kept columns), filled batch by batch."""

    def __init__(self, plan: Plan, n_copies: int, n_cols: int) -> None:
        k0, n, every = plan.start_tick, plan.n_ticks, plan.out_every
        self.first = -(-k0 // every)
        total = max(0, n // every - self.first + 1)  # the end's row included when it is one
        self.values = np.zeros((total, n_copies * max(n_cols, 1)))
        self.done = 0


def _step(copies: list[_Copy], kept: Sequence[int]) -> int | None:
    """Every tick of every copy, in batches; the index (in ``copies``) of a copy whose FMU
    failed, else None (every copy's rows in ``copy.rows``)."""
    plan = copies[0].plan
    m, n_driven, n_cols = len(plan.instances), max(len(plan.driven), 1), len(kept)
    slots = (TwinSlot * (m * len(copies)))()
    alive = []  # the per-copy source arrays the combined slots point at
    for c, copy in enumerate(copies):
        for i, inst in enumerate(plan.instances):
            slots[c * m + i] = copy.loop.slots[i]  # a copy of the struct: pointers into copy's state
            s = slots[c * m + i]  # shares the array's memory
            src = np.array(
                [p.src + (c * m if p.kind != InputKind.DRIVEN else c * n_driven) for p in inst.inputs] or [0],
                dtype=np.int32,
            )
            alive.append(src)
            s.in_src = src.ctypes.data
    cols = (TwinColumn * max(n_cols * len(copies), 1))(
        *[
            TwinColumn(c * m + col.instance, col.kind, col.idx, 0)
            for c in range(len(copies))
            for col in (plan.columns[j] for j in kept)
        ]
    )
    rows = _Rows(plan, len(copies), n_cols)
    run = getattr(stepper(), entry()[0])
    k, end, step = plan.start_tick, plan.n_ticks, plan.step_ns
    counters = TwinCounters()
    every = driven_every(plan)
    while k < end:
        k1 = min(k + BATCH_TICKS, end)
        driven = _driven(copies, k, k1, every, n_driven)
        view = rows.values[rows.done :]
        counters.rows = 0
        status = run(
            slots, len(slots), k, k1, step, plan.out_every, driven.ctypes.data, driven.shape[1], every,
            view.ctypes.data, view.shape[0], cols, n_cols * len(copies), ctypes.byref(counters),
        )  # fmt: skip
        if status == Status.OVERFLOW:
            raise RunError("the stepper's row buffer was too small (a bug in the batch)")
        if status != Status.OK:
            return int(counters.fail_slot) // m
        rows.done += int(counters.rows)
        k = k1
    for c, copy in enumerate(copies):
        copy.counters = (int(counters.macro_steps), int(counters.fmu_steps) // len(copies))
        copy.rows = (rows, c)
    return None


def _driven(copies: Sequence[_Copy], k0: int, k1: int, every: int, n_driven: int) -> np.ndarray:
    """Every copy's driven columns side by side, one row per tick that reads them from ``k0``
    to ``k1 - 1`` (:func:`twin.cosim.state.driven_ticks`: the paper replay's FMUs exchange
    every tenth tick)."""
    ticks = driven_ticks(k0, k1, every)
    out = np.zeros((len(ticks), n_driven * len(copies)))
    if not every:
        return out
    step = copies[0].plan.step_ns
    for c, copy in enumerate(copies):
        out[:, c * n_driven : (c + 1) * n_driven] = copy.state.driven.at_ticks(ticks, step)[:, :n_driven]
    return out


def _result(copy: _Copy, kept: Sequence[int], cosim_s: float, setup_s: float) -> RunResult:
    """Copy's run as the master gives it: its kept columns of every row (the end's too)."""
    plan = copy.plan
    assert copy.rows is not None
    rows, c = copy.rows
    n_cols = len(kept)
    values = rows.values[: rows.done, c * n_cols : (c + 1) * n_cols]
    times = (rows.first + np.arange(rows.done, dtype=np.int64)) * plan.scenario.output_interval_ns / NS_PER_S
    last = final_tick(plan, copy.state)
    if last is not None:
        times = np.concatenate([times, last[0]])
        values = np.vstack([values, last[1][:, list(kept)]])
    table = SignalTable(times)
    for j, col in enumerate(kept):
        table.add(plan.columns[col].meta, np.ascontiguousarray(values[:, j]))
    macro, fmu = copy.counters
    return RunResult(
        table=table,
        status="completed",
        cosim_s=cosim_s,
        setup_s=setup_s,
        macro_steps=macro,
        fmu_steps=fmu,
        end_ns=plan.scenario.start_ns + macro * plan.step_ns,
        start_ns=plan.scenario.start_ns,
    )
