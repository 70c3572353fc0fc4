"""The checkpoint file: the whole twin at one instant, stored as data that cannot run code.

A checkpoint (``checkpoint.npz``) is an uncompressed numpy archive read with
``allow_pickle=False``: nothing in it is ever unpickled or evaluated, so a run folder from
someone else can at worst be refused, never execute anything. It holds

- ``manifest``: UTF-8 JSON of the checkpoint's structure (plain JSON values; every numpy array
  and every byte string, such as an FMU's serialized state, stands there as a reference
  ``{"$array": "pN"}`` / ``{"$bytes": "pN"}``), with the format's name and version and, for
  each part, its dtype, shape and SHA-256;
- ``manifest_sha256``: the SHA-256 of the manifest's bytes;
- ``p0``, ``p1``, ...: the parts (numeric arrays only; byte strings as ``uint8``).

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
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())

    # a full disk: the last whole checkpoint stays, and the error names it
    write_atomic(path, write)


def _manifest(archive: Any, source: str) -> dict[str, Any]:
    for key in ("manifest", "manifest_sha256"):
        if key not in archive.files:
            raise CheckpointError(f"not a twin checkpoint (no {key})", source=source)
    raw = archive["manifest"]
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise CheckpointError("malformed manifest", source=source)
    text = raw.tobytes()
    if hashlib.sha256(text).hexdigest().encode("ascii") != archive["manifest_sha256"].tobytes():
        raise CheckpointError(
            "the manifest's SHA-256 does not match: the file was changed or damaged", source=source
        )
    try:
        manifest = json.loads(text.decode("utf-8"))
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
    return manifest


def _checked_parts(archive: Any, manifest: Mapping[str, Any], source: str) -> dict[str, np.ndarray]:
    listed = manifest["parts"]
    present = set(archive.files) - {"manifest", "manifest_sha256"}
    if present != set(listed):
        raise CheckpointError("the archive's parts differ from the manifest's list", source=source)
    parts = {}
    for name, meta in listed.items():
        array = archive[name]
        if not isinstance(meta, dict) or array.dtype.kind not in _KINDS:
            raise CheckpointError(f"part {name}: malformed", source=source)
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
            if name not in parts:
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
        with np.load(path, allow_pickle=False) as archive:
            manifest = _manifest(archive, source)
            parts = _checked_parts(archive, manifest, source)
    except CheckpointError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"unreadable: {type(exc).__name__}: {exc}", source=source) from None
    data = _decode(manifest["data"], parts, source)
    if not isinstance(data, dict):
        raise CheckpointError("malformed manifest", source=source)
    return data
