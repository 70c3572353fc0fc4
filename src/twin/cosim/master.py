"""The co-simulation master.

Time is an integer number of nanoseconds: tick k is at ``k * step`` (never summed floats).
Each FMU steps with its own period (a multiple of the scenario step). Exchange is Jacobi:
every FMU due at time t gets its inputs from the outputs all FMUs had at t, then all of
them step from t to t + period. The outputs of an FMU that stepped to t + p become visible
only at t + p (until then the others see its value at t: zero-order hold), so a fast FMU
never sees a slow one's future.

simpy drives the clock: the run is a simpy process that executes whole batches of ticks
between two points of interest (scenario events, progress marks, the batch limit) and then
yields a timeout to the next one, so the scheduler is not in the per-step path.

Order within a tick t: (1) outputs that became valid at t are committed, (2) scenario events
at t are applied (between batches), (3) inputs of the FMUs due at t are written, (4) the row
for t is recorded if t is an output time, (5) the due FMUs step.

The ticks of a batch run in the compiled stepper (``native/stepper.c``) over a static
exchange plan kept in numpy arrays that both sides share; ``loop="reference"`` runs the same
plan in plain Python instead (the tests check both give identical signals). The inputs that
profiles and events drive are evaluated for a whole batch at once with numpy.
"""

from __future__ import annotations

import ctypes
import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
import simpy

from twin.config.load import model_variables, variable_unit
from twin.config.spec import NS_PER_S, Scenario
from twin.cosim.profiles import Signal, constant, profile_function, ramp_from
from twin.errors import FMUError, RunError
from twin.fmu.build import ensure_fmu
from twin.fmu.slot import FMUSlot, RealPort
from twin.signals.table import Signal as SignalMeta
from twin.signals.table import SignalTable

ProgressFn = Callable[[int, int], None]
Loop = Literal["fast", "reference"]

#: ticks per batch: bounds the driven-input matrix and the row buffer (memory flat in run length)
BATCH_TICKS = 32_768

IN_CONNECTION, IN_DELAYED, IN_DRIVEN = 0, 1, 2


class Recorder(Protocol):
    """Where recorded rows go, chunk by chunk, while the run goes."""

    def open(self, signals: list[SignalMeta]) -> None: ...
    def append(self, times: np.ndarray, rows: np.ndarray) -> None: ...
    def close(self) -> None: ...


class MemoryRecorder:
    """Keeps every row in memory (tests, short runs); :meth:`table` gives the SignalTable."""

    def __init__(self) -> None:
        self.signals: list[SignalMeta] = []
        self._times: list[np.ndarray] = []
        self._rows: list[np.ndarray] = []

    def open(self, signals: list[SignalMeta]) -> None:
        self.signals = list(signals)

    def append(self, times: np.ndarray, rows: np.ndarray) -> None:
        self._times.append(np.array(times, dtype=np.float64))
        self._rows.append(np.array(rows, dtype=np.float64))

    def close(self) -> None:
        pass

    def table(self) -> SignalTable:
        n = len(self.signals)
        times = np.concatenate(self._times) if self._times else np.zeros(0)
        rows = np.concatenate(self._rows) if self._rows else np.zeros((0, n))
        table = SignalTable(times)
        for c, meta in enumerate(self.signals):
            table.add(meta, rows[:, c])
        return table


@dataclass
class RunResult:
    """What a run produced: the recorded signals (all rows up to a failure) and counters."""

    table: SignalTable | None
    status: str  # "completed" | "failed"
    error: RunError | None = None
    cosim_s: float = 0.0
    macro_steps: int = 0
    fmu_steps: int = 0
    end_ns: int = 0
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Instance:
    """One FMU in the exchange plan; the arrays are shared with the compiled stepper."""

    name: str
    model: str
    slot: FMUSlot
    period_ns: int
    outputs: list[str]
    in_names: list[str]
    in_port: RealPort  # its values are the inputs last set (in_val)
    out_port: RealPort  # its values receive the outputs after a step (pending)
    in_kind: np.ndarray
    in_src: np.ndarray
    in_idx: np.ndarray
    delay_buf: np.ndarray
    raw: np.ndarray
    cur: np.ndarray
    bias: np.ndarray


class Master:
    """Runs one :class:`~twin.config.spec.Scenario`."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        progress: ProgressFn | None = None,
        loop: Loop = "fast",
        recorder: Recorder | None = None,
        stop: Callable[[], str | None] | None = None,
        checkpoint_every_ns: int | None = None,
        on_checkpoint: Callable[[dict[str, Any]], None] | None = None,
        resume: dict[str, Any] | None = None,
    ) -> None:
        self.scenario = scenario
        self.progress = progress
        self.loop = loop
        self.recorder = recorder if recorder is not None else MemoryRecorder()
        self.stop = stop  # polled between batches: a signal name when the run must stop
        self.checkpoint_every_ns = checkpoint_every_ns
        self.on_checkpoint = on_checkpoint
        self.resume = resume
        self.instances: list[_Instance] = []
        self.driven: list[Signal] = []  # one function of time per driven input column
        self.driven_spec: list[tuple[Any, ...]] = []  # how to rebuild each (checkpoints)
        self._slots: Any = None  # ctypes array of TwinSlot

    # ------------------------------------------------------------------ set-up

    def _instance_seed(self, index: int) -> int:
        # distinct, reproducible noise streams per instance from the one scenario seed
        return (self.scenario.seed * 1_000_003 + 7919 * (index + 1)) % (2**31 - 1)

    def _create(self) -> None:
        sc = self.scenario
        index = {f.name: i for i, f in enumerate(sc.fmus)}
        for i, spec in enumerate(sc.fmus):
            slot = FMUSlot(Path(ensure_fmu(spec.model)), spec.name)
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
            n_in, n_out = len(in_names), len(outputs)
            inst = _Instance(
                name=spec.name,
                model=spec.model,
                slot=slot,
                period_ns=spec.period_ns,
                outputs=outputs,
                in_names=in_names,
                in_port=slot.port(in_names),
                out_port=slot.port(outputs),
                in_kind=np.full(max(n_in, 1), IN_DRIVEN, dtype=np.int32),
                in_src=np.zeros(max(n_in, 1), dtype=np.int32),
                in_idx=np.zeros(max(n_in, 1), dtype=np.int32),
                delay_buf=np.zeros(max(n_in, 1)),
                raw=np.zeros(max(n_out, 1)),
                cur=np.zeros(max(n_out, 1)),
                bias=np.zeros(max(n_out, 1)),
            )
            # every input no connection feeds is driven by a function of time: its profile,
            # or its declared start value until an event sets or ramps it
            for k, name in enumerate(in_names):
                start = variables[name].start
                inst.in_port.values[k] = float(start) if start is not None else 0.0
                inst.in_src[k] = len(self.driven)
                self.driven.append(constant(inst.in_port.values[k]))
                self.driven_spec.append(("constant", float(inst.in_port.values[k])))
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
            dst = self.instances[index[di]]
            k = dst.in_names.index(dv)
            dst.in_kind[k] = IN_DELAYED if c.delay else IN_CONNECTION
            dst.in_src[k] = index[si]
            dst.in_idx[k] = self.instances[index[si]].outputs.index(sv)
            if c.delay:
                dst.delay_buf[k] = float(c.initial or 0.0)
        for n, p in enumerate(sc.profiles):
            inst = self.instances[index[p.target.split(".")[0]]]
            k = inst.in_names.index(p.target.split(".")[1])
            self.driven[int(inst.in_src[k])] = profile_function(p)
            self.driven_spec[int(inst.in_src[k])] = ("profile", n)

    def _set_driven(self, column: int, spec: tuple[Any, ...]) -> None:
        """Drive input column ``column`` by ``spec``: ("constant", v), ("profile", index) or
        ("ramp", v0, v1, t0, duration); kept as data so a checkpoint can rebuild it."""
        kind = spec[0]
        if kind == "constant":
            fn = constant(spec[1])
        elif kind == "profile":
            fn = profile_function(self.scenario.profiles[int(spec[1])])
        else:
            fn = ramp_from(*map(float, spec[1:]))
        self.driven[column] = fn
        self.driven_spec[column] = tuple(spec)

    # ------------------------------------------------------------------ checkpoints

    def _snapshot(self, tick: int, counters: Any, events_applied: int) -> dict[str, Any]:
        """The whole twin at a batch boundary: FMU states (noise generators included),
        exchange buffers, driven inputs, clock and counters."""
        return {
            "tick": tick,
            "macro_steps": int(counters.macro_steps),
            "fmu_steps": int(counters.fmu_steps),
            "events_applied": events_applied,
            "driven": [list(d) for d in self.driven_spec],
            "instances": [
                {
                    "name": inst.name,
                    "state": inst.slot.save_state(),
                    "in_val": inst.in_port.values.copy(),
                    "delay_buf": inst.delay_buf.copy(),
                    "raw": inst.raw.copy(),
                    "cur": inst.cur.copy(),
                    "bias": inst.bias.copy(),
                    "pending": inst.out_port.values.copy(),
                    "pending_at": int(s.pending_at),
                }
                for inst, s in zip(self.instances, self._slots, strict=True)
            ],
        }

    def _restore(self, snap: dict[str, Any]) -> None:
        for inst, s, saved in zip(self.instances, self._slots, snap["instances"], strict=True):
            if saved["name"] != inst.name:
                raise RunError(f"checkpoint holds instance '{saved['name']}', the scenario '{inst.name}'")
            inst.slot.restore_state(saved["state"])
            for name in ("delay_buf", "raw", "cur", "bias"):
                getattr(inst, name)[:] = saved[name]
            inst.in_port.values[:] = saved["in_val"]
            inst.out_port.values[:] = saved["pending"]
            s.pending_at = int(saved["pending_at"])
        for column, spec in enumerate(snap["driven"]):
            self._set_driven(column, tuple(spec))

    def _init_order(self) -> list[int]:
        """Instances in dependency order of undelayed connections (the loader excluded loops)."""
        deps = {
            i: {int(inst.in_src[k]) for k in range(len(inst.in_names)) if inst.in_kind[k] == IN_CONNECTION}
            for i, inst in enumerate(self.instances)
        }
        order: list[int] = []
        while len(order) < len(self.instances):
            order.extend(i for i in deps if i not in order and deps[i] <= set(order))
        return order

    def _initialize(self) -> None:
        for i in self._init_order():
            inst = self.instances[i]
            inst.slot.enter_initialization()
            vals = inst.in_port.values
            for k in range(len(inst.in_names)):
                kind, src = inst.in_kind[k], int(inst.in_src[k])
                if kind == IN_CONNECTION:
                    vals[k] = self.instances[src].cur[inst.in_idx[k]]
                elif kind == IN_DELAYED:
                    # its source may not be initialized yet: that is what the delay is for
                    vals[k] = inst.delay_buf[k]
                else:
                    vals[k] = float(self.driven[src](np.zeros(1))[0])
            inst.slot.write(inst.in_port)
            inst.slot.exit_initialization()
            inst.slot.read(inst.out_port)
            n = len(inst.outputs)
            inst.raw[:n] = inst.out_port.values[:n]
            inst.cur[:] = inst.raw + inst.bias

    def _build_slots(self) -> Any:
        from twin.cosim.native import TwinSlot

        def ptr(a: np.ndarray) -> int:
            return int(a.ctypes.data)

        slots = (TwinSlot * len(self.instances))()
        for s, inst in zip(slots, self.instances, strict=True):
            f = inst.slot._slave._functions
            s.comp = inst.slot._c
            s.set_real = ctypes.cast(f["fmi2SetReal"], ctypes.c_void_p).value
            s.get_real = ctypes.cast(f["fmi2GetReal"], ctypes.c_void_p).value
            s.do_step = ctypes.cast(f["fmi2DoStep"], ctypes.c_void_p).value
            s.period_ticks = inst.period_ns // self.scenario.step_ns
            s.period_ns = inst.period_ns
            s.n_in, s.n_out = len(inst.in_names), len(inst.outputs)
            s.in_vr = ctypes.cast(inst.in_port.vr, ctypes.c_void_p).value
            s.in_val = ptr(inst.in_port.values)
            s.in_kind, s.in_src, s.in_idx, s.delay_buf = map(
                ptr, (inst.in_kind, inst.in_src, inst.in_idx, inst.delay_buf)
            )
            s.out_vr = ctypes.cast(inst.out_port.vr, ctypes.c_void_p).value
            s.out_raw, s.out_cur, s.out_pending, s.bias = map(
                ptr, (inst.raw, inst.cur, inst.out_port.values, inst.bias)
            )
            s.pending_at = -1
        return slots

    # ------------------------------------------------------------------ recording

    def _columns(self) -> list[tuple[int, int, int, SignalMeta]]:
        """(instance, kind 0 output / 1 input, index, meta): every output, every driven input."""
        cols = []
        for i, inst in enumerate(self.instances):
            variables = model_variables(inst.model)
            for k, name in enumerate(inst.outputs):
                v = variables[name]
                cols.append(
                    (
                        i,
                        0,
                        k,
                        SignalMeta(f"{inst.name}.{name}", variable_unit(v), inst.name, v.description or ""),
                    )
                )
            for k, name in enumerate(inst.in_names):
                if inst.in_kind[k] == IN_DRIVEN:
                    v = variables[name]
                    cols.append(
                        (
                            i,
                            1,
                            k,
                            SignalMeta(
                                f"{inst.name}.{name}", variable_unit(v), inst.name, v.description or ""
                            ),
                        )
                    )
        return cols

    # ------------------------------------------------------------------ the ticks

    def _driven_matrix(self, k0: int, k1: int) -> np.ndarray:
        t = np.arange(k0, k1, dtype=np.int64) * self.scenario.step_ns / NS_PER_S
        out = np.empty((k1 - k0, max(len(self.driven), 1)))
        for d, fn in enumerate(self.driven):
            out[:, d] = fn(t)
        return out

    def _ticks_reference(
        self, k0: int, k1: int, driven: np.ndarray, rows: np.ndarray, cols: Any, counters: Any
    ) -> None:
        """The same ticks as ``native/stepper.c``, in Python, on the same arrays."""
        sc = self.scenario
        out_every = sc.output_interval_ns // sc.step_ns
        for k in range(k0, k1):
            t_ns = k * sc.step_ns
            t = t_ns / NS_PER_S
            drow = driven[k - k0]
            for inst, s in zip(self.instances, self._slots, strict=True):
                if s.pending_at == k:
                    n = len(inst.outputs)
                    inst.raw[:n] = inst.out_port.values[:n]
                    np.add(inst.raw, inst.bias, out=inst.cur)
                    s.pending_at = -1
            due = [
                (inst, s)
                for inst, s in zip(self.instances, self._slots, strict=True)
                if k % s.period_ticks == 0
            ]
            for inst, _s in due:
                vals = inst.in_port.values
                for j in range(len(inst.in_names)):
                    kind, src = inst.in_kind[j], inst.in_src[j]
                    if kind == IN_CONNECTION:
                        vals[j] = self.instances[src].cur[inst.in_idx[j]]
                    elif kind == IN_DELAYED:
                        vals[j] = inst.delay_buf[j]
                        inst.delay_buf[j] = self.instances[src].cur[inst.in_idx[j]]
                    else:
                        vals[j] = drow[src]
                inst.slot.time = t
                inst.slot.write(inst.in_port)
            if k % out_every == 0:
                row = rows[counters.rows]
                for c, (i, kind, idx, _) in enumerate(cols):
                    inst = self.instances[i]
                    row[c] = inst.cur[idx] if kind == 0 else inst.in_port.values[idx]
                counters.rows += 1
            for inst, s in due:
                inst.slot.do_step(t, inst.period_ns / NS_PER_S)
                inst.slot.read(inst.out_port)
                bad = np.flatnonzero(~np.isfinite(inst.out_port.values[: len(inst.outputs)]))
                if bad.size:
                    inst.slot.time = t
                    raise self._non_finite(inst, int(bad[0]))
                s.pending_at = k + s.period_ticks
                counters.fmu_steps += 1
            counters.macro_steps += 1

    def _ticks_fast(
        self, k0: int, k1: int, driven: np.ndarray, rows: np.ndarray, ccols: Any, counters: Any
    ) -> None:
        from twin.cosim.native import CALLS, NON_FINITE, stepper

        sc = self.scenario
        status = stepper().twin_run_ticks(
            self._slots,
            len(self.instances),
            k0,
            k1,
            sc.step_ns,
            sc.output_interval_ns // sc.step_ns,
            driven.ctypes.data,
            len(self.driven),
            rows.ctypes.data,
            rows.shape[0],
            ccols,
            len(ccols),
            ctypes.byref(counters),
        )
        if status != 0:
            inst = self.instances[counters.fail_slot]
            inst.slot.time = counters.fail_tick * sc.step_ns / NS_PER_S
            if counters.fail_call == NON_FINITE:
                raise self._non_finite(inst, counters.fail_status)
            raise inst.slot._fail(CALLS.get(counters.fail_call, "?"), counters.fail_status)

    @staticmethod
    def _non_finite(inst: _Instance, j: int) -> FMUError:
        value = inst.out_port.values[j]
        return FMUError(
            inst.name,
            "fmi2GetReal",
            inst.slot.time,
            f"output '{inst.outputs[j]}' is {value} after fmi2DoStep returned fmi2OK",
        )

    # ------------------------------------------------------------------ the run

    def run(self) -> RunResult:
        """Run the scenario; a failure mid-run keeps every row recorded before it."""
        from twin.cosim.native import TwinColumn, TwinCounters

        sc = self.scenario
        start = wallclock.perf_counter()
        n_ticks = sc.duration_ns // sc.step_ns
        out_every = sc.output_interval_ns // sc.step_ns
        try:
            self._create()
            if self.resume is None:
                self._initialize()
            if self.loop == "fast":
                from twin.cosim.native import stepper

                stepper()  # build (first use) before the clock starts
        except RunError:
            self.close()
            raise
        self._slots = self._build_slots()
        if self.resume is not None:
            self._restore(self.resume)
        cols = self._columns()
        ccols = (TwinColumn * max(len(cols), 1))(*[TwinColumn(i, kind, idx, 0) for i, kind, idx, _ in cols])
        self.recorder.open([meta for *_, meta in cols])
        counters = TwinCounters()
        counters.fail_slot = -1
        events = list(sc.events)
        k_start = 0
        if self.resume is not None:
            k_start = int(self.resume["tick"])
            counters.macro_steps = int(self.resume["macro_steps"])
            counters.fmu_steps = int(self.resume["fmu_steps"])
            del events[: int(self.resume["events_applied"])]
        n_events = len(sc.events)
        inst_index = {inst.name: i for i, inst in enumerate(self.instances)}
        ticks = self._ticks_fast if self.loop == "fast" else self._ticks_reference

        def apply_events(t_ns: int) -> None:
            t_s = t_ns / NS_PER_S
            while events and events[0].at_ns == t_ns:
                e = events.pop(0)
                iname, var = e.target.split(".")
                inst = self.instances[inst_index[iname]]
                if e.action == "bias":
                    k = inst.outputs.index(var)
                    inst.bias[k] += e.value
                    inst.cur[k] = inst.raw[k] + inst.bias[k]
                    continue
                k = inst.in_names.index(var)
                now = float(inst.in_port.values[k])
                fn = (
                    constant(e.value)
                    if e.action == "set"
                    else ramp_from(now, e.value, t_s, e.duration_ns / NS_PER_S)
                )
                self.driven[int(inst.in_src[k])] = fn

        def run_batch(k0: int, k1: int) -> None:
            if events and events[0].at_ns == k0 * sc.step_ns:
                apply_events(k0 * sc.step_ns)
            driven = self._driven_matrix(k0, k1)
            first_row = -(-k0 // out_every)
            n_rows = max(0, -(-k1 // out_every) - first_row)
            rows = np.zeros((max(n_rows, 1), max(len(cols), 1)))
            counters.rows = 0
            try:
                ticks(k0, k1, driven, rows, ccols if self.loop == "fast" else cols, counters)
            finally:
                if counters.rows:
                    times = (
                        (first_row + np.arange(counters.rows, dtype=np.int64))
                        * sc.output_interval_ns
                        / NS_PER_S
                    )
                    self.recorder.append(times, rows[: counters.rows, : len(cols)])

        def final_tick() -> None:
            for inst, s in zip(self.instances, self._slots, strict=True):
                if s.pending_at == n_ticks:
                    n = len(inst.outputs)
                    inst.raw[:n] = inst.out_port.values[:n]
                    np.add(inst.raw, inst.bias, out=inst.cur)
            t = np.array([n_ticks * sc.step_ns / NS_PER_S])
            for inst in self.instances:
                for k in range(len(inst.in_names)):
                    if inst.in_kind[k] == IN_DRIVEN:
                        inst.in_port.values[k] = self.driven[int(inst.in_src[k])](t)[0]
            if n_ticks % out_every == 0:
                row = np.array(
                    [
                        [
                            self.instances[i].cur[k] if kind == 0 else self.instances[i].in_port.values[k]
                            for i, kind, k, _ in cols
                        ]
                    ]
                )
                self.recorder.append(np.array([n_ticks * sc.step_ns / NS_PER_S]), row.reshape(1, len(cols)))

        every = (self.checkpoint_every_ns or 0) // sc.step_ns
        checkpoints = set(range(every, n_ticks, every)) if every > 0 else set()
        marks = sorted(
            {e.at_ns // sc.step_ns for e in sc.events}
            | {n_ticks * j // 100 for j in range(1, 101)}
            | set(range(BATCH_TICKS, n_ticks, BATCH_TICKS))
            | checkpoints
            | {n_ticks}
        )
        failure: list[RunError] = []
        interrupted: list[str] = []

        def process(env: simpy.Environment) -> Any:
            k = k_start
            try:
                for mark in marks:
                    if mark <= k:
                        continue
                    run_batch(k, mark)
                    yield env.timeout((mark - k) * sc.step_ns)
                    k = mark
                    if self.progress:
                        self.progress(env.now + k_start * sc.step_ns, sc.duration_ns)
                    if mark in checkpoints and self.on_checkpoint:
                        self.on_checkpoint(self._snapshot(k, counters, n_events - len(events)))
                    if self.stop and (why := self.stop()):
                        interrupted.append(why)
                        return
                final_tick()
            except RunError as exc:  # the run stops; what was recorded stays
                failure.append(exc)

        env = simpy.Environment()
        env.process(process(env))
        try:
            env.run()
        finally:
            self.close()
            self.recorder.close()
        error = failure[0] if failure else None
        if error and counters.fail_slot >= 0:
            end_tick = counters.fail_tick
        elif error or interrupted:
            end_tick = counters.macro_steps
        else:
            end_tick = n_ticks
        return RunResult(
            table=self.recorder.table() if isinstance(self.recorder, MemoryRecorder) else None,
            status="failed" if error else ("interrupted" if interrupted else "completed"),
            info={"interrupted_by": interrupted[0]} if interrupted else {},
            error=error,
            cosim_s=wallclock.perf_counter() - start,
            macro_steps=int(counters.macro_steps),
            fmu_steps=int(counters.fmu_steps),
            end_ns=int(end_tick) * sc.step_ns,
        )

    def close(self) -> None:
        for inst in self.instances:
            inst.slot.close()
        self.instances = []


def run_scenario(scenario: Scenario, *, progress: ProgressFn | None = None, loop: Loop = "fast") -> RunResult:
    """Convenience: run a scenario with a fresh master, every row kept in memory."""
    return Master(scenario, progress=progress, loop=loop).run()


__all__ = ["FMUError", "Master", "MemoryRecorder", "Recorder", "RunResult", "run_scenario"]
