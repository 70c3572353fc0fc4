"""The FMU instances of a run: loading them, initializing them, freeing them.

Loading instantiates each FMU of the plan (built on first use), sets up its experiment and
sets its parameters; initialization (:func:`twin.cosim.loops.initialize`) runs the FMUs'
initialization mode variable by variable, each input set as soon as the output it is
connected to is read, and makes their initial outputs visible.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from twin.config.spec import NS_PER_S
from twin.cosim.loops import initialize
from twin.cosim.plan import Plan
from twin.fmu import catalog
from twin.fmu.pool import SlotPool
from twin.fmu.slot import FMUSlot


def open_slots(
    plan: Plan,
    pool: SlotPool | None = None,
    log: Callable[[str, str, str, str], None] | None = None,
    files: Mapping[str, Path] | None = None,
) -> list[FMUSlot]:
    """One instantiated FMU per planned instance, its experiment set up at the run's start,
    parameters set; none left open on a failure.

    With a ``pool``, an idle instance of the same FMU file and name is reset and reused
    (:mod:`twin.fmu.pool`) instead of instantiating another. With a ``log`` (a run into its
    folder, never a pooled study's point), the instances log everything (debug logging on) and
    every message goes to it as well. ``files`` gives each model's ``.fmu``
    (:func:`fmu_files`), where a caller opens many runs of the same models (a batch of
    samples): a file is found (its sources hashed, its cache entry checked) once for them all."""
    slots: list[FMUSlot] = []
    try:
        for inst in plan.instances:
            path = files[inst.model] if files is not None else catalog.fmu(inst.model)
            if pool is None:
                slot = FMUSlot(path, inst.name, log=log)
            else:
                slot = pool.open(path, inst.name, lambda p=path, n=inst.name: FMUSlot(p, n))
            slots.append(slot)
            slot.setup(plan.scenario.start_ns / NS_PER_S)
            slot.set_values(inst.parameters)
    except BaseException:
        close_slots(slots)
        raise
    return slots


def fmu_files(plan: Plan) -> dict[str, Path]:
    """The ``.fmu`` of each model of ``plan`` (built on first use), as :func:`open_slots` takes them."""
    return {inst.model: catalog.fmu(inst.model) for inst in plan.instances}


def check_initialization(plan: Plan) -> None:
    """Instantiate and initialize every instance of the plan, step none, free them: what the
    FMUs themselves refuse of their parameters (a model's own checks: heat shares that do not
    sum to one, a thermal network too stiff for its step) is found without running. Raises
    :class:`~twin.errors.FMUError` naming the instance and the FMU's reason."""
    from twin.cosim.state import make_state

    slots = open_slots(plan)
    try:
        initialize(plan, make_state(plan), slots)
    finally:
        close_slots(slots)


def close_slots(slots: Sequence[FMUSlot], pool: SlotPool | None = None) -> None:
    """Terminate and free every instance, or with a ``pool`` give them back to it for the
    next run (never raises)."""
    for slot in slots:
        if pool is None:
            slot.close()
        else:
            pool.release(slot)


__all__ = ["check_initialization", "close_slots", "fmu_files", "initialize", "open_slots"]
