"""The co-simulation master: a small facade over its parts (libcosim's ``execution``).

Time is an integer number of nanoseconds: tick k is at ``k * step`` (never summed floats).
Each FMU steps with its own period (a multiple of the scenario step). Exchange is Jacobi:
every FMU due at time t gets its inputs from the outputs all FMUs had at t, then all of
them step from t to t + period. The outputs of an FMU that stepped to t + p become visible
only at t + p (until then the others see its value at t: zero-order hold), so a fast FMU
never sees a slow one's future.

The parts, one role each:

- :mod:`~twin.cosim.plan`: the static plan, built once from the scenario (what steps when,
  what feeds each input, what is recorded), by :func:`~twin.cosim.plan.make_plan`;
- :mod:`~twin.cosim.state`: the exchange state every other part works on;
- :mod:`~twin.cosim.instances`: the FMU instances (load, initialize, free);
- :mod:`~twin.cosim.loops`: initialization variable by variable, and the algebraic loops
  iterated at each communication point;
- :mod:`~twin.cosim.stepping`: the stepping loop, compiled (:mod:`~twin.cosim.native`) or
  Python, behind one interface: runs a batch of ticks;
- :mod:`~twin.cosim.events`: scenario events, progress, checkpoints and batch limits as simpy
  processes (its docstring says why the ticks themselves are not simpy events);
- :mod:`~twin.cosim.checkpoint`: snapshot and restore of the whole master;
- :mod:`~twin.cosim.recording`: where the recorded rows go.

The master composes them: :meth:`Master.run` plans, loads and initializes (or restores),
starts the processes and runs the clock, which executes the ticks between two points in
time as one batch of the stepping loop.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Generator, Sequence
from dataclasses import dataclass, field
from typing import Any

import simpy

from twin.config.spec import Scenario
from twin.cosim import events
from twin.cosim.checkpoint import restore, snapshot
from twin.cosim.controls import RunControls
from twin.cosim.instances import close_slots, initialize, open_slots
from twin.cosim.loops import loop_solvers
from twin.cosim.native import NativeLoop
from twin.cosim.plan import Plan, make_plan
from twin.cosim.recording import MemoryRecorder, Recorder, batch_rows
from twin.cosim.state import State, driven_every, make_state
from twin.cosim.stepping import Loop, PythonLoop, Solver, Stepping, check_loop, final_tick
from twin.errors import FMUError, RunError
from twin.fmu.pool import SlotPool
from twin.fmu.slot import FMUSlot
from twin.signals.table import SignalTable

#: how the clock process ends: ("completed", None), ("failed", error) or ("interrupted", why)
_Outcome = tuple[str, Any]


@dataclass
class RunResult:
    """What a run produced: the recorded signals (all rows up to a failure) and counters."""

    table: SignalTable | None
    status: str  # "completed" | "failed" | "interrupted"
    error: RunError | None = None
    cosim_s: float = 0.0  # from the FMUs' loading to the last row: setup_s and open_s included
    setup_s: float = 0.0  # loading, instantiating and initializing the FMUs
    open_s: float = 0.0  # opening the recorder's sinks (the recording's blueprint among them)
    macro_steps: int = 0
    fmu_steps: int = 0
    end_ns: int = 0
    start_ns: int = 0  # where this process started: a resumed run's checkpoint, else the run's start
    info: dict[str, Any] = field(default_factory=dict)


class Master:
    """Runs the :class:`~twin.cosim.plan.Plan` of a scenario.

    Rows go to ``recorder`` (default: kept in memory). ``controls`` steer the run: asked to
    stop between batches, told the progress, saving the whole master at their interval
    (:class:`~twin.cosim.controls.RunControls`). ``loop`` chooses the stepping loop ("fast":
    compiled; "python": the same ticks in Python). ``resume`` continues from a state that
    ``controls.on_checkpoint`` received. With a ``pool`` the FMU instances come from it and go
    back to it after a run that completed (:mod:`twin.fmu.pool`: a sweep's points on one worker).
    """

    def __init__(
        self,
        plan: Plan,
        recorder: Recorder | None = None,
        controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
        *,
        loop: Loop = "fast",
        resume: dict[str, Any] | None = None,
        pool: SlotPool | None = None,
    ) -> None:
        self.plan = plan
        self.scenario = plan.scenario
        self.pool = pool
        self.controls = controls
        self.loop = check_loop(loop)
        self.recorder = recorder if recorder is not None else MemoryRecorder()
        self.resume = resume
        self.state: State | None = None
        self.slots: list[FMUSlot] = []
        self.solvers: list[Solver] = []
        # the ticks between two that read the driven inputs (a batch's matrix holds those rows)
        self._driven_every = driven_every(plan)

    # ------------------------------------------------------------------ set-up

    def _create(self) -> None:
        """The exchange state and the FMU instances."""
        self.state = make_state(self.plan)
        self.slots = open_slots(self.plan, self.pool, self.controls.fmi_log)

    def _initialize(self) -> None:
        initialize(self.plan, self.state, self.slots)

    def _start(self) -> tuple[Stepping, int]:
        """Everything before the clock starts; the loop and the tick to start from."""
        try:
            self._create()
            if self.resume is None:
                self._initialize()
            self.solvers = loop_solvers(self.plan, self.state, self.slots)
            stepping = make_stepping(self.loop, self.plan, self.state, self.slots, self.solvers)
            tick = (
                self.plan.start_tick
                if self.resume is None
                else restore(self.plan, self.state, self.slots, self.resume)
            )
        except BaseException:
            self.close()
            raise
        return stepping, tick

    # ------------------------------------------------------------------ the run

    def run(self) -> RunResult:
        """Run the scenario; a failure mid-run keeps every row recorded before it."""
        start = wallclock.perf_counter()
        stepping, tick = self._start()
        plan = self.plan
        self._start_ns = tick * plan.step_ns
        self._setup_s = wallclock.perf_counter() - start
        self.recorder.open([c.meta for c in plan.columns])
        self._open_s = wallclock.perf_counter() - start - self._setup_s
        env = simpy.Environment(initial_time=tick * plan.step_ns)
        events.start(env, plan, self.state, self.controls, self._checkpoint)
        clock = env.process(self._clock(env, stepping, tick))  # started last: see twin.cosim.events
        outcome: _Outcome = ("failed", None)
        try:
            outcome = env.run(until=clock)
        finally:
            self.close(reuse=outcome[0] == "completed")
            self.recorder.close()
        return self._result(outcome, start)

    def _clock(
        self, env: simpy.Environment, stepping: Stepping, k: int
    ) -> Generator[simpy.Event, Any, _Outcome]:
        """Runs the ticks up to the next point in time as one batch, then sleeps until then."""
        step, end = self.plan.step_ns, self.plan.n_ticks
        try:
            while k < end:
                k1 = int(min(env.peek(), end * step) // step)
                if k1 == k:  # due now: a process that just ended; let it go first
                    yield env.timeout(0)
                    continue
                self._batch(stepping, k, k1)
                yield env.timeout((k1 - k) * step)
                k = k1
                if why := self.controls.stopped():
                    return "interrupted", why
            last = final_tick(self.plan, self.state, self.solvers)
            if last is not None:
                self.recorder.append(*last)
        except RunError as exc:  # the run stops; what was recorded stays
            return "failed", exc
        return "completed", None

    def _batch(self, stepping: Stepping, k0: int, k1: int) -> None:
        driven = self.state.driven.matrix(k0, k1, self.plan.step_ns, self._driven_every)
        with batch_rows(self.plan, self.recorder, self.state.counters, k0, k1) as rows:
            stepping.ticks(k0, k1, driven, rows)

    def _checkpoint(self, tick: int) -> None:
        if self.controls.on_checkpoint is not None:
            self.controls.on_checkpoint(snapshot(self.plan, self.state, self.slots, tick))

    def _result(self, outcome: _Outcome, start: float) -> RunResult:
        status, detail = outcome
        c = self.state.counters
        table = self.recorder.table() if isinstance(self.recorder, MemoryRecorder) else None
        return RunResult(
            table=table,
            status=status,
            info={"interrupted_by": detail} if status == "interrupted" else {},
            error=detail if status == "failed" else None,
            cosim_s=wallclock.perf_counter() - start,
            setup_s=getattr(self, "_setup_s", 0.0),
            open_s=getattr(self, "_open_s", 0.0),
            macro_steps=int(c.macro_steps),
            fmu_steps=int(c.fmu_steps),
            # every tick before the end, the failure or the interruption was done (counted from
            # the run's start: a resumed run's counters are its whole run's)
            end_ns=self.scenario.start_ns + int(c.macro_steps) * self.plan.step_ns,
            start_ns=getattr(self, "_start_ns", 0),
        )

    def close(self, *, reuse: bool = False) -> None:
        """Free the FMU instances, or with ``reuse`` give them back to the pool (again: a no-op)."""
        close_slots(self.slots, self.pool if reuse else None)
        self.slots = []


def make_stepping(
    loop: Loop, plan: Plan, state: State, slots: Sequence[FMUSlot], solvers: Sequence[Solver] = ()
) -> Stepping:
    """The loop named ``loop`` over ``state`` (the compiled one is built on first use). A plan
    with algebraic loops (``solvers``) runs the Python loop whichever is named: the compiled
    stepper runs loop-free plans only, and the two agree bit for bit where both run."""
    if check_loop(loop) == "python" or solvers:
        return PythonLoop(plan, state, slots, solvers)
    return NativeLoop(plan, state, slots)


def run_scenario(scenario: Scenario, *, loop: Loop = "fast") -> RunResult:
    """Convenience: run a scenario with a fresh master, every row kept in memory."""
    return Master(make_plan(scenario), loop=loop).run()


__all__ = [
    "FMUError",
    "Loop",
    "Master",
    "MemoryRecorder",
    "Recorder",
    "RunControls",
    "RunResult",
    "run_scenario",
]
