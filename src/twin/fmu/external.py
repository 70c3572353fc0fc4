"""FMUs the twin did not build: any FMI 2.0 co-simulation ``.fmu`` a scenario names by path.

A scenario's ``model = "filters/lowpass.fmu"`` (relative to the scenario file) names one. Before
the run it is checked (:func:`check`): a regular file, a zip whose members pass
:mod:`twin.fmu.safezip` (names, kinds, sizes; every member unpacked once, so a damaged one is
found), a modelDescription.xml in UTF-8 or UTF-16 without a document type, checked as fmpy
checks an FMU (``fmpy validate``), FMI 2.0 with co-simulation, a ``modelIdentifier`` that is a
plain C name, and a library for this platform whose headers say it can be loaded
(:mod:`twin.fmu.library`); every problem is one line naming the file. Its SHA-256 is taken when
it is checked; to be loaded the file is copied into the process's private folder and hashed as
it is copied, and only a copy with the checked SHA-256 is unpacked (:func:`unpack`): the
library loaded is the member that was checked, never a file outside the FMU.

Within the twin an external model's name is its resolved path (it ends in ``.fmu``, which no
built-in model's name does), so :mod:`twin.fmu.catalog` answers its variables and its file.
"""

from __future__ import annotations

import hashlib
import os
import re
import zipfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from twin.errors import ConfigError
from twin.fmu.safezip import (
    MAX_ARCHIVE_BYTES,
    check_members,
    copy_member,
    open_regular,
    open_zip,
    read_member,
)

if TYPE_CHECKING:
    from twin.fmu.description import Description

__all__ = ["MAX_FMU_BYTES", "ExternalFMU", "Unpacked", "check", "is_external", "unpack", "verified_path"]

#: the largest FMU file read (a model's binaries and resources; a bigger one is refused)
MAX_FMU_BYTES = MAX_ARCHIVE_BYTES
#: FMI 2.0 (2.2.1): the modelIdentifier is the library's file name and the prefix of its
#: functions, so a plain C name; a path in it would have fmpy load a file outside the FMU
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,199}")
_WHAT = "an FMU is a zip file"


def is_external(model: str) -> bool:
    """``model`` names an FMU file, not one of the twin's models."""
    return model.endswith(".fmu")


@dataclass(frozen=True)
class ExternalFMU:
    """A checked FMU file: where, its SHA-256 when checked, its model description, the member
    its library is (``binaries/<platform>/<modelIdentifier>.so``) and the modelDescription's
    bytes as checked (UTF-8)."""

    path: Path
    sha256: str
    description: Description
    model_name: str
    library: str = ""
    xml: bytes = b""


def check(path: str | Path) -> ExternalFMU:
    """Check the FMU file ``path`` (see the module); one :class:`ConfigError` line otherwise."""
    with open_regular(Path(path), str(path), _WHAT, MAX_FMU_BYTES) as f:  # named as given
        st = os.fstat(f.fileno())
    return _check(Path(path).resolve(), st.st_size, st.st_mtime_ns)


def _sha256(f: BinaryIO) -> str:
    h = hashlib.sha256()
    while block := f.read(1 << 20):
        h.update(block)
    f.seek(0)
    return h.hexdigest()


@cache  # a sweep's client checks its scenario once per point
def _check(path: Path, size: int, mtime_ns: int) -> ExternalFMU:
    source = str(path)
    with open_regular(path, source, _WHAT, MAX_FMU_BYTES) as f:
        sha256 = _sha256(f)
        with open_zip(f, source, "not an FMU") as zf:
            return _check_archive(zf, path, sha256)


def _check_archive(zf: zipfile.ZipFile, path: Path, sha256: str) -> ExternalFMU:
    """The checks of :func:`check` on the opened archive: its members (names, kinds, sizes,
    every one unpacked once to find a damaged one), its description, its library."""
    import fmpy

    from twin.fmu.description import MAX_DESCRIPTION_BYTES, describe_xml, validate_xml
    from twin.fmu.library import check_library
    from twin.fmu.safezip import safe_xml

    source = str(path)
    members = {m.filename: m for m in check_members(zf, source)}
    if "modelDescription.xml" not in members:
        raise ConfigError("no modelDescription.xml in the archive", source=source)
    raw = read_member(zf, members["modelDescription.xml"], source, MAX_DESCRIPTION_BYTES)
    xml, root = safe_xml(raw, "modelDescription.xml", source)
    version = root.get("fmiVersion", "?")
    if version != "2.0":
        raise ConfigError(f"FMI {version}: the twin runs FMI 2.0 co-simulation FMUs", source=source)
    co_simulation = root.find("CoSimulation")
    if co_simulation is None:
        raise ConfigError("model exchange only: the twin runs co-simulation FMUs", source=source)
    identifier = co_simulation.get("modelIdentifier", "")
    if not _C_NAME.fullmatch(identifier):
        raise ConfigError(
            f"modelIdentifier {identifier!r} is not a plain C name (FMI 2.0: the library's file "
            "name inside the FMU and its functions' prefix)",
            source=source,
        )
    try:
        description = describe_xml(xml, source)
    except ConfigError as exc:
        raise ConfigError(
            (exc.message or "").replace(
                "not a readable FMI model description", "no readable modelDescription.xml"
            ),
            source=source,
        ) from None
    problems = validate_xml(xml)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        first = " ".join(problems[0].split())
        raise ConfigError(f"fmpy validate: {first}{more}", source=source)
    for m in members.values():  # a damaged member (a bad CRC, a broken stream) is found now
        if not m.is_dir() and m.filename != "modelDescription.xml":
            copy_member(zf, m, lambda block: None, source)
    library = f"binaries/{fmpy.platform}/{identifier}{fmpy.sharedLibraryExtension}"
    if library not in members:
        platforms = sorted(
            {n.split("/")[1] for n in members if n.startswith("binaries/") and n.count("/") > 1}
        )
        raise ConfigError(
            f"no binary for {fmpy.platform} (it has: {', '.join(platforms) or 'none'})", source=source
        )
    check_library(read_member(zf, members[library], source), library, source)
    return ExternalFMU(path, sha256, description, description.model_name, library, xml)


def verified_path(model: str) -> Path:
    """The FMU file of the external ``model``, its content hashed again: the file checked."""
    from twin.fmu.toolchain import file_sha256

    path = Path(model)
    checked = check(path)
    if file_sha256(path) != checked.sha256:
        raise ConfigError("the FMU changed since it was checked: not loaded", source=str(path))
    return path


@dataclass(frozen=True)
class Unpacked:
    """An FMU unpacked for loading: the folder fmpy is given, and the library in it."""

    folder: Path
    library: Path


def unpack(path: Path, folder: Path) -> Unpacked:
    """What an instance loads of the checked FMU ``path`` (its library for this platform and its
    ``resources/``), unpacked into the new, private and empty ``folder``; the library returned is the member
    that was checked. The file is first copied into ``folder`` and hashed as it is copied: only
    a copy whose SHA-256 is the checked one is unpacked (a file replaced since its check is
    refused), and its members are checked again as they are unpacked."""
    from twin.fmu.library import check_library
    from twin.fmu.safezip import extract

    checked = check(path)
    source = str(path)
    copy = folder / ".fmu"
    h = hashlib.sha256()
    with open_regular(path, source, _WHAT, MAX_FMU_BYTES) as src:
        fd = os.open(copy, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
        with os.fdopen(fd, "wb") as dst:
            while block := src.read(1 << 20):
                h.update(block)
                dst.write(block)
    try:
        if h.hexdigest() != checked.sha256:
            raise ConfigError("the FMU changed since it was checked: not loaded", source=source)
        with open(copy, "rb") as f, open_zip(f, source, "not an FMU") as zf:
            members = check_members(zf, source)
            loaded = [
                m for m in members if m.filename == checked.library or m.filename.startswith("resources/")
            ]
            extract(zf, loaded, folder / "fmu", source)
    finally:
        copy.unlink(missing_ok=True)
    root = folder / "fmu"
    library = root.joinpath(*checked.library.split("/"))
    check_library(library.read_bytes(), checked.library, source)
    return Unpacked(root, library)
