"""The compiled stepper (``native/stepper.c``): building it, loading it, and running ticks with it.

Built with cmake like the FMUs, together with the header generated from
:mod:`twin.cosim.layout`, and cached by a hash of all of them, so a fresh clone builds it on
first use and a changed layout rebuilds it. :class:`NativeLoop` is the fast implementation of
:class:`~twin.cosim.stepping.Stepping`: it points the stepper's structures at the arrays of
the exchange state and calls the FMUs' FMI functions directly from C.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.layout import (
    HEADER,
    Call,
    Status,
    TwinColumn,
    TwinSlot,
    c_header,
    entry,
    entry_argtypes,
)
from twin.cosim.plan import InputKind, Plan, shared
from twin.cosim.state import State, driven_every
from twin.cosim.stepping import non_finite
from twin.errors import FMUError, RunError
from twin.fmu.slot import FMUSlot
from twin.fmu.toolchain import build_cached_library

SOURCES = Path(__file__).parent / "native"
LIBRARY = "twin_stepper"

#: the FMI call a failure is reported under
CALL_NAMES = {Call.SET_REAL: "fmi2SetReal", Call.DO_STEP: "fmi2DoStep", Call.GET_REAL: "fmi2GetReal"}


def stepper_sources() -> dict[str, bytes]:
    """What the stepper is built from: the files in ``native/`` and the generated header."""
    files = {p.name: p.read_bytes() for p in sorted(SOURCES.iterdir()) if p.is_file()}
    files[HEADER] = c_header().encode()
    return files


def ensure_stepper() -> Path:
    """Path of the built stepper library, building it when its sources or its layout changed."""
    return build_cached_library(LIBRARY, stepper_sources())


@lru_cache(maxsize=1)
def stepper() -> ctypes.CDLL:
    """The loaded library with its entry point typed from the layout."""
    lib = ctypes.CDLL(str(ensure_stepper()))
    fn = getattr(lib, entry()[0])
    fn.argtypes = entry_argtypes()
    fn.restype = ctypes.c_int
    return lib


@lru_cache(maxsize=1)
def _entry_point() -> Any:
    """The stepper's typed entry point (built on first use): looked up once, not per run."""
    return getattr(stepper(), entry()[0])


class _Structure(NamedTuple):
    """What the stepper reads of a plan's structure, the same for every run of it: each
    instance's input kinds, sources and indices (int32) and factors and offsets (float64), the
    instances a connection reads, and the recorded columns. C reads them, never writes them."""

    inputs: list[tuple[np.ndarray, ...]]
    affine: list[tuple[np.ndarray, ...]]
    read: frozenset[int]
    cols: ctypes.Array


def _structure(plan: Plan) -> _Structure:
    """The plan's :class:`_Structure`, made once for every plan that shares its inputs and
    columns (:func:`twin.cosim.plan.shared`: a Monte Carlo's samples)."""
    owners = (plan.columns, *(inst.inputs for inst in plan.instances))
    return shared("stepper arrays", owners, lambda: _make_structure(plan))


def _make_structure(plan: Plan) -> _Structure:
    return _Structure(
        [
            tuple(
                np.array([getattr(i, a) for i in inst.inputs] or [0], dtype=np.int32)
                for a in ("kind", "src", "idx")
            )
            for inst in plan.instances
        ],
        [
            tuple(
                np.array([getattr(i, a) for i in inst.inputs] or [v], dtype=np.float64)
                for a, v in (("factor", 1.0), ("offset", 0.0))
            )
            for inst in plan.instances
        ],
        # the instances a connection reads (the others' outputs are fetched only where a row,
        # or Python between two batches, can see them: stepper.c, fetch_needed)
        frozenset(i.src for inst in plan.instances for i in inst.inputs if i.kind != InputKind.DRIVEN),
        (TwinColumn * max(len(plan.columns), 1))(
            *[TwinColumn(c.instance, c.kind, c.idx, 0) for c in plan.columns]
        ),
    )


class NativeLoop:
    """The ticks in the compiled stepper, on the arrays of the exchange state."""

    def __init__(self, plan: Plan, state: State, slots: Sequence[FMUSlot]) -> None:
        self.plan = plan
        self.state = state
        self.fmus = list(slots)
        self._run = _entry_point()  # built (first use) before the clock starts
        # the structure's arrays, shared with the other runs of it (kept alive with the loop)
        self._inputs, self._affine, self._read, self.cols = _structure(plan)
        self.driven_every = driven_every(plan)
        self.slots = (TwinSlot * len(plan.instances))()
        for i, s in enumerate(self.slots):
            self._point(i, s)

    def _point(self, i: int, s: TwinSlot) -> None:
        inst, buf = self.plan.instances[i], self.state.buffers[i]
        s.comp, s.set_real, s.get_real, s.do_step = self.fmus[i].native_handles()
        s.period_ticks, s.period_ns = inst.period_ticks, inst.period_ns
        s.n_in, s.n_out = len(inst.inputs), len(inst.outputs)
        s.read_always = int(i in self._read)
        s.in_vr, s.out_vr = ctypes.addressof(buf.in_port.vr), ctypes.addressof(buf.out_port.vr)
        s.in_val, s.out_pending = buf.in_port.values.ctypes.data, buf.out_port.values.ctypes.data
        s.in_kind, s.in_src, s.in_idx = (a.ctypes.data for a in self._inputs[i])
        s.in_factor, s.in_offset = (a.ctypes.data for a in self._affine[i])
        s.delay_buf, s.out_raw, s.out_cur, s.bias = (
            a.ctypes.data for a in (buf.delay_buf, buf.raw, buf.cur, buf.bias)
        )
        s.pending_at = self.state.pending_at.ctypes.data + i * self.state.pending_at.itemsize

    def ticks(self, k0: int, k1: int, driven: np.ndarray, rows: np.ndarray) -> None:
        plan, c = self.plan, self.state.counters
        status = self._run(
            self.slots,
            len(plan.instances),
            k0,
            k1,
            plan.step_ns,
            plan.out_every,
            driven.ctypes.data,
            len(self.state.driven),
            self.driven_every,
            rows.ctypes.data,
            rows.shape[0],
            self.cols,
            len(plan.columns),
            ctypes.byref(c),
        )
        if status == Status.OVERFLOW:
            raise RunError("the stepper's row buffer was too small (a bug in the master)")
        if status != Status.OK:
            raise self._failure()

    def _failure(self) -> FMUError:
        c = self.state.counters
        inst, slot = self.plan.instances[c.fail_slot], self.fmus[c.fail_slot]
        slot.time = c.fail_tick * self.plan.step_ns / NS_PER_S
        if c.fail_call == Call.NON_FINITE:
            return non_finite(inst, slot, self.state.buffers[inst.index], c.fail_status)
        return slot.error(CALL_NAMES.get(c.fail_call, "?"), c.fail_status)


__all__ = ["SOURCES", "NativeLoop", "ensure_stepper", "stepper", "stepper_sources"]
