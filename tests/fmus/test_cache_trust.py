"""The cache of built binaries is trusted only as far as it is private and checked.

A cached FMU's library or the stepper is loaded into the twin's process, and a shared library runs its
constructors when loaded: a library planted in the cache under the expected name must never
be loaded, and a cache others may write into is refused.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from twin.cli import main
from twin.cosim import native
from twin.errors import BuildError, UnsafeCacheError
from twin.fmu.build import built_library, ensure_fmu
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


# -------------------------------------------------- the libraries of built FMUs (build.built_library)


@pytest.fixture
def seeded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A new private cache holding this session's built HydraulicLoader (no build needed), and
    nothing else: no library taken out of it yet."""
    fmu = ensure_fmu("HydraulicLoader")  # in the session's cache
    folder = tmp_path / "cache"
    folder.mkdir(mode=0o700)
    for f in (fmu, digest_file(fmu)):
        shutil.copy(f, folder / f.name)
    monkeypatch.setenv("TWIN_CACHE_DIR", str(folder))
    return folder / fmu.name


def _member(fmu: Path) -> bytes:
    from fmpy import platform

    with zipfile.ZipFile(fmu) as zf:
        return zf.read(f"binaries/{platform}/HydraulicLoader{LIBRARY_SUFFIX}")


def test_a_built_fmus_library_is_its_own_taken_out_once(seeded: Path) -> None:
    library = built_library(seeded)
    assert library is not None and library.parent == seeded.parent and verified(library)
    assert library.read_bytes() == _member(seeded)
    stamp = library.stat().st_mtime_ns
    assert built_library(seeded) == library and library.stat().st_mtime_ns == stamp  # not again


@pytest.mark.parametrize("record", ["none", "wrong"])
def test_a_planted_fmu_library_is_taken_out_anew_and_never_loaded(
    seeded: Path, tmp_path: Path, record: str
) -> None:
    library = built_library(seeded)
    assert library is not None
    marker = tmp_path / "planted-ran"
    digest_file(library).unlink()
    planted = _plant(library, marker, tmp_path)
    if record == "wrong":
        digest_file(library).write_text("0" * 64 + "\n", encoding="ascii")
    again = built_library(seeded)
    assert again == library and again.read_bytes() == _member(seeded) != planted
    ctypes.CDLL(str(again))
    assert not marker.exists(), "the planted library's constructor ran"


def test_no_library_is_taken_from_an_fmu_that_is_not_what_was_built(seeded: Path) -> None:
    good = seeded.read_bytes()
    seeded.write_bytes(good[:-10] + b"0123456789")  # the same size, other bytes
    with pytest.raises(BuildError, match="do not match the SHA-256 recorded"):
        built_library(seeded)
    assert list(seeded.parent.glob(f"*{LIBRARY_SUFFIX}")) == []


def test_an_fmu_from_elsewhere_has_no_cached_library(seeded: Path, tmp_path: Path) -> None:
    elsewhere = tmp_path / "lab"
    elsewhere.mkdir()
    for f in (seeded, digest_file(seeded)):  # even with a record beside it
        shutil.copy(f, elsewhere / f.name)
    assert built_library(elsewhere / seeded.name) is None
    assert list(seeded.parent.glob(f"*{LIBRARY_SUFFIX}")) == []


def test_the_libraries_of_fmus_no_longer_cached_go_with_them(seeded: Path) -> None:
    stale = seeded.parent / f"HydraulicLoader-{'1' * 16}-{'2' * 16}{LIBRARY_SUFFIX}"
    stale.write_bytes(b"an older build's library")
    digest_file(stale).write_text(file_sha256(stale) + "\n", encoding="ascii")
    # another checkout's build of the same model, sharing the cache: its FMU is there
    shutil.copy(seeded, seeded.parent / f"HydraulicLoader-{'5' * 16}.fmu")
    kept = seeded.parent / f"HydraulicLoader-{'5' * 16}-{'6' * 16}{LIBRARY_SUFFIX}"
    kept.write_bytes(b"the other checkout's library")
    other = seeded.parent / f"OscillationDrive-{'3' * 16}-{'4' * 16}{LIBRARY_SUFFIX}"
    other.write_bytes(b"another model's")
    assert built_library(seeded) is not None
    assert not stale.exists() and not digest_file(stale).exists()
    assert kept.exists(), "the library of an FMU still in the cache was pruned"
    assert other.exists()  # another model's: not this one's to prune


def test_a_library_is_checked_again_once_its_last_instance_is_freed(seeded: Path, tmp_path: Path) -> None:
    """fmpy unloads a library when its last instance is freed: the next instance opens the
    file again, so the file is checked again (a planted one is replaced, never run)."""
    from twin.fmu.slot import FMUSlot

    fmu = ensure_fmu("HydraulicLoader")
    assert fmu == seeded
    first = FMUSlot(fmu, "first")
    library = Path(first.library)
    first.close()  # its library unloaded
    marker = tmp_path / "planted-ran"
    record = digest_file(library).read_text(encoding="ascii")
    _plant(library, marker, tmp_path)
    digest_file(library).write_text(record, encoding="ascii")  # the record of the real one
    second = FMUSlot(fmu, "second")
    try:
        assert not marker.exists(), "the planted library's constructor ran"
        assert Path(second.library) == library and library.read_bytes() == _member(seeded)
    finally:
        second.close()


def test_a_library_loaded_by_a_live_instance_is_not_loaded_again(seeded: Path, tmp_path: Path) -> None:
    """While an instance holds its library loaded, the next instance of the FMU is not checked
    again (slot._load_counted): the loader finds the library by its path among those loaded
    and maps nothing new. Shown with a library planted at that path meanwhile (a new file: the
    loaded one's pages stay as they are): the second instance runs the first's code, never the
    planted constructor; once both are freed, the next instance's load checks the file again."""
    from twin.fmu import slot as slot_module
    from twin.fmu.slot import FMUSlot

    fmu = ensure_fmu("HydraulicLoader")
    first = FMUSlot(fmu, "first")
    library = Path(first.library)
    assert slot_module._LIVE[str(fmu)][1] == 1
    marker = tmp_path / "planted-ran"
    planted = tmp_path / "planted.so"
    _plant(planted, marker, tmp_path)
    os.replace(planted, library)  # the record beside it still the real library's
    second = FMUSlot(fmu, "second")
    try:
        assert slot_module._LIVE[str(fmu)][1] == 2
        assert not marker.exists(), "the planted library's constructor ran"
        for s in (first, second):  # the real library's functions, in both
            s.setup(0.0)
            s.enter_initialization()
            s.exit_initialization()
    finally:
        second.close()
        first.close()
    assert str(fmu) not in slot_module._LIVE
    assert library.read_bytes() != _member(seeded)  # still the planted file: nothing checked it yet
    third = FMUSlot(fmu, "third")
    try:
        assert not marker.exists(), "the planted library's constructor ran"
        assert library.read_bytes() == _member(seeded)  # checked at the load: taken out anew
    finally:
        third.close()


def test_loads_and_frees_from_many_threads_are_counted_back_to_none(seeded: Path) -> None:
    """Threads opening and freeing instances of one FMU at once (a sweep's worker runs a point
    per thread): each load counted, each free taken back, none left once all are freed."""
    import threading

    from twin.fmu import slot as slot_module
    from twin.fmu.slot import FMUSlot

    fmu = ensure_fmu("HydraulicLoader")
    errors: list[BaseException] = []

    def churn(name: str) -> None:
        try:
            for k in range(25):
                s = FMUSlot(fmu, f"{name}-{k}")
                s.setup(0.0)
                s.close()
        except BaseException as exc:  # handed to the test's thread
            errors.append(exc)

    keep = FMUSlot(fmu, "kept")  # one held throughout: the others take the short way
    threads = [threading.Thread(target=churn, args=(f"t{i}",)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert slot_module._LIVE[str(fmu)][1] == 1
    keep.close()
    assert str(fmu) not in slot_module._LIVE


def test_a_relative_cache_folder_works(seeded: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """fmpy changes the working directory while it loads a library: the cache's paths are
    absolute, whatever TWIN_CACHE_DIR says."""
    from twin.fmu.slot import FMUSlot

    monkeypatch.chdir(seeded.parent.parent)
    monkeypatch.setenv("TWIN_CACHE_DIR", seeded.parent.name)
    assert private_cache_dir() == seeded.parent
    slot = FMUSlot(ensure_fmu("HydraulicLoader"), "relative")
    try:
        assert Path(slot.library).is_absolute() and Path(slot.library).parent == seeded.parent
        slot.setup(0.0)
        slot.enter_initialization()
        slot.exit_initialization()
    finally:
        slot.close()
