"""Zip archives and XML from elsewhere (an FMU, an SSP archive) read within stated bounds.

An archive names its members and states their sizes in headers it controls; its XML names its
own encoding and may declare entities. Everything here treats them as untrusted:

- only a regular file is opened, and opened without blocking (a FIFO or ``/dev/zero`` named
  ``.fmu`` or ``.ssp`` would block a reader or never end): :func:`open_regular`;
- every member name is a plain relative path that lands inside the folder it is unpacked into
  (no absolute name, no ``..``, ``.`` or empty part, no colon or backslash, no control
  character, no part longer than a file system's 255 bytes), no name is given twice and no
  file is also a folder; a member is a regular file or a folder (a symbolic link, a device or a
  FIFO is refused), not encrypted: :func:`check_members`;
- sizes are capped from the headers (:data:`MAX_MEMBER_BYTES`, :data:`MAX_UNPACKED_BYTES`,
  :data:`MAX_RATIO`) and again while unpacking, since a header can lie: :func:`read_member`,
  :func:`extract`; a damaged member (a bad CRC, a broken deflate stream) is one line;
- XML is read in UTF-8 or UTF-16 only, and a document type declaration (whatever the
  encoding) is refused, so no entity expands and no file of this machine is read:
  :func:`safe_xml`.

Every refusal is one :class:`~twin.errors.ConfigError` line naming the archive (and the member).
"""

from __future__ import annotations

import codecs
import io
import os
import re
import stat
import zipfile
import zlib
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, BinaryIO

from twin.errors import ConfigError

__all__ = [
    "MAX_ARCHIVE_BYTES",
    "MAX_MEMBERS",
    "MAX_MEMBER_BYTES",
    "MAX_RATIO",
    "MAX_UNPACKED_BYTES",
    "check_members",
    "extract",
    "open_regular",
    "read_member",
    "safe_xml",
]

#: the largest archive file read: an FMU's library and resources (the twin's own FMUs are about
#: 50 KB, a large Modelica model's a few tens of MB); a bigger file is refused before it is read
MAX_ARCHIVE_BYTES = 512 << 20
#: the most members an archive may have (an FMU holds a handful of binaries, sources and
#: resources; each member unpacked is a file created)
MAX_MEMBERS = 4096
#: the largest one member may unpack to: a library or a resource table of a real model is at
#: most tens of MB, so 256 MB leaves room and still fits the memory of a small machine
MAX_MEMBER_BYTES = 256 << 20
#: the most an archive may unpack to in all, as much as the largest archive file read
MAX_UNPACKED_BYTES = 512 << 20
#: a member of more than :data:`RATIO_FLOOR` bytes may unpack to at most this many times its
#: packed size: deflate reaches about 1000:1 only on filler (a zip bomb), while libraries pack
#: 2-5:1 and text tables about 10:1; so what an archive costs stays proportional to its size
MAX_RATIO = 100
#: below this, a member's ratio is not asked (a small file of zeros packs 1000:1 and costs nothing)
RATIO_FLOOR = 1 << 20
#: a part of a member name (a file system's NAME_MAX) and a whole name, in bytes of UTF-8
MAX_PART_BYTES = 255
MAX_NAME_BYTES = 1024

_METHODS = {zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "LZMA"}
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def open_regular(path: Path, source: str, what: str, limit: int = MAX_ARCHIVE_BYTES) -> BinaryIO:
    """``path`` opened for reading when it is a regular file of at most ``limit`` bytes;
    ``what`` says what it should be (``"an FMU is a zip file"``). Opened without blocking and
    checked on the open descriptor, so a FIFO put in its place after a check cannot block."""
    flags = (
        os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    )
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", source=source) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ConfigError(f"is not a regular file ({what})", source=source)
        if st.st_size > limit:
            raise ConfigError(f"{st.st_size} bytes: larger than {limit >> 20} MB", source=source)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _name_problem(name: str) -> str | None:
    """What is wrong with a member's name, None when it is a plain relative path."""
    if not name:
        return "an empty name"
    if name.startswith(("/", "\\")):
        return "an absolute path (it would land outside the archive's folder)"
    if "\\" in name:
        return "a backslash in its name (zip names use '/')"
    if ":" in name:
        return "a colon in its name (a drive or device)"
    if _CONTROL.search(name):
        return "a control character in its name"
    if len(name.encode("utf-8", "surrogatepass")) > MAX_NAME_BYTES:
        return f"a name longer than {MAX_NAME_BYTES} bytes"
    parts = name.removesuffix("/").split("/")
    if ".." in parts:
        return "a '..' in its name (it would land outside the archive's folder)"
    if any(p in ("", ".") for p in parts):
        return "an empty or '.' part in its name (a name must say one path)"
    if any(len(p.encode("utf-8", "surrogatepass")) > MAX_PART_BYTES for p in parts):
        return f"a part of its name longer than {MAX_PART_BYTES} bytes"
    return None


def _kind_problem(info: zipfile.ZipInfo) -> str | None:
    """What kind of member it is when not a regular file or folder (its Unix mode, if any)."""
    mode = info.external_attr >> 16
    if info.create_system == 3 and mode:  # made on Unix: the mode says the file's type
        kind = stat.S_IFMT(mode)
        if kind == stat.S_IFLNK:
            return "a symbolic link (the twin unpacks regular files only)"
        if kind not in (0, stat.S_IFREG, stat.S_IFDIR):
            return "not a regular file (a device, FIFO or socket)"
    if info.flag_bits & 0x1:
        return "encrypted"
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        # FMI 2.0 (and SSP, which packs as FMI does) allows these two only; zipfile hands a bzip2
        # or LZMA decompressor a whole block at once, so a few KB of it unpack gigabytes in
        # memory before any size could be counted
        method = _METHODS.get(info.compress_type, f"compression method {info.compress_type}")
        return f"packed with {method}: FMUs and SSP archives are packed with deflate or stored"
    return None


def member_limit(info: zipfile.ZipInfo) -> int:
    """The most ``info`` may unpack to: :data:`MAX_MEMBER_BYTES`, and :data:`MAX_RATIO` times its
    packed size once above :data:`RATIO_FLOOR`."""
    return min(MAX_MEMBER_BYTES, max(RATIO_FLOOR, MAX_RATIO * info.compress_size))


def _size_problem(info: zipfile.ZipInfo) -> str | None:
    if info.file_size > MAX_MEMBER_BYTES:
        return f"unpacks to {info.file_size} bytes, more than {MAX_MEMBER_BYTES >> 20} MB"
    if info.file_size > member_limit(info):
        return (
            f"unpacks {info.compress_size} bytes to {info.file_size}, more than {MAX_RATIO} times "
            "(a zip bomb's ratio)"
        )
    return None


def open_zip(f: BinaryIO, source: str, what: str) -> zipfile.ZipFile:
    """The zip archive in ``f``; one line when it is none (``what``: ``"not an FMU"``)."""
    try:
        return zipfile.ZipFile(f)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
        raise ConfigError(f"{what}: not a readable zip file ({exc})", source=source) from None


def check_members(zf: zipfile.ZipFile, source: str) -> list[zipfile.ZipInfo]:
    """The archive's members, each checked (see the module); one line on the first problem."""
    members = zf.infolist()
    if len(members) > MAX_MEMBERS:
        raise ConfigError(f"{len(members)} members: more than {MAX_MEMBERS}", source=source)
    seen: set[str] = set()
    files: set[str] = set()
    total = 0
    for m in members:
        why = _name_problem(m.filename) or _kind_problem(m) or _size_problem(m)
        if why is not None:
            raise ConfigError(f"member {m.filename!r}: {why}", source=source)
        name = m.filename.removesuffix("/")
        if name in seen:
            raise ConfigError(f"member {m.filename!r}: the archive holds that name twice", source=source)
        seen.add(name)
        if not m.is_dir():
            files.add(name)
        total += m.file_size
    if total > MAX_UNPACKED_BYTES:
        raise ConfigError(f"unpacks to {total} bytes, more than {MAX_UNPACKED_BYTES >> 20} MB", source=source)
    _packed_within(zf, members, source)
    for name in seen:
        parts = name.split("/")
        for k in range(1, len(parts)):
            folder = "/".join(parts[:k])
            if folder in files:
                raise ConfigError(
                    f"member {name!r} lies in {folder!r}, which is a file of the archive", source=source
                )
    return members


def _packed_within(zf: zipfile.ZipFile, members: list[zipfile.ZipInfo], source: str) -> None:
    """The packed sizes the headers claim fit in the file, one after another: a header claiming
    more (to pass the ratio) or members sharing their bytes (a bomb of overlapping members,
    each unpacking the same data) are refused."""
    fp = zf.fp
    if fp is None:
        return
    here = fp.tell()
    size = fp.seek(0, io.SEEK_END)
    fp.seek(here)
    packed = sum(m.compress_size for m in members)
    if packed > size or any(m.header_offset + m.compress_size > size for m in members):
        raise ConfigError(
            f"its headers claim {packed} packed bytes in a file of {size}: members overlap or lie",
            source=source,
        )


def _damaged(info: zipfile.ZipInfo, exc: BaseException, source: str) -> ConfigError:
    why = " ".join(str(exc).split()) or type(exc).__name__
    return ConfigError(f"member {info.filename!r} is damaged: {why}", source=source)


#: what zipfile and its decompressors raise for a damaged member (a bad CRC, a broken stream)
_DAMAGE = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError, ValueError, OSError)


def copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, sink: Callable[[bytes], Any], source: str) -> int:
    """Unpack ``info`` block by block into ``sink``; the bytes unpacked. Refused once it unpacks
    to more than its limit (:func:`member_limit`), whatever its header said, or is damaged."""
    limit = member_limit(info)
    n = 0
    try:
        f = zf.open(info)
    except _DAMAGE as exc:
        raise _damaged(info, exc, source) from None
    with f:
        while True:
            try:  # only the reading: a sink's own error (a full disk) is not the member's damage
                block = f.read(1 << 20)
            except _DAMAGE as exc:
                raise _damaged(info, exc, source) from None
            if not block:
                return n
            n += len(block)
            if n > limit:
                raise ConfigError(
                    f"member {info.filename!r} unpacks to more than {limit} bytes (its header said {info.file_size})",
                    source=source,
                )
            sink(block)


def read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, source: str, limit: int | None = None) -> bytes:
    """One member's bytes, bounded (:func:`copy_member`, and ``limit`` when given: an XML file's)."""
    if limit is not None and info.file_size > limit:
        raise ConfigError(f"{info.filename}: larger than {limit >> 20} MB", source=source)
    out = io.BytesIO()

    def keep(block: bytes) -> None:
        if limit is not None and out.tell() + len(block) > limit:
            raise ConfigError(f"{info.filename}: unpacks to more than {limit >> 20} MB", source=source)
        out.write(block)

    copy_member(zf, info, keep, source)
    return out.getvalue()


def extract(zf: zipfile.ZipFile, members: Iterable[zipfile.ZipInfo], folder: Path, source: str) -> list[Path]:
    """Unpack the regular files of ``members`` (checked by :func:`check_members`) into the new,
    private ``folder`` (made here); the files written. Each is created anew (``O_EXCL``, never
    through a link) and the total is capped again as it is written."""
    folder.mkdir(mode=0o700)
    written, total = [], 0
    for m in members:
        if m.is_dir():
            continue
        target = folder.joinpath(*m.filename.split("/"))
        target.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        flags = (
            os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        )
        fd = os.open(target, flags, 0o600)
        with os.fdopen(fd, "wb") as out:
            total += copy_member(zf, m, out.write, source)
        written.append(target)
        if total > MAX_UNPACKED_BYTES:
            raise ConfigError(f"unpacks to more than {MAX_UNPACKED_BYTES >> 20} MB", source=source)
    return written


# ------------------------------------------------------------------------------------------ XML

#: the encodings XML is read in: FMI 2.0 and SSP 1.0 write UTF-8; UTF-16 is the other encoding
#: every XML reader must know (XML 1.0, 4.3.3)
_FAMILY = {"utf-8": "UTF-8", "utf8": "UTF-8", "utf-16": "UTF-16", "utf16": "UTF-16"}
_DECLARATION = re.compile(r"^<\?xml\s[^>]*?\?>")
_DECLARED = re.compile(r"""^<\?xml\s[^>]*?encoding\s*=\s*["']([^"']{0,40})["']""")


def _codec(data: bytes) -> str:
    """The Python codec of ``data``'s bytes: its byte order mark, else UTF-8's or UTF-16's
    first bytes (``<?``), else UTF-8 (ASCII's bytes; its declaration says more)."""
    if data.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        return "utf-32"
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "utf-16"
    if data.startswith(codecs.BOM_UTF8):
        return "utf-8-sig"
    return {b"<\x00?\x00": "utf-16-le", b"\x00<\x00?": "utf-16-be"}.get(data[:4], "utf-8")


def _declared(text: str, what: str, source: str) -> str | None:
    """The encoding family (``UTF-8``, ``UTF-16``) the declaration names, None for none;
    one line for any other."""
    declared = _DECLARED.match(text[:200])
    if declared is None:
        return None
    name = declared.group(1)
    family = _FAMILY.get(name.strip().lower().replace("_", "-"))
    if family is None:
        raise ConfigError(
            f"{what}: encoding {name!r}: the twin reads XML in UTF-8 or UTF-16 (FMI and SSP write UTF-8)",
            source=source,
        )
    return family


def safe_xml(data: bytes, what: str, source: str) -> tuple[bytes, Any]:
    """``data``, an XML document named ``what`` (``modelDescription.xml``), as UTF-8 bytes
    without an XML declaration, and its root element (lxml), read without any document type:
    one line when it is in another encoding than UTF-8 or UTF-16, is not valid in its
    encoding, is not well-formed or declares a document type (an entity could expand without
    bound or read a file of this machine). Any XML reader given the bytes returned (fmpy's
    included) then reads exactly what was checked."""
    from lxml import etree

    codec = _codec(data)
    family = "UTF-16" if codec.startswith("utf-16") else "UTF-8"
    if codec == "utf-32":
        raise ConfigError(f"{what}: encoded in UTF-32; the twin reads XML in UTF-8 or UTF-16", source=source)
    if family == "UTF-8":  # the declaration first: Shift_JIS's bytes are seldom valid UTF-8
        _declared(data[:200].decode("latin-1"), what, source)
    try:
        text = data.decode(codec)
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{what}: not valid {family}: {exc.reason} at byte {exc.start}", source=source
        ) from None
    declared = _declared(text.lstrip("\ufeff"), what, source)
    if declared not in (None, family):
        raise ConfigError(f"{what}: declares {declared} but is encoded in {family}", source=source)
    text = _DECLARATION.sub("", text.lstrip("\ufeff"), count=1)
    if "<!DOCTYPE" in text:  # before parsing: an entity it declares may stop the parse first
        raise ConfigError(f"{what}: XML with a document type declaration is not read", source=source)
    utf8 = text.encode("utf-8")
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        root = etree.fromstring(utf8, parser)
    except etree.XMLSyntaxError as exc:
        raise ConfigError(
            f"{what}: not well-formed XML: {' '.join(str(exc).split())[:200]}", source=source
        ) from None
    info = root.getroottree().docinfo
    if info.doctype or info.internalDTD is not None or info.externalDTD is not None:
        raise ConfigError(f"{what}: XML with a document type declaration is not read", source=source)
    return utf8, root
