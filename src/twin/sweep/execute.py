"""Running points on Dask distributed: a local cluster or an existing scheduler.

By default an in-process :class:`distributed.LocalCluster` with one worker process per core
and one thread each (a point is single-threaded C and numpy: processes, not threads, run
them side by side). ``--scheduler tcp://host:8786`` connects to an existing cluster and uses
it unchanged.

Points are submitted in a sliding window (a few per worker thread) rather than all at once:
a point's scenario is built and checked on the client only when it is submitted, so a
100 000-point sweep holds a few dozen scenarios in memory, not all of them, on the client
and on the scheduler. A point whose values the scenario loader refuses (a sample outside a
variable's physical range) is recorded as failed without running.

A point that raises is a failed point (its error is its row's message). A worker that dies
while running a point (a crash in an FMU, the out-of-memory killer) makes the scheduler
retry the point on another worker; the local cluster allows one retry
(``allowed_failures=1``), an existing scheduler its own setting
(``distributed.scheduler.allowed-failures``, 3 by default). After that the point is recorded
as failed with the reason. Dask counts a death against every point the worker held at the
time, which the window keeps to about two per worker thread.
"""

from __future__ import annotations

import logging
import os
import resource
import time
import uuid
import warnings
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from twin.errors import ConfigError, RunError

#: tasks in flight per worker thread (keeps every worker busy while results travel back)
WINDOW_PER_THREAD = 2
#: a point's error message is kept to this length (it goes into one table cell)
MAX_ERROR = 500

Payload = dict[str, Any]
Record = dict[str, Any]


def one_line(exc: BaseException) -> str:
    """``Type: message`` of an exception on one line, bounded."""
    text = f"{type(exc).__name__}: {exc}".replace("\r", " ").replace("\n", " | ")
    return text[:MAX_ERROR]


def run_task(payload: Payload) -> Record:
    """What a worker runs for one point: never raises, a failure is a failed record.

    Returns the figures, the run folder's files when asked, and for the benchmark the
    seconds the point took and the worker process's peak resident memory.
    """
    from twin.sweep import shipping
    from twin.sweep.point import run_point, run_point_folder

    start = time.perf_counter()
    record: Record = {"index": payload["index"], "status": "ok", "error": "", "figures": {}, "files": {}}
    try:
        shipping.check_worker()
        if payload.get("folders"):
            record["figures"], record["files"] = run_point_folder(payload["scenario"])
        else:
            record["figures"] = run_point(payload["scenario"])
    except Exception as exc:
        record.update(status="failed", error=one_line(exc))
    record["point_s"] = time.perf_counter() - start
    record["pid"] = os.getpid()
    record["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return record


def failed(index: int, error: str) -> Record:
    """The record of a point that did not run (or whose worker died)."""
    return {"index": index, "status": "failed", "error": error[:MAX_ERROR], "figures": {}, "files": {}}


@contextmanager
def open_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A client of the given scheduler, or of a fresh local cluster (closed on exit).

    An unreachable scheduler is a :class:`ConfigError` (``--scheduler: ...``); the time to
    wait for it is Dask's ``distributed.comm.timeouts.connect``.
    """
    import dask
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is not None:
        timeout = dask.config.get("distributed.comm.timeouts.connect")
        try:
            client = Client(scheduler, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise ConfigError(f"cannot reach the scheduler: {one_line(exc)}", source="--scheduler") from None
    else:
        with warnings.catch_warnings():
            # port 8787 taken (another cluster): Dask serves the dashboard elsewhere, and the
            # address printed is the one it took
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            cluster = LocalCluster(
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,
                processes=True,
                scheduler_kwargs={"allowed_failures": 1},
                silence_logs=logging.ERROR,
            )
        client = Client(cluster, set_as_default=False)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def dashboard(client: Any) -> str | None:
    """The dashboard's address when the scheduler serves one (its pages need bokeh)."""
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:
        return None
    return client.dashboard_link if "dashboard" in services else None


def _threads(client: Any) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:
        return 1


def _outcome(future: Any, index: int) -> Record:
    """The record of a finished future; a lost scheduler is raised, not recorded."""
    from distributed import KilledWorker

    if future.status == "finished":
        return future.result()
    exc = future.exception()
    if isinstance(exc, KilledWorker):
        tries = exc.allowed_failures + 1
        return failed(index, f"KilledWorker: a worker died while running this point ({tries} tries)")
    if future.status == "cancelled":
        raise RunError(f"point {index} was cancelled: the scheduler is gone or restarted")
    return failed(index, one_line(exc))


def execute(
    client: Any,
    indices: Iterable[int],
    payload: Callable[[int], Payload | Record],
    task: Callable[[Payload], Record] = run_task,
) -> Iterator[Record]:
    """Run the points, yielding each record as it finishes (in any order).

    ``payload(i)`` builds point ``i``'s task input, or returns a failed record for a point
    that cannot run (then nothing is submitted).
    """
    from distributed import as_completed

    session = uuid.uuid4().hex[:8]
    pending = iter(indices)
    running: dict[Any, int] = {}
    queue = as_completed(loop=client.loop)
    window, checked = WINDOW_PER_THREAD * _threads(client), time.monotonic()

    def fill() -> Iterator[Record]:
        while len(running) < window:
            index = next(pending, None)
            if index is None:
                return
            item = payload(index)
            if "scenario" not in item:
                yield item
                continue
            future = client.submit(task, item, key=f"twin-point-{index}-{session}", pure=False)
            running[future] = index
            queue.add(future)

    yield from fill()
    for future in queue:
        index = running.pop(future)
        record = _outcome(future, index)
        future.release()
        yield record
        if time.monotonic() - checked > 1.0:  # workers may join (or leave) during a sweep
            window, checked = WINDOW_PER_THREAD * _threads(client), time.monotonic()
        yield from fill()
