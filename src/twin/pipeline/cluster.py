"""Running points on Dask distributed: a local cluster or an existing scheduler.

By default an in-process :class:`distributed.LocalCluster` with one worker process per core
and one thread each (a point is single-threaded C and numpy: processes, not threads, run
them side by side). ``--scheduler tcp://host:8786`` connects to an existing cluster and uses
it unchanged.

Points are submitted in a sliding window (a few tasks per worker thread) rather than all at
once: a point's scenario is built and checked on the client only when it is submitted, so a
100 000-point sweep holds a few dozen scenarios in memory, not all of them, on the client
and on the scheduler. A point whose values the scenario loader refuses (a sample outside a
variable's physical range) is recorded as failed without running. Short points travel
several to a task (about half a second of work each), because on a small machine the
per-task bookkeeping of client, scheduler and worker otherwise takes CPU from the points.

A point that raises is a failed point (its error is its row's message). A worker that dies
while running a task (a crash in an FMU, the out-of-memory killer) makes the scheduler
retry the task on another worker; the local cluster allows one retry
(``allowed_failures=1``), an existing scheduler its own setting
(``distributed.scheduler.allowed-failures``, 3 by default). Dask counts a death against
every task the worker held at the time, the crashing one and those queued beside it; so the
points of a task that still failed run again each alone, one task on the whole cluster,
and only a point that kills its worker alone is recorded as failed with the reason.
"""

from __future__ import annotations

import logging
import os
import resource
import sys
import threading
import time
import uuid
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from twin.errors import ConfigError, RunError

#: tasks in flight per worker thread (keeps every worker busy while results travel back)
WINDOW_PER_THREAD = 2
#: seconds of points one task should hold (short points travel in batches)
TASK_SECONDS = 0.5
#: the most points in one task
MAX_BATCH = 16
#: a batch is never so large that fewer tasks than this per worker thread remain to share out
TASKS_PER_THREAD_LEFT = 4
#: a point's error message is kept to this length (it goes into one table cell)
MAX_ERROR = 500

Payload = dict[str, Any]
Record = dict[str, Any]


def one_line(exc: BaseException) -> str:
    """``Type: message`` of an exception on one line, bounded."""
    text = f"{type(exc).__name__}: {exc}".replace("\r", " ").replace("\n", " | ")
    return text[:MAX_ERROR]


def peak_rss_mb() -> float:
    """This process's peak resident memory in MB: Linux's ``VmHWM``, not ``ru_maxrss``, which
    starts from the peak of the process that started this one (a Dask worker reports its
    nanny's peak, however little it uses itself, so a growing worker could not show).
    Elsewhere ``ru_maxrss`` (bytes on macOS, KiB on the others)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 1024.0


def failed(index: int, error: str) -> Record:
    """The record of a point that did not run (or whose worker died)."""
    return {"index": index, "status": "failed", "error": error[:MAX_ERROR], "figures": {}, "files": {}}


@dataclass(frozen=True)
class StudyOptions:
    """Where and how a study's many runs go: an existing Dask scheduler's address (None: a
    local cluster of ``workers`` processes, default one per core), whether to run only what
    its output folder lacks (``resume``), and where to tell its progress (points done, of
    which failed, of how many)."""

    scheduler: str | None = None
    workers: int | None = None
    resume: bool = False
    progress: Callable[[int, int, int], None] | None = None


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
        scheduler = check_scheduler(scheduler)
        timeout = dask.config.get("distributed.comm.timeouts.connect")
        try:
            client = Client(scheduler, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise ConfigError(f"cannot reach the scheduler: {one_line(exc)}", source="--scheduler") from None
    else:
        _resource_tracker()
        with warnings.catch_warnings():
            # port 8787 taken (another cluster): Dask serves the dashboard elsewhere, and the
            # address printed is the one it took
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            cluster = LocalCluster(
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,
                processes=True,
                scheduler_kwargs={"allowed_failures": 1},
                # a point's error reaches the client as its task's (the point's record), and a
                # lost worker as KilledWorker; what the workers, their nannies and the scheduler
                # (in this process) log on their own, even at ERROR, is the cluster's noise:
                # when a run's Ctrl-C ends its Monte Carlo, a worker's heartbeat can find the
                # scheduler gone and print a traceback under the command's one line
                silence_logs=logging.CRITICAL,
            )
        client = Client(cluster, set_as_default=False)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


#: Dask's developer logs, each a deque of the last N messages per connection, process and
#: kind: the client's and the scheduler's keep every message they sent (a point's task, its
#: prepared run of some 30 KB, among them) and a worker every task it was given. At Dask's
#: 1000 a long sweep's client grew by ~90 KB a point until each log filled (some 500 MB) and
#: its workers by ~13 KB a point; ten keep them small and flat. The system monitor's
#: history is cut from an hour to a minute. Read when the client, the scheduler and the
#: workers start (a local cluster's workers inherit it; an existing scheduler keeps its own).
BOUNDED_LOGS = {
    "distributed.admin.low-level-log-length": 10,
    "distributed.admin.system-monitor.log-length": 120,
}


def bounded_logs() -> Any:
    """Dask's configuration with :data:`BOUNDED_LOGS`, for the life of a study's cluster
    (``with bounded_logs(), open_client(...)``)."""
    import dask
    import distributed  # noqa: F401 (its defaults join dask's config first, not inside the set)

    return dask.config.set(BOUNDED_LOGS)


# ------------------------------------------------------------------ an existing scheduler

#: seconds to open a connection to an existing scheduler (and exchange Dask's handshake)
SCHEDULER_CONNECT_S = 10.0
#: seconds for its answer to "who are you" once connected: a listener that accepts and never
#: answers ends the command within connect + answer, never a hang
SCHEDULER_ANSWER_S = 15.0
_SCHEMES = ("tcp", "tls", "ws", "wss")


def scheduler_address(text: str, source: str = "--scheduler") -> str:
    """The address of an existing scheduler (``tcp://host:port``; ``host:port`` means tcp),
    checked for its form alone, before anything connects: a :class:`ConfigError` naming
    ``source`` otherwise (a file's name says to give it as ``--scheduler-file``)."""
    import re

    text = text.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if not sep and ("/" in text or text.endswith(".json") or os.path.isfile(text)):
        raise ConfigError(f"{text!r} is a file, not an address: give it as --scheduler-file", source=source)
    if scheme not in _SCHEMES:
        raise ConfigError(
            f"{text!r}: expected tcp://host:port (schemes: {', '.join(_SCHEMES)}), got scheme {scheme!r}",
            source=source,
        )
    match = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):([0-9]{1,5})", rest)
    if match is None or not 0 < int(match.group(2)) < 65536:
        raise ConfigError(f"{text!r}: expected host:port with a port number (tcp://host:8786)", source=source)
    return f"{scheme}://{rest}"


def read_scheduler_file(path: str) -> str:
    """The address in Dask's scheduler file (``dask scheduler --scheduler-file FILE``)."""
    import json

    source = f"--scheduler-file {path}"
    try:
        if os.path.getsize(path) > 2**20:
            raise ValueError("larger than 1 MB")
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"not a Dask scheduler file ({one_line(exc)[:160]})", source=source) from None
    address = data.get("address") if isinstance(data, dict) else None
    if not isinstance(address, str):
        raise ConfigError('not a Dask scheduler file (no "address")', source=source)
    return scheduler_address(address, source)


def check_scheduler(address: str, source: str = "--scheduler") -> str:
    """Connect to the scheduler at ``address`` and ask who it is, within
    :data:`SCHEDULER_CONNECT_S` and :data:`SCHEDULER_ANSWER_S`, before a Client exists (a
    Client that cannot connect leaves a thread and a traceback at exit); the checked address,
    or a :class:`ConfigError` naming ``source`` and what went wrong."""
    import asyncio

    from distributed.comm import connect

    address = scheduler_address(address, source)
    _knock(address, source)

    async def ask() -> Any:
        comm = await connect(address, timeout=SCHEDULER_CONNECT_S)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        answer = asyncio.run(asyncio.wait_for(ask(), SCHEDULER_CONNECT_S + SCHEDULER_ANSWER_S))
    except TimeoutError:
        total = SCHEDULER_CONNECT_S + SCHEDULER_ANSWER_S
        raise ConfigError(
            f"{address} accepted but did not answer within {total:.0f} s", source=source
        ) from None
    except Exception as exc:  # the comm layer's errors are many kinds (OSError, CommClosedError, ...)
        raise ConfigError(
            f"cannot reach the scheduler at {address}: {one_line(exc)}", source=source
        ) from None
    if not isinstance(answer, dict) or answer.get("type") != "Scheduler":
        raise ConfigError(f"{address} answered, but is not a Dask scheduler", source=source)
    return address


def _knock(address: str, source: str) -> None:
    """A plain TCP connection first: a refused one (nothing listens there) is said at once,
    where Dask's connect would retry it for its whole timeout."""
    import socket

    host, _, port = address.partition("://")[2].rpartition(":")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=SCHEDULER_CONNECT_S).close()
    except TimeoutError:
        raise ConfigError(
            f"cannot reach the scheduler at {address}: no answer to connect within {SCHEDULER_CONNECT_S:.0f} s",
            source=source,
        ) from None
    except OSError as exc:
        raise ConfigError(
            f"cannot reach the scheduler at {address}: {one_line(exc)}", source=source
        ) from None


def _resource_tracker() -> None:
    """Start multiprocessing's resource tracker from a thread of its own, before the workers.

    The command may have SIGINT and SIGTERM blocked (:mod:`twin.cli.interrupt`: it ends its
    workers itself, and a worker that a terminal's Ctrl-C reaches prints tracebacks while its
    nanny restarts it); the workers inherit the block from the thread that starts them. Starting
    the tracker unblocks both in the thread that starts it (bpo-33613): done on the first
    worker's start, that thread then started every worker open to the signals.
    """
    from multiprocessing import resource_tracker

    starter = threading.Thread(target=resource_tracker.ensure_running, name="resource tracker")
    starter.start()
    starter.join()


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


def run_batch(task: Callable[[Payload], Record], payloads: list[Payload]) -> list[Record]:
    """What a worker runs for one task: several points one after the other (never raises)."""
    return [task(p) for p in payloads]


class _Batcher:
    """How many points go into one task.

    Short points travel in batches: every task costs the scheduler, the client and the
    worker a few milliseconds of bookkeeping, and on a small machine that work takes CPU from
    the points themselves. A batch holds about :data:`TASK_SECONDS` of points (one point per
    task until points have been timed), never so many that fewer than
    :data:`TASKS_PER_THREAD_LEFT` tasks per worker thread remain to share out, and at most
    :data:`MAX_BATCH`. Long points run one per task.
    """

    def __init__(self) -> None:
        self.seconds = 0.0
        self.timed = 0

    def took(self, record: Record) -> None:
        if record.get("status") == "ok" and "point_s" in record:
            self.seconds += record["point_s"]
            self.timed += 1

    def size(self, remaining: int, threads: int) -> int:
        if self.timed == 0:
            return 1
        per_point = max(self.seconds / self.timed, 1e-3)
        fair = remaining // (TASKS_PER_THREAD_LEFT * threads)
        return max(1, min(int(TASK_SECONDS / per_point), fair, MAX_BATCH))


def _outcome(future: Any, indices: list[int], alone: bool) -> list[Record] | None:
    """The records of a finished task; ``None`` when its worker died while other tasks were
    in flight too (the death cannot be put down to one of its points: they run again, each
    alone); a lost scheduler is raised, not recorded."""
    from distributed import KilledWorker

    if future.status == "finished":
        return future.result()
    exc = future.exception()
    if isinstance(exc, KilledWorker):
        if not alone or len(indices) > 1:
            return None
        tries = exc.allowed_failures + 1
        return [failed(indices[0], f"KilledWorker: a worker died while running this point ({tries} tries)")]
    if future.status == "cancelled":
        raise RunError(f"point {indices[0]} was cancelled: the scheduler is gone or restarted")
    return [failed(i, one_line(exc)) for i in indices]


class _Tasks:
    """The tasks in flight: which points each holds, and what to submit next.

    A worker's death counts against every task it held, the one that killed it and those
    queued beside it. So the points of a task that died with others in flight become
    suspects: once the tasks in flight have finished, each suspect runs alone, one task on the
    whole cluster, and only a point that kills its worker alone is recorded as failed.
    """

    def __init__(
        self, client: Any, indices: Iterable[int], payload: Callable[[int], Payload | Record], task: Any
    ) -> None:
        from distributed import as_completed

        self.client, self.payload, self.task = client, payload, task
        self.session = uuid.uuid4().hex[:8]
        self.pending = deque(indices)
        self.suspects: deque[int] = deque()
        self.running: dict[Any, list[int]] = {}
        self.alone: set[Any] = set()  # tasks that had the cluster to themselves all along
        self.isolated = False  # a suspect is running: nothing else is submitted until it ends
        self.queue = as_completed(loop=client.loop)
        self.batcher = _Batcher()
        self.threads, self.checked = _threads(client), time.monotonic()

    def _next_batch(self) -> list[int]:
        if self.suspects:
            self.isolated = True
            return [self.suspects.popleft()]
        size = self.batcher.size(len(self.pending), self.threads)
        return [self.pending.popleft() for _ in range(min(size, len(self.pending)))]

    def _room(self) -> bool:
        if self.suspects or self.isolated:
            return not self.running  # a suspect runs alone
        return bool(self.pending) and len(self.running) < WINDOW_PER_THREAD * self.threads

    def fill(self) -> Iterator[Record]:
        """Submit tasks until the window is full; yields the records of points that cannot run."""
        if time.monotonic() - self.checked > 1.0:  # workers may join (or leave) during a sweep
            self.threads, self.checked = _threads(self.client), time.monotonic()
        while self._room():
            payloads = []
            for index in self._next_batch():
                item = self.payload(index)
                if "status" in item:  # a record: the point cannot run
                    yield item
                else:
                    payloads.append(item)
            if payloads:
                self._submit(payloads)

    def _submit(self, payloads: list[Payload]) -> None:
        batch = [p["index"] for p in payloads]
        key = f"twin-points-{batch[0]}-{len(batch)}-{self.session}"
        future = self.client.submit(run_batch, self.task, payloads, key=key, pure=False)
        if self.running:
            self.alone.clear()
        else:
            self.alone.add(future)
        self.running[future] = batch
        self.queue.add(future)

    def finished(self, future: Any) -> list[Record]:
        """The records of a finished task (none when its points must run again alone)."""
        batch = self.running.pop(future)
        self.isolated = False
        records = _outcome(future, batch, future in self.alone)
        self.alone.discard(future)
        future.release()
        if records is None:
            self.suspects.extend(batch)
            return []
        for record in records:
            self.batcher.took(record)
        return records


def _completed(queue: Any, stop: Callable[[], str | None] | None) -> Iterator[Any]:
    """The futures of ``queue`` (distributed's ``as_completed``) as they finish, until none is
    left or ``stop`` answers: a signal is not held until the next point finishes (a point of
    the paper's experiment takes seconds). As distributed's own iterator, it looks again at
    least every tenth of a second."""
    while True:
        while not queue.has_ready():
            if (stop is not None and stop() is not None) or queue.is_empty():
                return
            with queue.thread_condition:
                queue.thread_condition.wait(timeout=0.1)
        if stop is not None and stop() is not None:
            return
        yield next(queue)


def execute(
    client: Any,
    indices: Iterable[int],
    payload: Callable[[int], Payload | Record],
    task: Callable[[Payload], Record],
    stop: Callable[[], str | None] | None = None,
) -> Iterator[Record]:
    """Run the points, yielding each record as it finishes (in any order), until the last or
    until ``stop`` names a signal (then the points in flight are left to the cluster's close).

    ``payload(i)`` builds point ``i``'s task input, or returns a failed record for a point
    that cannot run (then nothing is submitted). Points go out in batches (:class:`_Batcher`);
    the points of a task whose worker died (after the scheduler's retries) run again, each
    alone (:class:`_Tasks`), so the points beside a crashing one still finish and only the
    crashing one is recorded as failed.
    """
    if stop is not None and stop() is not None:
        return  # the cluster took its time to start: nothing is submitted any more
    tasks = _Tasks(client, indices, payload, task)
    yield from tasks.fill()
    for future in _completed(tasks.queue, stop):
        yield from tasks.finished(future)
        if stop is not None and stop() is not None:
            return
        yield from tasks.fill()
