"""An FMU's shared library looked at before it is loaded: none of its code runs to say it is unfit.

Loading a library runs its constructors; a library that then lacks an FMI function fails in
fmpy with a traceback, after its code has run. On Linux the twin reads the library's ELF
headers first (:func:`check_library`): it must be a shared object for this machine's
architecture and class that exports every FMI 2.0 function fmpy binds (``fmi2CancelStep``
included). On other platforms the loader's own error is the line (:mod:`twin.fmu.slot`).
"""

from __future__ import annotations

import struct
import sys
from functools import cache

from twin.errors import ConfigError

__all__ = ["check_library", "required_functions"]

_ET_DYN = 3
_SHT_DYNSYM = 11
_SHN_UNDEF = 0


@cache
def required_functions() -> frozenset[str]:
    """The FMI 2.0 functions fmpy's co-simulation binding looks up in a library."""
    from fmpy.fmi2 import FMU2Slave

    return frozenset(n for n in dir(FMU2Slave) if n.startswith("fmi2"))


@cache
def _this_machine() -> tuple[int, int, int] | None:
    """(class, byte order, machine) of this Python's own executable, None when it is no ELF."""
    try:
        with open(sys.executable, "rb") as f:
            head = f.read(64)
    except OSError:
        return None
    if head[:4] != b"\x7fELF":
        return None
    order = "<" if head[5] == 1 else ">"
    return head[4], head[5], struct.unpack_from(order + "H", head, 18)[0]


def _exported(data: bytes, wide: bool, order: str) -> set[str] | None:
    """The names a shared object defines in its dynamic symbol table (None without sections)."""
    if wide:
        shoff, shentsize, shnum = (
            struct.unpack_from(order + "Q", data, 40)[0],
            *struct.unpack_from(order + "HH", data, 58),
        )
        sh, sym = order + "IIQQQQIIQQ", order + "IBBHQQ"
    else:
        shoff, shentsize, shnum = (
            struct.unpack_from(order + "I", data, 32)[0],
            *struct.unpack_from(order + "HH", data, 46),
        )
        sh, sym = order + "IIIIIIIIII", order + "IIIBBH"
    if not shoff or not shnum:
        return None
    sections = [struct.unpack_from(sh, data, shoff + i * shentsize) for i in range(shnum)]
    names: set[str] = set()
    for s in sections:
        if s[1] != _SHT_DYNSYM:
            continue
        offset, size, link, entsize = s[4], s[5], s[6], s[9]
        strtab = sections[link]
        str_off, str_size = strtab[4], strtab[5]
        for k in range(size // max(entsize, 1)):
            entry = struct.unpack_from(sym, data, offset + k * entsize)
            name_at = entry[0]
            shndx = entry[3] if wide else entry[5]
            if shndx == _SHN_UNDEF or name_at >= str_size:
                continue
            end = data.find(b"\0", str_off + name_at, str_off + str_size)
            names.add(data[str_off + name_at : end].decode("ascii", "replace"))
    return names


def check_library(data: bytes, member: str, source: str) -> None:
    """One line naming ``member`` of the FMU ``source`` when its bytes ``data`` are not a
    shared library this process can load as an FMI 2.0 co-simulation library (Linux: read from
    its ELF headers, nothing loaded; elsewhere nothing is checked here)."""
    if not sys.platform.startswith("linux"):
        return
    if data[:4] != b"\x7fELF":
        raise ConfigError(f"{member} is not a shared library (no ELF header)", source=source)
    here = _this_machine()
    try:
        order = "<" if data[5] == 1 else ">"
        e_type, machine = struct.unpack_from(order + "HH", data, 16)
        if here is not None and (data[4], data[5], machine) != here:
            raise ConfigError(
                f"{member} is built for another machine (ELF class {data[4]}, machine {machine}; "
                f"this one: class {here[0]}, machine {here[2]})",
                source=source,
            )
        if e_type != _ET_DYN:
            raise ConfigError(f"{member} is not a shared library (ELF type {e_type})", source=source)
        exported = _exported(data, data[4] == 2, order)
    except (struct.error, IndexError) as exc:
        raise ConfigError(f"{member} is not a readable ELF file ({exc})", source=source) from None
    if exported is None:
        return  # no section headers (stripped to the bone): the loader says what it lacks
    missing = sorted(required_functions() - exported)
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        raise ConfigError(
            f"{member} lacks {', '.join(missing[:3])}{more}: an FMI 2.0 co-simulation library "
            "exports every fmi2 function",
            source=source,
        )
