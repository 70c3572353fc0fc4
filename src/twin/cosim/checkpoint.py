"""Snapshot and restore of the whole master at a batch boundary (libcosim's serialization).

A snapshot is a plain dict (FMU states as bytes, buffers as numpy arrays, driven inputs as
the data that rebuilds them, clock and counters); how it is stored is the caller's business
(the run folder writes it as checked data that cannot run code: twin.outputs.checkpoint_file).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from twin.cosim.plan import Plan
from twin.cosim.state import State
from twin.errors import RunError
from twin.fmu.slot import FMUSlot

#: the buffers of an instance a snapshot keeps, by the snapshot's name for them
_BUFFERS = ("delay_buf", "raw", "cur", "bias")


def snapshot(plan: Plan, state: State, slots: Sequence[FMUSlot], tick: int) -> dict[str, Any]:
    """The whole twin at ``tick``: FMU states (noise generators included), exchange buffers,
    driven inputs, clock and counters."""
    c = state.counters
    return {
        "tick": tick,
        "macro_steps": int(c.macro_steps),
        "fmu_steps": int(c.fmu_steps),
        "events_applied": state.events_applied,
        "driven": [list(d) for d in state.driven.specs],
        "instances": [
            {
                "name": inst.name,
                "state": slot.save_state(),
                "in_val": buf.in_port.values.copy(),
                **{name: getattr(buf, name).copy() for name in _BUFFERS},
                "pending": buf.out_port.values.copy(),
                "pending_at": int(state.pending_at[inst.index]),
            }
            for inst, slot, buf in zip(plan.instances, slots, state.buffers, strict=True)
        ],
    }


def restore(plan: Plan, state: State, slots: Sequence[FMUSlot], snap: dict[str, Any]) -> int:
    """Put the twin back where ``snap`` was taken; returns the tick to continue from."""
    saved_instances = snap["instances"]
    if len(saved_instances) != len(plan.instances) or len(snap["driven"]) != len(state.driven):
        raise RunError(
            f"the checkpoint holds {len(saved_instances)} instances and {len(snap['driven'])} driven inputs, "
            f"the scenario {len(plan.instances)} and {len(state.driven)}"
        )
    for inst, slot, buf, saved in zip(plan.instances, slots, state.buffers, saved_instances, strict=True):
        if saved["name"] != inst.name:
            raise RunError(f"checkpoint holds instance '{saved['name']}', the scenario '{inst.name}'")
        slot.restore_state(saved["state"])
        for name in _BUFFERS:
            getattr(buf, name)[:] = saved[name]
        buf.in_port.values[:] = saved["in_val"]
        buf.out_port.values[:] = saved["pending"]
        state.pending_at[inst.index] = int(saved["pending_at"])
    for column, spec in enumerate(snap["driven"]):
        state.driven.set(column, tuple(spec))
    state.counters.macro_steps = int(snap["macro_steps"])
    state.counters.fmu_steps = int(snap["fmu_steps"])
    state.events_applied = int(snap["events_applied"])
    return int(snap["tick"])


__all__ = ["restore", "snapshot"]
