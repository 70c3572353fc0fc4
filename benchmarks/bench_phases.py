#!/usr/bin/env python3
"""Where the time of a `twin run` goes (a script, not a timed test).

Runs each scenario as a fresh `twin run` process (warm FMU cache) several times and prints, side
by side, the medians of: the whole process's wall time, its peak resident memory (of all its
processes together, the plot helper included, sampled every 20 ms; and of the largest), and the run's
own phases from summary.json (``timing.phases_s``: FMU set-up, stepping, opening and writing the
outputs while the run goes, the error model, each output file's closing). What the phases do not
cover is the interpreter's start, the imports and the command's checks (``start+imports``), so
the columns add up to the wall time.

    python benchmarks/bench_phases.py                     # the paper's replay and the MIL endurance test
    python benchmarks/bench_phases.py --reps 5 --quick    # the paper's replay only
    python benchmarks/bench_phases.py --set fmu.sensors.parameters.solver_step=0.1   # a what-if
    python benchmarks/bench_phases.py --write-docs        # ... the table into docs/performance/

Goals of issue 15: the paper's replay <= 0.8 s for the whole process; the MIL endurance run
<= 4 s and <= 150 MB.

``twin run`` is now ``twin.pipeline.prepare`` then ``twin.pipeline.run`` (issue 28); it is
timed as before, a fresh ``python -m twin run`` process, and its phases are still
``timing.phases_s`` of its summary.json (the phases the run has: a new one shows as a row).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import machine, machine_line, print_machine, write_docs
from treemem import wait_with_tree_peak

RUNS = {
    "paper replay": ["li2017-thermal-experiment", "--uncertainty", "0"],
    "MIL endurance": ["mil-endurance"],
}
GOALS = {"paper replay": (0.8, None), "MIL endurance": (4.0, 150.0)}


def run_env() -> dict[str, str]:
    """This environment, but with Python's bytecode cache on: an installed twin has its .pyc
    files, and a checkout writes them on its first run. PYTHONDONTWRITEBYTECODE (set on some
    machines) would make every run compile twin's modules again."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def one_run(args: list[str], sets: list[str], out: Path) -> dict[str, float]:
    """One fresh process: wall s; peak MB of the largest process (wait4: the run's own, or its
    plot helper's; never below this script's own peak, since ru_maxrss starts from the peak of
    the starting process) and of all of them together (sampled); the run's phases."""
    cmd = [sys.executable, "-m", "twin", "run", *args, "--out", str(out), "--quiet", "--force"]
    for s in sets:
        cmd += ["--set", s]
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=run_env())
    status, usage, tree_mb = wait_with_tree_peak(proc.pid)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(
            f"twin run {' '.join(args)} failed: {proc.stderr.read().decode() if proc.stderr else ''}"
        )
    phases = json.loads((out / "summary.json").read_text())["timing"]["phases_s"]
    row = {"wall": wall, "peak MB, all": tree_mb, "peak MB, largest": usage.ru_maxrss / 1024.0}
    row["start+imports"] = wall - sum(phases.values())
    row.update(phases)
    return row


def measure(runs: dict[str, list[str]], sets: list[str], reps: int) -> dict[str, dict[str, float]]:
    """The medians of ``reps`` fresh processes of each run, the runs alternating (a slow spell
    of the machine hits both), after one run each that builds or finds the FMUs."""
    with tempfile.TemporaryDirectory() as tmp:
        for run_args in runs.values():
            one_run(run_args, sets, Path(tmp) / "warm")
        samples: dict[str, list[dict[str, float]]] = {name: [] for name in runs}
        for _ in range(reps):
            for name, run_args in runs.items():
                samples[name].append(one_run(run_args, sets, Path(tmp) / name.replace(" ", "-")))
    rows = {}
    for name, got in samples.items():
        keys = list(dict.fromkeys(k for r in got for k in r))
        rows[name] = {k: statistics.median(r.get(k, 0.0) for r in got) for k in keys}
    return rows


def verdicts(name: str, r: dict[str, float]) -> list[tuple[str, float, bool]]:
    """(goal, limit, met) of a run: the goal was set for one process; a run now has two (its
    plots draw in their own), so both memory readings are judged: the run's largest process,
    and all of them together."""
    wall_goal, mem_goal = GOALS[name]
    out = [("wall, s", wall_goal, r["wall"] <= wall_goal)]
    if mem_goal is not None:
        for key in ("peak MB, largest", "peak MB, all"):
            out.append((key, mem_goal, r[key] <= mem_goal))
    return out


def markdown(rows: dict[str, dict[str, float]], reps: int, sets: list[str]) -> str:
    """The phases as a Markdown table, one column a run, then the goals."""
    keys = list(dict.fromkeys(k for r in rows.values() for k in r))
    lines = [
        "| medians (s; peak in MB) | " + " | ".join(rows) + " |",
        "|---|" + "---:|" * len(rows),
    ]
    for k in keys:
        lines.append(f"| {k} | " + " | ".join(_cell(k, r.get(k, 0.0)) for r in rows.values()) + " |")
    lines += ["", "| goal | limit | measured | met |", "|---|---:|---:|---|"]
    for name, r in rows.items():
        for key, limit, met in verdicts(name, r):
            value = r["wall"] if key == "wall, s" else r[key]
            lines.append(
                f"| {name}: {key} | <= {limit:g} | {_cell(key, value)} | {'yes' if met else '**no**'} |"
            )
    what = f"; `--set {' '.join(sets)}`" if sets else ""
    lines += ["", f"Medians of {reps} fresh `twin run` processes each, warm FMU cache{what}."]
    return "\n".join(lines)


def _cell(key: str, value: float) -> str:
    return f"{value:.0f}" if "MB" in key else f"{value:.3f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="the paper's replay only")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="passed to twin run")
    parser.add_argument(
        "--write-docs", action="store_true", help="write the table to docs/performance/bench_phases.md"
    )
    args = parser.parse_args(argv)
    print("twin run: where the time goes")
    info = print_machine(machine())
    runs = {k: v for k, v in RUNS.items() if not (args.quick and k != "paper replay")}
    rows = measure(runs, args.set, args.reps)
    keys = list(dict.fromkeys(k for r in rows.values() for k in r))
    print(
        f"twin run, medians of {args.reps} fresh processes each (s; peak in MB)"
        + (f", --set {args.set}" if args.set else "")
    )
    print(f"{'':24}" + "".join(f"{name:>16}" for name in rows))
    for k in keys:
        print(f"{k:24}" + "".join(f"{r.get(k, 0.0):16.3f}" for r in rows.values()))
    for name, r in rows.items():
        said = [f"{key} <= {limit:g}: {'met' if met else 'NOT met'}" for key, limit, met in verdicts(name, r)]
        print(f"goal {name}: " + "; ".join(said))
    table = markdown(rows, args.reps, args.set)
    print(f"\n== the table (docs/performance/bench_phases.md)\n\nmachine: {machine_line(info)}\n\n{table}")
    if args.write_docs:
        write_docs(__file__, table, info, argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
