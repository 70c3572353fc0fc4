"""The FMU catalog (sources, descriptions) and the toolchain's cmake + content-hash cache."""

from __future__ import annotations

import ctypes
import math
import os
import shutil
import textwrap
import time
from pathlib import Path
from types import MappingProxyType

import pytest

from twin.errors import BuildError, ConfigError
from twin.fmu import catalog, toolchain
from twin.fmu.build import generate_vars_header
from twin.fmu.slot import FMUSlot

MODELS = catalog.model_names()


def test_a_declared_type_gives_unit_and_range() -> None:
    v = catalog.variables("ThermalNetwork")["t_start_base"]  # <Real declaredType="Temperature" .../>
    assert (v.unit, v.min, v.max, v.start) == ("K", 173.15, 473.15, 293.15)
    assert (v.type, v.causality, v.variability) == ("Real", "parameter", "fixed")


def test_starts_are_typed_and_missing_bounds_are_infinite() -> None:
    variables = catalog.variables("HydraulicLoader")
    profile, table_n, start_at_command = (variables[n] for n in ("profile", "table_n", "start_at_command"))
    assert (profile.start, profile.min, profile.max) == (0, 0.0, 3.0) and type(profile.start) is int
    assert table_n.start == 2 and start_at_command.start is False
    radial_load = variables["radial_load"]  # <Real unit="N"/>: an output without start or bounds
    assert (radial_load.unit, radial_load.start, radial_load.min, radial_load.max) == (
        "N",
        None,
        -math.inf,
        math.inf,
    )


@pytest.mark.parametrize("model", MODELS)
def test_a_built_fmu_describes_itself_as_its_sources_do(model: str, fmu_paths: dict[str, Path]) -> None:
    built = catalog.describe(fmu_paths[model])
    source = catalog.model(model).description
    assert built == source
    assert built.model_identifier == model and built.guid


def test_the_override_names_the_sources_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    copy = tmp_path / "fmus"
    shutil.copytree(catalog.sources_dir(), copy)
    shutil.rmtree(copy / "SensorsDAQ")
    monkeypatch.setenv(catalog.SOURCES_ENV, str(copy))
    assert catalog.sources_dir() == copy
    assert "SensorsDAQ" not in catalog.model_names()
    with pytest.raises(ConfigError, match="unknown model 'SensorsDAQ'"):
        catalog.model("SensorsDAQ")


def test_an_override_without_sources_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(catalog.SOURCES_ENV, str(tmp_path))
    with pytest.raises(ConfigError, match=f"FMU sources not found.*{catalog.SOURCES_ENV}"):
        catalog.sources_dir()


def test_value_references_with_a_gap_are_refused() -> None:
    description = catalog.model("ThermalNetwork").description
    variables = dict(description.variables)
    first = next(iter(variables))
    variables[first] = catalog.Variable(**{**vars(variables[first]), "value_reference": 999})
    gap = catalog.Description(description.guid, description.model_identifier, MappingProxyType(variables))
    with pytest.raises(BuildError, match="Real value references must be 0"):
        generate_vars_header(gap)


def test_native_handles_are_the_functions_the_slot_calls(fmu_paths: dict[str, Path]) -> None:
    slot = FMUSlot(fmu_paths["ThermalNetwork"], "handles")
    try:
        h = slot.native_handles()
        dll = slot._slave.dll
        assert h.component and h.component == slot._slave.component
        for name, address in (
            ("fmi2SetReal", h.set_real),
            ("fmi2GetReal", h.get_real),
            ("fmi2DoStep", h.do_step),
        ):
            assert address == ctypes.cast(getattr(dll, name), ctypes.c_void_p).value
    finally:
        slot.close()


def test_later_instances_get_the_prototypes_fmpy_gives(fmu_paths: dict[str, Path]) -> None:
    """FMU2SlaveTyped reuses the first instance's typing of the FMI functions: every function
    of a later instance's library is typed exactly as fmpy's own loader types it."""
    from fmpy.fmi2 import FMU2Slave

    from twin.fmu.slot import FMU2SlaveTyped

    first = FMUSlot(fmu_paths["ThermalNetwork"], "typed-first")
    later = FMUSlot(fmu_paths["SensorsDAQ"], "typed-later")
    try:
        assert FMU2SlaveTyped._prototypes, "the first instance left no prototypes to reuse"
        ours = later._slave
        theirs = FMU2Slave(
            guid=later.description.guid,
            unzipDirectory=later.unzipdir,
            modelIdentifier=later.description.model_identifier,
            instanceName="fmpy-itself",
            libraryPath=later.library,
        )
        assert sorted(ours._functions) == sorted(theirs._functions)
        assert len(ours._functions) > 30
        for name, f in theirs._functions.items():
            mine = ours._functions[name]
            assert (mine.argtypes, mine.restype, mine.argnames) == (f.argtypes, f.restype, f.argnames), name
            assert ctypes.cast(mine, ctypes.c_void_p).value == ctypes.cast(f, ctypes.c_void_p).value
    finally:
        later.close()
        first.close()


# ---------------------------------------------------------------------------- toolchain


def test_content_hash_depends_on_names_contents_order_and_salt() -> None:
    base = toolchain.content_hash({"a.c": b"x", "b.c": b"y"})
    variants = [
        {"a.c": b"x", "b.c": b"z"},
        {"a.c": b"x", "c.c": b"y"},
        {"b.c": b"y", "a.c": b"x"},
    ]
    assert all(toolchain.content_hash(v) != base for v in variants)
    assert toolchain.content_hash({"a.c": b"x", "b.c": b"y"}, "2") != base


def test_cached_builds_once_and_prunes_older_entries(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(toolchain.CACHE_ENV, str(tmp_path))
    made: list[str] = []

    def make(text: str):
        def build(scratch: Path) -> Path:
            made.append(text)
            (scratch / "out").write_text(text)
            return scratch / "out"

        return build

    first = toolchain.cached("thing", "aaaa", ".bin", make("one"))
    assert toolchain.cached("thing", "aaaa", ".bin", make("again")) == first
    second = toolchain.cached("thing", "bbbb", ".bin", make("two"))
    assert made == ["one", "two"] and second.read_text() == "two"
    # another checkout's entry in use (used just now) is kept: pruning it would break that
    # checkout's next run
    assert first.exists() and toolchain.verified(second)
    # one nobody used for longer than PRUNE_AFTER_S goes, with its record (SHA-256 at build time)
    old = time.time() - toolchain.PRUNE_AFTER_S - 60
    os.utime(first, (old, old))
    toolchain.cached("thing", "cccc", ".bin", make("three"))
    assert not first.exists() and not toolchain.digest_file(first).exists()
    assert second.exists() and made == ["one", "two", "three"]


_LIBRARY = {
    "CMakeLists.txt": textwrap.dedent(
        """\
        cmake_minimum_required(VERSION 3.15)
        project(twin_probe C)
        add_library(twin_probe SHARED probe.c)
        set_target_properties(twin_probe PROPERTIES PREFIX "")
        install(TARGETS twin_probe DESTINATION "${TWIN_OUT_DIR}")
        """
    ).encode(),
    "probe.c": b"int twin_probe_answer(void) { return 42; }\n",
}


def test_build_cached_library_builds_a_cmake_folder_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(toolchain.CACHE_ENV, str(tmp_path))
    library = toolchain.build_cached_library("twin_probe", _LIBRARY)
    assert ctypes.CDLL(str(library)).twin_probe_answer() == 42
    stamp = library.stat().st_mtime_ns
    assert toolchain.build_cached_library("twin_probe", _LIBRARY) == library
    assert library.stat().st_mtime_ns == stamp
    changed = {**_LIBRARY, "probe.c": b"int twin_probe_answer(void) { return 7; }\n"}
    rebuilt = toolchain.build_cached_library("twin_probe", changed)
    assert rebuilt != library and library.is_file()  # a library is never pruned: checkouts share the cache
    assert ctypes.CDLL(str(rebuilt)).twin_probe_answer() == 7


def test_a_compile_error_is_a_build_error_with_the_compiler_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(toolchain.CACHE_ENV, str(tmp_path))
    broken = {**_LIBRARY, "probe.c": b"int twin_probe_answer(void) { return }\n"}
    with pytest.raises(BuildError, match=r"building the twin_probe library failed \(build\)") as exc:
        toolchain.build_cached_library("twin_probe", broken)
    assert "probe.c" in str(exc.value)


def test_folder_files_reads_a_folder_sorted_without_hidden_files(tmp_path: Path) -> None:
    for name in ("b.c", "a.h", ".swp"):
        (tmp_path / name).write_text(name)
    (tmp_path / "sub").mkdir()
    assert toolchain.folder_files(tmp_path) == {"a.h": b"a.h", "b.c": b"b.c"}


def test_a_description_is_parsed_once_per_content(tmp_path: Path) -> None:
    """The source modelDescription.xml and the FMU built from it hold the same bytes: one
    parse (fmpy's validation loads its schema for each); other bytes, another parse."""
    from twin.fmu.build import ensure_fmu
    from twin.fmu.catalog import describe

    source = catalog.sources_dir() / "HydraulicLoader" / "modelDescription.xml"
    fmu = ensure_fmu("HydraulicLoader")
    assert describe(fmu) is describe(source)
    edited = tmp_path / "modelDescription.xml"
    text = source.read_text(encoding="utf-8")
    edited.write_text(text.replace('name="servo_frequency"', 'name="servo_freq"', 1), encoding="utf-8")
    other = describe(edited)
    assert "servo_freq" in other.variables and "servo_frequency" not in other.variables
    assert "servo_frequency" in describe(source).variables


def test_roles_name_outputs_of_their_model_and_an_fmu_from_elsewhere_has_none(lowpass_fmu: Path) -> None:
    """What the twin reads by meaning (the swing counter, a body's true displacement, the
    temperatures the 3D view draws) is declared by the FMUs themselves, each an output."""
    declared = {m: dict(catalog.roles(m)) for m in catalog.model_names()}
    assert declared["OscillationDrive"]["swing_cycles"] == "cycles"
    assert declared["FixtureMechanics"]["thermal_dz.detecting_frame"] == "dz_detecting_frame"
    for model, roles in declared.items():
        variables = catalog.variables(model)
        assert all(variables[v].causality == "output" for v in roles.values()), model
    assert catalog.describe(lowpass_fmu).roles == {}
