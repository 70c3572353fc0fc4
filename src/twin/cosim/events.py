"""What happens at points in time: scenario events and the run's wake-ups, as simpy processes.

simpy's clock is the run's clock, in integer nanoseconds. Each kind of point in time is a
process that sleeps until its next time and acts (libcosim's manipulators and observers):

- the scenario's events (set, ramp, bias; a fault is a set of ``fault_inject``) change the
  driven inputs or the outputs' biases (:func:`apply`);
- progress marks report how far the run is, a hundred times per run;
- checkpoints save the whole master at their interval;
- batch limits wake the master every :data:`~twin.cosim.plan.BATCH_TICKS` ticks, so that the
  driven matrix and the row buffer of one batch stay bounded (memory flat in run length).

The master's clock process (:meth:`twin.cosim.master.Master._clock`) asks simpy when the next
of these is due (``env.peek()``) and runs every tick up to it as one batch of the stepping
loop, then sleeps until then itself. Its timeout is always scheduled after the others', so at
a time ``T`` every process due at ``T`` runs after the ticks before ``T`` and before those
from ``T``: the order the semantics need, without priorities. Processes due at the same time
run in the order they went to sleep, and none depends on that order: a checkpoint taken just
before or just after an event at its time resumes to the same run, because it counts the
events it includes (``events_applied``) and keeps the driven inputs they changed.

Why the hot loop is not inside simpy: a tick is a few microseconds of FMU work and the
compiled stepper runs one in a fraction of a microsecond, while one simpy event costs
several microseconds of Python. Scheduling every tick (or every output row, which may be
every tick) would make the scheduler the cost of the run; what happens at every tick in the
same order (commit, inputs, row, step) is a loop, not an event. The instances' own periods
(multi-rate) stay in the loop for the same reason: a ``k % period`` test per instance and tick
costs nanoseconds in C, a wake-up per instance step would cost microseconds. simpy gets what is genuinely
event-like: sparse, irregular points in time that change the state, each written as a small
process instead of being merged by hand into one list of marks.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Iterable
from typing import Any

import simpy

from twin.config.spec import NS_PER_S
from twin.cosim.controls import RunControls
from twin.cosim.plan import Plan, PlannedEvent
from twin.cosim.state import State

Process = Generator[simpy.Event, Any, None]


def apply(event: PlannedEvent, state: State) -> None:
    """Apply one scenario event to the state (between batches, at the event's tick)."""
    buf = state.buffers[event.instance]
    k = event.index
    if event.action == "bias":
        buf.bias[k] += event.value
        buf.cur[k] = buf.raw[k] + buf.bias[k]
    elif event.action == "set":
        state.driven.set(event.column, ("constant", event.value))
    else:  # a ramp from the value the input was last set to
        now = float(buf.in_port.values[k])
        state.driven.set(
            event.column, ("ramp", now, event.value, event.at_ns / NS_PER_S, event.duration_ns / NS_PER_S)
        )
    state.events_applied += 1


def _scenario_events(env: simpy.Environment, plan: Plan, state: State) -> Process:
    """Applies the events not applied yet, each at its time (those due now at once)."""
    for event in plan.events[state.events_applied :]:
        if event.at_ns > env.now:
            yield env.timeout(event.at_ns - env.now)
        apply(event, state)


def _at_ticks(
    env: simpy.Environment, step_ns: int, ticks: Iterable[int], action: Callable[[], None]
) -> Process:
    """Wakes at each of ``ticks`` still ahead and calls ``action``."""
    for tick in ticks:
        if tick * step_ns > env.now:
            yield env.timeout(tick * step_ns - env.now)
            action()


def start(
    env: simpy.Environment, plan: Plan, state: State, controls: RunControls, checkpoint: Callable[[int], None]
) -> None:
    """Start every process of the run in ``env`` (whose clock is at the run's start).

    ``controls.progress(done_ns, total_ns)`` is told at each progress mark (the simulated time
    done since the run's start, of the run's whole);
    ``checkpoint(tick)`` is called at each of ``controls``' checkpoint times. Progress marks
    and batch limits wake the master even without a listener: they are where batches end, so
    a run is cut the same way however it is observed.
    """
    start = plan.scenario.start_ns
    duration = plan.scenario.duration_ns - start
    step = plan.step_ns

    def report() -> None:
        if controls.progress is not None:
            controls.progress(env.now - start, duration)

    def save() -> None:
        checkpoint(env.now // step)

    env.process(_scenario_events(env, plan, state))
    env.process(_at_ticks(env, step, plan.progress_ticks(), report))
    env.process(_at_ticks(env, step, plan.batch_limit_ticks(), lambda: None))
    env.process(_at_ticks(env, step, plan.checkpoint_ticks(controls.checkpoint_every_ns), save))


__all__ = ["apply", "start"]
