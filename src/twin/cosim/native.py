"""The compiled stepper (``native/stepper.c``): building, loading and its ctypes structures.

Built with cmake like the FMUs and cached by a hash of its sources, so a fresh clone builds it
on first use. The master falls back to its Python reference loop only when asked to.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

from twin.errors import BuildError
from twin.fmu.build import _check_tools, cache_dir

SOURCES = Path(__file__).parent / "native"
LIBRARY = "twin_stepper"


class TwinSlot(ctypes.Structure):
    _fields_ = [
        ("comp", ctypes.c_void_p),
        ("set_real", ctypes.c_void_p),
        ("get_real", ctypes.c_void_p),
        ("do_step", ctypes.c_void_p),
        ("period_ticks", ctypes.c_int64),
        ("period_ns", ctypes.c_int64),
        ("n_in", ctypes.c_int32),
        ("n_out", ctypes.c_int32),
        ("in_vr", ctypes.c_void_p),
        ("in_val", ctypes.c_void_p),
        ("in_kind", ctypes.c_void_p),
        ("in_src", ctypes.c_void_p),
        ("in_idx", ctypes.c_void_p),
        ("delay_buf", ctypes.c_void_p),
        ("out_vr", ctypes.c_void_p),
        ("out_raw", ctypes.c_void_p),
        ("out_cur", ctypes.c_void_p),
        ("out_pending", ctypes.c_void_p),
        ("bias", ctypes.c_void_p),
        ("pending_at", ctypes.c_int64),
    ]


class TwinColumn(ctypes.Structure):
    _fields_ = [
        ("slot", ctypes.c_int32),
        ("kind", ctypes.c_int32),
        ("idx", ctypes.c_int32),
        ("pad", ctypes.c_int32),
    ]


class TwinCounters(ctypes.Structure):
    _fields_ = [
        ("macro_steps", ctypes.c_int64),
        ("fmu_steps", ctypes.c_int64),
        ("rows", ctypes.c_int64),
        ("fail_tick", ctypes.c_int64),
        ("fail_slot", ctypes.c_int32),
        ("fail_call", ctypes.c_int32),
        ("fail_status", ctypes.c_int32),
        ("pad", ctypes.c_int32),
    ]


CALLS = {1: "fmi2SetReal", 2: "fmi2DoStep", 3: "fmi2GetReal", 4: "fmi2GetReal"}
NON_FINITE = 4


def _digest() -> str:
    h = hashlib.sha256(b"stepper-1")
    for p in sorted(SOURCES.iterdir()):
        if p.is_file():
            h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:16]


def ensure_stepper() -> Path:
    """Path of the built stepper library, building it when its sources changed."""
    target = cache_dir() / f"{LIBRARY}-{_digest()}.so"
    if target.is_file():
        return target
    _, cmake = _check_tools()
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="twin-stepper-") as tmp:
        out = Path(tmp) / "out"
        for cmd in (
            [
                cmake,
                "-S",
                str(SOURCES),
                "-B",
                str(Path(tmp) / "build"),
                "-DCMAKE_BUILD_TYPE=Release",
                f"-DTWIN_OUT_DIR={out}",
            ],
            [cmake, "--build", str(Path(tmp) / "build"), "--target", "install"],
        ):
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-25:])
                raise BuildError(f"building the stepper failed:\n{tail}")
        built = next(out.glob(f"{LIBRARY}*"))
        tmp_target = target.with_name(target.name + f".{os.getpid()}.tmp")
        shutil.copyfile(built, tmp_target)
        os.replace(tmp_target, target)
    return target


@lru_cache(maxsize=1)
def stepper() -> ctypes.CDLL:
    """The loaded library with ``twin_run_ticks`` typed."""
    lib = ctypes.CDLL(str(ensure_stepper()))
    fn = lib.twin_run_ticks
    fn.argtypes = [
        ctypes.POINTER(TwinSlot),
        ctypes.c_int32,
        ctypes.c_int64,
        ctypes.c_int64,
        ctypes.c_int64,
        ctypes.c_int64,
        ctypes.c_void_p,
        ctypes.c_int32,
        ctypes.c_void_p,
        ctypes.c_int64,
        ctypes.POINTER(TwinColumn),
        ctypes.c_int32,
        ctypes.POINTER(TwinCounters),
    ]
    fn.restype = ctypes.c_int
    return lib
