#!/usr/bin/env python3
"""Benchmark of ``twin sweep`` on a local Dask cluster (a script, not a timed test).

Prints side by side, in one run:

(a) throughput of a 200-point sweep of a short scenario (the paper's replay cut to 60 min)
    on 1 and on 2 workers, and the speed-up (goal: >= 1.7x on a 2-core machine);
(b) the scheduler's overhead per point: in that 2-worker sweep, the wall time the workers did
    not spend in points, per point; and the round trip of a point that does nothing (a task
    that returns at once, so all that is left is submitting, scheduling, the result's way
    back and the client's bookkeeping), one point a task, goal < 20 ms; beside it the same
    per point when such points travel several to a task, as a sweep sends short points;
(c) peak resident memory of each worker over a 1000-point sweep: after its first tenth of
    the points and at the end (goal: flat, within 20 %);
(d) FMU set-up per point (the run's ``fmu_setup`` phase: instances, parameters,
    initialization, the stepping loop's set-up), in this process, of a point with fresh
    instances and of one with the instances of the point before, reset (``twin.fmu.pool``, as
    a sweep's worker runs its points): medians side by side and their ratio (issue 15's goal
    for reused instances: <= 5 ms).

(e) flat memory (``--flat-memory``): a sweep of 10 000 points of a tiny scenario (the
    paper's replay cut to 2 min) on 2 workers; the resident memory (VmRSS, not the peak) of
    each worker and of the client (whose process also holds the local cluster's scheduler)
    after 1 000 points and after 10 000 (goal: within 10 %).

Timings start once the cluster is up (its start-up is printed apart). The cluster's start,
the design and the table are the real ``twin sweep`` code paths (:func:`run_sweep`).

    python benchmarks/bench_sweep.py            # the figures above (a few minutes)
    python benchmarks/bench_sweep.py --quick    # a fast check that everything runs
    python benchmarks/bench_sweep.py --write-docs   # ... the table into docs/performance/
    python benchmarks/bench_sweep.py --flat-memory  # (e) alone (a few minutes)

Since issue 28 a sweep's point is a :class:`~twin.pipeline.prepare.PreparedRun` made on the
client (:func:`~twin.pipeline.prepare.prepare_scenario`: the plan, the error model's
configuration) and run by the worker (:func:`~twin.pipeline.point.point_task`, which runs
:func:`~twin.pipeline.stages.run_point`). So (d) prepares each point outside its timer and
times ``run_point`` on it, what a worker's point now is; the batch size (b) is
:data:`twin.pipeline.cluster.MAX_BATCH` (was ``twin.sweep.execute``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from machine import machine, machine_line, print_machine, write_docs

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "li2017-thermal-experiment.toml"

SPEC = """[sweep]
base = "{base}"
design = "lhs"
samples = {samples}
seed = {seed}
set = ['scenario.duration = "60 min"']
{outputs}

[problem]
names = ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift"]
bounds = [[0.0, 9.0], [-0.3e-6, 0.3e-6]]
"""


def _spec(folder: Path, samples: int, seed: int, *, empty: bool) -> Any:
    from twin.sweep.spec import load_spec

    # an empty point has no figures: it names no outputs
    outputs = "" if empty else 'outputs = ["drift_mm.probe", "compensation.residual_rms_um.after"]'
    path = folder / f"bench-{samples}-{seed}.toml"
    text = SPEC.format(base=PAPER.as_posix(), samples=samples, seed=seed, outputs=outputs)
    path.write_text(text, encoding="utf-8")
    return load_spec(path)


def noop_task(payload: dict[str, Any]) -> dict[str, Any]:
    """A point that does nothing: what remains of its time is the machinery's."""
    return {
        "index": payload["index"],
        "status": "ok",
        "error": "",
        "figures": {},
        "files": {},
        "point_s": 0.0,
    }


def _sweep(folder: Path, samples: int, workers: int, seed: int, **kwargs: Any) -> dict[str, Any]:
    """``run_sweep`` on a local cluster of ``workers``; ``kwargs``: its ``task``, ``on_record``."""
    from twin.cosim import RunControls
    from twin.pipeline.cluster import StudyOptions
    from twin.sweep.runner import run_sweep

    out = folder / f"out-{samples}-{workers}-{seed}-{time.monotonic_ns()}"
    spec = _spec(folder, samples, seed, empty="task" in kwargs)
    return run_sweep(spec, out, RunControls(), StudyOptions(workers=workers), **kwargs)


def throughput(folder: Path, points: int, reps: int) -> dict[str, Any]:
    """(a) and the first half of (b): 1 vs 2 workers, alternating, medians of ``reps``."""
    import statistics

    runs: dict[int, list[dict[str, Any]]] = {1: [], 2: []}
    for rep in range(reps):
        for workers in (1, 2):
            runs[workers].append(_sweep(folder, points, workers, seed=rep)["timing"])
    med = {
        w: {
            k: statistics.median(t[k] for t in runs[w])
            for k in ("points_per_s", "overhead_ms_per_point", "startup_s", "mean_point_s")
        }
        for w in runs
    }
    return {"workers": med, "speedup": med[2]["points_per_s"] / med[1]["points_per_s"]}


def round_trip(folder: Path, points: int, max_batch: int) -> float:
    """Second half of (b): ms per point of a sweep whose points do nothing, on 2 workers, at
    most ``max_batch`` points to a task (1: each point's own round trip; the sweep's own
    :data:`twin.pipeline.cluster.MAX_BATCH`: what a sweep of such short points costs a point)."""
    import cloudpickle

    from twin.pipeline import cluster

    if __name__ != "__main__":  # imported: send the task by value (as a script it already is)
        cloudpickle.register_pickle_by_value(sys.modules[__name__])
    kept, cluster.MAX_BATCH = cluster.MAX_BATCH, max_batch
    try:
        timing = _sweep(folder, points, 2, seed=99, task=noop_task)["timing"]
    finally:
        cluster.MAX_BATCH = kept
    return timing["elapsed_s"] * timing["threads"] / timing["points_run"] * 1e3


def memory(folder: Path, points: int) -> dict[int, tuple[float, float]]:
    """(c): each worker's peak RSS (MB) after its first tenth of the points and at the end."""
    seen: dict[int, list[float]] = {}

    def watch(record: dict[str, Any]) -> None:
        seen.setdefault(record["pid"], []).append(record["peak_rss_mb"])

    _sweep(folder, points, 2, seed=7, on_record=watch)
    return {pid: (rss[max(0, len(rss) // 10 - 1)], rss[-1]) for pid, rss in seen.items() if len(rss) >= 10}


def _vmrss_mb() -> float:
    """This process's resident memory now (MB), Linux's ``VmRSS``."""
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def rss_task(payload: dict[str, Any]) -> dict[str, Any]:
    """A sweep's point that also says its worker's resident memory after it."""
    from twin.pipeline.point import point_task

    record = point_task(payload)
    record["rss_mb"] = _vmrss_mb()
    return record


FLAT_SPEC = """[sweep]
base = "{base}"
design = "random"
samples = {samples}
seed = 5
set = ['scenario.duration = "2 min"', 'scenario.output_interval = "10 s"']
outputs = ["drift_mm.probe", "compensation.residual_rms_um.after"]

[problem]
names = ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift"]
bounds = [[0.0, 9.0], [-0.3e-6, 0.3e-6]]
"""


def flat_memory(folder: Path, points: int, early: int) -> dict[str, Any]:
    """(e): resident memory (MB) of each worker and of the client after ``early`` points and
    after all ``points``: medians of each worker's last 50 records up to there (a worker's
    memory moves a little between points as numpy's buffers come and go)."""
    import statistics

    from twin.cosim import RunControls
    from twin.pipeline.cluster import StudyOptions
    from twin.sweep.runner import run_sweep
    from twin.sweep.spec import load_spec

    if __name__ != "__main__":
        import cloudpickle

        cloudpickle.register_pickle_by_value(sys.modules[__name__])
    path = folder / "flat.toml"
    path.write_text(FLAT_SPEC.format(base=PAPER.as_posix(), samples=points), encoding="utf-8")
    seen: dict[int, list[float]] = {}
    client: dict[str, float] = {}
    count = [0]
    start = time.perf_counter()

    def watch(record: dict[str, Any]) -> None:
        count[0] += 1
        seen.setdefault(record["pid"], []).append(record["rss_mb"])
        if count[0] in (early, points):
            client[str(count[0])] = _vmrss_mb()
            print(f"   {count[0]} points after {time.perf_counter() - start:.0f} s", flush=True)

    run_sweep(load_spec(path), folder / "flat-out", RunControls(), StudyOptions(workers=2),
              task=rss_task, on_record=watch)  # fmt: skip
    workers = {}
    for pid, rss in seen.items():
        share = len(rss) * early // points  # this worker's records up to the early mark
        workers[pid] = (statistics.median(rss[max(0, share - 50) : share]), statistics.median(rss[-50:]))
    return {"workers": workers, "client": (client[str(early)], client[str(points)]), "early": early,
            "points": points, "elapsed_s": time.perf_counter() - start}  # fmt: skip


def _flat_rows(r: dict[str, Any]) -> list[str]:
    rows = []
    pairs = [(f"worker {k + 1}", r["workers"][pid]) for k, pid in enumerate(sorted(r["workers"]))]
    for name, (early, end) in [*pairs, ("client (and scheduler)", r["client"])]:
        growth = end / early - 1
        rows.append(
            _row(
                f"(e) {name} RSS, {r['early']} vs {r['points']} points",
                f"{early:.0f} -> {end:.0f} MB ({growth:+.1%})",
                "within 10 %",
                abs(growth) <= 0.1,
            )
        )
    return rows


def setup_per_point(points: int) -> dict[str, float]:
    """(d): median ms of the ``fmu_setup`` phase and of the whole point (``run_point`` on a
    point prepared outside the timer, as a sweep's client prepares it), fresh vs reused,
    alternating so a slow drift of the machine hits both alike."""
    import statistics

    from twin.config.load import load_scenario
    from twin.fmu.pool import SlotPool
    from twin.pipeline import prepare_scenario, run_point

    sc = load_scenario(PAPER, ['scenario.duration="60 min"'])
    base = prepare_scenario(sc)  # the error model's configuration, once (as run_sweep does)
    pool = SlotPool()
    run_point(prepare_scenario(sc, base.evaluation))  # warm: the FMU files unpacked
    run_point(prepare_scenario(sc, base.evaluation), pool=pool)  # ... and the pool filled
    got: dict[str, list[float]] = {"fresh": [], "reused": [], "fresh point": [], "reused point": []}
    for _ in range(points):
        for label, kwargs in (("fresh", {}), ("reused", {"pool": pool})):
            point = prepare_scenario(sc, base.evaluation)
            start = time.perf_counter()
            summary = run_point(point, **kwargs)
            got[f"{label} point"].append(time.perf_counter() - start)
            got[label].append(summary.timing.phases_s["fmu_setup"])
    return {k: statistics.median(v) * 1e3 for k, v in got.items()}


def _row(name: str, value: str, goal: str = "", ok: bool | None = None) -> str:
    verdict = {None: "", True: "yes", False: "**no**"}[ok]
    return f"| {name:<44} | {value:>22} | {goal:>12} | {verdict:>6} |"


def measure(sizes: dict[str, int]) -> dict[str, Any]:
    """Every figure of (a)-(d) at these sizes."""
    from twin.pipeline.cluster import MAX_BATCH

    with tempfile.TemporaryDirectory(prefix="twin-bench-sweep-") as tmp:
        folder = Path(tmp)
        return {
            "throughput": throughput(folder, sizes["points"], sizes["reps"]),
            "round_trip": round_trip(folder, sizes["noop_points"], 1),
            "round_trip_batched": round_trip(folder, sizes["noop_points"], MAX_BATCH),
            "memory": memory(folder, sizes["memory_points"]),
            "setup": setup_per_point(sizes["setup_points"]),
        }


def _sweep_rows(t: dict[str, Any], points: int) -> list[str]:
    w1, w2 = t["workers"][1], t["workers"][2]
    return [
        _row(f"(a) {points}-point sweep, 1 worker", f"{w1['points_per_s']:.2f} points/s"),
        _row(f"(a) {points}-point sweep, 2 workers", f"{w2['points_per_s']:.2f} points/s"),
        _row("(a) speed-up, 2 vs 1 worker", f"{t['speedup']:.2f}x", ">= 1.7x", t["speedup"] >= 1.7),
        _row("    mean point (in the worker), 2 workers", f"{w2['mean_point_s'] * 1e3:.0f} ms"),
        _row("    cluster start-up, 2 workers", f"{w2['startup_s']:.1f} s"),
        _row(
            "(b) overhead per point, 2-worker sweep",
            f"{w2['overhead_ms_per_point']:.1f} ms",
            "< 20 ms",
            w2["overhead_ms_per_point"] < 20,
        ),
    ]


def _round_trip_rows(r: dict[str, Any], noop_points: int) -> list[str]:
    from twin.pipeline.cluster import MAX_BATCH

    rt = r["round_trip"]
    return [
        _row(
            f"(b) round trip of an empty point, one a task ({noop_points})",
            f"{rt:.1f} ms",
            "< 20 ms",
            rt < 20,
        ),
        _row(
            f"    the same, up to {MAX_BATCH} a task (as a sweep sends them)",
            f"{r['round_trip_batched']:.1f} ms",
        ),
    ]


def _memory_rows(mem: dict[int, tuple[float, float]], memory_points: int) -> list[str]:
    rows = []
    for k, (early, end) in enumerate(mem[pid] for pid in sorted(mem)):
        growth = end / early - 1
        rows.append(
            _row(
                f"(c) worker {k + 1} peak RSS, 1/10 vs all {memory_points // 2}",
                f"{early:.0f} -> {end:.0f} MB ({growth:+.0%})",
                "within 20 %",
                abs(growth) <= 0.2,
            )
        )
    return rows


def _setup_rows(setup: dict[str, float]) -> list[str]:
    return [
        _row("(d) FMU set-up per point, fresh instances", f"{setup['fresh']:.2f} ms"),
        _row(
            "(d) FMU set-up per point, reused (pool)",
            f"{setup['reused']:.2f} ms",
            "<= 5 ms",
            setup["reused"] <= 5.0,
        ),
        _row("    ratio fresh / reused", f"{setup['fresh'] / setup['reused']:.2f}x"),
        _row(
            "    whole point (60 min replay), fresh / reused",
            f"{setup['fresh point']:.1f} / {setup['reused point']:.1f} ms",
        ),
    ]


def markdown(r: dict[str, Any], sizes: dict[str, int], load: float) -> str:
    """The figures against their goals as a Markdown table, and how they were measured."""
    lines = [
        f"| {'measure':<44} | {'measured':>22} | {'goal':>12} | {'met':>6} |",
        "|" + "-" * 46 + "|" + "-" * 23 + ":|" + "-" * 13 + ":|" + "-" * 8 + "|",
    ]
    lines += _sweep_rows(r["throughput"], sizes["points"])
    lines += _round_trip_rows(r, sizes["noop_points"])
    lines += _memory_rows(r["memory"], sizes["memory_points"])
    lines += _setup_rows(r["setup"])
    reps = sizes["reps"]
    lines += [
        "",
        f"(a) medians of {reps} sweep{'s' if reps > 1 else ''} on each number of workers, alternating; "
        f"(d) medians of {sizes['setup_points']} points each, alternating. "
        f"Load average at the start: {load:.1f}.",
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes: a check that it runs, not figures")
    parser.add_argument(
        "--write-docs", action="store_true", help="write the table to docs/performance/bench_sweep.md"
    )
    parser.add_argument(
        "--flat-memory", action="store_true", help="(e) alone: worker and client memory over 10 000 points"
    )
    args = parser.parse_args()
    if args.flat_memory:
        points, early = (1000, 100) if args.quick else (10_000, 1000)
        print(f"twin sweep benchmark (e): {points} points" + (" (--quick)" if args.quick else ""))
        print_machine(machine())
        with tempfile.TemporaryDirectory(prefix="twin-bench-sweep-") as tmp:
            found = flat_memory(Path(tmp), points, early)
        print(f"\n{found['points']} points in {found['elapsed_s']:.0f} s\n")
        print("\n".join(_flat_rows(found)))
        return 0
    small = (40, 1, 100, 100, 10) if args.quick else (200, 2, 500, 1000, 60)
    sizes = dict(zip(("points", "reps", "noop_points", "memory_points", "setup_points"), small, strict=True))
    load = os.getloadavg()[0]
    print("twin sweep benchmark" + (" (--quick)" if args.quick else ""))
    info = print_machine(machine())
    print(f"   load        {load:.1f}")
    if load > 0.5 * (os.cpu_count() or 1):
        print("note: the machine is busy; ratios are indicative, measure on a quiet machine for the record")
    table = markdown(measure(sizes), sizes, load)
    print(f"\n== the table (docs/performance/bench_sweep.md)\n\nmachine: {machine_line(info)}\n\n{table}")
    if args.write_docs:
        write_docs(__file__, table, info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
