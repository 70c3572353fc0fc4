"""Ship the built FMUs and the compiled stepper to Dask workers, as bytes with their sha256.

Workers may be other machines with no shared file system and no compiler: the client builds
every binary once (the content-hashed cache of :mod:`twin.fmu.build` and
:mod:`twin.cosim.native`), and a :class:`~distributed.diagnostics.plugin.WorkerPlugin`
carries the bytes to every worker, now and when one joins or restarts later. The worker
checks each file's sha256 before it writes it into its own cache (under the same name,
which holds the hash of the sources it was built from), so a point loads exactly the
client's binaries, and no task carries a path of the client's.

A worker whose twin differs from the client's (other FMU sources, hence other cache names)
would otherwise build its own FMUs or fail for want of a compiler; it is refused instead,
naming what differs. This module is the only one that knows the cache's layout.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from distributed.diagnostics.plugin import WorkerPlugin

from twin.errors import RunError
from twin.files import write_bytes_atomic
from twin.pipeline.worker_state import PROBLEM as _PROBLEM
from twin.pipeline.worker_state import check_worker

__all__ = ["PLUGIN_NAME", "Artifact", "BinariesPlugin", "check_worker", "collect", "install"]

PLUGIN_NAME = "twin-sweep-binaries"


@dataclass(frozen=True)
class Artifact:
    """One cached binary: its file name in the cache, its bytes and their sha256."""

    name: str
    data: bytes
    sha256: str


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _expected_names() -> set[str]:
    """The cache names this installation of the twin loads (the hashes of its own sources)."""
    from twin.cosim.native import LIBRARY, stepper_sources
    from twin.fmu.build import source_hash
    from twin.fmu.catalog import model_names
    from twin.fmu.toolchain import LIBRARY_SUFFIX, content_hash

    stepper = f"{LIBRARY}-{content_hash(stepper_sources())}{LIBRARY_SUFFIX}"
    return {f"{m}-{source_hash(m)}.fmu" for m in model_names()} | {stepper}


def collect() -> tuple[Artifact, ...]:
    """Build (or take from the cache) every FMU and the stepper: the client's side."""
    from twin.cosim.native import ensure_stepper
    from twin.fmu import catalog

    paths = [catalog.fmu(m) for m in catalog.model_names()] + [ensure_stepper()]
    out = []
    for p in paths:
        data = p.read_bytes()
        out.append(Artifact(p.name, data, _sha256(data)))
    return tuple(out)


def install(artifacts: tuple[Artifact, ...]) -> list[Path]:
    """Write the artifacts into this machine's cache after checking each one: the worker's side.

    Raises :class:`RunError` when a file's bytes do not match their sha256, when a name is
    not a plain file name, or when this twin's sources differ from the client's.
    """
    from twin.fmu.toolchain import private_cache_dir, record_digest, verified

    target = private_cache_dir()
    written = []
    for a in artifacts:
        if Path(a.name).name != a.name or a.name.startswith("."):
            raise RunError(f"refused binary name {a.name!r}: not a plain file name")
        if _sha256(a.data) != a.sha256:
            raise RunError(f"{a.name}: sha256 mismatch (damaged in transfer)")
        path = target / a.name
        if verified(path) and _sha256(path.read_bytes()) == a.sha256:
            continue
        write_bytes_atomic(path, a.data)  # a point starting now sees the old file or the new one
        record_digest(path, a.sha256)  # the cache loads only what it can check
        written.append(path)
    missing = sorted(_expected_names() - {a.name for a in artifacts})
    if missing:
        raise RunError(
            "this worker's twin differs from the client's (it would load "
            + ", ".join(missing)
            + "): install the same version on every worker"
        )
    return written


class BinariesPlugin(WorkerPlugin):
    """Installs the client's binaries on every worker, now and when one (re)starts."""

    name = PLUGIN_NAME

    def __init__(self, artifacts: tuple[Artifact, ...]) -> None:
        self.artifacts = artifacts

    def setup(self, worker: object) -> None:
        _PROBLEM.clear()
        try:
            install(self.artifacts)
        except (RunError, OSError) as exc:
            _PROBLEM.append(f"worker {getattr(worker, 'address', '?')}: {exc}")
            raise
