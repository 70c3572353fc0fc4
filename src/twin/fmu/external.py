"""FMUs the twin did not build: any FMI 2.0 co-simulation ``.fmu`` a scenario names by path.

A scenario's ``model = "filters/lowpass.fmu"`` (relative to the scenario file) names one. Before
the run it is checked as fmpy checks an FMU (``fmpy validate``: the modelDescription against the
schema and its rules), and it must be FMI 2.0, offer co-simulation and carry a binary for this
platform; every problem is one line naming the file. Its SHA-256 is taken when it is checked,
and the file is hashed again before it is unpacked and loaded: a file replaced between the check
and the run is refused (the twin never loads a binary it has not checked).

Within the twin an external model's name is its resolved path (it ends in ``.fmu``, which no
built-in model's name does), so :mod:`twin.fmu.catalog` answers its variables and its file.
"""

from __future__ import annotations

import os
import stat
import zipfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from twin.errors import ConfigError

if TYPE_CHECKING:
    from twin.fmu.description import Description

__all__ = ["MAX_FMU_BYTES", "ExternalFMU", "check", "is_external", "verified_path"]

#: the largest FMU file read (a model's binaries and resources; a bigger one is refused)
MAX_FMU_BYTES = 512 << 20


def is_external(model: str) -> bool:
    """``model`` names an FMU file, not one of the twin's models."""
    return model.endswith(".fmu")


@dataclass(frozen=True)
class ExternalFMU:
    """A checked FMU file: where, its SHA-256 when checked, its model description."""

    path: Path
    sha256: str
    description: Description
    model_name: str


def _regular(path: Path) -> os.stat_result:
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ConfigError(f"cannot read the FMU: {exc.strerror or exc}", source=str(path)) from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError("not a regular file (an FMU is a zip file)", source=str(path))
    if st.st_size > MAX_FMU_BYTES:
        raise ConfigError(f"{st.st_size} bytes: larger than {MAX_FMU_BYTES >> 20} MB", source=str(path))
    return st


def check(path: str | Path) -> ExternalFMU:
    """Check the FMU file ``path`` (see the module); one :class:`ConfigError` line otherwise."""
    path = Path(path).resolve()
    st = _regular(path)
    return _check(path, st.st_size, st.st_mtime_ns)


@cache  # a sweep's client checks its scenario once per point
def _check(path: Path, size: int, mtime_ns: int) -> ExternalFMU:
    import fmpy
    from fmpy.validation import validate_fmu

    from twin.fmu.description import describe
    from twin.fmu.toolchain import file_sha256

    if not zipfile.is_zipfile(path):
        raise ConfigError("not an FMU (not a zip file)", source=str(path))
    version, co_simulation = _fmi_version(path)
    if version != "2.0":
        raise ConfigError(f"FMI {version}: the twin runs FMI 2.0 co-simulation FMUs", source=str(path))
    if not co_simulation:
        raise ConfigError("model exchange only: the twin runs co-simulation FMUs", source=str(path))
    try:
        description = describe(path)
    except ConfigError as exc:
        raise ConfigError(
            exc.message.replace("not a readable FMI model description", "no readable modelDescription.xml"),
            source=str(path),
        ) from None
    problems = validate_fmu(str(path))
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        first = " ".join(problems[0].split())
        raise ConfigError(f"fmpy validate: {first}{more}", source=str(path))
    platforms = fmpy.supported_platforms(str(path))
    if fmpy.platform not in platforms:
        raise ConfigError(
            f"no binary for {fmpy.platform} (it has: {', '.join(platforms) or 'none'})", source=str(path)
        )
    return ExternalFMU(path, file_sha256(path), description, description.model_name)


def _fmi_version(path: Path) -> tuple[str, bool]:
    """The ``fmiVersion`` of an FMU's modelDescription.xml and whether it offers co-simulation,
    read before fmpy parses it as a version it may not be (an FMI 3.0 file fails fmpy's FMI 2.0
    reading with a KeyError)."""
    from xml.etree import ElementTree as ET

    try:
        with zipfile.ZipFile(path) as zf:
            info = zf.getinfo("modelDescription.xml")
            if info.file_size > 64 << 20:
                raise ConfigError("modelDescription.xml larger than 64 MB", source=str(path))
            data = zf.read(info)
        if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
            raise ConfigError("modelDescription.xml with a document type declaration", source=str(path))
        root = ET.fromstring(data)
        return root.get("fmiVersion", "?"), root.find("CoSimulation") is not None
    except KeyError:
        raise ConfigError("no modelDescription.xml in the archive", source=str(path)) from None
    except (ET.ParseError, zipfile.BadZipFile, OSError) as exc:
        raise ConfigError(f"no readable modelDescription.xml: {exc}", source=str(path)) from None


def verified_path(model: str) -> Path:
    """The FMU file of the external ``model``, its content hashed again: the file checked."""
    from twin.fmu.toolchain import file_sha256

    path = Path(model)
    checked = check(path)
    if file_sha256(path) != checked.sha256:
        raise ConfigError("the FMU changed since it was checked: not loaded", source=str(path))
    return path
