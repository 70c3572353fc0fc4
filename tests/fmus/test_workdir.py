"""An FMU from elsewhere is extracted into a private folder per process, removed at exit; the
folders a killed process left are removed by the next twin process. An FMU the twin built loads
its library from the cache, where it was taken out once (:func:`twin.fmu.build.built_library`)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twin.fmu.build import ensure_fmu

HOLD = """
import sys, time
from pathlib import Path
from twin.fmu.slot import FMUSlot
slot = FMUSlot(Path(sys.argv[1]), "held")
print(slot.unzipdir, flush=True)
time.sleep(600)
"""

EXTRACT = """
import sys
from pathlib import Path
from twin.fmu.slot import FMUSlot
slot = FMUSlot(Path(sys.argv[1]), "once")
print(slot.unzipdir, flush=True)
slot.close()
"""


def _env(tmp: Path) -> dict[str, str]:
    return {**os.environ, "TMPDIR": str(tmp)}


def _foreign(folder: Path, model: str = "HydraulicLoader") -> Path:
    """A copy of a built FMU outside the cache: an FMU from elsewhere, as a lab's would be."""
    folder.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy(ensure_fmu(model), folder / f"{model}.fmu"))


def test_a_killed_process_leaves_no_extracted_fmu_behind_for_long(tmp_path: Path) -> None:
    fmu = str(_foreign(tmp_path / "lab"))
    held = subprocess.Popen(
        [sys.executable, "-c", HOLD, fmu], env=_env(tmp_path), stdout=subprocess.PIPE, text=True
    )
    try:
        unzipdir = Path(held.stdout.readline().strip())
        assert unzipdir.is_dir() and unzipdir.is_relative_to(tmp_path / f"twin-{os.getuid()}")
        assert (unzipdir.parent.parent.stat().st_mode & 0o777) == 0o700
    finally:
        held.send_signal(signal.SIGKILL)
        held.wait(timeout=30)
    assert unzipdir.is_dir()  # a SIGKILL runs no clean-up
    time.sleep(0.1)
    done = subprocess.run(
        [sys.executable, "-c", EXTRACT, fmu], env=_env(tmp_path), capture_output=True, text=True, check=True
    )
    assert not unzipdir.parent.exists(), "the killed process's folder is still there"
    own = Path(done.stdout.strip())
    assert not own.parent.exists(), "a process that ended normally left its folder"
    assert list((tmp_path / f"twin-{os.getuid()}").iterdir()) == []


@pytest.mark.parametrize("mode", [0o777, 0o755])
def test_a_shared_extraction_parent_is_refused(tmp_path: Path, mode: int) -> None:
    parent = tmp_path / f"twin-{os.getuid()}"
    parent.mkdir()
    os.chmod(parent, mode)
    done = subprocess.run(
        [sys.executable, "-c", EXTRACT, str(_foreign(tmp_path / "lab"))],
        env=_env(tmp_path), capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode != 0 and "is not a private folder of this user" in done.stderr


@pytest.mark.parametrize("origin", ["built", "foreign"])
def test_instances_of_one_fmu_file_share_one_library(tmp_path: Path, origin: str) -> None:
    """A run's or a sweep worker's instances of one FMU load one library: a built FMU's from
    the cache, a foreign one's from one folder, unpacked once."""
    from twin.fmu.slot import FMUSlot
    from twin.fmu.toolchain import private_cache_dir

    fmu = ensure_fmu("HydraulicLoader") if origin == "built" else _foreign(tmp_path / "lab")
    a, b = FMUSlot(fmu, "a"), FMUSlot(fmu, "b")
    try:
        assert a.library == b.library and Path(a.library).is_file()
        in_cache = Path(a.library).parent == private_cache_dir()
        assert in_cache == (origin == "built")
        # two instances, one library: each keeps its own state
        a.setup(0.0)
        b.setup(0.0)
        a.set_value("load_mean", 1.0)
        b.set_value("load_mean", 2.0)
        pa, pb = a.port(["load_mean"]), b.port(["load_mean"])
        for slot in (a, b):
            slot.enter_initialization()
            slot.exit_initialization()
        a.read(pa)
        b.read(pb)
        assert pa.values[0] == 1.0 and pb.values[0] == 2.0
    finally:
        a.close()
        b.close()
    assert Path(a.library).is_file()  # kept for the next instance (a foreign one's: until the process ends)


def test_only_what_an_instance_loads_is_unpacked(tmp_path: Path) -> None:
    """The library for this platform (and resources, had the FMU any), not the sources and
    documentation: each file and folder written costs a fresh process's set-up time."""
    import zipfile

    from fmpy import platform

    from twin.fmu.slot import FMUSlot

    fmu = _foreign(tmp_path / "lab", "ThermalNetwork")
    slot = FMUSlot(fmu, "t")
    try:
        root = Path(slot.unzipdir)
        unpacked = sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())
        assert unpacked == [f"binaries/{platform}/ThermalNetwork.so"]
        assert any(n.startswith("sources/") for n in zipfile.ZipFile(fmu).namelist())  # there, not unpacked
        slot.setup(0.0)  # and the instance runs
        slot.enter_initialization()
        slot.exit_initialization()
    finally:
        slot.close()
