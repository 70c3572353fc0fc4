"""Snapshot and restore of the whole master at a batch boundary (libcosim's serialization).

A snapshot is a plain dict (FMU states as bytes, buffers as numpy arrays, driven inputs as
the data that rebuilds them, clock and counters); how it is stored is the caller's business
(the run folder writes it as checked data that cannot run code: twin.outputs.checkpoint_file).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from twin.cosim.plan import Plan
from twin.cosim.state import State, make_state
from twin.errors import CheckpointError, FMUError, RunError
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


#: the largest counter a snapshot may hold: the compiled stepper's counters are 64-bit
_INT64_MAX = 2**63 - 1
#: what a snapshot's problems are reported under (the run folder's checkpoint file)
CHECKPOINT_NAME = "checkpoint.npz"


def _bad(key: str, what: str, source: str) -> CheckpointError:
    return CheckpointError(what, source=source, key=f"master.{key}")


def _int(snap: dict[str, Any], key: str, lo: int, hi: int, source: str) -> None:
    value = snap.get(key)
    if type(value) is not int or not lo <= value <= hi:
        raise _bad(key, f"expected an integer from {lo} to {hi}, got {str(value)[:40]!r}", source)


def _number(x: Any) -> bool:
    return type(x) in (int, float) and math.isfinite(x)


def _check_driven(plan: Plan, specs: Any, source: str) -> None:
    """Each driven input's record is one the twin writes: ``("constant", value)``,
    ``("profile", index)`` or ``("ramp", v0, v1, t0_s, duration_s)`` of finite numbers."""
    if not isinstance(specs, list) or len(specs) != len(plan.driven):
        raise _bad("driven", f"expected a list of {len(plan.driven)} driven inputs", source)
    n_profiles = len(plan.scenario.profiles)
    for i, spec in enumerate(specs):
        kind = spec[0] if isinstance(spec, list) and spec else None
        ok = (
            (kind == "constant" and len(spec) == 2 and _number(spec[1]))
            or (kind == "profile" and len(spec) == 2 and type(spec[1]) is int and 0 <= spec[1] < n_profiles)
            or (kind == "ramp" and len(spec) == 5 and all(map(_number, spec[1:])) and spec[4] > 0)
        )
        if not ok:
            raise _bad(
                f"driven[{i}]",
                f'expected ["constant", value], ["profile", index below {n_profiles}] or '
                f'["ramp", v0, v1, t0, duration > 0] of finite numbers, got {str(spec)[:60]}',
                source,
            )


def _check_instances(plan: Plan, saved: Any, source: str) -> None:
    """One record per instance, by name and order, each buffer a float64 array of the shape
    the plan gives the instance's (the compiled stepper reads them through pointers)."""
    if not isinstance(saved, list) or len(saved) != len(plan.instances):
        raise _bad("instances", f"expected a list of {len(plan.instances)} instances", source)
    fresh = make_state(plan)
    for i, (inst, buf, rec) in enumerate(zip(plan.instances, fresh.buffers, saved, strict=True)):
        where = f"instances[{i}]"
        if not isinstance(rec, dict) or rec.get("name") != inst.name:
            raise _bad(f"{where}.name", f"expected instance {inst.name!r}", source)
        if not isinstance(rec.get("state"), bytes):
            raise _bad(f"{where}.state", "expected the FMU's serialized state (bytes)", source)
        shapes = {name: getattr(buf, name) for name in _BUFFERS}
        shapes |= {"in_val": buf.in_port.values, "pending": buf.out_port.values}
        for name, live in shapes.items():
            value = rec.get(name)
            if not isinstance(value, np.ndarray) or value.dtype != np.float64 or value.shape != live.shape:
                got = (
                    f"{value.dtype} {value.shape}" if isinstance(value, np.ndarray) else type(value).__name__
                )
                raise _bad(f"{where}.{name}", f"expected float64 of shape {live.shape}, got {got}", source)
        pending = rec.get("pending_at")
        if type(pending) is not int or not -1 <= pending <= _INT64_MAX:
            raise _bad(f"{where}.pending_at", f"expected an integer from -1 to {_INT64_MAX}", source)


def check_snapshot(plan: Plan, snap: Any, source: str = CHECKPOINT_NAME) -> None:
    """Every value of ``snap`` (a checkpoint's master part, read from a file that may be
    crafted: checksums prove only that the file is whole) of the kind, range and shape
    :func:`snapshot` writes for ``plan``: a :class:`CheckpointError` (exit 2) naming the key,
    before any FMU is touched or any file of the run folder changed."""
    if not isinstance(snap, dict):
        raise CheckpointError("expected an object", source=source, key="master")
    # a tick within the run: one beyond its end (or 2^70) would "complete" a run never run
    _int(snap, "tick", plan.start_tick, plan.n_ticks, source)
    for key in ("macro_steps", "fmu_steps"):
        _int(snap, key, 0, _INT64_MAX, source)
    _int(snap, "events_applied", 0, len(plan.events), source)
    _check_driven(plan, snap.get("driven"), source)
    _check_instances(plan, snap.get("instances"), source)


def restore(plan: Plan, state: State, slots: Sequence[FMUSlot], snap: dict[str, Any]) -> int:
    """Put the twin back where ``snap`` was taken (checked by :func:`check_snapshot`); returns
    the tick to continue from. An FMU that refuses its saved state is a checkpoint that cannot
    be trusted (exit 2), not a run that failed."""
    saved_instances = snap["instances"]
    if len(saved_instances) != len(plan.instances) or len(snap["driven"]) != len(state.driven):
        raise RunError(
            f"the checkpoint holds {len(saved_instances)} instances and {len(snap['driven'])} driven inputs, "
            f"the scenario {len(plan.instances)} and {len(state.driven)}"
        )
    for inst, slot, buf, saved in zip(plan.instances, slots, state.buffers, saved_instances, strict=True):
        if saved["name"] != inst.name:
            raise RunError(f"checkpoint holds instance '{saved['name']}', the scenario '{inst.name}'")
        try:
            slot.restore_state(saved["state"])
        except FMUError as exc:
            raise CheckpointError(
                f"the FMU refuses its saved state in {exc.call}: {exc.detail}",
                source=CHECKPOINT_NAME,
                key=f"master.instances.{inst.name}.state",
            ) from None
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


__all__ = ["CHECKPOINT_NAME", "check_snapshot", "restore", "snapshot"]
