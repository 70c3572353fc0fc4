"""What decides a study's rows, as digests by name: a resumed sweep (or held-out run) must be
the very same study, and when it is not, the one line refusing it names what changed.

A study's rows depend on its own file (the design, its fixed overrides, its outputs), on the
base scenario and every file that scenario reads (the files it ``extends``, its FMUs'
parameter files, its coefficients and spreads files, an input's table file), and on the code
that runs a point (the twin's version, the FMUs' and the stepper's source hashes). Each is
recorded under a name a user recognises (``sweep.set``, ``file scenarios/sine-load.toml``,
``FMU sources``) in the folder's ``sweep.json``; :func:`changed` compares two records.

TOML files are digested as their parsed data (a comment or a blank line decides no row);
any other file as its bytes.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

__all__ = ["changed", "code_digests", "digest", "file_digests", "scenario_files"]

#: the most files one scenario may name for its record (an extends chain of 16, a few
#: parameter files each): a bound, so a crafted file cannot make the record unbounded
MAX_FILES = 256


def digest(value: Any) -> str:
    """A short hash of a JSON-able value (dict keys sorted)."""
    text = json.dumps(value, sort_keys=True, default=repr, ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()[:16]


def _file_digest(path: Path) -> str:
    data = path.read_bytes()
    if path.suffix == ".toml":
        try:
            return digest(tomllib.loads(data.decode("utf-8")))
        except (UnicodeDecodeError, tomllib.TOMLDecodeError):
            pass  # not TOML after all: its bytes decide
    return hashlib.sha256(data).hexdigest()[:16]


def _strings(data: Any) -> Iterator[str]:
    if isinstance(data, str):
        yield data
    elif isinstance(data, Mapping):
        for v in data.values():
            yield from _strings(v)
    elif isinstance(data, list):
        for v in data:
            yield from _strings(v)


def _named_files(path: Path) -> list[Path]:
    """The files one scenario file names: its ``extends`` and every string value that is the
    name of an existing file beside it (parameter files, coefficients, spreads, tables)."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return []  # an SSP archive or a single FMU: its own bytes are its record
    folder = path.resolve().parent
    out = []
    for text in _strings(data):
        if not text or len(text) > 4096 or "\0" in text:
            continue
        try:
            candidate = (folder / text).resolve()
            if candidate.is_file():
                out.append(candidate)
        except (OSError, ValueError):
            continue
    return out


def scenario_files(path: str | Path) -> list[Path]:
    """The scenario file ``path`` and every file it names, and they name, in a fixed order:
    what its points read. When the scenario names no coefficients file, the committed default
    (the error model's) is among them."""
    from twin.errormodel.coefficients import default_path

    start = Path(path).resolve()
    seen: dict[Path, None] = {}
    todo = [start]
    while todo and len(seen) < MAX_FILES:
        p = todo.pop(0)
        if p in seen:
            continue
        seen[p] = None
        if p.suffix == ".toml":
            todo.extend(_named_files(p))
    if not any(_names_coefficients(p) for p in seen if p.suffix == ".toml"):
        seen[default_path().resolve()] = None
    return list(seen)


def _names_coefficients(path: Path) -> bool:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    em = data.get("errormodel")
    return isinstance(em, dict) and "coefficients" in em


def _shown(path: Path) -> str:
    """A file's name as a user knows it: relative to the current folder when inside it."""
    try:
        return str(path.relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def file_digests(paths: list[Path]) -> dict[str, str]:
    """``{"file <name>": digest}`` of each file (a file gone since: ``"missing"``)."""
    out = {}
    for p in paths:
        try:
            out[f"file {_shown(p)}"] = _file_digest(p)
        except OSError:
            out[f"file {_shown(p)}"] = "missing"
    return out


def code_digests() -> dict[str, str]:
    """The twin's version and the source hashes of its FMUs and stepper: the code of a point."""
    from twin import __version__
    from twin.cosim.native import stepper_sources
    from twin.fmu.build import source_hash
    from twin.fmu.catalog import model_names
    from twin.fmu.toolchain import content_hash

    sources = {m: source_hash(m) for m in model_names()}
    sources["stepper"] = content_hash(stepper_sources())
    return {"twin version": __version__, "FMU sources": digest(sources)}


def changed(old: Any, new: Mapping[str, str]) -> str | None:
    """What differs between a folder's record ``old`` and the study's ``new``, as a phrase
    naming the first few (None: the same study)."""
    if not isinstance(old, Mapping):
        return "its sweep.json holds no record of its inputs (written by an older twin)"
    names = [k for k in new if old.get(k) != new[k]]
    names += [k for k in old if k not in new]
    if not names:
        return None
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return f"{shown} changed since it ran"
