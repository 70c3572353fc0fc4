"""The co-simulation master.

Time is an integer number of nanoseconds: tick k is at ``k * step`` (never summed floats).
Each FMU steps with its own period (a multiple of the scenario step). Exchange is Jacobi:
every FMU due at time t gets its inputs from the outputs all FMUs had at t, then all of
them step from t to t + period. The outputs of an FMU that stepped to t + p become visible
only at t + p (until then the others see its value at t: zero-order hold), so a fast FMU
never sees a slow one's future.

simpy drives the clock: the run is a simpy process that executes whole runs of ticks
between two points of interest (scenario events, progress marks) and then yields a timeout
to the next one, so the scheduler is not in the per-step path.

Order within a tick t: (1) outputs that became valid at t are committed, (2) scenario events
at t are applied, (3) inputs of the FMUs due at t are written, (4) the row for t is recorded
if t is an output time, (5) the due FMUs step.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import simpy

from twin.config.load import model_variables, variable_unit
from twin.config.spec import NS_PER_S, Scenario
from twin.cosim.profiles import Signal, profile_function, ramp_from
from twin.errors import FMUError, RunError
from twin.fmu.build import ensure_fmu
from twin.fmu.slot import FMUSlot, RealPort
from twin.signals.table import Signal as SignalMeta
from twin.signals.table import SignalTable

ProgressFn = Callable[[int, int], None]


@dataclass
class RunResult:
    """What a run produced: the recorded signals (all rows up to a failure) and counters."""

    table: SignalTable
    status: str  # "completed" | "failed"
    error: RunError | None = None
    cosim_s: float = 0.0
    macro_steps: int = 0
    fmu_steps: int = 0
    end_ns: int = 0
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Instance:
    name: str
    slot: FMUSlot
    period_ns: int
    outputs: list[str]
    out_port: RealPort
    in_names: list[str]
    in_port: RealPort
    current: np.ndarray  # outputs visible now (bias included)
    raw: np.ndarray  # outputs as the FMU gave them at its last communication point
    bias: np.ndarray
    pending: np.ndarray
    pending_at: int = -1
    # input k <- (source instance index, source output index) for connections
    links: list[tuple[int, int, int]] = field(default_factory=list)
    delayed: list[tuple[int, int, int, float]] = field(default_factory=list)  # (k, src, idx, buffer)
    driven: dict[int, Signal] = field(default_factory=dict)  # input k <- profile/event function


class Master:
    """Runs one :class:`~twin.config.spec.Scenario`."""

    def __init__(self, scenario: Scenario, *, progress: ProgressFn | None = None) -> None:
        self.scenario = scenario
        self.progress = progress
        self.instances: list[_Instance] = []
        self._unzipdirs: dict[str, str] = {}

    # ------------------------------------------------------------------ set-up

    def _instance_seed(self, index: int) -> int:
        # distinct, reproducible noise streams per instance from the one scenario seed
        return (self.scenario.seed * 1_000_003 + 7919 * (index + 1)) % (2**31 - 1)

    def _create(self) -> None:
        sc = self.scenario
        index = {f.name: i for i, f in enumerate(sc.fmus)}
        for i, spec in enumerate(sc.fmus):
            fmu_path = ensure_fmu(spec.model)
            slot = FMUSlot(Path(fmu_path), spec.name)
            variables = model_variables(spec.model)
            outputs = [n for n, v in variables.items() if v.causality == "output" and v.type == "Real"]
            in_names = sorted(
                {c.dst.split(".")[1] for c in sc.connections if c.dst.split(".")[0] == spec.name}
                | {p.target.split(".")[1] for p in sc.profiles if p.target.split(".")[0] == spec.name}
                | {
                    e.target.split(".")[1]
                    for e in sc.events
                    if e.action != "bias" and e.target.split(".")[0] == spec.name
                }
            )
            n_out = len(outputs)
            inst = _Instance(
                name=spec.name,
                slot=slot,
                period_ns=spec.period_ns,
                outputs=outputs,
                out_port=slot.port(outputs),
                in_names=in_names,
                in_port=slot.port(in_names),
                current=np.zeros(n_out),
                raw=np.zeros(n_out),
                bias=np.zeros(n_out),
                pending=np.zeros(n_out),
            )
            # inputs that only a later event drives keep their declared start value until then
            for k, name in enumerate(in_names):
                start = variables[name].start
                inst.in_port.values[k] = float(start) if start is not None else 0.0
            self.instances.append(inst)
            slot.setup(0.0)
            params = dict(spec.parameters)
            if "seed" in variables and "seed" not in params:
                slot.set_value("seed", self._instance_seed(i))
            for name, p in params.items():
                slot.set_value(name, p.value)
        for c in sc.connections:
            si, sv = c.src.split(".")
            di, dv = c.dst.split(".")
            src, dst = index[si], self.instances[index[di]]
            k = dst.in_names.index(dv)
            idx = self.instances[src].outputs.index(sv)
            if c.delay:
                dst.delayed.append((k, src, idx, float(c.initial or 0.0)))
            else:
                dst.links.append((k, src, idx))
        for p in sc.profiles:
            inst = self.instances[index[p.target.split(".")[0]]]
            inst.driven[inst.in_names.index(p.target.split(".")[1])] = profile_function(p)

    def _init_order(self) -> list[int]:
        """Instances in dependency order of undelayed connections (the loader excluded loops)."""
        deps = {i: {src for _, src, _ in inst.links} for i, inst in enumerate(self.instances)}
        order: list[int] = []
        while len(order) < len(self.instances):
            ready = [i for i in deps if i not in order and deps[i] <= set(order)]
            order.extend(ready)
        return order

    def _write_inputs(self, inst: _Instance, t_s: float, *, advance_delays: bool = True) -> None:
        vals = inst.in_port.values
        for k, src, idx in inst.links:
            vals[k] = self.instances[src].current[idx]
        for j, (k, src, idx, buffered) in enumerate(inst.delayed):
            vals[k] = buffered
            if advance_delays:  # the next exchange gets the source's value of this one
                inst.delayed[j] = (k, src, idx, float(self.instances[src].current[idx]))
        for k, fn in inst.driven.items():
            vals[k] = fn(t_s)
        inst.slot.write(inst.in_port)

    def _initialize(self) -> None:
        for i in self._init_order():
            inst = self.instances[i]
            inst.slot.enter_initialization()
            # a delayed input starts from its declared initial value (its source may not be
            # initialized yet: that is what the delay is for)
            self._write_inputs(inst, 0.0, advance_delays=False)
            inst.slot.exit_initialization()
            inst.slot.read(inst.out_port)
            inst.raw[:] = inst.out_port.values[: len(inst.outputs)]
            inst.current[:] = inst.raw + inst.bias

    # ------------------------------------------------------------------ recording

    def _columns(self) -> list[tuple[int, str, int, SignalMeta]]:
        """(instance, kind, index, meta): every output, and every input the scenario drives."""
        cols = []
        for i, inst in enumerate(self.instances):
            variables = model_variables(self.scenario.fmus[i].model)
            for k, name in enumerate(inst.outputs):
                v = variables[name]
                cols.append(
                    (
                        i,
                        "out",
                        k,
                        SignalMeta(f"{inst.name}.{name}", variable_unit(v), inst.name, v.description or ""),
                    )
                )
            for k, name in enumerate(inst.in_names):
                if k in inst.driven:
                    v = variables[name]
                    cols.append(
                        (
                            i,
                            "in",
                            k,
                            SignalMeta(
                                f"{inst.name}.{name}", variable_unit(v), inst.name, v.description or ""
                            ),
                        )
                    )
        return cols

    # ------------------------------------------------------------------ the run

    def run(self) -> RunResult:
        """Run the scenario; a failure mid-run returns every row recorded before it."""
        sc = self.scenario
        start = wallclock.perf_counter()
        n_ticks = sc.duration_ns // sc.step_ns
        n_rows = sc.duration_ns // sc.output_interval_ns + 1
        try:
            self._create()
            self._initialize()
        except RunError:
            self.close()
            raise
        cols = self._columns()
        data = np.zeros((n_rows, len(cols)))
        times = np.arange(n_rows, dtype=np.int64) * sc.output_interval_ns
        state = {"row": 0, "macro": 0, "fmu_steps": 0, "tick": 0}
        events = list(sc.events)
        overrides: dict[tuple[int, int], Signal] = {}
        inst_index = {inst.name: i for i, inst in enumerate(self.instances)}

        def apply_events(t_ns: int) -> None:
            t_s = t_ns / NS_PER_S
            while events and events[0].at_ns == t_ns:
                e = events.pop(0)
                iname, var = e.target.split(".")
                inst = self.instances[inst_index[iname]]
                if e.action == "bias":
                    k = inst.outputs.index(var)
                    inst.bias[k] += e.value
                    inst.current[k] = inst.raw[k] + inst.bias[k]
                    continue
                k = inst.in_names.index(var)
                now = inst.in_port.values[k]
                inst.driven[k] = (
                    (lambda v: lambda t: v)(e.value)
                    if e.action == "set"
                    else ramp_from(float(now), e.value, t_s, e.duration_ns / NS_PER_S)
                )
                overrides[(inst_index[iname], k)] = inst.driven[k]

        def record(row: int) -> None:
            for c, (i, kind, k, _) in enumerate(cols):
                inst = self.instances[i]
                data[row, c] = inst.current[k] if kind == "out" else inst.in_port.values[k]

        def run_ticks(k0: int, k1: int) -> None:
            # ticks k0..k1-1; each as described in the module docstring
            for k in range(k0, k1):
                t_ns = k * sc.step_ns
                t_s = t_ns / NS_PER_S
                state["tick"] = k
                for inst in self.instances:
                    if inst.pending_at == t_ns:
                        inst.raw[:] = inst.pending
                        np.add(inst.raw, inst.bias, out=inst.current)
                        inst.pending_at = -1
                if events and events[0].at_ns == t_ns:
                    apply_events(t_ns)
                due = [inst for inst in self.instances if t_ns % inst.period_ns == 0]
                for inst in due:
                    self._write_inputs(inst, t_s)
                if t_ns % sc.output_interval_ns == 0:
                    record(state["row"])
                    state["row"] += 1
                for inst in due:
                    h = inst.period_ns / NS_PER_S
                    inst.slot.do_step(t_s, h)
                    inst.slot.read(inst.out_port)
                    inst.pending[:] = inst.out_port.values[: len(inst.outputs)]
                    inst.pending_at = t_ns + inst.period_ns
                    state["fmu_steps"] += 1
                state["macro"] += 1

        def final_tick() -> None:
            t_ns = n_ticks * sc.step_ns
            for inst in self.instances:
                if inst.pending_at == t_ns:
                    inst.raw[:] = inst.pending
                    np.add(inst.raw, inst.bias, out=inst.current)
            for inst in self.instances:
                for k, fn in inst.driven.items():
                    inst.in_port.values[k] = fn(t_ns / NS_PER_S)
            if t_ns % sc.output_interval_ns == 0:
                record(state["row"])
                state["row"] += 1

        marks = sorted(
            {e.at_ns // sc.step_ns for e in sc.events}
            | {n_ticks * j // 100 for j in range(1, 101)}
            | {n_ticks}
        )

        failure: list[RunError] = []

        def process(env: simpy.Environment) -> Any:
            k = 0
            try:
                for mark in marks:
                    if mark <= k:
                        continue
                    run_ticks(k, mark)
                    yield env.timeout((mark - k) * sc.step_ns)
                    k = mark
                    if self.progress:
                        self.progress(env.now, sc.duration_ns)
                final_tick()
            except RunError as exc:  # the run stops; what was recorded stays
                failure.append(exc)

        env = simpy.Environment()
        env.process(process(env))
        try:
            env.run()
        finally:
            self.close()
        error = failure[0] if failure else None
        rows = state["row"]
        table = SignalTable(times[:rows] / NS_PER_S)
        for c, (_, _, _, meta) in enumerate(cols):
            table.add(meta, data[:rows, c])
        return RunResult(
            table=table,
            status="failed" if error else "completed",
            error=error,
            cosim_s=wallclock.perf_counter() - start,
            macro_steps=state["macro"],
            fmu_steps=state["fmu_steps"],
            end_ns=state["tick"] * sc.step_ns if error else n_ticks * sc.step_ns,
        )

    def close(self) -> None:
        for inst in self.instances:
            inst.slot.close()
        self.instances = []


def run_scenario(scenario: Scenario, *, progress: ProgressFn | None = None) -> RunResult:
    """Convenience: run a scenario with a fresh master."""
    return Master(scenario, progress=progress).run()


__all__ = ["FMUError", "Master", "RunResult", "run_scenario"]
