"""The checkpoint file: the whole twin at one instant, stored as data that cannot run code.

A checkpoint (``checkpoint.npz``) is an uncompressed numpy archive whose parts are read as
plain numeric ``.npy`` data: nothing in it is ever unpickled or evaluated, so a run folder from
someone else can at worst be refused, never execute anything. Memory is bounded too: a part
must be stored uncompressed, within :data:`MAX_PART_BYTES`, its header's shape accounting for
exactly its bytes, and the manifest nests at most :data:`MAX_DEPTH` deep. It holds

- ``manifest``: UTF-8 JSON of the checkpoint's structure (plain JSON values; every numpy array
  and every byte string, such as an FMU's serialized state, stands there as a reference
  ``{"$array": "pN"}`` / ``{"$bytes": "pN"}``), with the format's name and version and, for
  each part, its dtype, shape and SHA-256;
- ``manifest_sha256``: the SHA-256 of the manifest's bytes;
- ``p0``, ``p1``, ...: the parts (numeric arrays only; byte strings as ``uint8``), stored uncompressed.

Reading checks everything before anything is used: the manifest's hash, format and version,
that the archive holds exactly the parts the manifest lists, and each part's dtype, shape and
hash. Any mismatch is a :class:`~twin.errors.CheckpointError` (exit code 2, one line).
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from twin.errors import CheckpointError
from twin.files import write_atomic
from twin.outputs.guard import open_output

FORMAT = "twin-checkpoint"
VERSION = 1
#: numpy kinds a part may have: booleans, integers, unsigned, floats (never objects)
_KINDS = set("biuf")


def _digest(array: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(f"{array.dtype.str}{array.shape}".encode())
    h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()


class _Encoder:
    """Plain JSON values from a checkpoint's dict, with arrays and bytes set aside as parts."""

    def __init__(self) -> None:
        self.parts: dict[str, np.ndarray] = {}

    def _part(self, array: np.ndarray, tag: str) -> dict[str, str]:
        if array.dtype.kind not in _KINDS:
            raise TypeError(f"cannot checkpoint an array of dtype {array.dtype}")
        name = f"p{len(self.parts)}"
        self.parts[name] = np.ascontiguousarray(array)
        return {tag: name}

    def encode(self, x: Any) -> Any:
        if isinstance(x, np.ndarray):
            return self._part(x, "$array")
        if isinstance(x, bytes | bytearray):
            return self._part(np.frombuffer(bytes(x), dtype=np.uint8), "$bytes")
        if isinstance(x, np.generic):
            return x.item()
        if isinstance(x, Mapping):
            if not all(isinstance(k, str) and not k.startswith("$") for k in x):
                raise TypeError("checkpoint keys must be strings not starting with '$'")
            return {k: self.encode(v) for k, v in x.items()}
        if isinstance(x, list | tuple):
            return [self.encode(v) for v in x]
        if x is None or isinstance(x, bool | int | float | str):
            return x
        raise TypeError(f"cannot checkpoint a {type(x).__name__}")


def save(path: Path, data: Mapping[str, Any]) -> None:
    """Write ``data`` to ``path`` atomically (a kill never leaves half a checkpoint)."""
    enc = _Encoder()
    body = enc.encode(data)
    manifest = {
        "format": FORMAT,
        "version": VERSION,
        "parts": {
            n: {"dtype": a.dtype.str, "shape": list(a.shape), "sha256": _digest(a)}
            for n, a in enc.parts.items()
        },
        "data": body,
    }
    raw = json.dumps(manifest, separators=(",", ":")).encode("utf-8")
    arrays = {
        "manifest": np.frombuffer(raw, dtype=np.uint8),
        "manifest_sha256": np.frombuffer(hashlib.sha256(raw).hexdigest().encode("ascii"), dtype=np.uint8),
        **enc.parts,
    }

    def write(tmp: Path) -> None:
        with open_output(tmp) as f:  # made exclusively by write_atomic: never a planted link
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())

    # a full disk: the last whole checkpoint stays, and the error names it
    write_atomic(path, write)


#: the largest manifest read (its JSON holds the structure only: the data are in the parts)
MAX_MANIFEST_BYTES = 16 * 2**20
#: the largest part read: a day's run at the shipped recording interval keeps well under this
#: in memory (kept_rows), and a part is read only after its size is checked against its header
MAX_PART_BYTES = 2**30
#: the deepest nesting of the manifest's data (a twin's is 4 deep; JSON parsing and decoding
#: recurse, so a crafted 100 000-deep manifest is refused before either)
MAX_DEPTH = 32


class _Archive:
    """The parts of a checkpoint's zip archive, read one by one with their sizes checked.

    ``np.savez`` stores its members uncompressed: a compressed member (a deflate bomb whose
    1 MB inflates to gigabytes) is refused from its header, and every member's size is checked
    against the limits and its own ``.npy`` header before its bytes are read."""

    def __init__(self, zf: zipfile.ZipFile, source: str) -> None:
        self.source = source
        self.zf = zf
        self.members: dict[str, zipfile.ZipInfo] = {}
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            if info.compress_type != zipfile.ZIP_STORED:
                raise CheckpointError(
                    f"part {name!r} is compressed: a twin checkpoint stores its parts as they are",
                    source=source,
                )
            if name in self.members:
                raise CheckpointError(f"part {name!r} appears twice", source=source)
            self.members[name] = info

    @property
    def files(self) -> list[str]:
        return list(self.members)

    def read(self, name: str, limit: int = MAX_PART_BYTES) -> np.ndarray:
        """One part as a read-only array: its header's dtype (numeric kinds only) and shape
        must account for exactly its stored bytes, at most ``limit``."""
        info = self.members[name]
        if info.file_size > limit:
            raise CheckpointError(
                f"part {name!r} holds {info.file_size} bytes, more than the {limit} a checkpoint part may",
                source=self.source,
            )
        with self.zf.open(info) as f:
            try:
                major, _ = np.lib.format.read_magic(f)
                read_header = (
                    np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
                )
                shape, fortran, dtype = read_header(f)
            except (ValueError, TypeError, SyntaxError) as exc:
                raise CheckpointError(
                    f"part {name!r}: not a numeric array ({exc})", source=self.source
                ) from None
            if dtype.kind not in _KINDS or dtype.hasobject or fortran:
                raise CheckpointError(
                    f"part {name!r}: dtype {dtype} is not a plain numeric array", source=self.source
                )
            count = 1
            for n in shape:
                count *= n  # Python integers: a header claiming 1e12 elements does not overflow
            size = info.file_size - f.tell()
            if count * dtype.itemsize != size:
                raise CheckpointError(
                    f"part {name!r}: its header claims {count} elements of {dtype.itemsize} bytes, it stores {size} bytes",
                    source=self.source,
                )
            data = f.read(size + 1)
        if len(data) != size:
            raise CheckpointError(f"part {name!r} is cut short", source=self.source)
        return np.frombuffer(data, dtype=dtype).reshape(shape)


def _depth(x: Any) -> int:
    """How deep ``x`` nests (lists and objects), found without recursion."""
    deepest, stack = 0, [(x, 1)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, level)
            if deepest > MAX_DEPTH:
                return deepest
            stack.extend((v, level + 1) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


def _manifest_bytes(archive: _Archive, source: str) -> bytes:
    """The manifest's bytes, at most :data:`MAX_MANIFEST_BYTES`, checked by their SHA-256."""
    for key in ("manifest", "manifest_sha256"):
        if key not in archive.files:
            raise CheckpointError(f"not a twin checkpoint (no {key})", source=source)
    raw = archive.read("manifest", MAX_MANIFEST_BYTES)
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise CheckpointError("malformed manifest", source=source)
    text = raw.tobytes()
    if hashlib.sha256(text).hexdigest().encode("ascii") != archive.read("manifest_sha256", 1024).tobytes():
        raise CheckpointError(
            "the manifest's SHA-256 does not match: the file was changed or damaged", source=source
        )
    return text


def _manifest(archive: _Archive, source: str) -> dict[str, Any]:
    text = _manifest_bytes(archive, source)
    try:
        manifest = json.loads(text.decode("utf-8"))
    except RecursionError:  # the parser recurses: a crafted 100 000-deep manifest ends here
        raise CheckpointError(f"manifest nested more than {MAX_DEPTH} deep", source=source) from None
    except (UnicodeDecodeError, ValueError):
        raise CheckpointError("malformed manifest", source=source) from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise CheckpointError("not a twin checkpoint", source=source)
    if manifest.get("version") != VERSION:
        raise CheckpointError(
            f"checkpoint version {manifest.get('version')!r}, this twin reads version {VERSION}",
            source=source,
        )
    if not isinstance(manifest.get("parts"), dict) or "data" not in manifest:
        raise CheckpointError("malformed manifest", source=source)
    if _depth(manifest["data"]) > MAX_DEPTH:
        raise CheckpointError(f"manifest nested more than {MAX_DEPTH} deep", source=source)
    return manifest


def _checked_parts(archive: _Archive, manifest: Mapping[str, Any], source: str) -> dict[str, np.ndarray]:
    listed = manifest["parts"]
    present = set(archive.files) - {"manifest", "manifest_sha256"}
    if present != set(listed):
        raise CheckpointError("the archive's parts differ from the manifest's list", source=source)
    parts = {}
    for name, meta in listed.items():
        if not isinstance(meta, dict):
            raise CheckpointError(f"part {name}: malformed", source=source)
        array = archive.read(name)
        if array.dtype.str != meta.get("dtype") or list(array.shape) != meta.get("shape"):
            raise CheckpointError(f"part {name}: dtype or shape differs from the manifest", source=source)
        if _digest(array) != meta.get("sha256"):
            raise CheckpointError(
                f"part {name}: SHA-256 does not match: the file was changed or damaged", source=source
            )
        parts[name] = array
    return parts


def _decode(x: Any, parts: Mapping[str, np.ndarray], source: str) -> Any:
    if isinstance(x, dict):
        if len(x) == 1 and next(iter(x)) in ("$array", "$bytes"):
            tag, name = next(iter(x.items()))
            if not isinstance(name, str) or name not in parts:
                raise CheckpointError(f"reference to a missing part {name!r}", source=source)
            return parts[name].copy() if tag == "$array" else parts[name].tobytes()
        return {k: _decode(v, parts, source) for k, v in x.items()}
    if isinstance(x, list):
        return [_decode(v, parts, source) for v in x]
    return x


def load(path: Path) -> dict[str, Any]:
    """Read and check a checkpoint; :class:`CheckpointError` when it cannot be trusted."""
    source = str(path)
    if not path.is_file():
        raise CheckpointError(
            "no checkpoint (the run was started without --checkpoint-every?)", source=source
        )
    try:
        with zipfile.ZipFile(path) as zf:
            archive = _Archive(zf, source)
            manifest = _manifest(archive, source)
            parts = _checked_parts(archive, manifest, source)
    except CheckpointError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        raise CheckpointError(f"unreadable: {type(exc).__name__}: {exc}", source=source) from None
    data = _decode(manifest["data"], parts, source)
    if not isinstance(data, dict):
        raise CheckpointError("malformed manifest", source=source)
    return data
