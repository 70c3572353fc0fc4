"""The run gives the C heap's free pages back before its outputs load beside the plot helper
(twin.pipeline.stages._give_back_free_pages): the default run's peak memory is that overlap."""

from __future__ import annotations

import ctypes
import os

from twin.pipeline.stages import _give_back_free_pages


def _resident_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def test_the_free_pages_inside_the_heap_go_back_to_the_system() -> None:
    if getattr(ctypes.CDLL(None), "malloc_trim", None) is None:
        _give_back_free_pages()  # no glibc: nothing to give back, and nothing fails
        return
    # 100 MB of blocks below glibc's mmap threshold (so on the heap), zeroed (so resident), all
    # freed but the last: that one holds the heap's top, so glibc keeps the pages below it
    blocks = [bytearray(64 * 1024) for _ in range(1600)]
    last = blocks[-1]
    del blocks
    before = _resident_mb()
    _give_back_free_pages()
    after = _resident_mb()
    assert before - after > 50, (before, after)
    assert len(last) == 64 * 1024
