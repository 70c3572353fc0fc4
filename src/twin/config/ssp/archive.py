"""An SSP archive opened safely: members confined to it, sizes bounded, XML read without any
document type (no entity expansion, no local file read) and validated against the SSP 1.0
schema that fmpy ships; its files unpacked once under the FMU cache.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import uuid
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.config.ssp.names import SSD_NAME
from twin.errors import ConfigError
from twin.fmu.safezip import (
    MAX_ARCHIVE_BYTES,
    MAX_MEMBERS,
    MAX_UNPACKED_BYTES,
    check_members,
    extract,
    open_regular,
    open_zip,
    read_member,
    safe_xml,
)

__all__ = ["MAX_MEMBERS", "MAX_UNPACKED", "MAX_XML", "SCHEMAS", "Archive", "discard_unpacked"]

#: most bytes an archive may unpack to (:mod:`twin.fmu.safezip` states every bound of a member)
MAX_UNPACKED = MAX_UNPACKED_BYTES
#: the largest XML file (.ssd, .ssv, .ssm) read from an archive: the twin's own export writes
#: about 40 KB, a system of a few hundred components a few MB
MAX_XML = 16 << 20
#: the SSP 1.0 schema of each kind of file (fmpy ships them)
SCHEMAS = {
    "ssd": "SystemStructureDescription.xsd",
    "ssv": "SystemStructureParameterValues.xsd",
    "ssm": "SystemStructureParameterMapping.xsd",
}
_WHAT = "an SSP archive is a zip file"

#: the cache folders this process unpacked, by archive: removed again when the archive is refused
_CREATED: dict[Path, Path] = {}


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
        validated); refused, it leaves nothing unpacked."""
        source = str(path)
        with open_regular(path, source, _WHAT, MAX_ARCHIVE_BYTES) as f:
            h = hashlib.sha256()
            while block := f.read(1 << 20):
                h.update(block)
            f.seek(0)
            with open_zip(f, source, "not an SSP archive") as zf:
                members = check_members(zf, source)
                names = {m.filename for m in members}
                if SSD_NAME not in names:
                    raise ConfigError(f"no {SSD_NAME} in the archive", source=source)
                xml = {m.filename: _read_xml(zf, m, source) for m in members if _is_xml(m.filename)}
                folder = _unpack(path, h.hexdigest(), zf, members)
        archive = cls(path, source, members, folder, xml)
        try:
            validate(archive.xml(SSD_NAME), "ssd", SSD_NAME, source)
        except BaseException:
            discard_unpacked(path)
            raise
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
    """One XML member parsed: bounded in size (its header and what it unpacks to), in UTF-8 or
    UTF-16, no document type declaration in whatever encoding (an entity could expand without
    bound or read a file of this machine), well-formed."""
    data = read_member(zf, info, source, MAX_XML)
    return safe_xml(data, info.filename, source)[1]


def _unpack(path: Path, sha256: str, zf: zipfile.ZipFile, members: list[zipfile.ZipInfo]) -> Path:
    """The archive's files under the FMU cache, in a folder named by its SHA-256 (so a run of
    the same archive, a resume included, names the same FMU files). Unpacked into a hidden
    folder of a unique name, then renamed: a failure (a member that unpacks to more than its
    header said, a full disk) leaves nothing, and two processes never write the same files."""
    from twin.fmu.toolchain import private_cache_dir

    parent = private_cache_dir() / "ssp"
    folder = parent / sha256[:32]
    if (folder / ".complete").is_file():
        return folder
    parent.mkdir(mode=0o700, exist_ok=True)
    tmp = parent / f".{sha256[:32]}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
    try:
        extract(zf, members, tmp, str(path))
        (tmp / ".complete").write_text("ok\n")
        if folder.exists() and not (folder / ".complete").is_file():
            shutil.rmtree(folder, ignore_errors=True)  # an older version's unfinished unpacking
        try:
            os.rename(tmp, folder)
        except OSError:
            if not (folder / ".complete").is_file():
                raise
            shutil.rmtree(tmp, ignore_errors=True)  # another process unpacked it meanwhile
            return folder
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _CREATED[path.resolve()] = folder
    return folder


def discard_unpacked(path: Path) -> None:
    """Remove what this process unpacked of the archive ``path`` into the cache: a refused
    archive leaves no copy behind (one unpacked by an earlier run that ran it stays)."""
    folder = _CREATED.pop(Path(path).resolve(), None)
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)
