"""Where the FMU sources are, and what one model's sources hold.

The sources of every model (``fmus/`` in the source tree: ``common/`` and one folder per
model) travel with the package as data of ``twin.fmu`` (``twin/fmu/sources/`` in an
installed wheel, mapped from ``fmus/`` by ``pyproject.toml``). They are looked up in order:

1. ``TWIN_FMU_SOURCES``, a developer's override (a folder holding ``common/`` and the models);
2. the package data, through :mod:`importlib.resources` (a regular, non-editable install);
3. the ``fmus/`` folder beside ``src/`` when the package runs from a checkout (an editable
   install or ``PYTHONPATH=src``: setuptools' editable finder cannot map a data folder outside
   ``src/``, and the checkout's own folder is the one its code belongs with).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib.resources import files
from pathlib import Path

from twin.errors import ConfigError
from twin.fmu.description import Description, Variable, describe
from twin.fmu.toolchain import folder_files

__all__ = ["SOURCES_ENV", "Model", "model", "model_names", "shipped_folder", "sources_dir"]

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


@cache
def _describe_source(xml_path: Path) -> Description:
    return describe(xml_path)


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

    def stat_key(self) -> tuple[tuple[str, int, int, int, int], ...]:
        """(path, size, modification time, change time, inode) of every file :meth:`files`
        reads: what their content hash is kept by, in a process (a sweep's worker asks for
        every point) and across processes (:func:`twin.fmu.toolchain.hash_by_stats`). A file
        written anew (an editor's save, a checkout) has another change time or inode, whatever
        its size and modification time."""
        out = []
        for folder, common in ((self.root / "common", True), (self.folder, False)):
            with os.scandir(folder) as it:
                entries = sorted(
                    (
                        e
                        for e in it
                        if (
                            os.path.splitext(e.name)[1] in _COMMON_SUFFIXES
                            if common
                            else not e.name.startswith(".")
                        )
                    ),
                    key=lambda e: e.name,
                )
            for e in entries:
                st = e.stat()  # through a link, as files() reads it
                if stat.S_ISREG(st.st_mode):
                    out.append((e.path, st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino))
        return tuple(out)


def model(name: str, src: Path | None = None) -> Model:
    """The model ``name`` of the sources folder (default: :func:`sources_dir`)."""
    src = src or sources_dir()
    if not (src / name / "modelDescription.xml").is_file():
        raise ConfigError(f"unknown model '{name}' (known: {', '.join(model_names(src))})", source="fmus")
    return Model(name, src)
