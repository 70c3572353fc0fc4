"""The one place that knows an FMU: its sources, its modelDescription and its build.

The sources of every model (``fmus/`` in the source tree: ``common/`` and one folder per
model) travel with the package as data of ``twin.fmu`` (``twin/fmu/sources/`` in an
installed wheel, mapped from ``fmus/`` by ``pyproject.toml``). They are looked up in order:

1. ``TWIN_FMU_SOURCES``, a developer's override (a folder holding ``common/`` and the models);
2. the package data, through :mod:`importlib.resources` (a regular, non-editable install);
3. the ``fmus/`` folder beside ``src/`` when the package runs from a checkout (an editable
   install or ``PYTHONPATH=src``: setuptools' editable finder cannot map a data folder outside
   ``src/``, and the checkout's own folder is the one its code belongs with).

A model's variables are read from its ``modelDescription.xml`` by :func:`describe` (fmpy's
reader, the only one in the package), resolved once into :class:`Variable` records: unit and
range come from the variable or its declared type. :func:`fmu` returns a built ``.fmu`` from
the content-hashed cache (:mod:`twin.fmu.build` does the building).
"""

from __future__ import annotations

import hashlib
import io
import math
import os
import stat
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib.resources import files
from pathlib import Path
from types import MappingProxyType
from typing import Any

from twin.errors import ConfigError
from twin.fmu.toolchain import folder_files

#: environment variable overriding where the FMU sources are
SOURCES_ENV = "TWIN_FMU_SOURCES"
#: a file every sources folder has
_MARKER = Path("common") / "fmi2_wrapper.c"
#: the build inputs shared by every model (the rest of common/ is not compiled)
_COMMON_SUFFIXES = {".c", ".h"}


def shipped_folder(package: str, name: str, checkout_name: str) -> list[Path]:
    """Where a data folder shipped with the package may be: its package data, then the checkout.

    ``package``'s resource ``name`` in an installed wheel; ``checkout_name`` beside ``src/``
    when running from a source tree. Returns the candidates in that order (they may not exist).
    """
    return list(_shipped_folder(package, name, checkout_name))


@cache  # where the package is does not change in a process; a sweep's client asks every point
def _shipped_folder(package: str, name: str, checkout_name: str) -> tuple[Path, ...]:
    candidates = []
    shipped = files(package) / name
    if isinstance(shipped, Path):  # a real folder (not inside a zip)
        candidates.append(shipped)
    import twin  # the package's own location says which checkout it belongs to

    candidates.append(Path(twin.__file__).resolve().parents[2] / checkout_name)
    return tuple(candidates)


def sources_dir() -> Path:
    """The folder holding ``common/`` and one folder per model (see the module's docstring)."""
    return _find_sources(os.environ.get(SOURCES_ENV) or None)


@cache  # asked for by every variable look-up; the answer only changes with the override
def _find_sources(env: str | None) -> Path:
    candidates = [Path(env)] if env else shipped_folder("twin.fmu", "sources", "fmus")
    for c in candidates:
        if (c / _MARKER).is_file():
            return c
    raise ConfigError(
        "FMU sources not found (looked in "
        + ", ".join(str(c) for c in candidates)
        + f"); reinstall the package (pip install .) or set {SOURCES_ENV} to a folder holding common/"
        " and one folder per model",
        source="fmus",
    )


def model_names(src: Path | None = None) -> list[str]:
    """Names of every model folder (those with a modelDescription.xml), sorted."""
    src = src or sources_dir()
    return sorted(p.parent.name for p in src.glob("*/modelDescription.xml"))


# ---------------------------------------------------------------------------- modelDescription


@dataclass(frozen=True)
class Variable:
    """One scalar variable of a modelDescription, with unit and range resolved.

    ``min``/``max`` are the declared bounds (or those of the declared type), ``-inf``/``inf``
    when there are none; ``unit`` is ``""`` when none is declared; ``start`` is typed by
    ``type`` (``float``, ``int``, ``bool`` or ``str``) and ``None`` when absent.
    """

    name: str
    value_reference: int
    type: str
    causality: str
    variability: str
    unit: str
    min: float
    max: float
    start: float | int | bool | str | None
    description: str


@dataclass(frozen=True)
class Description:
    """What a modelDescription.xml says that the twin uses."""

    guid: str
    model_identifier: str
    variables: Mapping[str, Variable]


def _declared(sv: Any, attribute: str) -> Any:
    """An attribute of an fmpy variable, else of its declared type (None if neither gives one)."""
    value = getattr(sv, attribute, None)
    if value in (None, "") and sv.declaredType is not None:
        value = getattr(sv.declaredType, attribute, None)
    return value


def _start(kind: str, text: str | None) -> float | int | bool | str | None:
    if text is None:
        return None
    if kind == "Boolean":
        return text in ("true", "1")
    return {"Real": float, "Integer": int, "Enumeration": int}.get(kind, str)(text)


def _variable(sv: Any) -> Variable:
    lo, hi = _declared(sv, "min"), _declared(sv, "max")
    return Variable(
        name=sv.name,
        value_reference=int(sv.valueReference),
        type=sv.type,
        causality=sv.causality,
        variability=sv.variability,
        unit=str(_declared(sv, "unit") or ""),
        min=float(lo) if lo is not None else -math.inf,
        max=float(hi) if hi is not None else math.inf,
        start=_start(sv.type, sv.start),
        description=sv.description or "",
    )


#: descriptions by the SHA-256 of their modelDescription.xml: a model's source file and the FMU
#: built from it hold the same bytes, so a process parses and validates each one once (fmpy
#: loads the XML schema for every file it validates: 2 ms each, a tenth of a fresh process's
#: FMU set-up)
_BY_CONTENT: dict[bytes, Description] = {}


def _description_bytes(path: Path) -> bytes:
    if path.is_dir():
        return (path / "modelDescription.xml").read_bytes()
    if path.suffix.lower() == ".xml":
        return path.read_bytes()
    with zipfile.ZipFile(path) as fmu:
        return fmu.read("modelDescription.xml")


def describe(path: str | Path) -> Description:
    """Read a ``modelDescription.xml``, an extracted FMU folder or an ``.fmu`` file (validated
    by fmpy; once per content and process)."""
    xml = _description_bytes(Path(path))
    key = hashlib.sha256(xml).digest()
    found = _BY_CONTENT.get(key)
    if found is None:
        found = _BY_CONTENT[key] = _parse(xml)
    return found


def _parse(xml: bytes) -> Description:
    """The description in ``xml``, parsed by fmpy from exactly these bytes (fmpy reads a file
    object as an FMU: they go to it as the one member of a zip in memory)."""
    from fmpy import read_model_description

    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as fmu:
        fmu.writestr("modelDescription.xml", xml)
    archive.seek(0)
    md = read_model_description(archive)
    identifier = md.coSimulation.modelIdentifier if md.coSimulation is not None else ""
    variables = {sv.name: _variable(sv) for sv in md.modelVariables}
    return Description(md.guid, identifier, MappingProxyType(variables))


@cache
def _describe_source(xml_path: Path) -> Description:
    return describe(xml_path)


# ---------------------------------------------------------------------------- one model


@dataclass(frozen=True)
class Model:
    """One model of the sources folder ``root``: its build inputs, its description, its FMU."""

    name: str
    root: Path

    @property
    def folder(self) -> Path:
        return self.root / self.name

    @property
    def description(self) -> Description:
        """The model's modelDescription.xml, read once."""
        return _describe_source(self.folder / "modelDescription.xml")

    @property
    def variables(self) -> Mapping[str, Variable]:
        """Its variables by name, in the file's order."""
        return self.description.variables

    def files(self) -> dict[str, bytes]:
        """Everything that goes into its FMU by file name: common C code, then its own files."""
        common = {
            k: v for k, v in folder_files(self.root / "common").items() if Path(k).suffix in _COMMON_SUFFIXES
        }
        return common | folder_files(self.folder)

    def stat_key(self) -> tuple[tuple[str, int, int], ...]:
        """(name, size, modification time) of every file :meth:`files` reads: what a process
        may keep the files' content hash by (a sweep's worker asks for every point)."""
        common = [p for p in (self.root / "common").iterdir() if p.suffix in _COMMON_SUFFIXES]
        own = [p for p in self.folder.iterdir() if not p.name.startswith(".")]
        out = []
        for p in sorted(common, key=lambda p: p.name) + sorted(own, key=lambda p: p.name):
            st = p.stat()
            if stat.S_ISREG(st.st_mode):
                out.append((str(p), st.st_size, st.st_mtime_ns))
        return tuple(out)

    def fmu(self) -> Path:
        """An up-to-date ``.fmu`` from the cache, built when any of its files changed."""
        from twin.fmu.build import ensure_fmu  # the builder reads the catalog: import it late

        return ensure_fmu(self.name, src=self.root)


def model(name: str, src: Path | None = None) -> Model:
    """The model ``name`` of the sources folder (default: :func:`sources_dir`)."""
    src = src or sources_dir()
    if not (src / name / "modelDescription.xml").is_file():
        raise ConfigError(f"unknown model '{name}' (known: {', '.join(model_names(src))})", source="fmus")
    return Model(name, src)


def variables(name: str) -> Mapping[str, Variable]:
    """The variables of model ``name`` by name, from its modelDescription.xml (no build needed);
    for an external FMU (a name ending in ``.fmu``, :mod:`twin.fmu.external`), from its file."""
    from twin.fmu import external

    if external.is_external(name):
        return external.check(name).description.variables
    return _variables(name, sources_dir())


@cache  # every connection, parameter and input check asks (a sweep's client, once per point)
def _variables(name: str, src: Path) -> Mapping[str, Variable]:
    return model(name, src).variables


def fmu(name: str) -> Path:
    """Path of an up-to-date ``.fmu`` of model ``name`` (built and cached on first use); an
    external FMU's own file, hashed again (it must be the file that was checked)."""
    from twin.fmu import external

    if external.is_external(name):
        return external.verified_path(name)
    return model(name).fmu()
