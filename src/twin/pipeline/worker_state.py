"""Whether this process, as a Dask worker, could install the client's binaries: set by the
plugin of :mod:`twin.pipeline.shipping`, checked by every point before it runs.

Apart from the plugin so that a point run in process (:mod:`twin.pipeline.point`) checks it
without importing Dask's ``distributed``, which the plugin's class needs and an in-process
Monte Carlo never uses.
"""

from __future__ import annotations

from twin.errors import RunError

__all__ = ["PROBLEM", "check_worker"]

#: why this worker cannot run points (set by the plugin; checked by every task)
PROBLEM: list[str] = []


def check_worker() -> None:
    """Raise :class:`RunError` when the binaries could not be installed on this worker."""
    if PROBLEM:
        raise RunError(PROBLEM[-1])
