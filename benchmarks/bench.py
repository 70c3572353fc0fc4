#!/usr/bin/env python3
"""Performance benchmark of the twin's co-simulation master (a script, not a timed test).

Prints, as medians of several repetitions measured side by side in one run (the contenders of
each section alternate within every repetition, so slow drifts of a noisy machine hit all alike):

(a) master overhead per FMU step: one FixtureMechanics stepped N times through raw ctypes FMI
    calls (set inputs, fmi2DoStep, get outputs, preallocated buffers) vs the same FMU run by the
    master on a one-FMU scenario with the same N steps;
(b) the tester system (scenarios/base/tester-system.toml, every FMU at the same step) run by our
    master and by libcosimpy with the same FMUs, parameters, connections, inputs, step, duration;
(c) wall time and real-time factor of the paper's 480-minute replay (`twin run`) and of the
    MIL endurance run (scenarios/mil-endurance.toml), each a fresh process;
(d) peak resident memory of those runs (all the run's processes together, the plot helper
    included, sampled: benchmarks/treemem.py);
(e) memory flatness: peak RSS of a 1 h vs a 10 h run of scenarios/constant-load.toml.

It ends with a Markdown table of the figures against their goals; ``--write-docs`` writes it
to docs/performance/bench.md (under the command and the machine line), which the docs include.

    python benchmarks/bench.py            # everything (several minutes: the endurance run is long)
    python benchmarks/bench.py --quick    # a fast check: few reps, short runs, no endurance
    python benchmarks/bench.py --quick --write-docs   # ... and its table into the docs

With ``--before REV`` it measures instead issue 32's six figures (the default ``twin run`` and its
peak memory, the MIL endurance run, its cost per simulated hour, the tester system against
libcosimpy, ``twin heldout``) for the tree at REV and for this one, side by side, alternating in
every repetition (benchmarks/before.py; ``--write-docs``: docs/performance/bench_before.md)::

    python benchmarks/bench.py --before e3eb90e                  # all six (about 20 min)
    python benchmarks/bench.py --before e3eb90e --only 1235 --reps 3
    python benchmarks/bench.py --before HEAD~5 --quick           # one repetition, 2 held-out testers

Since issue 28 the master takes a plan (:func:`twin.cosim.make_plan`) instead of a scenario:
the plan, made inside the master's set-up before, is made here just before the master and its
time counted in the twin's set-up (and so in set-up + stepping), so sections (a) and (b) mean
what they did. Sections (c)-(e) time ``twin run``, which is now ``twin.pipeline.prepare`` then
``twin.pipeline.run``: the same command, the same fresh process.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
import typing
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from machine import commit, machine, machine_line, print_machine, write_docs
from treemem import wait_with_tree_peak

from twin.config.durations import NS_PER_S, parse_duration
from twin.config.load import load_scenario
from twin.config.spec import Scenario
from twin.cosim import Master, make_plan
from twin.fmu.build import ensure_fmu
from twin.fmu.catalog import variables as model_variables
from twin.fmu.slot import FMUSlot
from twin.seeds import instance_seed

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
TESTER = SCENARIOS / "base" / "tester-system.toml"
ENDURANCE = SCENARIOS / "mil-endurance.toml"
CONSTANT_LOAD = SCENARIOS / "constant-load.toml"
TESTER_FMUS = ("hydraulic", "oscillation", "mechanics", "sensors", "thermal")

#: master methods whose time is set-up (instantiation, parameters, initialization), not stepping
SETUP_METHODS = ("_create", "_initialize")

RESULTS: dict[str, Any] = {}  # what the final table is made of


# ----------------------------------------------------------------------------- helpers


def median(xs: Sequence[float]) -> float:
    return float(statistics.median(xs))


def spread(xs: Sequence[float], fmt: str = "{:.3f}", unit: str = "") -> str:
    """'median (min-max, n=k)'."""
    if not xs:
        return "n/a"
    m = fmt.format(median(xs))
    if len(xs) == 1:
        return f"{m}{unit} (n=1)"
    return f"{m}{unit} ({fmt.format(min(xs))}-{fmt.format(max(xs))}, n={len(xs)})"


def header(title: str) -> None:
    print(f"\n== {title}", flush=True)


def libcosim_version() -> str | None:
    try:
        from importlib.metadata import version

        import libcosimpy  # noqa: F401

        return version("libcosimpy")
    except Exception:
        return None


def master_loops() -> list[str | None]:
    """The values of Master's ``loop`` keyword, read from its type (``Literal[...]``), else [None].

    Read rather than written here, so the benchmark follows a renamed loop (the pure-Python
    loop was ``"reference"`` and becomes ``"python"``) without an edit; [None] when Master has
    no ``loop`` keyword (its only loop).
    """
    parameter = inspect.signature(Master).parameters.get("loop")
    if parameter is None:
        return [None]
    try:
        hint = typing.get_type_hints(Master.__init__)["loop"]
    except NameError:  # another annotation names a TYPE_CHECKING-only import: look the alias up
        hint = getattr(sys.modules[Master.__module__], str(parameter.annotation), None)
    values = [v for v in typing.get_args(hint) if isinstance(v, str)]
    if not values:
        raise RuntimeError("Master's loop keyword is not annotated with a Literal of its values")
    return values


def loop_label(loop: str | None) -> str:
    return f"twin ({loop} loop)" if loop else "twin master"


def run_master(scenario: Scenario, loop: str | None) -> dict[str, Any]:
    """One in-process master run: cosim_s, its set-up part and the stepping part.

    Set-up is the making of the plan (:func:`twin.cosim.make_plan`, which the master did in its
    ``_create`` before it took a plan) and the time spent in the master's
    ``_create``/``_initialize`` (instantiating the FMUs, parameters, initialization mode), timed
    by wrapping them on the instance; ``cosim_s`` is the master's own plus the plan's;
    ``loop_s`` is ``cosim_s`` minus the set-up (the stepping, recording and the few scheduler
    yields).
    """
    t0 = time.perf_counter()
    plan = make_plan(scenario)
    plan_s = time.perf_counter() - t0
    master = Master(plan, loop=loop) if loop else Master(plan)
    setup = {"s": 0.0, "wrapped": 0}
    for name in SETUP_METHODS:
        fn = getattr(master, name, None)
        if callable(fn):

            def timed(*a: Any, _fn: Callable[..., Any] = fn, **kw: Any) -> Any:
                t0 = time.perf_counter()
                try:
                    return _fn(*a, **kw)
                finally:
                    setup["s"] += time.perf_counter() - t0

            setattr(master, name, timed)
            setup["wrapped"] += 1
    t0 = time.perf_counter()
    result = master.run()
    wall = time.perf_counter() - t0
    if result.status != "completed":
        raise RuntimeError(f"master run {result.status}: {result.error}")
    return {
        "wall_s": plan_s + wall,
        "cosim_s": plan_s + result.cosim_s,
        "setup_s": plan_s + setup["s"] if setup["wrapped"] else None,
        "loop_s": result.cosim_s - setup["s"] if setup["wrapped"] else None,
        "fmu_steps": result.fmu_steps,
        "macro_steps": result.macro_steps,
        "result": result,
    }


# ----------------------------------------------------------------------------- (a) overhead

OVERHEAD_MODEL = "FixtureMechanics"
OVERHEAD_STEP_NS = 10_000_000  # 10 ms = the model's solver_step start value: one internal step per doStep


def _model_io(model: str) -> tuple[list[str], dict[str, float], list[str]]:
    variables = model_variables(model)
    inputs = [n for n, v in variables.items() if v.causality == "input" and v.type == "Real"]
    starts = {n: float(variables[n].start) if variables[n].start is not None else 0.0 for n in inputs}
    outputs = [n for n, v in variables.items() if v.causality == "output" and v.type == "Real"]
    return inputs, starts, outputs


def one_fmu_scenario(tmp: Path, n_steps: int) -> Scenario:
    """FixtureMechanics alone at its solver step; every Real input driven by a constant profile."""
    inputs, starts, _ = _model_io(OVERHEAD_MODEL)
    duration_ns = n_steps * OVERHEAD_STEP_NS
    lines = [
        "[scenario]",
        'name = "bench-one-fmu"',
        f'duration = "{duration_ns} ns"',
        f'step = "{OVERHEAD_STEP_NS} ns"',
        f'output_interval = "{duration_ns} ns"   # record the first and last rows only',
        "seed = 1",
        "",
        "[fmu.mechanics]",
        f'model = "{OVERHEAD_MODEL}"',
        f'period = "{OVERHEAD_STEP_NS} ns"',
        f"parameters = {{ solver_step = {OVERHEAD_STEP_NS / NS_PER_S!r} }}",
    ]
    for name in inputs:
        lines += ["", f"[input.mechanics.{name}]", 'profile = "constant"', f"value = {starts[name]!r}"]
    path = tmp / "one-fmu.toml"
    path.write_text("\n".join(lines) + "\n")
    return load_scenario(path)


C_LOOP = r"""
#include <stddef.h>
typedef int (*set_real_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_real_t)(void *, const unsigned int *, size_t, double *);
typedef int (*do_step_t)(void *, double, double, int);

/* n steps of (fmi2SetReal, fmi2DoStep, fmi2GetReal); returns the steps done */
long raw_loop(void *c, void *sr, void *ds, void *gr, const unsigned int *ivr, size_t ni, const double *iv,
              const unsigned int *ovr, size_t no, double *ov, long n, double h) {
    long k;
    for (k = 0; k < n; k++) {
        if (((set_real_t)sr)(c, ivr, ni, iv) > 1) return k;
        if (((do_step_t)ds)(c, (double)k * h, h, 1) > 1) return k;
        if (((get_real_t)gr)(c, ovr, no, ov) > 1) return k;
    }
    return n;
}
"""
_C_LIB: list[Any] = []


def c_loop() -> Any | None:
    """The same three FMI calls per step from C (built here with cc -O2), or None without a compiler."""
    import ctypes
    import shutil

    if _C_LIB:
        return _C_LIB[0]
    cc = shutil.which("cc") or shutil.which("gcc")
    lib = None
    if cc:
        import atexit

        tmp = Path(tempfile.mkdtemp(prefix="twin-bench-c-"))
        atexit.register(shutil.rmtree, tmp, True)
        (tmp / "raw_loop.c").write_text(C_LOOP)
        built = subprocess.run(
            [cc, "-O2", "-shared", "-fPIC", "-o", str(tmp / "raw_loop.so"), str(tmp / "raw_loop.c")]
        )
        if built.returncode == 0:
            lib = ctypes.CDLL(str(tmp / "raw_loop.so"))
            lib.raw_loop.restype = ctypes.c_long
            vp, sz = ctypes.c_void_p, ctypes.c_size_t
            lib.raw_loop.argtypes = [vp, vp, vp, vp, vp, sz, vp, vp, sz, vp, ctypes.c_long, ctypes.c_double]
    _C_LIB.append(lib)
    return lib


def raw_run(n_steps: int, variant: str) -> float:
    """Seconds for n_steps of (set inputs, doStep, get outputs) through ctypes, set-up excluded.

    ``slot``: FMUSlot.write/do_step/read (preallocated buffers, status checks);
    ``ctypes``: the bare fmi2SetReal/fmi2DoStep/fmi2GetReal function pointers in a local loop;
    ``c``: the same function pointers called from a C loop (the floor: no Python at all).
    """
    inputs, starts, outputs = _model_io(OVERHEAD_MODEL)
    slot = FMUSlot(ensure_fmu(OVERHEAD_MODEL), f"raw-{variant}")
    try:
        h = OVERHEAD_STEP_NS / NS_PER_S
        slot.setup(0.0)
        slot.set_value("solver_step", h)
        in_port, out_port = slot.port(inputs), slot.port(outputs)
        in_port.values[: len(inputs)] = [starts[n] for n in inputs]
        slot.enter_initialization()
        slot.write(in_port)
        slot.exit_initialization()
        slot.read(out_port)
        if variant == "slot":
            write, do_step, read = slot.write, slot.do_step, slot.read
            t0 = time.perf_counter()
            for k in range(n_steps):
                write(in_port)
                do_step(k * h, h)
                read(out_port)
            return time.perf_counter() - t0
        set_real, do_step_c, get_real, c = slot._set_real, slot._do_step, slot._get_real, slot._c
        ivr, ni, iptr = in_port.vr, in_port.n, in_port.ptr
        ovr, no, optr = out_port.vr, out_port.n, out_port.ptr
        if variant == "c":
            import ctypes

            lib = c_loop()
            fp = [ctypes.cast(f, ctypes.c_void_p).value for f in (set_real, do_step_c, get_real)]
            t0 = time.perf_counter()
            done = lib.raw_loop(
                c, *fp, ctypes.addressof(ivr), ni, iptr, ctypes.addressof(ovr), no, optr, n_steps, h
            )
            elapsed = time.perf_counter() - t0
            if done != n_steps:
                raise RuntimeError(f"FMI call failed at step {done}")
            return elapsed
        t0 = time.perf_counter()
        for k in range(n_steps):
            if (
                set_real(c, ivr, ni, iptr) > 1
                or do_step_c(c, k * h, h, 1) > 1
                or get_real(c, ovr, no, optr) > 1
            ):
                raise RuntimeError(f"FMI call failed at step {k}")
        return time.perf_counter() - t0
    finally:
        slot.close()


def bench_overhead(n_steps: int, reps: int) -> None:
    header(
        f"(a) master overhead per FMU step: {OVERHEAD_MODEL} alone, {n_steps} steps of {OVERHEAD_STEP_NS / 1e6:g} ms"
    )
    inputs, _, outputs = _model_io(OVERHEAD_MODEL)
    print(
        f"   per step: fmi2SetReal({len(inputs)} inputs) + fmi2DoStep + fmi2GetReal({len(outputs)} outputs); "
        "the master drives every input with a constant profile and records only the first and last rows"
    )
    loops = master_loops()
    variants = ["ctypes", "slot"] + (["c"] if c_loop() is not None else [])
    per: dict[str, list[float]] = {v: [] for v in variants}
    setup_note = ""
    with tempfile.TemporaryDirectory(prefix="twin-bench-") as tmp:
        scenario = one_fmu_scenario(Path(tmp), n_steps)
        for loop in loops:
            per[loop_label(loop)] = []
        raw_run(min(n_steps, 1000), "ctypes")  # warm-up: FMU unzipped, library loaded
        for _ in range(reps):
            for variant in variants:
                per[variant].append(raw_run(n_steps, variant) / n_steps * 1e6)
            for loop in loops:
                r = run_master(scenario, loop)
                if r["fmu_steps"] != n_steps:
                    raise RuntimeError(f"master made {r['fmu_steps']} FMU steps, expected {n_steps}")
                if r["loop_s"] is None:
                    # set-up not separable: count it in (documented below)
                    setup_note = "master set-up methods not found: its per-step figure includes set-up"
                    per[loop_label(loop)].append(r["cosim_s"] / n_steps * 1e6)
                else:
                    per[loop_label(loop)].append(r["loop_s"] / n_steps * 1e6)
    raw = median(per["ctypes"])
    print(f"   {'raw ctypes (bare function pointers)':42s} {spread(per['ctypes'], '{:.2f}', ' us')}")
    print(f"   {'raw ctypes via FMUSlot.write/do_step/read':42s} {spread(per['slot'], '{:.2f}', ' us')}")
    c_us = median(per["c"]) if "c" in per else None
    if c_us is not None:
        print(f"   {'the same calls from C (cc -O2, no Python)':42s} {spread(per['c'], '{:.2f}', ' us')}")
    else:
        print("   the same calls from C: skipped (no C compiler)")
    RESULTS["overhead"] = {
        "raw_us": raw,
        "slot_us": median(per["slot"]),
        "c_us": c_us,
        "n": n_steps,
        "loops": {},
    }
    for loop in loops:
        label = loop_label(loop)
        m = median(per[label])
        print(
            f"   {label + ' (cosim_s - set-up)':42s} {spread(per[label], '{:.2f}', ' us')}   "
            f"overhead {m - raw:+.2f} us/step vs bare ctypes, {m - median(per['slot']):+.2f} vs FMUSlot"
            + (f", {m - c_us:+.2f} vs C" if c_us is not None else "")
        )
        RESULTS["overhead"]["loops"][label] = {"master_us": m, "overhead_us": m - raw}
    if setup_note:
        print(f"   note: {setup_note}")
    else:
        print(
            f"   set-up = time in Master.{'/'.join(SETUP_METHODS)} (instantiate, parameters, initialization)"
        )


# ----------------------------------------------------------------------------- (b) vs libcosimpy


def tester_scenario(duration: str, step: str, tester: Path = TESTER) -> tuple[Scenario, list[str]]:
    """The tester system with every FMU at ``step`` (``tester``: another tree's file, for --before)."""
    overrides = [f'fmu.{n}.period="{step}"' for n in TESTER_FMUS]
    # the thermal network's solver step (1 s in its calibration) must divide its period
    overrides += [f"fmu.thermal.parameters.solver_step={_seconds(step)!r}"]
    overrides += [f'scenario.duration="{duration}"', f'scenario.step="{step}"']
    return load_scenario(tester, overrides), overrides


def _seconds(text: str) -> float:
    return parse_duration(text) / NS_PER_S


def zero_unsafe(scenario: Scenario) -> list[Any]:
    """Connections libcosim cannot initialize with our FMUs.

    libcosim reads outputs in initialization mode and passes them on; our FMUs compute their
    outputs only at fmi2ExitInitializationMode (0 before), and an input whose declared range
    excludes 0 (a temperature in K) then refuses the value with fmi2Error. These are the
    connections from an output without a start value to such an input.
    """
    models = {f.name: f.model for f in scenario.fmus}
    out = []
    for c in scenario.connections:
        (si, sv), (di, dv) = c.src.split("."), c.dst.split(".")
        target = model_variables(models[di])[dv]
        lo, hi = target.min, target.max
        if model_variables(models[si])[sv].start is None and not lo <= 0.0 <= hi:
            out.append(c)
    return out


def _libcosim_initial_value(execution: Any, idx: int, ref: int, vtype: int, value: Any) -> bool:
    """Set one start value of a libcosim slave through the setter of the variable's type."""
    from libcosimpy.CosimEnums import CosimVariableType

    if vtype == CosimVariableType.BOOLEAN.value:
        return execution.boolean_initial_value(idx, ref, bool(value))
    if vtype == CosimVariableType.INTEGER.value:
        return execution.integer_initial_value(idx, ref, int(value))
    return execution.real_initial_value(idx, ref, float(value))


def _libcosim_add_slaves(
    execution: Any, scenario: Scenario
) -> tuple[list[Any], dict[str, int], dict[str, Any]]:
    """Every FMU of the scenario as a libcosim slave with its parameters (and the master's seeds).

    Returns the slaves (to keep them alive), each instance's slave index and its variables
    (name -> (reference, type)).
    """
    from libcosimpy.CosimSlave import CosimLocalSlave

    keep, index, refs = [], {}, {}
    for i, spec in enumerate(scenario.fmus):
        if spec.period_ns != scenario.step_ns:
            raise RuntimeError(f"{spec.name}: period differs from the step (not benchmarked in libcosim)")
        slave = CosimLocalSlave(fmu_path=str(ensure_fmu(spec.model)), instance_name=spec.name)
        keep.append(slave)
        idx = execution.add_local_slave(local_slave=slave)
        index[spec.name] = idx
        refs[spec.name] = {v.name.decode(): (v.reference, v.type) for v in execution.slave_variables(idx)}
        values: dict[str, Any] = {k: p.value for k, p in spec.parameters.items()}
        if "seed" in refs[spec.name] and "seed" not in values:
            values["seed"] = instance_seed(scenario.seed, i)
        for name, value in values.items():
            if not _libcosim_initial_value(execution, idx, *refs[spec.name][name], value):
                raise RuntimeError(f"libcosim refused {spec.name}.{name} = {value!r}")
    return keep, index, refs


def _libcosim_wire(
    execution: Any,
    scenario: Scenario,
    index: dict[str, int],
    refs: dict[str, Any],
    unsafe: set[Any],
    init_outputs: dict[str, float],
) -> None:
    """Constant inputs as initial values, then the connections (the unsafe ones as initial values)."""
    for p in scenario.profiles:
        if p.kind != "constant":
            raise RuntimeError(f"input {p.target}: only constant profiles are translated to libcosim")
        inst, var = p.target.split(".")
        execution.real_initial_value(index[inst], refs[inst][var][0], float(p.params["value"]))
    for c in scenario.connections:  # delayed ones too: connected directly (libcosim's exchange is Jacobi)
        (si, sv), (di, dv) = c.src.split("."), c.dst.split(".")
        if c in unsafe:
            execution.real_initial_value(index[di], refs[di][dv][0], float(init_outputs[c.src]))
        elif (
            execution.connect_real_variables(index[si], refs[si][sv][0], index[di], refs[di][dv][0]) is False
        ):
            raise RuntimeError(f"libcosim refused connection {c.src} -> {c.dst}")


def _libcosim_last_outputs(
    observer: Any, scenario: Scenario, index: dict[str, int], refs: dict[str, Any]
) -> dict[str, float]:
    """The last value of every Real output, as 'instance.variable' -> value."""
    from libcosimpy.CosimEnums import CosimVariableType

    last = {}
    for spec in scenario.fmus:
        outs = [
            k
            for k, (_, t) in refs[spec.name].items()
            if t == CosimVariableType.REAL.value and model_variables(spec.model)[k].causality == "output"
        ]
        vals = observer.last_real_values(index[spec.name], [refs[spec.name][k][0] for k in outs])
        last.update({f"{spec.name}.{k}": float(v) for k, v in zip(outs, vals, strict=True)})
    return last


def libcosim_run(scenario: Scenario, init_outputs: dict[str, float], mode: str) -> dict[str, Any]:
    """The scenario in libcosimpy: same FMU files, parameters, seeds, connections, constant inputs.

    ``mode="connect"`` makes every connection; ``mode="initial"`` replaces the
    :func:`zero_unsafe` ones by the destination's initial value (the source's value after
    initialization), so libcosim can initialize; the other connections stay.
    """
    # imported before the clock starts (the helpers' own imports then cost nothing)
    from libcosimpy.CosimEnums import CosimVariableType  # noqa: F401
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave  # noqa: F401

    if scenario.events:
        raise RuntimeError("scenario events are not translated to libcosim")
    unsafe = set(zero_unsafe(scenario)) if mode == "initial" else set()
    t0 = time.perf_counter()
    execution = CosimExecution.from_step_size(step_size=scenario.step_ns)
    _keep, index, refs = _libcosim_add_slaves(execution, scenario)
    _libcosim_wire(execution, scenario, index, refs, unsafe, init_outputs)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    t1 = time.perf_counter()
    if not execution.step(scenario.duration_ns // scenario.step_ns):
        raise RuntimeError("libcosim execution failed")
    t2 = time.perf_counter()
    last = _libcosim_last_outputs(observer, scenario, index, refs)
    return {"setup_s": t1 - t0, "loop_s": t2 - t1, "total_s": t2 - t0, "last": last}


class LibcosimFailed(RuntimeError):
    pass


def _worker(flag: str, spec: dict[str, Any]) -> subprocess.CompletedProcess[str]:
    """This script as a worker in a fresh process, with a temporary directory of its own,
    removed after it: a worker leaves by ``os._exit`` (its teardown is not timed), so what it
    unpacked stays, and the next twin process would clean it up within its timed set-up."""
    with tempfile.TemporaryDirectory(prefix="twin-bench-worker-") as tmp:
        return subprocess.run(
            [sys.executable, str(Path(__file__).resolve()), flag],
            input=json.dumps(spec),
            capture_output=True,
            text=True,
            env={**os.environ, "TMPDIR": tmp},
        )


def libcosim_child(spec: dict[str, Any]) -> dict[str, Any]:
    """One libcosim run in a fresh process (a libcosim error aborts the whole process)."""
    proc = _worker("--libcosim-worker", spec)
    if proc.returncode != 0:
        lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
        what = [ln for ln in lines if ln.startswith("what():")]
        raise LibcosimFailed((what or lines or [f"exit code {proc.returncode}"])[-1])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def libcosim_worker() -> int:
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.WARNING)
    spec = json.loads(sys.stdin.read())
    scenario, _ = tester_scenario(spec["duration"], spec["step"], Path(spec.get("tester", TESTER)))
    result = libcosim_run(scenario, spec["init_outputs"], spec["mode"])
    print(json.dumps(result))
    sys.stdout.flush()
    os._exit(0)  # skip libcosim's teardown: its time is not measured and it is not needed


def twin_child(spec: dict[str, Any]) -> dict[str, Any]:
    """One run of our master in a fresh process, its first there, as libcosim's are timed: the
    FMU files read and unpacked, their libraries loaded (process start and imports not counted)."""
    proc = _worker("--twin-worker", spec)
    if proc.returncode != 0:
        raise RuntimeError(f"twin worker exited {proc.returncode}: {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def twin_worker() -> int:
    spec = json.loads(sys.stdin.read())
    scenario, _ = tester_scenario(spec["duration"], spec["step"], Path(spec.get("tester", TESTER)))
    r = run_master(scenario, spec["loop"])
    table = r["result"].table
    last = {name: float(table[name][-1]) for name in table.names()}
    first = {name: float(table[name][0]) for name in table.names()}  # libcosim's initial values (--before)
    print(json.dumps({"total_s": r["cosim_s"], "loop_s": r["loop_s"], "last": last, "first": first}))
    sys.stdout.flush()
    os._exit(0)  # as libcosim's worker: the teardown is not measured


def _libcosim_mode(scenario: Scenario, version: str | None, spec: dict[str, Any]) -> str:
    """How libcosim gets the system: "connect" (as connected) or "initial" (explained on stdout).

    A trial run as connected decides: if libcosim cannot initialize it, the :func:`zero_unsafe`
    connections become constant initial values.
    """
    if version is None:
        print("   libcosimpy: not installed (pip install libcosimpy); only our master is timed")
        return "connect"
    print(
        f"   libcosimpy {version}: default fixed-step algorithm (its own worker threads), last-value observer, "
        "each run in a fresh process (timed inside it; process start and imports not counted)"
    )
    try:
        libcosim_child({**spec, "mode": "connect"})
    except LibcosimFailed as exc:
        unsafe = zero_unsafe(scenario)
        print(f"   libcosim cannot initialize the system as connected: {exc}")
        print(
            f"   (libcosim reads outputs in initialization mode; our FMUs compute theirs at "
            f"fmi2ExitInitializationMode and report 0 before, which {len(unsafe)} range-checked inputs refuse)"
        )
        print(
            f"   => libcosim runs with those {len(unsafe)} connections replaced by constant initial values "
            f"(the sources' values after initialization); {len(scenario.connections) - len(unsafe)} connections stay. "
            "Same FMU work per step, fewer transfers: favours libcosim"
        )
        print("      replaced: " + ", ".join(f"{c.src}->{c.dst}" for c in unsafe))
        return "initial"
    return "connect"


def _time_ours(
    scenario: Scenario,
    loops: list[str | None],
    spec: dict[str, Any],
    ours: dict[str, dict[str, list[float]]],
) -> dict[str, float]:
    """One run of each master loop in a fresh process (compared with libcosim's, which are
    too), and one more in this process, whose FMU files are unpacked and libraries loaded by
    the runs before (as a sweep's worker runs its points); timings appended to ``ours``; the
    last fresh run's final outputs."""
    last: dict[str, float] = {}
    for loop in loops:
        r = twin_child({**spec, "loop": loop})
        d = ours[loop_label(loop)]
        d["total"].append(r["total_s"])
        d["loop"].append(r["loop_s"] if r["loop_s"] is not None else r["total_s"])
        last = r["last"]
        d["warm"].append(run_master(scenario, loop)["cosim_s"])
    return last


def _agreement(theirs: dict[str, float], ours: dict[str, float]) -> tuple[int, int, tuple[float, str] | None]:
    """(bit-identical final outputs, outputs compared, (largest relative difference, its name))."""
    common = [k for k in theirs if k in ours]
    diffs = sorted((abs(theirs[k] - ours[k]) / max(abs(ours[k]), abs(theirs[k]), 1e-300), k) for k in common)
    return sum(d == 0.0 for d, _ in diffs), len(diffs), diffs[-1] if diffs else None


def _report_libcosim(
    ours: dict[str, dict[str, list[float]]],
    lib: dict[str, list[float]],
    agreement: tuple[int, int, tuple[float, str] | None] | None,
    lib_error: str | None,
) -> None:
    """Print the timings of section (b) and store its figures in RESULTS["libcosim"]."""
    b = RESULTS["libcosim"]
    print(
        f"   {'':34s} {'stepping (s)':>30s}   {'set-up + stepping (s)':>30s}   "
        f"{'the same, FMUs loaded before (s)':>32s}"
    )
    for label, d in ours.items():
        print(
            f"   {label:34s} {spread(d['loop']):>30s}   {spread(d['total']):>30s}   {spread(d['warm']):>32s}"
        )
    if not lib["total"]:
        if lib_error:
            print(f"   libcosim failed: {lib_error}")
        for label, d in ours.items():
            b["ours"][label] = {"ours_s": median(d["total"]), "ratio": None, "ratio_loop": None}
        return
    print(
        f"   {'libcosimpy ' + str(b['version']):34s} {spread(lib['loop']):>30s}   {spread(lib['total']):>30s}"
    )
    for label, d in ours.items():
        rl = median(lib["loop"]) / median(d["loop"])
        rt = median(lib["total"]) / median(d["total"])
        rw = median(lib["total"]) / median(d["warm"])
        print(
            f"   ratio libcosim/{label}: {rl:.2f}x stepping, {rt:.2f}x with set-up "
            f"({rw:.2f}x with the twin's FMUs loaded before)"
        )
        b["ours"][label] = {"ours_s": median(d["total"]), "ratio": rt, "ratio_loop": rl, "ratio_warm": rw}
    b["lib_s"] = median(lib["total"])
    if agreement is not None:
        same, total, worst = agreement
        print(
            f"   same system check: {same} of {total} final outputs bit-identical in twin and libcosim"
            + (f"; largest relative difference {worst[0]:.1e} ({worst[1]})" if worst and worst[0] > 0 else "")
            + (
                "; the others depend on the temperatures libcosim holds constant"
                if b["mode"] == "initial"
                else ""
            )
        )


def bench_libcosim(duration: str, step: str, reps: int) -> None:
    scenario, overrides = tester_scenario(duration, step)
    n = scenario.duration_ns // scenario.step_ns
    header(
        f"(b) tester system, {len(scenario.fmus)} FMUs all at {step}, {duration} ({n} macro steps): twin vs libcosimpy"
    )
    print(f"   scenario: {TESTER.relative_to(ROOT)} with --set " + " ".join(f"'{o}'" for o in overrides))
    delayed = sum(c.delay for c in scenario.connections)
    print(
        f"   same FMU files, parameters (+ the master's per-instance seeds), {len(scenario.connections)} connections, "
        "constant inputs as initial values; "
        + (
            f"the {delayed} delayed connection(s) are connected directly in libcosim (it has no delay)"
            if delayed
            else "the friction loop undelayed in both (no direct feedthrough on it)"
        )
    )
    version = libcosim_version()
    loops = master_loops()
    # warm-up (FMUs built and cached); its first row = the initialized outputs
    warm = run_master(scenario, loops[0])
    table = warm["result"].table
    spec: dict[str, Any] = {
        "duration": duration,
        "step": step,
        "init_outputs": {name: float(table[name][0]) for name in table.names()},
    }
    mode = _libcosim_mode(scenario, version, spec)
    ours: dict[str, dict[str, list[float]]] = {
        loop_label(lp): {"loop": [], "total": [], "warm": []} for lp in loops
    }
    lib: dict[str, list[float]] = {"loop": [], "total": []}
    agreement = None
    lib_error = None
    for _ in range(reps):
        last_ours = _time_ours(scenario, loops, spec, ours)
        if version is None or lib_error is not None:
            continue
        try:
            lr = libcosim_child({**spec, "mode": mode})
        except LibcosimFailed as exc:
            lib_error = str(exc)
            continue
        lib["loop"].append(lr["loop_s"])
        lib["total"].append(lr["total_s"])
        agreement = _agreement(lr["last"], last_ours)
    RESULTS["libcosim"] = {
        "n": n,
        "duration": duration,
        "step": step,
        "ours": {},
        "version": version,
        "mode": mode,
        "n_unsafe": len(zero_unsafe(scenario)),
    }
    _report_libcosim(ours, lib, agreement, lib_error)


# ----------------------------------------------------------------------------- (c)-(e) whole runs


def twin_command() -> list[str]:
    exe = Path(sys.executable).parent / "twin"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "twin"]


def cli_run(args: Sequence[str], out: Path) -> dict[str, Any]:
    """`twin run ARGS --quiet --out OUT` as a fresh process: wall from spawn to exit, its own peak RSS."""
    cmd = [*twin_command(), "run", *args, "--quiet", "--out", str(out)]
    with tempfile.TemporaryFile() as log:
        t0 = time.perf_counter()
        # bytecode cache on, as an installed twin has it (PYTHONDONTWRITEBYTECODE, set on some
        # machines, would add the compiling of the twin's modules to every run)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=str(ROOT), env=env)
        # rusage of this child (and what it waited for) alone, and the sum with its plot helper
        status, usage, tree_mb = wait_with_tree_peak(proc.pid)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            log.seek(0)
            raise RuntimeError(
                f"{' '.join(cmd)} exited {proc.returncode}: {log.read().decode(errors='replace')[-2000:]}"
            )
    summary = json.loads((out / "summary.json").read_text())
    timing = summary.get("timing", {})
    return {
        "wall_s": wall,
        "maxrss_mb": tree_mb,  # all the run's processes together
        # KiB on Linux: the largest process, never below this benchmark's own peak when it started
        # the run (ru_maxrss starts from the starter's); not printed
        "own_maxrss_mb": usage.ru_maxrss / 1024,
        "cosim_s": timing.get("cosim_s"),
        "total_s": timing.get("total_s"),
        "sim_s": summary.get("sim_end_s"),
        "fmu_steps": timing.get("fmu_steps"),
        "rtf": timing.get("realtime_factor"),
    }


def bench_runs(name: str, label: str, args: Sequence[str], reps: int) -> dict[str, list[float]]:
    runs: dict[str, list[float]] = {
        "wall_s": [],
        "cosim_s": [],
        "total_s": [],
        "maxrss_mb": [],
        "rtf": [],
        "rtf_wall": [],
    }
    with tempfile.TemporaryDirectory(prefix="twin-bench-") as tmp:
        for rep in range(reps):
            r = cli_run(args, Path(tmp) / f"{name}-{rep}")
            for k in ("wall_s", "cosim_s", "total_s", "maxrss_mb", "rtf"):
                if r[k] is not None:
                    runs[k].append(r[k])
            runs["rtf_wall"].append(r["sim_s"] / r["wall_s"])
            runs["sim_s"] = [r["sim_s"]]
            runs["fmu_steps"] = [r["fmu_steps"]]
    print(f"   {label} (simulated {runs['sim_s'][0] / 3600:g} h, {runs['fmu_steps'][0]} FMU steps)")
    print(f"     wall from process start to exit  {spread(runs['wall_s'], unit=' s')}")
    print(f"     timing.total_s (in-process)      {spread(runs['total_s'], unit=' s')}")
    print(f"     timing.cosim_s (the loop alone)  {spread(runs['cosim_s'], unit=' s')}")
    print(
        f"     real-time factor                 {spread(runs['rtf'], '{:.0f}')} on cosim_s, "
        f"{spread(runs['rtf_wall'], '{:.0f}')} on wall"
    )
    print(f"     peak RSS (d)                     {spread(runs['maxrss_mb'], '{:.0f}', ' MB')}")
    return runs


def bench_whole_runs(reps: int, endurance_reps: int, skip_endurance: bool) -> None:
    header("(c, d) whole runs, `twin run --quiet --out TMP` each as a fresh process (FMUs already built)")
    # the replay alone: its uncertainty Monte Carlo (the scenario's [uncertainty]) is another
    # figure, not measured here
    RESULTS["replay"] = bench_runs(
        "replay",
        "the paper's 480-minute replay (default scenario, --uncertainty 0)",
        ["--uncertainty", "0"],
        reps,
    )
    if skip_endurance:
        print("   MIL endurance run: skipped (--skip-endurance / --quick)")
        return
    RESULTS["endurance"] = bench_runs(
        "endurance", f"MIL endurance ({ENDURANCE.relative_to(ROOT)})", [str(ENDURANCE)], endurance_reps
    )


def bench_flatness(short: str, long: str, reps: int) -> None:
    header(f"(e) memory flatness: {CONSTANT_LOAD.relative_to(ROOT)}, output every 10 s, {short} vs {long}")
    peaks: dict[str, list[float]] = {short: [], long: []}
    walls: dict[str, list[float]] = {short: [], long: []}
    with tempfile.TemporaryDirectory(prefix="twin-bench-") as tmp:
        for rep in range(reps):
            for d in (short, long):
                args = [
                    str(CONSTANT_LOAD),
                    "--set",
                    f'scenario.duration="{d}"',
                    "--set",
                    'scenario.output_interval="10 s"',
                ]
                r = cli_run(args, Path(tmp) / f"flat-{d.replace(' ', '')}-{rep}")
                peaks[d].append(r["maxrss_mb"])
                walls[d].append(r["wall_s"])
    for d in (short, long):
        print(f"   {d:>6s}: peak RSS {spread(peaks[d], '{:.0f}', ' MB')}, wall {spread(walls[d], unit=' s')}")
    ratio = median(peaks[long]) / median(peaks[short])
    print(f"   ratio peak RSS {long} / {short}: {ratio:.3f} (flat if within 1.20)")
    RESULTS["flatness"] = {
        "short": short,
        "long": long,
        "short_mb": median(peaks[short]),
        "long_mb": median(peaks[long]),
        "ratio": ratio,
    }


# ----------------------------------------------------------------------------- the table


def _met(ok: bool | None) -> str:
    return "" if ok is None else ("yes" if ok else "**no**")


Row = tuple[str, str, str, str]  # figure, measured, target, met


def _below(what: str, measured: str, value: float, limit: float, unit: str) -> Row:
    """A row whose target is an upper limit: "< limit unit", met if value < limit."""
    return (what, measured, f"< {limit:g} {unit}", _met(value < limit))


def _overhead_rows(o: dict[str, Any]) -> list[Row]:
    rows = []
    for label, d in o["loops"].items():
        vs_c = (
            f"; {d['master_us'] - o['c_us']:+.2f} us vs the same calls from C, {o['c_us']:.2f} us"
            if o["c_us"] is not None
            else ""
        )
        rows.append(
            (
                f"master overhead per FMU step, {label} (1 FMU, {o['n']} steps)",
                f"{d['overhead_us']:+.2f} us ({d['master_us']:.2f} vs raw ctypes {o['raw_us']:.2f} us{vs_c})",
                "<= 2 us",
                _met(d["overhead_us"] <= 2.0),
            )
        )
    return rows


def _libcosim_rows(b: dict[str, Any]) -> list[Row]:
    rows = []
    for label, d in b["ours"].items():
        what = f"tester system, 5 FMUs at {b['step']}, {b['duration']}: {label}"
        if d["ratio"] is None:
            rows.append((what, f"{d['ours_s']:.3f} s (libcosimpy not installed)", ">= 2x faster", ""))
            continue
        note = " [1]" if b["mode"] == "initial" else ""
        measured = (
            f"{d['ours_s']:.3f} s vs {b['lib_s']:.3f} s, each a fresh process: **{d['ratio']:.2f}x** "
            f"({d['ratio_loop']:.2f}x stepping only; {d['ratio_warm']:.2f}x with the twin's FMUs loaded before)"
        )
        rows.append((what + note + " vs libcosimpy", measured, ">= 2x faster", _met(d["ratio"] >= 2.0)))
    return rows


def _replay_rows(r: dict[str, list[float]]) -> list[Row]:
    loop, wall = median(r["cosim_s"]), median(r["wall_s"])
    return [
        _below(
            "480-min replay: co-simulation loop (timing.cosim_s)",
            f"{loop:.2f} s (real-time factor {median(r['rtf']):.0f})",
            loop,
            1.0,
            "s",
        ),
        _below(
            "480-min replay: `twin run --uncertainty 0` from process start",
            f"{wall:.2f} s (real-time factor {median(r['rtf_wall']):.0f})",
            wall,
            3.0,
            "s",
        ),
        ("480-min replay: peak RSS", f"{median(r['maxrss_mb']):.0f} MB", "", ""),
    ]


def _endurance_rows(r: dict[str, list[float]]) -> list[Row]:
    wall, rss = median(r["wall_s"]), median(r["maxrss_mb"])
    measured = f"{wall:.1f} s (loop {median(r['cosim_s']):.1f} s, real-time factor {median(r['rtf']):.0f})"
    return [
        _below("MIL endurance 41.7 h (0.1 s): `twin run` from process start", measured, wall, 60.0, "s"),
        _below("MIL endurance: peak RSS", f"{rss:.0f} MB", rss, 400, "MB"),
    ]


def _flatness_rows(f: dict[str, Any]) -> list[Row]:
    return [
        (
            f"peak RSS {f['short']} vs {f['long']} (constant load)",
            f"{f['short_mb']:.0f} MB vs {f['long_mb']:.0f} MB: ratio {f['ratio']:.2f}",
            "within 20 %",
            _met(f["ratio"] <= 1.2),
        )
    ]


def markdown_table(args: argparse.Namespace) -> str:
    """The figures against their goals (the machine and the command are the docs file's header)."""
    rows: list[Row] = []
    for key, make in (("overhead", _overhead_rows), ("libcosim", _libcosim_rows), ("replay", _replay_rows)):
        if key in RESULTS:
            rows += make(RESULTS[key])
    if "endurance" in RESULTS:
        rows += _endurance_rows(RESULTS["endurance"])
    elif "replay" in RESULTS:
        rows.append(("MIL endurance 41.7 h", "skipped", "< 60 s, < 400 MB", ""))
    if "flatness" in RESULTS:
        rows += _flatness_rows(RESULTS["flatness"])
    lines = ["| figure | measured | target | met |", "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    lines += [
        "",
        f"Medians of {args.reps} repetitions ({args.endurance_reps} for the "
        + ("endurance and " if "endurance" in RESULTS else "")
        + f"memory-flatness runs){'; --quick: short runs, no endurance run' if args.quick else ''}.",
    ]
    if RESULTS.get("libcosim", {}).get("mode") == "initial":
        lines += [
            "",
            "[1] libcosim reads outputs in initialization mode, where our FMUs still report 0 (they compute "
            "outputs at fmi2ExitInitializationMode), and the temperature inputs refuse 0 K: libcosim ran with the "
            f"{RESULTS['libcosim']['n_unsafe']} thermal->temperature connections replaced by constant initial values "
            "(same FMU work per step, fewer transfers). Ratio = libcosim time / ours, set-up included.",
        ]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main


def main_before(args: argparse.Namespace, argv: Sequence[str] | None) -> int:
    """``--before REV``: issue 32's figures for REV's tree and this one (benchmarks/before.py)."""
    import before

    figures = args.only or "123456"
    if not figures or set(figures) - set(before.FIGURES):
        print(f"bench.py: --only {figures}: with --before, pick figures among 123456", file=sys.stderr)
        return 2
    plan = before.Plan(
        figures="".join(k for k in before.FIGURES if k in figures),
        reps=args.reps or (1 if args.quick else 5),
        heldout_reps=args.heldout_reps or (1 if args.quick else 3),
        quick=args.quick,
    )
    print("twin benchmark, before and after" + (" (--quick)" if args.quick else ""))
    info = print_machine(machine())
    table, complete = before.compare(
        args.before, args.before_venv, plan, commit() or "this tree", machine_line(info)
    )
    if args.write_docs and not complete:
        print("\nnot written to the docs: a figure failed")
    elif args.write_docs:
        write_docs(__file__, table, info, argv, name="bench_before")
    return 0 if complete else 1


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "--quick", action="store_true", help="few reps, short durations, no endurance run (a fast check)"
    )
    p.add_argument("--reps", type=int, help="repetitions of each measurement (default 5; 3 with --quick)")
    p.add_argument(
        "--endurance-reps",
        type=int,
        help="repetitions of the long runs: endurance, 1 h/10 h (default min(reps, 3); 1 with --quick)",
    )
    p.add_argument("--skip-endurance", action="store_true", help="skip the MIL endurance run (the long one)")
    p.add_argument("--steps", type=int, help="FMU steps of section (a) (default 100000; 20000 with --quick)")
    p.add_argument(
        "--only",
        help="sections to run, e.g. --only ab (default: abcde); with --before the figures, e.g. --only 125 "
        "(default: 123456)",
    )
    p.add_argument(
        "--before",
        metavar="REV",
        help="issue 32's figures for the tree at REV (a git worktree with its own environment) and this "
        "one, side by side, alternating in every repetition (sections a-e are not run)",
    )
    p.add_argument(
        "--before-venv",
        metavar="DIR",
        type=Path,
        help="with --before: the older tree's virtual environment, kept there for the next run (made if "
        "missing; the tree is installed into it each run); default: a temporary one",
    )
    p.add_argument(
        "--heldout-reps",
        type=int,
        help="with --before: repetitions of figure 6, twin heldout (default 3; 1 with --quick)",
    )
    p.add_argument(
        "--write-docs",
        action="store_true",
        help="write the table to docs/performance/bench.md (with --before: bench_before.md) unless a "
        "section failed",
    )
    p.add_argument("--libcosim-worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--twin-worker", action="store_true", help=argparse.SUPPRESS)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.libcosim_worker:
        return libcosim_worker()
    if args.twin_worker:
        return twin_worker()
    if args.before:
        return main_before(args, argv)
    return main_sections(args, argv)


def main_sections(args: argparse.Namespace, argv: Sequence[str] | None) -> int:
    """Sections (a)-(e) of this tree alone."""
    args.only = args.only or "abcde"
    if args.quick:
        args.skip_endurance = True
    args.reps = args.reps or (3 if args.quick else 5)
    args.endurance_reps = args.endurance_reps or (1 if args.quick else min(args.reps, 3))
    steps = args.steps or (20_000 if args.quick else 100_000)
    tester_duration = "2 min" if args.quick else "10 min"
    flat = ("6 min", "60 min") if args.quick else ("1 h", "10 h")

    print("twin co-simulation benchmark" + (" (--quick)" if args.quick else ""))
    info = print_machine(machine())
    loops = master_loops()
    print(f"   master      loops benchmarked: {', '.join(loop_label(lp) for lp in loops)}")
    print("   building/checking FMUs ...", flush=True)
    for model in ("FixtureMechanics", "HydraulicLoader", "OscillationDrive", "SensorsDAQ", "ThermalNetwork"):
        ensure_fmu(model)

    sections: list[tuple[str, Callable[[], None]]] = [
        ("a", lambda: bench_overhead(steps, args.reps)),
        ("b", lambda: bench_libcosim(tester_duration, "0.1 s", args.reps)),
        ("c", lambda: bench_whole_runs(args.reps, args.endurance_reps, args.skip_endurance)),
        ("e", lambda: bench_flatness(*flat, args.endurance_reps)),
    ]
    failed = 0
    t0 = time.perf_counter()
    for key, fn in sections:
        if key not in args.only and not (key == "c" and "d" in args.only):
            continue
        try:
            fn()
        except Exception:
            failed += 1
            print(f"   section ({key}) FAILED:")
            traceback.print_exc(file=sys.stdout)
    print(f"\n(benchmark took {time.perf_counter() - t0:.0f} s)")
    table = markdown_table(args)
    print(f"\n== the table (docs/performance/bench.md)\n\nmachine: {machine_line(info)}\n\n{table}")
    if args.write_docs and failed:
        print("\nnot written to the docs: a section failed")
    elif args.write_docs:
        write_docs(__file__, table, info, argv)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
