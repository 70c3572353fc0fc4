#!/usr/bin/env python3
"""Benchmark of ``twin update`` on the paper's record (a script, not a timed test).

Runs the command a user types, ``twin update`` (the shipped record
scenarios/records/li2017.toml, its own sampler settings), as a fresh process, and prints its
wall time, the peak resident memory of its process tree (sampled: benchmarks/treemem.py), the
size of samples.parquet, and whether it converged (R-hat, ESS from its summary.json), against
issue 31's goal: within 3 min on this 2-core machine, converged (R-hat <= 1.01, ESS >= 400).
With ``--src OLD/src`` the same command of an older tree runs beside it, alternating, so the
two figures stand side by side from one run.

    python benchmarks/bench_update.py                 # once
    python benchmarks/bench_update.py --reps 2 --src /path/to/old/src
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

from machine import print_machine
from treemem import wait_with_tree_peak

GOAL_S, GOAL_R_HAT, GOAL_ESS = 180.0, 1.01, 400.0


def measure(out: Path, src: str | None) -> dict[str, float]:
    """One ``twin update --out OUT --quiet`` in a fresh process (``src``: an older tree's code)."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "twin", "update", "--out", str(out), "--quiet"], env=env)
    status, _, tree_mb = wait_with_tree_peak(proc.pid)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"twin update failed (exit {os.waitstatus_to_exitcode(status)})")
    summary = json.loads((out / "summary.json").read_text())
    g = summary["diagnostics"]
    return {
        "wall_s": wall,
        "peak_mb": tree_mb,
        "parquet_mb": (out / "samples.parquet").stat().st_size / 2**20,
        "r_hat_max": g["r_hat_max"],
        "ess_min": g["ess_min"],
        "updated_median_mm": summary["drift_mm"]["updated"]["median"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=1, help="repetitions (the median is printed)")
    ap.add_argument("--src", help="an older tree's src folder, run beside this one")
    args = ap.parse_args()
    print_machine()
    trees = {"this tree": None} | ({f"--src {args.src}": args.src} if args.src else {})
    results: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.reps):
            for label, src in trees.items():  # alternating: a drift of the machine hits both
                results[label].append(measure(Path(tmp) / f"{rep}-{len(results[label])}-{hash(label)}", src))
    print(
        "\n| tree | wall s | peak MB (all processes) | samples.parquet MB | R-hat max | ESS min | updated median mm | goal met |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for label, rows in results.items():
        m = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
        met = m["wall_s"] <= GOAL_S and m["r_hat_max"] <= GOAL_R_HAT and m["ess_min"] >= GOAL_ESS
        print(
            f"| {label} | {m['wall_s']:.1f} | {m['peak_mb']:.0f} | {m['parquet_mb']:.1f} | {m['r_hat_max']:.4f} "
            f"| {m['ess_min']:.0f} | {m['updated_median_mm']:+.4f} | {'yes' if met else 'NO'} |"
        )
    print(
        f"\ngoal (issue 31): <= {GOAL_S:.0f} s, R-hat <= {GOAL_R_HAT}, ESS >= {GOAL_ESS:.0f}; median of {args.reps}"
    )


if __name__ == "__main__":
    main()
