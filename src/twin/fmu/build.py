"""Build the twin's C models into FMI 2.0 co-simulation FMUs.

The catalog (:mod:`twin.fmu.catalog`) says what a model is: its files (``common/`` C code and
the model's folder: ``modelDescription.xml``, ``config.h``, ``model.c``, ``readme.md``) and
its description. Building a model:

1. generates ``model_vars.h`` (value references, variable table, GUID) from the description,
   so the C code and the XML cannot disagree;
2. lays out an FMU tree (XML, ``sources/``, ``documentation/``), writes fmpy's CMake settings
   (``fmpy.build.create_cmake_settings``) and runs cmake (:func:`twin.fmu.toolchain.run_cmake`)
   with fmpy's ``c-code/CMakeLists.txt`` and FMI headers, so the platform binary lands in
   ``binaries/<platform>/``;
3. zips the tree into ``<Model>.fmu`` with sources included (any FMI tool can rebuild it).

:func:`ensure_fmu` (what :func:`twin.fmu.catalog.fmu` returns) keeps the ``.fmu`` in the
toolchain's cache under a hash of every file that goes into it, rebuilding when any of them
changed, so a fresh clone or install just works.
"""

from __future__ import annotations

import functools
import hashlib
import io
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path

from twin.errors import BuildError
from twin.files import write_atomic
from twin.fmu.description import Description, Variable
from twin.fmu.sources import Model, model, model_names, sources_dir
from twin.fmu.toolchain import (
    LIBRARY_SUFFIX,
    cache_dir,
    cached,
    content_hash,
    digest_file,
    find_tools,
    hash_by_stats,
    private_cache_dir,
    progress,
    run_cmake,
)
from twin.fmu.workdir import process_dir

__all__ = [
    "BUILD_FORMAT",
    "build_all",
    "build_fmu",
    "built_library",
    "cache_dir",
    "ensure_fmu",
    "fmu_sources_dir",
    "generate_vars_header",
    "model_names",
    "source_hash",
]

#: bump when the generator or the FMU layout changes, so cached FMUs are rebuilt
BUILD_FORMAT = "3"

#: how the twin builds its FMUs beyond fmpy's Release settings: the wrapper, the model and the
#: shared code (rng.c, linalg.c) are separate files, and the calls between them (model_outputs,
#: model_step, the noise draws) are made on every internal step; link-time optimization inlines
#: them, and hidden visibility keeps every symbol but the FMI functions (FMI2_Export: default
#: visibility) out of the library's interface, so no call goes through the PLT. Neither changes
#: an operation's order or its rounding (no -ffast-math, no FMA contraction on baseline x86-64):
#: the outputs keep their bits (tests/fmus/test_cost_not_values.py)
OPTIMIZE = {"CMAKE_INTERPROCEDURAL_OPTIMIZATION": "ON", "CMAKE_C_VISIBILITY_PRESET": "hidden"}

#: the sources folder (kept under its old name: tests and benchmarks use it)
fmu_sources_dir = sources_dir
#: kept for twin.cosim.native until its stepper is built by toolchain.build_cached_library
_check_tools = find_tools

_CAUSALITY = {
    "parameter": "CAUS_PARAMETER",
    "calculatedParameter": "CAUS_CALCULATED_PARAMETER",
    "input": "CAUS_INPUT",
    "output": "CAUS_OUTPUT",
    "local": "CAUS_LOCAL",
    "independent": "CAUS_INDEPENDENT",
}
_VARIABILITY = {
    "constant": "VAR_CONSTANT",
    "fixed": "VAR_FIXED",
    "tunable": "VAR_TUNABLE",
    "discrete": "VAR_DISCRETE",
    "continuous": "VAR_CONTINUOUS",
}


def source_hash(model_name: str, src: Path | None = None) -> str:
    """Content hash of everything that goes into a model's FMU (sources, XML, readme).

    Kept per process while no file's size, modification or change time changes (a sweep's
    worker asks for it five times a point), and across processes by the same key
    (:func:`~twin.fmu.toolchain.hash_by_stats`: a fresh process reads no source file)."""
    m = model(model_name, src)
    return _content_hash(m, m.stat_key())


@functools.lru_cache(maxsize=64)
def _content_hash(m: Model, stats: tuple[tuple[str, int, int, int, int], ...]) -> str:
    return hash_by_stats(stats, BUILD_FORMAT, lambda: content_hash(m.files(), BUILD_FORMAT))


# ---------------------------------------------------------------------------- model_vars.h


def _c_double(x: float) -> str:
    if x == float("inf"):
        return "HUGE_VAL"
    if x == float("-inf"):
        return "-HUGE_VAL"
    return repr(float(x))


def _c_row(v: Variable) -> str:
    """One VarInfo row: name, causality, variability, start, min, max (a Boolean spans 0..1)."""
    start = float(v.start or 0.0)  # a Boolean's True is 1.0
    lo, hi = (0.0, 1.0) if v.type == "Boolean" else (v.min, v.max)
    return (
        f'    {{"{v.name}", {_CAUSALITY[v.causality]}, {_VARIABILITY[v.variability]}, '
        f"{_c_double(start)}, {_c_double(lo)}, {_c_double(hi)}}},"
    )


def generate_vars_header(description: Description, where: str = "modelDescription.xml") -> str:
    """C header with value references, the variable tables and the GUID of one model.

    Value references must run 0..n-1 per base type: they index the value arrays directly
    (``where`` names the file in that error).
    """
    lines = [
        "/* model_vars.h -- GENERATED by twin.fmu.build from modelDescription.xml; do not edit. */",
        "#ifndef MODEL_VARS_H",
        "#define MODEL_VARS_H",
        "#include <math.h>",
        f'#define MODEL_GUID "{description.guid}"',
    ]
    tables = []
    for kind, count_name, table in (
        ("Real", "N_REALS", "VARS_REAL"),
        ("Integer", "N_INTEGERS", "VARS_INTEGER"),
        ("Boolean", "N_BOOLEANS", "VARS_BOOLEAN"),
    ):
        vs = sorted(
            (v for v in description.variables.values() if v.type == kind), key=lambda v: v.value_reference
        )
        if [v.value_reference for v in vs] != list(range(len(vs))):
            raise BuildError(f"{where}: {kind} value references must be 0..{len(vs) - 1} without gaps")
        lines.append(f"#define {count_name} {len(vs)}")
        lines.extend(f"#define VR_{v.name} {v.value_reference}" for v in vs)
        rows = [_c_row(v) for v in vs] or ['    {"", CAUS_LOCAL, VAR_CONSTANT, 0.0, 0.0, 0.0},']
        tables.append(f"static const VarInfo {table}[] = {{\n" + "\n".join(rows) + "\n};")
        if kind == "Real":  # the outputs the wrapper checks after every step, without a search
            outs = [str(v.value_reference) for v in vs if v.causality == "output"]
            lines.append(f"#define N_OUTPUT_REALS {len(outs)}")
            tables.append(f"static const int OUTPUT_REALS[] = {{{', '.join(outs) or '0'}}};")
    lines += ['#include "config.h"', "#endif", "#ifdef MODEL_VARS_TABLES", *tables, "#endif"]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- build


def _zip_tree(tree: Path, fmu_path: Path) -> None:
    """Zip with sorted names and a fixed timestamp, so the same sources give the same bytes."""

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
            for p in sorted(tree.rglob("*")):
                if p.is_file():
                    info = zipfile.ZipInfo(p.relative_to(tree).as_posix(), date_time=(2017, 3, 1, 0, 0, 0))
                    info.compress_type = zipfile.ZIP_DEFLATED
                    info.external_attr = 0o644 << 16
                    zf.writestr(info, p.read_bytes())

    write_atomic(fmu_path, write)  # a concurrent reader never sees half a file


def _lay_out(tree: Path, m: Model, files: Mapping[str, bytes]) -> None:
    """The FMU's folder: the XML at the top, the readme in documentation/, the rest in sources/."""
    places = {"modelDescription.xml": tree, "readme.md": tree / "documentation"}
    for folder in (tree / "sources", tree / "documentation"):
        folder.mkdir(parents=True)
    for name, data in files.items():
        (places.get(name, tree / "sources") / name).write_bytes(data)
    (tree / "sources" / "model_vars.h").write_text(generate_vars_header(m.description, str(m.folder)))


def build_fmu(
    model_name: str, out_dir: Path, *, src: Path | None = None, debug: bool = False, optimize: bool = True
) -> Path:
    """Build one model into ``out_dir/<model>.fmu`` and return its path.

    ``optimize=False`` builds with fmpy's settings alone (no :data:`OPTIMIZE`): the test that
    the optimized build keeps every output's bits compares against it.

    Raises :class:`ToolMissingError` without a compiler or cmake and :class:`BuildError`
    (with the tail of the compiler output) when compilation fails.
    """
    import fmpy
    from fmpy.build import create_cmake_settings  # fmpy's cmake settings, headers and CMakeLists

    m = model(model_name, src)
    files = m.files()
    find_tools()  # before any work: a missing tool is the one thing to report
    # one line per model, terminal or not: a first build is seconds of silence per FMU
    progress(f"building FMU {model_name} (first use of its sources)")
    out_dir.mkdir(parents=True, exist_ok=True)
    # in this process's own folder, which the next twin process removes when an interruption
    # (or a SIGKILL) left it (twin.fmu.workdir)
    with tempfile.TemporaryDirectory(prefix=f"build-{model_name}-", dir=process_dir()) as tmp:
        tree, build_dir = Path(tmp) / "fmu", Path(tmp) / "build"
        _lay_out(tree, m, files)
        build_dir.mkdir()
        create_cmake_settings(
            tree, build_dir, configuration="Debug" if debug else "Release", all_warnings=True
        )
        run_cmake(
            Path(fmpy.__file__).parent / "c-code",
            build_dir,
            f"FMU '{model_name}'",
            OPTIMIZE if optimize else None,
        )
        fmu_path = out_dir / f"{model_name}.fmu"
        _zip_tree(tree, fmu_path)
    return fmu_path


def ensure_fmu(model_name: str, *, src: Path | None = None) -> Path:
    """Path of an up-to-date ``.fmu`` of ``model_name``, building it if its sources changed."""
    src = src or sources_dir()
    digest = source_hash(model_name, src)
    return cached(model_name, digest, ".fmu", lambda scratch: build_fmu(model_name, scratch, src=src))


def built_library(fmu: Path) -> Path | None:
    """The platform library of an FMU that :func:`ensure_fmu` built, kept in the cache beside
    it as an entry of its own (``<FMU's name>-<16 hex digits of its SHA-256>.so``), or None
    for any other file: an FMU from elsewhere (:mod:`twin.fmu.external`) is unpacked into a
    private folder of each process that loads it (:func:`twin.fmu.slot.FMUSlot`).

    The library is taken out of the FMU once, when the FMU's bytes still match the SHA-256
    recorded at its build, and is from then on checked against its own recorded SHA-256
    each time it is asked for, as every cache entry is (:func:`twin.fmu.toolchain.cached`):
    before each load of it (:func:`twin.fmu.slot.FMUSlot` does not ask while an instance
    holds the library loaded, when the loader loads nothing new). A fresh process
    then loads the tester's five FMUs without unpacking any. The FMUs built here have no ``resources/``
    (:func:`_lay_out`), so the library is all an instance loads of them.
    """
    from fmpy import platform as fmpy_platform

    folder = private_cache_dir()
    if fmu.suffix != ".fmu" or fmu.resolve().parent != folder.resolve():
        return None
    try:
        recorded = digest_file(fmu).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return None  # not an entry of this cache's (no record): not one to take a library from
    model_name = fmu.stem.rsplit("-", 1)[0]

    def take_out(scratch: Path) -> Path:
        data = fmu.read_bytes()  # unzipped from the bytes that were hashed, not the file again
        if hashlib.sha256(data).hexdigest() != recorded:
            raise BuildError(f"{fmu}: its bytes do not match the SHA-256 recorded at its build")
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            names = zf.namelist()
            if any(n.startswith("resources/") for n in names):
                raise BuildError(f"{fmu}: has resources/, which the FMUs built here never have")
            library = f"binaries/{fmpy_platform}/{model_name}{LIBRARY_SUFFIX}"
            if library not in names:
                raise BuildError(f"{fmu}: no {library} in it")
            out = scratch / Path(library).name
            out.write_bytes(zf.read(library))
        # libraries of FMUs no longer in the cache (older sources, pruned by cached()) go too
        for stale in folder.glob(f"{model_name}-*{LIBRARY_SUFFIX}"):
            if not (folder / f"{stale.name[: -len(LIBRARY_SUFFIX)].rsplit('-', 1)[0]}.fmu").exists():
                stale.unlink(missing_ok=True)
                digest_file(stale).unlink(missing_ok=True)
        return out

    try:
        return cached(fmu.stem, recorded[:16], LIBRARY_SUFFIX, take_out)
    except OSError as exc:  # a full disk: say what was being written
        exc.filename = exc.filename or f"{folder} (the library of {fmu.name})"
        raise


def build_all(out_dir: Path | None = None) -> dict[str, Path]:
    """Build every model; into ``out_dir`` if given, else into the cache."""
    return {m: build_fmu(m, out_dir) if out_dir else ensure_fmu(m) for m in model_names()}
