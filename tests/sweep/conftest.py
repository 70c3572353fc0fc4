"""Fixtures of the sweep tests: a private binary cache, sweep files, a real Dask cluster.

The cache is private to these tests (a copy of the built FMUs and stepper), so other
processes sharing the user's cache cannot swap binaries under a running sweep. The cluster
is the ``dask scheduler`` and ``dask worker`` commands of distributed, on 127.0.0.1 only,
each worker with its own empty cache and no usable C compiler: a point can only run if the
client's binaries were shipped to it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.sweep.helpers import BIN, child_env, stop

#: how long a cluster may take to come up on a busy machine
START_TIMEOUT_S = 90


@pytest.fixture(scope="package", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """TWIN_CACHE_DIR -> a copy of the current binaries, for this package's tests only."""
    from twin.cosim.native import ensure_stepper
    from twin.fmu.build import ensure_fmu, model_names
    from twin.fmu.toolchain import digest_file

    cache = tmp_path_factory.mktemp("cache")
    for path in [ensure_fmu(m) for m in model_names()] + [ensure_stepper()]:
        shutil.copyfile(path, cache / path.name)
        shutil.copyfile(digest_file(path), digest_file(cache / path.name))
    old = os.environ.get("TWIN_CACHE_DIR")
    os.environ["TWIN_CACHE_DIR"] = str(cache)
    yield cache
    if old is None:
        os.environ.pop("TWIN_CACHE_DIR", None)
    else:
        os.environ["TWIN_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, object]]:
    """A ``dask scheduler`` and two ``dask worker`` processes; yields the address and the
    workers' caches; always ended, even when the test fails."""
    root = tmp_path_factory.mktemp("cluster")
    scheduler_file = root / "scheduler.json"
    logs = [open(root / f"{name}.log", "wb") for name in ("scheduler", "worker-1", "worker-2")]  # noqa: SIM115
    procs: list[subprocess.Popen[bytes]] = []
    caches = [root / "cache-1", root / "cache-2"]
    try:
        procs.append(
            subprocess.Popen(
                [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                 "--scheduler-file", str(scheduler_file)],
                env=child_env(DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="1"),
                stdout=logs[0], stderr=subprocess.STDOUT, start_new_session=True,
            )
        )  # fmt: skip
        _wait_for(lambda: scheduler_file.is_file() and scheduler_file.stat().st_size > 0, "the scheduler")
        address = json.loads(scheduler_file.read_text())["address"]
        for cache, log in zip(caches, logs[1:], strict=True):
            procs.append(
                subprocess.Popen(
                    [str(BIN / "dask"), "worker", address, "--nthreads", "1", "--nworkers", "1",
                     "--host", "127.0.0.1", "--no-dashboard", "--death-timeout", "60"],
                    # an empty cache and no compiler: only shipped binaries can run a point
                    env=child_env(TWIN_CACHE_DIR=str(cache), CC="/bin/false"),
                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                )
            )  # fmt: skip
        _wait_for_workers(address, 2)
        yield {"address": address, "caches": caches, "logs": root}
    finally:
        for proc in reversed(procs):
            stop(proc)
        for log in logs:
            log.close()


def _wait_for(ready: object, what: str) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    while not ready():  # type: ignore[operator]
        if time.monotonic() > deadline:
            pytest.fail(f"{what} did not start within {START_TIMEOUT_S} s")
        time.sleep(0.2)


def _wait_for_workers(address: str, n: int) -> None:
    from distributed import Client

    with Client(address, timeout=30, set_as_default=False) as client:
        client.wait_for_workers(n, timeout=START_TIMEOUT_S)
