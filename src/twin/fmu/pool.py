"""FMU instances kept for the next run of the same process (a sweep's worker runs many points).

Instantiating an FMU costs about a millisecond in fmpy alone (it loads and types every FMI
function of the library again), five of them a point; a sweep's point on a short scenario
takes not much more. A :class:`SlotPool` keeps the instances of a run that ended well and hands
them to the next run of the same FMU file and instance name after ``fmi2Reset``, which puts an
instance back into the state right after instantiation, every variable at its start value
(FMI 2.0, section 2.1.6). The next run then sets up the experiment, sets its parameters and
initializes as a fresh instance would; ``tests/fmus/test_pool.py`` checks that its signals are
bit for bit those of fresh instances, with other parameters in between.

An instance of a run that failed or was interrupted is freed, never kept: its FMU may be in
its error state, and a reset is not what a failed instance should be trusted with.
"""

from __future__ import annotations

import atexit
import os
import threading
from collections.abc import Callable
from pathlib import Path

from twin.fmu.slot import FMUSlot, file_key

__all__ = ["SlotPool", "sweep_pool"]

Key = tuple[tuple[str, int, int], str]


class SlotPool:
    """Idle, reset FMU instances by (FMU file, instance name); thread-safe.

    ``per_key`` bounds the idle instances kept of one file and name (a process runs one point
    per thread, so one each is what it reuses).
    """

    def __init__(self, per_key: int = 1) -> None:
        self.per_key = per_key
        self._idle: dict[Key, list[FMUSlot]] = {}
        self._lock = threading.Lock()
        self.reused = 0  # instances handed out again (for tests and benchmarks)
        self.created = 0  # instances made because none was idle
        self._resolved: dict[Path, str] = {}

    def open(self, fmu_path: Path, instance_name: str, make: Callable[[], FMUSlot]) -> FMUSlot:
        """An idle instance of that file and name, reset and ready for ``setup``, else ``make()``."""
        key = (self._file_key(fmu_path), instance_name)
        with self._lock:
            idle = self._idle.get(key)
            slot = idle.pop() if idle else None
        if slot is None:
            slot = make()
            slot.pool_key = key
            self.created += 1
            return slot
        slot.reuse()
        self.reused += 1
        return slot

    def _file_key(self, fmu_path: Path) -> tuple[str, int, int]:
        """:func:`~twin.fmu.slot.file_key`, the path resolved once per pool (resolving it was
        most of the key's cost, asked for by every instance a Monte Carlo sample opens); the
        size and modification time are the file's now, so a rebuilt FMU is never taken for
        the one whose instances are idle."""
        resolved = self._resolved.get(fmu_path)
        if resolved is None:
            resolved = self._resolved.setdefault(fmu_path, file_key(fmu_path)[0])
        st = os.stat(fmu_path)
        return resolved, st.st_size, st.st_mtime_ns

    def release(self, slot: FMUSlot) -> None:
        """Keep ``slot`` for the next run after ``fmi2Reset``; free it if the reset fails, if it
        came from outside the pool or if enough of its kind are idle."""
        key = getattr(slot, "pool_key", None)
        if key is None or not slot.reset():
            slot.close()
            return
        with self._lock:
            idle = self._idle.setdefault(key, [])
            if len(idle) < self.per_key:
                idle.append(slot)
                return
        slot.close()

    def clear(self) -> None:
        """Free every idle instance."""
        with self._lock:
            slots = [s for idle in self._idle.values() for s in idle]
            self._idle.clear()
        for slot in slots:
            slot.close()

    def __len__(self) -> int:
        with self._lock:
            return sum(len(v) for v in self._idle.values())


_SWEEP_POOL: SlotPool | None = None


def sweep_pool() -> SlotPool:
    """The process's pool for sweep points (freed at the process's exit, before its unpacked
    FMU folders are removed)."""
    global _SWEEP_POOL
    if _SWEEP_POOL is None:
        _SWEEP_POOL = SlotPool()
        atexit.register(_SWEEP_POOL.clear)
    return _SWEEP_POOL
