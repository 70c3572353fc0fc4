"""An SSP archive opened safely: members confined to it, sizes bounded, XML read without any
document type (no entity expansion, no local file read) and validated against the SSP 1.0
schema that fmpy ships; its files unpacked once under the FMU cache.
"""

from __future__ import annotations

import os
import stat
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from twin.config.ssp.names import SSD_NAME
from twin.errors import ConfigError

__all__ = ["MAX_MEMBERS", "MAX_UNPACKED", "MAX_XML", "SCHEMAS", "Archive"]

#: most members and bytes an archive may unpack to (a zip bomb is refused, not unpacked)
MAX_MEMBERS = 256
MAX_UNPACKED = 2 << 30
#: the largest XML file read from an archive
MAX_XML = 16 << 20
#: the SSP 1.0 schema of each kind of file (fmpy ships them)
SCHEMAS = {
    "ssd": "SystemStructureDescription.xsd",
    "ssv": "SystemStructureParameterValues.xsd",
    "ssm": "SystemStructureParameterMapping.xsd",
}


def _regular(path: Path, source: str) -> None:
    """Only a regular file is opened: a FIFO or a device named .ssp would block the reader."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ConfigError(f"cannot read the archive: {exc.strerror or exc}", source=source) from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError("not a regular file (an SSP archive is a zip file)", source=source)


def _safe_members(zf: zipfile.ZipFile, source: str) -> list[zipfile.ZipInfo]:
    """The archive's members, refused when one would land outside it, two would land on the same
    path (a file and a folder of one name), or it unpacks too big."""
    members = zf.infolist()
    if len(members) > MAX_MEMBERS:
        raise ConfigError(f"{len(members)} members: more than {MAX_MEMBERS}", source=source)
    if sum(m.file_size for m in members) > MAX_UNPACKED:
        raise ConfigError(f"unpacks to more than {MAX_UNPACKED >> 30} GB", source=source)
    files = {m.filename for m in members if not m.is_dir()}
    for m in members:
        parts = PurePosixPath(m.filename).parts
        if m.filename.startswith(("/", "\\")) or ".." in parts or ":" in m.filename or "\\" in m.filename:
            raise ConfigError(f"member {m.filename!r} would land outside the archive's folder", source=source)
        for k in range(1, len(parts)):
            if "/".join(parts[:k]) in files:
                raise ConfigError(
                    f"member {m.filename!r} lies in {'/'.join(parts[:k])!r}, which is a file of the archive",
                    source=source,
                )
    return members


def _parser() -> Any:
    from lxml import etree

    # no entity is resolved and nothing is fetched; a document type is refused after parsing
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)


def validate(root: Any, kind: str, where: str, source: str) -> None:
    """``root`` against the SSP 1.0 schema of ``kind`` (ssd, ssv, ssm): one line naming
    ``where`` (the file, or the element an inline set sits in) with the first problem."""
    from fmpy.ssp.ssd import validate_tree

    try:
        validate_tree(root, SCHEMAS[kind])
    except Exception as exc:  # lxml's and fmpy's errors for a document that breaks the schema
        lines = [ln.strip() for ln in str(exc).splitlines()[1:] if ln.strip()]
        first = " ".join((lines[0] if lines else str(exc)).split())[:300]
        raise ConfigError(f"{where}: not valid SSP 1.0: {first}", source=source) from None


@dataclass
class Archive:
    """An opened SSP archive: its members' names, its XML files read on demand, its folder."""

    path: Path
    source: str
    members: list[zipfile.ZipInfo]
    folder: Path
    _xml: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def open(cls, path: Path) -> Archive:
        """The archive at ``path``, checked and unpacked (its ``SystemStructure.ssd`` read and
        validated)."""
        source = str(path)
        _regular(path, source)
        try:
            zf = zipfile.ZipFile(path)
        except (OSError, zipfile.BadZipFile) as exc:
            raise ConfigError(f"not an SSP archive: {exc}", source=source) from None
        with zf:
            members = _safe_members(zf, source)
            names = {m.filename for m in members}
            if SSD_NAME not in names:
                raise ConfigError(f"no {SSD_NAME} in the archive", source=source)
            xml = {m.filename: _read_xml(zf, m, source) for m in members if _is_xml(m.filename)}
            folder = _unpack(path, zf, members)
        archive = cls(path, source, members, folder, xml)
        validate(archive.xml(SSD_NAME), "ssd", SSD_NAME, source)
        return archive

    def has(self, name: str) -> bool:
        return any(m.filename == name for m in self.members)

    def xml(self, name: str) -> Any:
        """The root element of the archive's XML file ``name`` (a ConfigError if it has none)."""
        root = self._xml.get(name)
        if root is None:
            raise ConfigError(f"no {name} in the archive", source=self.source)
        return root

    def file(self, name: str) -> Path:
        """Where the member ``name`` is unpacked."""
        return self.folder / name


def _is_xml(name: str) -> bool:
    return name == SSD_NAME or name.endswith((".ssv", ".ssm"))


def _read_xml(zf: zipfile.ZipFile, info: zipfile.ZipInfo, source: str) -> Any:
    """One XML member parsed: bounded in size, no document type declaration, well-formed."""
    from lxml import etree

    name = info.filename
    if info.file_size > MAX_XML:
        raise ConfigError(f"{name}: larger than {MAX_XML >> 20} MB", source=source)
    data = zf.read(info)
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        raise ConfigError(
            f"{name}: not well-formed XML: {' '.join(str(exc).split())[:200]}", source=source
        ) from None
    info_ = root.getroottree().docinfo
    # no document type, in whatever encoding: an entity could expand without bound or read a file
    # of this machine
    if info_.doctype or info_.internalDTD is not None or info_.externalDTD is not None:
        raise ConfigError(f"{name}: XML with a document type declaration is not read", source=source)
    return root


def _unpack(path: Path, zf: zipfile.ZipFile, members: list[zipfile.ZipInfo]) -> Path:
    """The archive's files under the FMU cache, in a folder named by its SHA-256 (so a run of
    the same archive, a resume included, names the same FMU files)."""
    from twin.fmu.toolchain import file_sha256, private_cache_dir

    folder = private_cache_dir() / "ssp" / file_sha256(path)[:32]
    done = folder / ".complete"
    if done.is_file():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    for m in members:
        if m.is_dir():
            continue
        target = folder / m.filename
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
        with zf.open(m) as src, open(tmp, "wb") as dst:
            while block := src.read(1 << 20):
                dst.write(block)
        os.replace(tmp, target)
    done.write_text("ok\n")
    return folder
