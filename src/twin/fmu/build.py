"""Build the twin's C models in ``fmus/`` into FMI 2.0 co-simulation FMUs.

Each model folder holds ``modelDescription.xml`` (the single source of truth for its
variables), ``config.h``, ``model.c`` and ``readme.md``; ``fmus/common/`` holds the one FMI
wrapper and the shared solver code. Building a model:

1. generates ``model_vars.h`` (value references, variable table, GUID) from the XML, so the C
   code and the XML cannot disagree;
2. lays out an FMU tree (XML, ``sources/``, ``documentation/``), writes fmpy's CMake settings
   (``fmpy.build.create_cmake_settings``) and runs cmake with fmpy's ``c-code/CMakeLists.txt``
   and FMI headers, so the platform binary lands in ``binaries/<platform>/``;
3. zips the tree into ``<Model>.fmu`` with sources included (any FMI tool can rebuild it).

:func:`ensure_fmu` is what the rest of the package calls: it returns a cached ``.fmu`` whose
name carries a hash of every source file, rebuilding when any of them changed, so a fresh
clone just works.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

from twin.errors import BuildError, ConfigError, ToolMissingError

#: bump when the generator or the FMU layout changes, so cached FMUs are rebuilt
BUILD_FORMAT = "2"

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


def fmu_sources_dir() -> Path:
    """The folder holding ``common/`` and one folder per model.

    ``TWIN_FMU_SOURCES`` overrides; otherwise the ``fmus/`` folder of the source tree this
    package was installed from (editable install, or run from a checkout).
    """
    env = os.environ.get("TWIN_FMU_SOURCES")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[3] / "fmus")
    for c in candidates:
        if (c / "common" / "fmi2_wrapper.c").is_file():
            return c
    raise ConfigError(
        "FMU sources not found (looked in "
        + ", ".join(str(c) for c in candidates)
        + "); install the package editable from a checkout (pip install -e .) or set TWIN_FMU_SOURCES",
        source="fmus",
    )


def model_names(src: Path | None = None) -> list[str]:
    """Names of every model folder (those with a modelDescription.xml), sorted."""
    src = src or fmu_sources_dir()
    return sorted(p.parent.name for p in src.glob("*/modelDescription.xml"))


def cache_dir() -> Path:
    """Where built FMUs are kept: ``TWIN_CACHE_DIR`` or ``$XDG_CACHE_HOME/twin/fmus``."""
    env = os.environ.get("TWIN_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "twin" / "fmus"


def _model_files(src: Path, model: str) -> list[Path]:
    model_dir = src / model
    if not (model_dir / "modelDescription.xml").is_file():
        raise ConfigError(f"unknown model '{model}' (known: {', '.join(model_names(src))})", source="fmus")
    common = sorted(p for p in (src / "common").iterdir() if p.suffix in {".c", ".h"})
    own = sorted(p for p in model_dir.iterdir() if p.is_file() and not p.name.startswith("."))
    return common + own


def source_hash(model: str, src: Path | None = None) -> str:
    """Content hash of everything that goes into a model's FMU (sources, XML, readme)."""
    src = src or fmu_sources_dir()
    h = hashlib.sha256(BUILD_FORMAT.encode())
    for p in _model_files(src, model):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


# ---------------------------------------------------------------------------- model_vars.h


@dataclass(frozen=True)
class _Var:
    name: str
    vr: int
    kind: str
    causality: str
    variability: str
    start: float
    vmin: float
    vmax: float


def _c_double(x: float) -> str:
    if x == float("inf"):
        return "HUGE_VAL"
    if x == float("-inf"):
        return "-HUGE_VAL"
    return repr(float(x))


def _read_vars(xml_path: Path) -> tuple[str, list[_Var]]:
    root = ET.parse(xml_path).getroot()
    guid = root.get("guid", "")
    types: dict[str, ET.Element] = {}
    for st in root.iter("SimpleType"):
        child = next(iter(st))
        types[st.get("name", "")] = child
    out = []
    model_variables = root.find("ModelVariables")
    for sv in model_variables if model_variables is not None else []:
        elem = next(iter(sv))
        kind = elem.tag
        declared = types.get(elem.get("declaredType", ""))

        def attr(name: str, elem: ET.Element = elem, declared: ET.Element | None = declared) -> str | None:
            v = elem.get(name)
            if v is None and declared is not None:
                v = declared.get(name)
            return v

        if kind == "Boolean":
            start = 1.0 if attr("start") == "true" else 0.0
            vmin, vmax = 0.0, 1.0
        else:
            start = float(attr("start") or 0.0)
            vmin = float(attr("min")) if attr("min") is not None else float("-inf")
            vmax = float(attr("max")) if attr("max") is not None else float("inf")
        out.append(
            _Var(
                name=sv.get("name", ""),
                vr=int(sv.get("valueReference", "-1")),
                kind=kind,
                causality=sv.get("causality", "local"),
                variability=sv.get("variability", "continuous"),
                start=start,
                vmin=vmin,
                vmax=vmax,
            )
        )
    return guid, out


def generate_vars_header(xml_path: Path) -> str:
    """C header with value references, the variable tables and the GUID of one model.

    Value references must run 0..n-1 per base type: they index the value arrays directly.
    """
    guid, variables = _read_vars(xml_path)
    lines = [
        "/* model_vars.h -- GENERATED by twin.fmu.build from modelDescription.xml; do not edit. */",
        "#ifndef MODEL_VARS_H",
        "#define MODEL_VARS_H",
        "#include <math.h>",
        f'#define MODEL_GUID "{guid}"',
    ]
    tables = []
    for kind, count_name, table in (
        ("Real", "N_REALS", "VARS_REAL"),
        ("Integer", "N_INTEGERS", "VARS_INTEGER"),
        ("Boolean", "N_BOOLEANS", "VARS_BOOLEAN"),
    ):
        vs = sorted((v for v in variables if v.kind == kind), key=lambda v: v.vr)
        if [v.vr for v in vs] != list(range(len(vs))):
            raise BuildError(f"{xml_path}: {kind} value references must be 0..{len(vs) - 1} without gaps")
        lines.append(f"#define {count_name} {len(vs)}")
        for v in vs:
            lines.append(f"#define VR_{v.name} {v.vr}")
        rows = [
            f'    {{"{v.name}", {_CAUSALITY[v.causality]}, {_VARIABILITY[v.variability]}, '
            f"{_c_double(v.start)}, {_c_double(v.vmin)}, {_c_double(v.vmax)}}},"
            for v in vs
        ] or ['    {"", CAUS_LOCAL, VAR_CONSTANT, 0.0, 0.0, 0.0},']
        tables.append(f"static const VarInfo {table}[] = {{\n" + "\n".join(rows) + "\n};")
    lines.append('#include "config.h"')
    lines.append("#endif")
    lines.append("#ifdef MODEL_VARS_TABLES")
    lines.extend(tables)
    lines.append("#endif")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- build


def _check_tools() -> tuple[str, str]:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise ToolMissingError(
            "no C compiler found: install one (Debian: apt-get install -y gcc) to build the FMUs",
            source="build",
        )
    cmake = shutil.which("cmake")
    if not cmake:
        raise ToolMissingError(
            "cmake not found: pip install cmake (it is a dependency of twin) or apt-get install -y cmake",
            source="build",
        )
    return cc, cmake


def _zip_tree(tree: Path, fmu_path: Path) -> None:
    """Zip with sorted names and a fixed timestamp, so the same sources give the same bytes."""
    tmp = fmu_path.with_name(fmu_path.name + f".{os.getpid()}.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(tree.rglob("*")):
            if p.is_file():
                info = zipfile.ZipInfo(p.relative_to(tree).as_posix(), date_time=(2017, 3, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                zf.writestr(info, p.read_bytes())
    os.replace(tmp, fmu_path)  # atomic: a concurrent reader never sees half a file


def build_fmu(model: str, out_dir: Path, *, src: Path | None = None, debug: bool = False) -> Path:
    """Build one model into ``out_dir/<model>.fmu`` and return its path.

    Raises :class:`ToolMissingError` without a compiler or cmake and :class:`BuildError`
    (with the tail of the compiler output) when compilation fails.
    """
    import fmpy
    from fmpy.build import create_cmake_settings  # fmpy's cmake settings, headers and CMakeLists

    src = src or fmu_sources_dir()
    files = _model_files(src, model)
    _, cmake = _check_tools()
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"twin-build-{model}-") as tmp:
        tree = Path(tmp) / "fmu"
        sources = tree / "sources"
        sources.mkdir(parents=True)
        (tree / "documentation").mkdir()
        for p in files:
            if p.name == "modelDescription.xml":
                shutil.copyfile(p, tree / p.name)
            elif p.name == "readme.md":
                shutil.copyfile(p, tree / "documentation" / "readme.md")
            else:
                shutil.copyfile(p, sources / p.name)
        (sources / "model_vars.h").write_text(generate_vars_header(tree / "modelDescription.xml"))
        build_dir = Path(tmp) / "build"
        build_dir.mkdir()
        create_cmake_settings(
            tree,
            build_dir,
            configuration="Debug" if debug else "Release",
            all_warnings=True,
        )
        c_code = Path(fmpy.__file__).parent / "c-code"
        for cmd in (
            [cmake, "-S", str(c_code), "-B", str(build_dir)],
            [cmake, "--build", str(build_dir), "--target", "install"],
        ):
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-25:])
                raise BuildError(f"building FMU '{model}' failed ({' '.join(cmd[:2])} ...):\n{tail}")
        fmu_path = out_dir / f"{model}.fmu"
        _zip_tree(tree, fmu_path)
    return fmu_path


def ensure_fmu(model: str) -> Path:
    """Path of an up-to-date ``.fmu`` of ``model``, building it if its sources changed."""
    src = fmu_sources_dir()
    digest = source_hash(model, src)
    target = cache_dir() / f"{model}-{digest}.fmu"
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="twin-fmu-", dir=target.parent) as tmp:
        built = build_fmu(model, Path(tmp), src=src)
        os.replace(built, target)
    for stale in target.parent.glob(f"{model}-*.fmu"):
        if stale != target:
            stale.unlink(missing_ok=True)
    return target


def build_all(out_dir: Path | None = None) -> dict[str, Path]:
    """Build every model; into ``out_dir`` if given, else into the cache."""
    result = {}
    for model in model_names():
        result[model] = build_fmu(model, out_dir) if out_dir else ensure_fmu(model)
    return result
