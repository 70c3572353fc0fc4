"""Peak memory of a process tree, for the benchmarks: a `twin run` is two processes (the run and
its plot helper, src/twin/outputs/plot_process.py), and os.wait4's ru_maxrss gives only the
largest of them. :func:`wait_with_tree_peak` also samples the sum of all of them.

As a script it measures one command (the benchmarks import it instead)::

    python benchmarks/treemem.py twin run --quiet --force --out /tmp/run
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from typing import Any

#: seconds between two samples: the plot helper lives for many of them and its memory only
#: grows until it ends, so this catches its peak without loading the machine
INTERVAL_S = 0.02


def _sample(pid: int, done: threading.Event, out: list[float]) -> None:
    import psutil  # a dependency of Dask's

    peak = 0
    with contextlib.suppress(psutil.Error):
        root = psutil.Process(pid)
        while not done.is_set():
            total = 0
            for proc in [root, *root.children(recursive=True)]:
                with contextlib.suppress(psutil.Error):
                    total += proc.memory_info().rss
            peak = max(peak, total)
            done.wait(INTERVAL_S)
    out.append(peak / 2**20)


def wait_with_tree_peak(pid: int) -> tuple[int, Any, float]:
    """Wait for the child ``pid``: (wait status, its rusage from os.wait4, the largest sum of
    the resident memory of it and its descendants in MB, sampled every :data:`INTERVAL_S`)."""
    done, peak = threading.Event(), []
    sampler = threading.Thread(target=_sample, args=(pid, done, peak))
    sampler.start()
    try:
        _, status, usage = os.wait4(pid, 0)
    finally:
        done.set()
        sampler.join()
    return status, usage, peak[0] if peak else float("nan")


def main(argv: list[str]) -> int:
    """Run the command ``argv``; print its wall time, the peak of its process tree (sampled)
    and of its largest process (wait4); its exit code."""
    if not argv:
        print(__doc__)
        return 2
    start = time.perf_counter()
    proc = subprocess.Popen(argv)
    status, usage, tree_mb = wait_with_tree_peak(proc.pid)
    wall = time.perf_counter() - start
    print(
        f"wall {wall:.3f} s; peak RSS {tree_mb:.0f} MB all processes (sampled every {INTERVAL_S * 1e3:g} ms), "
        f"{usage.ru_maxrss / 1024:.0f} MB the largest (wait4)",
        file=sys.stderr,
    )
    return os.waitstatus_to_exitcode(status)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
