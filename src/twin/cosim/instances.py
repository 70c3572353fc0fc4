"""The FMU instances of a run: loading them, initializing them, freeing them.

Loading instantiates each FMU of the plan (built on first use), sets up its experiment and
sets its parameters; initialization runs the FMUs' initialization mode in dependency order,
each one's inputs gathered from the outputs of those before it, and makes their initial
outputs visible.
"""

from __future__ import annotations

from collections.abc import Sequence

from twin.cosim.plan import Plan
from twin.cosim.state import State
from twin.cosim.stepping import Gather
from twin.fmu import catalog
from twin.fmu.slot import FMUSlot


def open_slots(plan: Plan) -> list[FMUSlot]:
    """One instantiated FMU per planned instance, parameters set; none left open on a failure."""
    slots: list[FMUSlot] = []
    try:
        for inst in plan.instances:
            slot = FMUSlot(catalog.fmu(inst.model), inst.name)
            slots.append(slot)
            slot.setup(0.0)
            for name, value in inst.parameters:
                slot.set_value(name, value)
    except BaseException:
        close_slots(slots)
        raise
    return slots


def initialize(plan: Plan, state: State, slots: Sequence[FMUSlot]) -> None:
    """Initialization mode of every instance in dependency order; their outputs become visible."""
    drow = state.driven.row(0.0)
    for i in plan.init_order:
        inst, slot, buf = plan.instances[i], slots[i], state.buffers[i]
        slot.enter_initialization()
        # a delayed input keeps its initial value: its source may not be initialized yet
        Gather(inst, state.buffers)(drow, exchange=False)
        slot.write(buf.in_port)
        slot.exit_initialization()
        slot.read(buf.out_port)
        buf.commit()


def close_slots(slots: Sequence[FMUSlot]) -> None:
    """Terminate and free every instance (never raises)."""
    for slot in slots:
        slot.close()


__all__ = ["close_slots", "initialize", "open_slots"]
