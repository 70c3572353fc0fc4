#!/usr/bin/env python3
"""Benchmark of ``twin compensate`` on long records (a script, not a timed test).

Prints side by side, in one run, the whole command's wall time and peak resident memory (each
in its own process, measured by ``os.wait4``) for two files of 200,000 rows:

(a) a lab's record: time, eight temperatures and the probe (10 columns, about 23 MB);
(b) a wide record like a run's ``signals.csv``: those columns plus 70 more the error model
    does not read (80 columns, about 250 MB: issue 13 measured 19 s and 1.16 GB on such a file).

Goals (issue 13): < 2 s and < 200 MB for 200,000 rows.

    python benchmarks/bench_compensate.py            # both files, 200,000 rows
    python benchmarks/bench_compensate.py --rows 20000   # a fast check
    python benchmarks/bench_compensate.py --src OLD/src  # an older tree's code on the same files
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GOAL_S, GOAL_MB = 2.0, 200.0
#: the paper's eight measuring points (twin.errormodel.sources.DEFAULT_TEMPERATURES), named
#: here so that this process imports neither numpy nor the twin (see measure())
POINTS = ("bearing_block", "heel_block", "bearing", "t_plate", "base", "long_pole", "detecting_frame", "room")


def write_record(path: Path, rows: int, extra: int) -> None:
    """A record of ``rows`` at 1 s: a slow warm-up with sensor noise, ``extra`` unread columns."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv

    rng = np.random.default_rng(1)
    t = np.arange(rows, dtype=np.float64)
    rise = 5.0 * (1 - np.exp(-t / 36000.0))
    cols = {"time": t}
    for i in range(8):
        cols[f"T{i}"] = 293.15 + rise + 0.02 * rng.standard_normal(rows)
    cols["probe"] = 4.8e-3 - 2e-6 * rise + 5e-8 * rng.standard_normal(rows)
    for i in range(extra):
        cols[f"other.signal_{i}"] = rng.standard_normal(rows)
    with open(path, "wb") as f:
        f.write((",".join(cols) + "\n").encode())
        pacsv.write_csv(
            pa.table({f"c{i}": v for i, v in enumerate(cols.values())}),
            f,
            pacsv.WriteOptions(include_header=False, quoting_style="none"),
        )


def config(path: Path) -> None:
    temps = ", ".join(f'{p} = "T{i}"' for i, p in enumerate(POINTS))
    path.write_text(
        f'[errormodel]\nreading = "probe"\nfactors = ["thermal", "interference"]\ntemperatures = {{ {temps} }}\n'
    )


def measure(csv: Path, toml: Path, out: Path, src: str | None = None) -> tuple[float, float]:
    """Wall time (s) and peak RSS (MB) of one ``twin compensate`` process (the twin of ``src``,
    a source folder, instead of the installed one when given).

    Linux keeps a process's peak RSS across exec: a child spawned by a process holding 250 MB
    reports at least 250 MB whatever it does itself. So this process stays small (the files are
    written by a child of their own, and nothing here imports numpy) and the peak is the
    command's own."""
    # twin.cli.main: older trees have no twin.entry
    cmd = [sys.executable, "-c", "import sys; from twin.cli import main; sys.exit(main())"]
    env = {**os.environ, **({"PYTHONPATH": src} if src else {})}
    start = time.perf_counter()
    proc = subprocess.Popen([*cmd, "compensate", str(csv), "--config", str(toml), "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)  # fmt: skip
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"twin compensate failed: {proc.stderr.read().decode() if proc.stderr else ''}")
    return wall, usage.ru_maxrss / 1024.0  # kB on Linux


def main() -> None:
    if len(sys.argv) == 5 and sys.argv[1] == "--write":  # the child that writes a record
        write_record(Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]))
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=200_000)
    parser.add_argument("--src", help="measure the twin in this source folder (e.g. an old commit's src)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        config(d / "lab.toml")
        code = f" (code of {args.src})" if args.src else ""
        print(f"twin compensate{code}, {args.rows} rows; goals < {GOAL_S} s, < {GOAL_MB:.0f} MB")
        print(f"{'record':<34} {'file MB':>8} {'wall s':>8} {'peak MB':>8}  goal")
        for name, extra in (("(a) lab: 10 columns", 0), ("(b) wide, like signals.csv: 80 columns", 70)):
            csv = d / f"{extra}.csv"
            subprocess.run(
                [sys.executable, __file__, "--write", str(csv), str(args.rows), str(extra)], check=True
            )
            measure(csv, d / "lab.toml", d / "warm", args.src)  # the first run pays the cold file cache
            wall, rss = measure(csv, d / "lab.toml", d / f"out{extra}", args.src)
            met = "met" if wall < GOAL_S and rss < GOAL_MB else "NOT met"
            print(f"{name:<34} {csv.stat().st_size / 1e6:>8.1f} {wall:>8.2f} {rss:>8.0f}  {met}")
            csv.unlink()


if __name__ == "__main__":
    main()
