"""Runs of one system stepped together by the compiled stepper: a Monte Carlo's samples.

A Monte Carlo's samples are one scenario with other parameter values, seeds and driven
profiles: the same instances, connections, periods and recorded columns (one
:func:`structure`). Run one by one, every sample pays the master's Python around its FMU work
(simpy's clock, a profile matrix and a row buffer per batch of ticks, the recorder) for a few
milliseconds of stepping. Stepped together, the copies' instances are one array of slots for
the stepper's one call per batch of ticks: each copy's connections read the slots of its own
copy's instances and its driven inputs the columns of its own copy.

Copies often run some instance the same way: a Monte Carlo's updated sample is its prior
sample with the tester's posterior set, which sets the mechanics' and the sensors' parameters
only, so both samples' thermal networks make the very same calls. Such an instance (the same
model, parameters, seeds, start values and driven profiles, fed only by instances that are
the same in turn: :func:`identities`, from the plans' values, never from the model's name) is
opened and stepped once, by the first copy that has it; the others read its slot where they
would read their own, and their initialization reads what its initialization read. Every
FMU is still called in the order and with the values of its run alone (the stepper gathers
every input before any instance steps), so every copy's rows are bit for bit those of its run
alone (tests/cosim/test_batch.py).

A batch may record only the rows within some seconds of either end of its runs (``ends_s``:
what a Monte Carlo's sample reports is read off there, :func:`twin.errormodel.evaluate.end_reach_s`):
the ticks in between are stepped as every other, with no row recorded and no output fetched
for one (an FMU's outputs are computed when read, so that changes none of the rows kept).

What a batch does not do, it refuses (:func:`unbatchable`): scenario events, algebraic loops
(the Python loop's). A copy whose FMUs fail in their set-up or while stepping
is not run on: the caller runs it alone (:attr:`BatchRuns.alone`), where the master reports
the failure as it would anyway, with everything recorded up to it; the others are opened and
run again without it (a copy that borrowed its instance opens its own).
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import time
from collections import Counter
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.instances import close_slots, fmu_files, initialize, open_slots
from twin.cosim.layout import Status, TwinColumn, TwinCounters, TwinSlot, entry
from twin.cosim.master import RunResult
from twin.cosim.native import NativeLoop, stepper
from twin.cosim.plan import BATCH_TICKS, InputKind, Plan, exact_key
from twin.cosim.state import State, driven_every, driven_ticks, make_state
from twin.cosim.stepping import final_tick
from twin.errors import RunError
from twin.fmu.pool import SlotPool
from twin.fmu.slot import FMUSlot, NativeHandles, RealPort
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
    slots: list[FMUSlot]  # the instances it opened (not those it borrows)
    loop: NativeLoop
    #: the instances whose run another copy's same-named instance runs for it (its index ->
    #: that copy, opened before it): :func:`identities`
    borrowed: dict[int, _Copy] = field(default_factory=dict)
    #: after the run: the rows of every copy and this copy's place among them, and its
    #: macro steps and FMU steps
    rows: tuple[_Rows, int] | None = None
    counters: tuple[int, int] = (0, 0)


class Batch:
    """Runs of ``plans`` (one :func:`structure`, none :func:`unbatchable`) stepped together, in
    three parts so that a caller may step one batch while it works on another:
    :meth:`open` loads and initializes every copy and computes the driven inputs' rows ahead
    (Python: :func:`_driven_ahead`), :meth:`step` runs every tick (the compiled stepper: the
    interpreter's lock is released while it runs), :meth:`results` gives
    each completed copy's result with the ``keep`` columns of every row. :meth:`close` gives
    the instances back to ``pool`` (a pool that keeps as many idle instances per FMU as a batch
    has copies reuses them all); a batch is a context manager that closes. With ``ends_s``, each
    result holds only the rows within that many seconds of either end of its run
    (:func:`_stretches`). ``files``, a dict a caller's batches share, keeps the models' files
    the first of them found (:meth:`open`), for the next ones."""

    def __init__(
        self,
        plans: Sequence[Plan],
        keep: Collection[str],
        pool: SlotPool | None = None,
        ends_s: float | None = None,
        files: dict[str, Path] | None = None,
    ) -> None:
        if plans:
            first = structure(plans[0])
            for plan in plans:
                why = unbatchable(plan)
                if why is not None or structure(plan) != first:
                    raise ValueError(
                        f"plan of {plan.scenario.name!r} cannot join the batch: {why or 'another structure'}"
                    )
        self.plans, self.pool = list(plans), pool
        self.stretches = _stretches(plans[0], ends_s) if plans else []
        self.kept = [j for j, c in enumerate(plans[0].columns) if c.meta.name in keep] if plans else []
        self.copies: list[_Copy] = []
        self.alone: list[int] = []
        #: the driven rows of the stepper's calls that :meth:`open` computed ahead for its
        #: copies (:func:`_driven_ahead`): handed to the next :meth:`attempt` (a retry's
        #: copies, fewer, have none)
        self._ahead: _Ahead | None = None
        self.setup_s = self.step_s = 0.0
        self._attempted = False
        self._failed: int | None = None  # the copy whose FMU failed in the last attempt
        self._files: dict[str, Path] | None = None  # each model's .fmu (found at open)
        #: the models' files the batches before found (filled by the first that needs them)
        self._found = files
        self._identities = identities(self.plans)

    def open(self) -> Batch:
        """Load and initialize every copy (a copy an FMU refuses goes to :attr:`alone`) and
        compute the driven rows of the stepper's calls ahead (:func:`_driven_ahead`: their
        time counts as stepping, not as the set-up)."""
        start = time.perf_counter()
        if self.plans:
            # the copies share their models (structure): each file is found once for them all
            try:
                self._files = self._found_files(self.plans[0])
            except RunError:
                self._files = None  # each copy finds it again, fails and runs alone (its error told)
        sharing = _Sharing(self._identities)
        for index, plan in enumerate(self.plans):
            copy = _open(index, plan, self.pool, self._files, sharing)
            if copy is None:
                self.alone.append(index)
            else:
                self.copies.append(copy)
        ahead_start = time.perf_counter()
        self._ahead = _driven_ahead(self.copies, self.stretches)
        self.step_s += time.perf_counter() - ahead_start
        self.setup_s = ahead_start - start
        return self

    def _found_files(self, plan: Plan) -> dict[str, Path]:
        """:func:`~twin.cosim.instances.fmu_files` of ``plan``, from the files the batches
        before found where they have every model's (each file is checked when an instance
        loads it; a pooled instance loads none: 1.7 ms a batch saved on a slow day)."""
        found = self._found
        if found is None:
            return fmu_files(plan)
        if not {inst.model for inst in plan.instances} <= found.keys():
            found.update(fmu_files(plan))
        return found

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
            # shared again among those left: a copy that borrowed the failed one's instance
            # opens its own (or another's), so that it runs as it would alone
            sharing = _Sharing(self._identities)
            for c in (c for i, c in enumerate(self.copies) if i != failed):
                again = _open(c.index, c.plan, self.pool, self._files, sharing)
                if again is None:
                    self.alone.append(c.index)
                else:
                    reopened.append(again)
            self.copies = reopened
            self.attempt()  # in this thread: it computes the driven rows of the copies left

    def attempt(self) -> None:
        """Step every copy to the end once, the compiled stepper's ticks and nothing of the
        pool's (so a thread of its own may run it); a copy whose FMU failed is noted for
        :meth:`step`."""
        start = time.perf_counter()
        self._attempted = True
        ahead, self._ahead = self._ahead, None  # taken call by call: not held past its own
        self._failed = _step(self.copies, self.kept, self.stretches, ahead) if self.copies else None
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
        self._ahead = None
        for copy in self.copies:
            close_slots(copy.slots, self.pool)
            copy.slots = []

    def __enter__(self) -> Batch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_batch(
    plans: Sequence[Plan], keep: Collection[str], pool: SlotPool | None = None, ends_s: float | None = None
) -> BatchRuns:
    """Step the runs of ``plans`` together (:class:`Batch`: open, step, results, close)."""
    with Batch(plans, keep, pool, ends_s) as batch:
        batch.open().step()
        return batch.results()


def _open(
    index: int, plan: Plan, pool: SlotPool | None, files: Mapping[str, Path] | None, sharing: _Sharing
) -> _Copy | None:
    """Copy ``index``'s instances loaded and initialized (None: an FMU refused), but those a
    copy opened before runs for it (``sharing``): their initialization is replayed to it."""
    ids = sharing.identities[index]
    lent = {i: sharing.owners[ident] for i, ident in enumerate(ids) if ident in sharing.owners}
    own = [i for i in range(len(plan.instances)) if i not in lent]
    # what an FMU's refusal raises; anything else is a bug and goes up
    try:
        # the instances it opens: a plan of those alone (open_slots reads their list only)
        slots = open_slots(
            dataclasses.replace(plan, instances=tuple(plan.instances[i] for i in own)) if lent else plan,
            pool,
            files=files,
        )
    except RunError:
        return None
    fmus: list[Any] = [None] * len(plan.instances)
    for i, slot in zip(own, slots, strict=True):
        fmus[i] = _Recorded(slot) if sharing.wanted(ids[i]) else slot
    for i, (_, recorded) in lent.items():
        fmus[i] = _Replayed(recorded)
    try:
        state = make_state(plan)
        initialize(plan, state, fmus)
        copy = _Copy(index, plan, state, slots, NativeLoop(plan, state, fmus))
    except RunError:
        close_slots(slots)
        return None
    copy.borrowed = {i: owner for i, (owner, _) in lent.items()}
    for i in own:
        if isinstance(fmus[i], _Recorded):
            sharing.owners.setdefault(ids[i], (copy, fmus[i]))
    return copy


# ---------------------------------------------------------------- instances run once for many


def identities(plans: Sequence[Plan]) -> list[list[int]]:
    """Per plan, per instance: a number that two instances share only when their runs are the
    same call for call, so that one run serves both: the same model, name and period, the
    same parameters (the noise seed among them) and start values, each driven input driven
    by the same column (its profile's data), each connected input fed from instances that
    are the same in turn (their numbers equal), told apart by exact values (0.0 from -0.0).

    The numbers are refined from what each instance is given to what feeds it until no class
    splits: the coarsest partition in which every instance's sources are in its class's
    sources' classes, so a cycle of delayed connections is shared whole or not at all."""
    own: dict[object, int] = {}
    profiles: dict[int, object] = {}  # each profile's key, made once (samples share most)
    ids = [
        [own.setdefault(_given(plan, i, profiles), len(own)) for i in range(len(plan.instances))]
        for plan in plans
    ]
    n = len(own)
    while True:
        refined: dict[object, int] = {}
        ids = [
            [
                refined.setdefault(
                    (ids[c][i], tuple(ids[c][p.src] for p in inst.inputs if p.kind != InputKind.DRIVEN)),
                    len(refined),
                )
                for i, inst in enumerate(plan.instances)
            ]
            for c, plan in enumerate(plans)
        ]
        if len(refined) == n:
            return ids
        n = len(refined)


def _given(plan: Plan, i: int, profiles: dict[int, object]) -> object:
    """What the plan gives instance ``i`` but its connections' sources, as a key of exact
    values: names compared as strings, numbers by their bits (:func:`~twin.cosim.plan.exact_key`:
    the parameters' names and values in one serialization, the names written as strings)."""
    inst = plan.instances[i]
    return (
        inst.name, inst.model, inst.period_ns, inst.period_ticks, inst.outputs, inst.out_vrs,
        plan.scenario.start_ns,
        exact_key(inst.parameters),
        tuple((p.name, p.vr, int(p.kind), p.idx) for p in inst.inputs),
        exact_key(tuple((p.initial, p.factor, p.offset) for p in inst.inputs)),
        tuple(_driven_spec(plan, p.src, profiles) for p in inst.inputs if p.kind == InputKind.DRIVEN),
    )  # fmt: skip


def _driven_spec(plan: Plan, column: int, profiles: dict[int, object]) -> object:
    """How a driven column is driven, as a key of exact values: a profile by its data, not its
    place in the scenario; its table (a sample's room: hundreds of points) by the float64
    bits the profile evaluates. ``profiles`` keeps each profile's key by the profile (a
    frozen value, alive while the plans are: the samples of a batch share the tester's
    load and drive profiles, an updated sample its prior sample's room)."""
    spec = plan.driven[column]
    if spec[0] != "profile":
        return exact_key(spec)
    profile = plan.scenario.profiles[int(spec[1])]
    key = profiles.get(id(profile))
    if key is None:
        table = np.array(profile.table, dtype=np.float64)
        params = sorted(profile.params.items())
        key = profiles[id(profile)] = (
            profile.target, profile.kind, profile.source, tuple(k for k, _ in params),
            exact_key(tuple(v for _, v in params)), table.shape, table.tobytes(),
        )  # fmt: skip
    return key


class _Sharing:
    """While a batch opens its copies: which instance a copy opened runs for the copies after
    it (by :func:`identities`), with what its initialization read."""

    def __init__(self, ids: Sequence[Sequence[int]]) -> None:
        self.identities = ids
        self.owners: dict[int, tuple[_Copy, _Recorded]] = {}
        seen: Counter[int] = Counter(x for row in ids for x in row)
        self._many = {x for x, k in seen.items() if k > 1}

    def wanted(self, ident: int) -> bool:
        """Whether another copy has an instance of this identity (its calls are recorded)."""
        return ident in self._many


class _Recorded:
    """An opened instance whose initialization is recorded for the copies that borrow it:
    every port it is given and every value read from it, in order."""

    def __init__(self, slot: FMUSlot) -> None:
        self.slot = slot
        self.name = slot.name
        self.calls: list[tuple[str, bytes, bytes]] = []

    def enter_initialization(self) -> None:
        self.slot.enter_initialization()

    def exit_initialization(self) -> None:
        self.slot.exit_initialization()

    def write(self, port: RealPort) -> None:
        self.slot.write(port)
        self.calls.append(("write", bytes(port.vr), port.values[: port.n].tobytes()))

    def read(self, port: RealPort) -> None:
        self.slot.read(port)
        self.calls.append(("read", bytes(port.vr), port.values[: port.n].tobytes()))

    def native_handles(self) -> NativeHandles:
        return self.slot.native_handles()


class _Replayed:
    """A borrowed instance as the borrowing copy's initialization sees it: its calls are
    those the owner's were (the same plan's order, the same values: the same identity), so
    each read gives what the owner's read gave. A call that is not the owner's next is a
    :class:`~twin.errors.RunError`: the copy then runs alone, on an instance of its own."""

    def __init__(self, recorded: _Recorded) -> None:
        self.recorded = recorded
        self.name = recorded.name
        self.at = 0

    def enter_initialization(self) -> None:
        pass  # the owner's instance did

    def exit_initialization(self) -> None:
        pass

    def _next(self, call: str, port: RealPort) -> bytes:
        calls = self.recorded.calls
        if self.at >= len(calls) or calls[self.at][:2] != (call, bytes(port.vr)):
            raise RunError(f"instance {self.name} is not initialized as the one it borrows (a bug)")
        self.at += 1
        return calls[self.at - 1][2]

    def write(self, port: RealPort) -> None:
        if self._next("write", port) != port.values[: port.n].tobytes():
            raise RunError(f"instance {self.name} is given other values than the one it borrows (a bug)")

    def read(self, port: RealPort) -> None:
        port.values[: port.n] = np.frombuffer(self._next("read", port), dtype=np.float64)

    def native_handles(self) -> NativeHandles:
        return self.recorded.native_handles()  # never stepped: the owner's slot runs for it


class _Rows:
    """Every recorded row of every copy (the kept columns), filled batch by batch, and the
    output rows (the run's ``k``-th output tick: row ``k``) they are."""

    def __init__(self, plan: Plan, n_copies: int, n_cols: int, stretches: Sequence[_Stretch]) -> None:
        every = plan.out_every
        self.numbers = np.concatenate(
            [
                np.arange(-(-k0 // every), -(-k1 // every), dtype=np.int64)
                for k0, k1, kept in stretches
                if kept
            ]
            or [np.zeros(0, dtype=np.int64)]
        )
        self.values = np.zeros((len(self.numbers), n_copies * max(n_cols, 1)))
        self.done = 0


#: a stretch of a run's ticks: its first tick, the tick after its last, whether its rows are kept
_Stretch = tuple[int, int, bool]
#: the stepper's output interval for a stretch whose rows are not kept: an output tick past any
#: run's end, so that it records no row and fetches no output for one
_NO_ROWS = 1 << 62


def _stretches(plan: Plan, ends_s: float | None) -> list[_Stretch]:
    """The run's ticks in stretches whose rows are kept or not: every row kept, or with
    ``ends_s`` those of the ticks within ``ends_s`` of either end (the run's start, its end)."""
    k0, n, step = plan.start_tick, plan.n_ticks, plan.step_ns
    if ends_s is None:
        return [(k0, n, True)]
    if not ends_s >= 0.0:
        raise ValueError(f"ends_s must be a number of seconds >= 0, got {ends_s}")
    reach = math.ceil(ends_s * NS_PER_S)
    head = min(n, (k0 * step + reach) // step + 1)  # the ticks at most reach after the start
    tail = -(-(n * step - reach) // step)  # the ticks at least reach before the end
    if tail <= head:
        return [(k0, n, True)]
    return [(k0, head, True), (head, tail, False), (tail, n, True)]


def _chunks(stretches: Sequence[_Stretch]) -> Iterator[tuple[int, int, bool]]:
    """The stepper's calls over ``stretches``: each call's first tick, the tick after its
    last (at most :data:`BATCH_TICKS` apart) and whether its rows are kept."""
    for k, end, kept_rows in stretches:
        while k < end:
            k1 = min(k + BATCH_TICKS, end)
            yield k, k1, kept_rows
            k = k1


#: the bytes of driven rows a batch computes ahead, in the thread that opens it: a Monte Carlo
#: steps a batch in a thread of its own while its own thread evaluates the batch before, in
#: Python; the driven rows' numpy calls, made in the stepping thread, each waited for the
#: interpreter's lock (in the default run 0.66 s of their 0.84 s, a quarter of the stepping
#: thread's time, on a slow day). The calls whose rows do not fit (long runs, many copies)
#: have them computed by the stepping thread, one call's at a time, as before: what the rows
#: computed ahead add to a batch's memory stays within this (the paper replay's 20 copies
#: hold 2.3 MB of them; one call of BATCH_TICKS ticks of 20 copies with 5 columns driven at
#: every tick would hold 26 MB).
DRIVEN_AHEAD_BYTES = 8 << 20


@dataclass
class _Ahead:
    """A batch's driven rows computed ahead: their columns (placed so for the stepper, which
    :func:`_step` takes from here) and the rows of the calls computed, by (first tick, tick
    after the last)."""

    columns: _Columns
    rows: dict[tuple[int, int], np.ndarray]


def _driven_ahead(copies: Sequence[_Copy], stretches: Sequence[_Stretch]) -> _Ahead | None:
    """The driven rows (:func:`_driven`) of the stepper's calls over ``stretches``, taken in
    order while they fit in :data:`DRIVEN_AHEAD_BYTES` together (a call's that does not is
    left out, a later, smaller one's still taken), with the columns they hold."""
    if not copies:
        return None
    budget = DRIVEN_AHEAD_BYTES
    ahead = _Ahead(_Columns(copies), {})
    every = driven_every(copies[0].plan)
    for k, k1, _ in _chunks(stretches):
        size = len(driven_ticks(k, k1, every)) * ahead.columns.width * 8  # as _driven makes it
        if size > budget:
            continue
        budget -= size
        ahead.rows[(k, k1)] = _driven(copies, ahead.columns, k, k1, every)
    return ahead


def _step(
    copies: list[_Copy],
    kept: Sequence[int],
    stretches: Sequence[_Stretch],
    ahead: _Ahead | None = None,
) -> int | None:
    """Every tick of every copy, in batches; the index (in ``copies``) of a copy whose FMU
    failed, else None (every copy's rows, those of the ``stretches`` kept, in ``copy.rows``).
    The driven rows of a batch of ticks are taken out of ``ahead`` (:func:`_driven_ahead`, for
    these copies) where they were computed, else computed here."""
    plan = copies[0].plan
    n_cols = len(kept)
    columns = ahead.columns if ahead is not None else _Columns(copies)
    computed = ahead.rows if ahead is not None else {}
    placed = _Placed(copies, columns)
    slots = placed.slots
    cols = (TwinColumn * max(n_cols * len(copies), 1))(
        *[
            TwinColumn(placed.slot_of[c][col.instance], col.kind, col.idx, 0)
            for c in range(len(copies))
            for col in (plan.columns[j] for j in kept)
        ]
    )
    rows = _Rows(plan, len(copies), n_cols, stretches)
    run = getattr(stepper(), entry()[0])
    step = plan.step_ns
    counters = TwinCounters()
    every = driven_every(plan)
    for k, k1, kept_rows in _chunks(stretches):
        out_every = plan.out_every if kept_rows else _NO_ROWS
        driven = computed.pop((k, k1), None)  # freed once its call is made
        if driven is None:
            driven = _driven(copies, columns, k, k1, every)
        view = rows.values[rows.done :]
        counters.rows = 0
        status = run(
            slots, len(slots), k, k1, step, out_every, driven.ctypes.data, driven.shape[1], every,
            view.ctypes.data, view.shape[0], cols, n_cols * len(copies), ctypes.byref(counters),
        )  # fmt: skip
        if status == Status.OVERFLOW:
            raise RunError("the stepper's row buffer was too small (a bug in the batch)")
        if status != Status.OK:
            return placed.copy_at[int(counters.fail_slot)]
        rows.done += int(counters.rows)
    if rows.done != len(rows.numbers):
        raise RunError(f"the stepper recorded {rows.done} rows, not {len(rows.numbers)} (a bug in the batch)")
    fmu_steps = _fmu_steps(plan)
    for c, copy in enumerate(copies):
        copy.counters = (int(counters.macro_steps), fmu_steps)
        copy.rows = (rows, c)
        _take_over(copy)
    return None


class _Placed:
    """The stepper's slots for ``copies``: one per instance a copy opened (its borrowed ones
    are its owners' slots), the connections of each reading the slots of its own copy's
    sources and its driven inputs the driven rows' columns of its own copy (``columns``)."""

    def __init__(self, copies: Sequence[_Copy], columns: _Columns) -> None:
        plan = copies[0].plan
        where = {id(copy): c for c, copy in enumerate(copies)}
        #: per copy, per instance: the slot that runs it
        self.slot_of: list[list[int]] = []
        #: per slot: the copy (its place in ``copies``) that opened it, and its instance
        mine: list[tuple[int, int]] = []
        for c, copy in enumerate(copies):
            row = []
            for i in range(len(plan.instances)):
                owner = copy.borrowed.get(i)
                if owner is None:
                    row.append(len(mine))
                    mine.append((c, i))
                else:  # opened before it: placed already
                    row.append(self.slot_of[where[id(owner)]][i])
            self.slot_of.append(row)
        self.copy_at = [c for c, _ in mine]
        self.slots = (TwinSlot * len(mine))()
        self._alive = []  # the source arrays the slots point at
        for n, (c, i) in enumerate(mine):
            self.slots[n] = copies[c].loop.slots[i]  # a copy of the struct: pointers into copy c's state
            s = self.slots[n]  # shares the array's memory
            src = np.array(
                [
                    columns.of[c][p.src] if p.kind == InputKind.DRIVEN else self.slot_of[c][p.src]
                    for p in plan.instances[i].inputs
                ]
                or [0],
                dtype=np.int32,
            )
            self._alive.append(src)
            s.in_src = src.ctypes.data


def _fmu_steps(plan: Plan) -> int:
    """The FMU steps of a copy's run: each instance's, at the multiples of its period (as its
    run alone counts them; a borrowed instance's are its owner's)."""
    k0, end = plan.start_tick, plan.n_ticks
    return sum(
        len(range(-(-k0 // i.period_ticks) * i.period_ticks, end, i.period_ticks)) for i in plan.instances
    )


def _take_over(copy: _Copy) -> None:
    """A borrowed instance's exchange state at the end is its owner's: the copy's last row
    (:func:`twin.cosim.stepping.final_tick`) reads it as it reads its own instances'."""
    for i, owner in copy.borrowed.items():
        mine, theirs = copy.state.buffers[i], owner.state.buffers[i]
        for name in ("delay_buf", "raw", "cur", "bias"):
            np.copyto(getattr(mine, name), getattr(theirs, name))
        np.copyto(mine.in_port.values, theirs.in_port.values)
        np.copyto(mine.out_port.values, theirs.out_port.values)
        copy.state.pending_at[i] = owner.state.pending_at[i]


class _Columns:
    """The driven columns of a batch's copies, each distinct one once in the stepper's driven
    rows: a Monte Carlo's samples share the tester's load and drive profiles, and an updated
    sample its prior sample's room, so twenty copies of the paper replay's five columns are
    about fifteen columns, not a hundred (:meth:`twin.cosim.state.Driven.column_keys`)."""

    def __init__(self, copies: Sequence[_Copy]) -> None:
        place: dict[object, int] = {}
        #: per column of the rows: the copy (its place in ``copies``) and its column that give it
        self.first: list[tuple[int, int]] = []
        #: per copy, per driven column of its own: its column in the rows
        self.of: list[list[int]] = []
        for c, copy in enumerate(copies):
            row = []
            for d, key in enumerate(copy.state.driven.column_keys()):
                if key not in place:
                    place[key] = len(self.first)
                    self.first.append((c, d))
                row.append(place[key])
            self.of.append(row)
        #: the rows' width (one column, never read, where nothing is driven)
        self.width = max(len(self.first), 1)


def _driven(copies: Sequence[_Copy], columns: _Columns, k0: int, k1: int, every: int) -> np.ndarray:
    """The copies' driven ``columns``, one row per tick that reads them from ``k0`` to ``k1 - 1``
    (:func:`twin.cosim.state.driven_ticks`: the paper replay's FMUs exchange every tenth tick),
    each column the values its copy's own function gives (:meth:`twin.cosim.state.Driven.at_ticks`:
    the same times, the same numbers)."""
    ticks = driven_ticks(k0, k1, every)
    out = np.zeros((len(ticks), columns.width))
    if not every:
        return out
    t = ticks * copies[0].plan.step_ns / NS_PER_S
    for j, (c, d) in enumerate(columns.first):
        out[:, j] = copies[c].state.driven.functions[d](t)
    return out


def _result(copy: _Copy, kept: Sequence[int], cosim_s: float, setup_s: float) -> RunResult:
    """Copy's run as the master gives it: its kept columns of every row recorded (the end's too)."""
    plan = copy.plan
    assert copy.rows is not None
    rows, c = copy.rows
    n_cols = len(kept)
    values = rows.values[: rows.done, c * n_cols : (c + 1) * n_cols]
    times = rows.numbers * plan.scenario.output_interval_ns / NS_PER_S
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
