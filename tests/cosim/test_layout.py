"""The stepper's structures come from one description: C and ctypes cannot disagree."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import pytest

from twin.cosim import layout, native
from twin.fmu.toolchain import content_hash

CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler")


def compile_c(tmp_path: Path, header: str, source: str) -> subprocess.CompletedProcess:
    (tmp_path / layout.HEADER).write_text(header)
    (tmp_path / "t.c").write_text(source)
    return subprocess.run(
        [CC, "-std=c11", "-fsyntax-only", "-Wall", "-Werror", str(tmp_path / "t.c")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


def test_ctypes_classes_follow_the_declarations() -> None:
    for name, cls in layout.STRUCTURES.items():
        assert [f for f, _ in cls._fields_] == [m for _, m in layout.members(name)]
    # scalars keep their width; pointers are addresses
    fields = dict(layout.TwinSlot._fields_)
    assert fields["period_ticks"] is ctypes.c_int64 and fields["n_in"] is ctypes.c_int32
    assert fields["pending_at"] is ctypes.c_void_p and fields["do_step"] is ctypes.c_void_p
    name, params = layout.entry()
    assert name == "twin_run_ticks" and len(layout.entry_argtypes()) == len(params) == 14


@needs_cc
def test_the_stepper_compiles_against_the_generated_header(tmp_path: Path) -> None:
    source = (native.SOURCES / "stepper.c").read_text()
    proc = compile_c(tmp_path, layout.c_header(), source)
    assert proc.returncode == 0, proc.stderr


@needs_cc
def test_a_member_retyped_on_one_side_fails_the_build(tmp_path: Path) -> None:
    # as if the C side had been edited by hand: the generated asserts catch the new offsets
    header = layout.c_header().replace("int32_t n_in;", "int64_t n_in;", 1)
    proc = compile_c(tmp_path, header, f'#include "{layout.HEADER}"\n')
    assert proc.returncode != 0
    assert "TwinSlot.n_out: offset differs from ctypes" in proc.stderr


@needs_cc
def test_an_entry_point_that_disagrees_with_the_prototype_fails_the_build(tmp_path: Path) -> None:
    source = (
        (native.SOURCES / "stepper.c")
        .read_text()
        .replace("int32_t n_slots, int64_t k0", "int64_t n_slots, int64_t k0", 1)
    )
    assert source != (native.SOURCES / "stepper.c").read_text()
    proc = compile_c(tmp_path, layout.c_header(), source)
    assert proc.returncode != 0 and "twin_run_ticks" in proc.stderr


def test_the_generated_header_is_part_of_the_build_and_of_its_hash(monkeypatch: pytest.MonkeyPatch) -> None:
    files = native.stepper_sources()
    assert files[layout.HEADER] == layout.c_header().encode()
    assert {"stepper.c", "CMakeLists.txt"} <= set(files)
    before = content_hash(files)
    monkeypatch.setattr(native, "c_header", lambda: layout.c_header() + "/* changed */\n")
    assert content_hash(native.stepper_sources()) != before
