"""Algebraic loops solved by fixed-point iteration, and initialization variable by variable.

A true algebraic loop (a cycle of connections through outputs with direct feedthrough,
:mod:`twin.config.loops`) has no order in which its values can be computed once: at a
communication point each of its outputs is a function of inputs that are functions of the
others. :class:`LoopSolver` iterates it there: the loop's instances get their inputs, the
master sets them, reads the outputs again (FMI 2.0 allows fmi2SetReal on inputs and
fmi2GetReal on outputs any number of times after fmi2DoStep, before the next one), passes them
on through the connections and repeats until no input of the loop's instances changes by more
than :data:`TOLERANCE` of its magnitude (or its nominal value, if larger) from one pass to the
next; the instances then step from those inputs. A loop that has not converged after
:data:`MAX_ITERATIONS` passes stops the run with a :class:`~twin.errors.RunError` naming it.

Why no state rollback (fmi2GetFMUstate/fmi2SetFMUstate): the iteration never steps. Setting an
input at a communication point only changes the outputs that depend on it directly, computed
from the state the FMU holds at that point; fmi2DoStep is called once, after the iteration, with
the inputs it converged to, held over the step as for any other input. Rollback is needed by a
master that repeats a step (to iterate on the inputs at its end, or to reject it); this one
never repeats a step, so no FMU is asked to be able to go back.

Initialization (:func:`initialize`) is done variable by variable for the same reason: with a
loop between instances, no instance can be initialized whole before another. Every instance
enters initialization mode; the inputs known at once (driven, delayed) are set; then, stage by
stage (:class:`twin.cosim.plan.PlannedStage`), the inputs whose sources are read are set and
the outputs whose dependencies are set are read (FMI 2.0 allows fmi2GetReal in initialization
mode), a cycle of the initial dependencies being iterated as above; each instance leaves
initialization mode as soon as every input of it is set (its outputs are then read from the
initialized instance), and at last every instance's outputs become visible.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.plan import InputKind, Plan, PlannedInput, PlannedLoop, VarIndex, shared
from twin.cosim.state import Buffers, State
from twin.cosim.stepping import Gather, non_finite
from twin.errors import RunError
from twin.fmu import catalog
from twin.fmu.slot import FMUSlot, RealPort

__all__ = ["MAX_ITERATIONS", "TOLERANCE", "LoopError", "LoopSolver", "initialize", "loop_solvers"]

#: an iteration has converged when no input changed by more than this, relative to the larger
#: of its magnitude and its nominal value, from one pass to the next
TOLERANCE = 1e-12
#: passes of an iteration before the run stops with the loop named (a loop whose error shrinks
#: by a factor q each pass needs about 12 / -log10(q) passes: 17 for q = 0.2, 124 for q = 0.8)
MAX_ITERATIONS = 500


def _scales(plan: Plan, instances: Sequence[int]) -> np.ndarray:
    """Each input's nominal magnitude, instance after instance (what a change is judged against
    when its value is near zero)."""
    out = []
    for i in instances:
        inst = plan.instances[i]
        variables = catalog.variables(inst.model)
        out += [variables[n].nominal for n in inst.in_names]
    return np.array(out, dtype=np.float64)


def _converged(new: np.ndarray, old: np.ndarray, nominal: np.ndarray) -> bool:
    return bool(np.all(np.abs(new - old) <= TOLERANCE * np.maximum(np.abs(new), nominal)))


class LoopError(RunError):
    """An algebraic loop that fixed-point iteration did not solve: ``loop`` names its cycle,
    ``when`` says where ("at initialization", "at t = 12 s")."""

    def __init__(self, loop: str, when: str) -> None:
        self.loop = loop
        self.when = when
        super().__init__(loop, when)  # the arguments, so that a copy made from .args is the same

    def __str__(self) -> str:
        return (
            f"algebraic loop {self.loop} did not converge {self.when}: its inputs still changed by "
            f"more than {TOLERANCE:g} (relative) after {MAX_ITERATIONS} passes of fixed-point "
            "iteration; break it with a [[delay]] (from, to, initial)"
        )


class LoopSolver:
    """One algebraic loop of the plan, iterated at its instances' communication points."""

    def __init__(self, loop: PlannedLoop, plan: Plan, state: State, slots: Sequence[FMUSlot]) -> None:
        self.name = loop.name
        self.instances = loop.instances
        # the loader made every instance of a loop step with one period (twin.config.loops)
        self.period_ticks = plan.instances[self.instances[0]].period_ticks
        self.members = [
            (plan.instances[i], slots[i], state.buffers[i], Gather(plan.instances[i], state.buffers))
            for i in self.instances
        ]
        self.nominal = _scales(plan, self.instances)

    def _inputs(self) -> np.ndarray:
        return np.concatenate([buf.in_port.values[: len(inst.inputs)] for inst, _, buf, _ in self.members])

    def solve(self, drow: np.ndarray, t: float, *, exchange: bool) -> int:
        """Gather the loop's instances' inputs (``exchange``: as :class:`Gather` does), then iterate
        until they converge; the FMUs hold the last inputs set, and their outputs, read from
        those, are visible. Returns the passes made.

        A pass goes round the instances in turn (Gauss-Seidel): each takes its connected inputs
        from the outputs read last, this pass's included, and its outputs are read again."""
        for _, _, _, gather in self.members:
            gather(drow, exchange=exchange)
        for n in range(1, MAX_ITERATIONS + 1):
            for inst, slot, buf, gather in self.members:
                gather.connect()
                slot.time = t
                slot.write(buf.in_port)
                slot.read(buf.out_port)
                values = buf.out_port.values[: len(inst.outputs)]
                if not np.isfinite(values).all():
                    raise non_finite(inst, slot, buf, int(np.flatnonzero(~np.isfinite(values))[0]))
                buf.commit()
            held = self._inputs()
            for _, _, _, gather in self.members:
                gather.connect()
            if _converged(self._inputs(), held, self.nominal):
                self._put(held)  # what the FMUs hold, and what their outputs were read from
                return n
        raise LoopError(self.name, f"at t = {t:.6g} s")

    def _put(self, x: np.ndarray) -> None:
        at = 0
        for inst, _, buf, _ in self.members:
            n = len(inst.inputs)
            buf.in_port.values[:n] = x[at : at + n]
            at += n


def loop_solvers(plan: Plan, state: State, slots: Sequence[FMUSlot]) -> list[LoopSolver]:
    """A solver for each algebraic loop of the plan, in the plan's order (each after those it
    depends on)."""
    return [LoopSolver(loop, plan, state, slots) for loop in plan.loops]


# ------------------------------------------------------------------------- initialization


def _connected(i: PlannedInput, buffers: Sequence[Buffers]) -> float:
    """What a connection gives its input now: as :class:`Gather` computes it, bit for bit."""
    v = buffers[i.src].cur[i.idx]
    return v * i.factor + i.offset if i.factor != 1.0 or i.offset != 0.0 else v


class _Groups(NamedTuple):
    """Variables (instance, index) by instance, in the instances' order, each instance's in
    the order given."""

    groups: tuple[tuple[int, list[int]], ...]

    @classmethod
    def of(cls, refs: Sequence[VarIndex]) -> _Groups:
        groups: dict[int, list[int]] = {}
        for i, k in refs:
            groups.setdefault(i, []).append(k)
        return cls(tuple(sorted(groups.items())))


class _Order(NamedTuple):
    """What :func:`initialize` does, in its order, for any run of a plan's structure: the
    inputs known before anything is read, then per stage the inputs it sets, the instances
    that leave initialization mode, the outputs it reads and its cycles."""

    known: _Groups
    stages: tuple[tuple[_Groups, list[int], _Groups, tuple[PlannedLoop, ...]], ...]


def _order(plan: Plan) -> _Order:
    """The plan's :class:`_Order`, worked out once for the plans that share its stages and
    inputs (:func:`twin.cosim.plan.shared`: a Monte Carlo's samples)."""
    owners = (plan.init_stages, *(inst.inputs for inst in plan.instances))
    return shared("initialization order", owners, lambda: _make_order(plan))


def _make_order(plan: Plan) -> _Order:
    known = [
        (inst.index, j)
        for inst in plan.instances
        for j, i in enumerate(inst.inputs)
        if i.kind != InputKind.CONNECTION
    ]
    return _Order(
        _Groups.of(known),
        tuple(
            (_Groups.of(stage.inputs), sorted(leaving), _Groups.of(stage.outputs), stage.cycles)
            for stage, leaving in zip(plan.init_stages, _leaving(plan), strict=True)
        ),
    )


class _Variables:
    """Some inputs or outputs of the instances, set or read in one call per instance."""

    def __init__(
        self, plan: Plan, state: State, slots: Sequence[FMUSlot], refs: Sequence[VarIndex] | _Groups
    ) -> None:
        self.plan, self.state = plan, state
        grouped = refs if isinstance(refs, _Groups) else _Groups.of(refs)
        self.groups = [(i, slots[i], ks) for i, ks in grouped.groups]
        self.ports: list[RealPort] = []

    def _port(self, n: int, vrs: Sequence[int]) -> RealPort:
        while len(self.ports) <= n:
            self.ports.append(RealPort(vrs))
        return self.ports[n]

    def set_inputs(self, *, connected: bool) -> np.ndarray:
        """Set these inputs (``connected``: from their sources first); their values set."""
        out = []
        for n, (i, slot, ks) in enumerate(self.groups):
            inst, buf = self.plan.instances[i], self.state.buffers[i]
            port = self._port(n, [inst.inputs[k].vr for k in ks])
            if connected:
                for k in ks:
                    buf.in_port.values[k] = _connected(inst.inputs[k], self.state.buffers)
            port.values[: len(ks)] = buf.in_port.values[ks]
            slot.write(port)
            out.append(port.values[: len(ks)].copy())
        return np.concatenate(out) if out else np.zeros(0)

    def held(self) -> np.ndarray:
        """The values these inputs were last set to."""
        out = [self.state.buffers[i].in_port.values[k] for i, _, ks in self.groups for k in ks]
        return np.array(out, dtype=np.float64)

    def values_from_sources(self) -> np.ndarray:
        """What these (connected) inputs would be given now."""
        out = [
            _connected(self.plan.instances[i].inputs[k], self.state.buffers)
            for i, _, ks in self.groups
            for k in ks
        ]
        return np.array(out, dtype=np.float64)

    def nominal(self) -> np.ndarray:
        """The nominal magnitude of each of these inputs, in the order of their values."""
        out = []
        for i, _, ks in self.groups:
            inst = self.plan.instances[i]
            variables = catalog.variables(inst.model)
            out += [variables[inst.inputs[k].name].nominal for k in ks]
        return np.array(out, dtype=np.float64)

    def read_outputs(self) -> None:
        """Read these outputs; they become visible (their bias added)."""
        for n, (i, slot, ks) in enumerate(self.groups):
            inst, buf = self.plan.instances[i], self.state.buffers[i]
            port = self._port(n, [inst.out_vrs[k] for k in ks])
            slot.read(port)
            buf.raw[ks] = port.values[: len(ks)]
            buf.cur[ks] = buf.raw[ks] + buf.bias[ks]


def _initial_cycle(plan: Plan, state: State, slots: Sequence[FMUSlot], loop: PlannedLoop) -> None:
    """A cycle of initial dependencies, iterated as :meth:`LoopSolver.solve` iterates (instance
    after instance) on its own inputs and outputs: its outputs are read first from the inputs
    the FMUs hold (their start values until set)."""
    members = [
        (
            _Variables(plan, state, slots, [v for v in loop.inputs if v[0] == i]),
            _Variables(plan, state, slots, [v for v in loop.outputs if v[0] == i]),
        )
        for i in loop.instances
    ]
    every = _Variables(plan, state, slots, loop.inputs)
    nominal = every.nominal()
    for _, outputs in members:
        outputs.read_outputs()
    for _ in range(MAX_ITERATIONS):
        for inputs, outputs in members:
            inputs.set_inputs(connected=True)
            outputs.read_outputs()
        if _converged(every.values_from_sources(), every.held(), nominal):
            return
    raise LoopError(loop.name, "at initialization")


def _leaving(plan: Plan) -> list[set[int]]:
    """Per initialization stage, the instances that may leave initialization mode before its
    outputs are read: every input of theirs is set by then (driven and delayed ones before the
    stages, connected ones in a stage before, or in this one and on none of its cycles, which
    set them again). An instance with a connected input no stage sets leaves at the end."""
    last = {inst.index: -1 for inst in plan.instances}  # the stage that sets its last input
    staged: set[VarIndex] = set()
    iterated: list[set[int]] = []
    for s, stage in enumerate(plan.init_stages):
        on_cycles = [v for c in stage.cycles for v in c.inputs]
        for i, k in (*stage.inputs, *on_cycles):
            last[i] = s
            staged.add((i, k))
        iterated.append({i for i, _ in on_cycles})
    for inst in plan.instances:
        if any(
            p.kind == InputKind.CONNECTION and (inst.index, k) not in staged
            for k, p in enumerate(inst.inputs)
        ):
            last[inst.index] = len(plan.init_stages)
    leaving: list[set[int]] = [set() for _ in plan.init_stages]
    for i, s in last.items():
        if s < 0:
            at = 0
        elif s < len(leaving):
            at = s + (i in iterated[s])  # after the cycles that set its inputs again
        else:
            continue  # leaves at the end
        if at < len(leaving):
            leaving[at].add(i)
    return leaving


def initialize(plan: Plan, state: State, slots: Sequence[FMUSlot]) -> None:
    """Initialization mode of every instance, variable by variable (see the module); the
    outputs become visible.

    An instance leaves initialization mode as soon as every input of it is set, before its
    outputs are read for the others (:func:`_leaving`), not after every instance's: an FMU
    that works out its initial state for an output read in initialization mode works it out
    again when it leaves it (FMI 2.0 lets fmi2GetReal read an initialized instance's outputs
    at the start time, and lets the others be still in initialization mode)."""
    order = _order(plan)
    drow = state.driven.row(plan.scenario.start_ns / NS_PER_S)
    for slot in slots:
        slot.enter_initialization()
    for inst in plan.instances:
        Gather(inst, state.buffers).drive(drow)
    # driven inputs and delayed ones (their initial value): known before anything is read
    _Variables(plan, state, slots, order.known).set_inputs(connected=False)
    left: set[int] = set()

    def leave(i: int) -> None:
        slots[i].write(state.buffers[i].in_port)
        slots[i].exit_initialization()
        left.add(i)

    for inputs, leaving, outputs, cycles in order.stages:
        _Variables(plan, state, slots, inputs).set_inputs(connected=True)
        for i in leaving:
            if i not in left:
                leave(i)
        _Variables(plan, state, slots, outputs).read_outputs()
        for cycle in cycles:
            _initial_cycle(plan, state, slots, cycle)
    for i, (slot, buf) in enumerate(zip(slots, state.buffers, strict=True)):
        if i not in left:
            leave(i)
        slot.read(buf.out_port)
        buf.commit()
