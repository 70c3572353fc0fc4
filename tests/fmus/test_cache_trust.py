"""The cache of built binaries is trusted only as far as it is private and checked.

A cached FMU or stepper is loaded into the twin's process, and a shared library runs its
constructors when loaded: a library planted in the cache under the expected name must never
be loaded, and a cache others may write into is refused.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from twin.cli import main
from twin.cosim import native
from twin.errors import UnsafeCacheError
from twin.fmu.build import ensure_fmu
from twin.fmu.toolchain import (
    LIBRARY_SUFFIX,
    content_hash,
    digest_file,
    file_sha256,
    private_cache_dir,
    verified,
)

PLANTED = r"""
#include <stdio.h>
__attribute__((constructor)) static void planted(void) {
    FILE *f = fopen("%s", "w");
    if (f) { fputs("the planted library ran\n", f); fclose(f); }
}
int twin_stepper_run(void) { return 0; }
"""


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("TWIN_CACHE_DIR", str(folder))
    return folder


def _plant(path: Path, marker: Path, tmp_path: Path) -> bytes:
    source = tmp_path / "planted.c"
    source.write_text(PLANTED % marker, encoding="utf-8")
    path.parent.mkdir(parents=True, exist_ok=True)
    cc = shutil.which("cc") or shutil.which("gcc")
    assert cc, "a C compiler builds the FMUs anyway"
    subprocess.run([cc, "-shared", "-fPIC", "-o", str(path), str(source)], check=True)
    return path.read_bytes()


@pytest.mark.parametrize("record", ["none", "wrong"])
def test_a_planted_library_is_built_over_and_never_loaded(cache: Path, tmp_path: Path, record: str) -> None:
    name = f"{native.LIBRARY}-{content_hash(native.stepper_sources())}{LIBRARY_SUFFIX}"
    marker = tmp_path / "planted-ran"
    planted = _plant(cache / name, marker, tmp_path)
    if record == "wrong":  # a record that does not describe the planted bytes
        digest_file(cache / name).write_text("0" * 64 + "\n", encoding="ascii")
    path = native.ensure_stepper()  # what the master loads (native.stepper() keeps it per process)
    assert path == cache / name
    ctypes.CDLL(str(path))  # load what the cache gave: the real stepper, built over the planted one
    assert not marker.exists(), "the planted library's constructor ran"
    assert path.read_bytes() != planted and verified(path)


def test_a_changed_cached_fmu_is_built_anew(cache: Path) -> None:
    fmu = ensure_fmu("HydraulicLoader")
    good = fmu.read_bytes()
    assert verified(fmu) and digest_file(fmu).read_text().strip() == file_sha256(fmu)
    fmu.write_bytes(good[:-10] + b"0123456789")  # the same size, other bytes
    assert not verified(fmu)
    again = ensure_fmu("HydraulicLoader")
    assert again == fmu and verified(again) and again.read_bytes() != good[:-10] + b"0123456789"


def test_a_new_cache_is_private(cache: Path) -> None:
    assert private_cache_dir() == cache
    assert cache.stat().st_mode & 0o777 == 0o700


@pytest.mark.parametrize("mode", [0o777, 0o770, 0o722])
def test_a_cache_others_may_write_into_is_refused(
    cache: Path, mode: int, capsys: pytest.CaptureFixture
) -> None:
    cache.mkdir()
    os.chmod(cache, mode)
    with pytest.raises(UnsafeCacheError, match="writable by others"):
        private_cache_dir()
    assert main(["build"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "writable by others" in err[0] and "TWIN_CACHE_DIR" in err[0]
    assert list(cache.iterdir()) == []  # nothing built into it


def test_a_cache_that_is_a_file_is_refused(cache: Path) -> None:
    cache.write_text("not a folder")
    with pytest.raises(UnsafeCacheError, match="not a folder"):
        private_cache_dir()
