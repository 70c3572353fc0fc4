"""Hostile run folders, checkpoints and output folders, through the real command line.

Every case is generated here, from one real run: a link planted where a command writes, a
checkpoint whose checksums are valid but whose values are crafted, a deflate bomb, a header
claiming 10^12 elements, a manifest nested 100 000 deep. Each ends in exit 2 and one line
naming the file (and the checkpoint's key), or is handled correctly; nothing outside the
chosen folder changes, and a refused resume changes nothing of the run folder.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from twin.outputs import checkpoint_file

from .cli import REPO, one_line, twin

pytestmark = pytest.mark.slow

CONSTANT = str(REPO / "scenarios" / "constant-load.toml")
#: a 20-min run with a checkpoint at 10 min: 12 000 ticks of 0.1 s, the checkpoint at tick 6000
RUN_ARGS = ("--set", 'scenario.duration="20 min"', "--checkpoint-every", "10 min")
N_TICKS = 12_000
VICTIM = b"a file outside the run folder\n"


@pytest.fixture(scope="module")
def checkpointed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder as a kill leaves it: a checkpoint at 10 min, no summary.json."""
    out = tmp_path_factory.mktemp("ck") / "run"
    proc = twin("run", CONSTANT, "--quiet", "--out", str(out), *RUN_ARGS)
    assert proc.returncode == 0, proc.stderr
    (out / "summary.json").unlink()
    return out


@pytest.fixture
def killed(checkpointed: Path, tmp_path: Path) -> Path:
    """A fresh copy of the killed run's folder."""
    out = tmp_path / "run"
    shutil.copytree(checkpointed, out)
    return out


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.name != ".twin.lock"}


def _crafted(folder: Path, mutate: Callable[[dict[str, Any]], None]) -> None:
    """The folder's checkpoint with ``mutate`` applied, saved with valid checksums."""
    data = checkpoint_file.load(folder / "checkpoint.npz")
    mutate(data)
    (folder / "checkpoint.npz").unlink()
    checkpoint_file.save(folder / "checkpoint.npz", data)


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """Set the dotted ``path`` (list indexes as numbers) of a checkpoint's data to ``value``."""

    def mutate(data: dict[str, Any]) -> None:
        *head, last = [int(k) if k.isdigit() else k for k in path.split(".")]
        node: Any = data
        for k in head:
            node = node[k]
        node[last] = value

    return mutate


CRAFTED = {
    # the tick: of no number kind, before the start, beyond the end, beyond any counter
    "tick-nan": ("master.tick", float("nan"), "master.tick"),
    "tick-inf": ("master.tick", float("inf"), "master.tick"),
    "tick-string": ("master.tick", "abc", "master.tick"),
    "tick-negative": ("master.tick", -1, "master.tick"),
    "tick-beyond-the-end": ("master.tick", N_TICKS + 1, "master.tick"),
    "tick-2^70": ("master.tick", 2**70, "master.tick"),
    "counter-negative": ("master.fmu_steps", -5, "master.fmu_steps"),
    # where signals.csv continues: -1, 0 (would empty it), beyond its end, not a row's end
    "csv-position-minus-1": ("recorder.csv_position", [-1, 599.0], "recorder.csv_position"),
    "csv-position-0": ("recorder.csv_position", [0, 0.0], "recorder.csv_position"),
    "csv-position-beyond": ("recorder.csv_position", [10**9, 599.0], "recorder.csv_position"),
    "csv-position-mid-row": ("recorder.csv_position", [1000, 599.0], "recorder.csv_position"),
    "csv-position-string": ("recorder.csv_position", ["1000", 599.0], "recorder.csv_position"),
    # driven inputs of the wrong kind and shape
    "driven-kind": ("master.driven.0", ["bogus", 1], "master.driven[0]"),
    "driven-shape": ("master.driven.0", ["ramp", 1.0], "master.driven[0]"),
    "driven-profile-index": ("master.driven.0", ["profile", 99], "master.driven[0]"),
    "driven-not-a-list": ("master.driven", {"a": 1}, "master.driven"),
    # buffers of the wrong dtype or shape
    "buffer-dtype": ("master.instances.0.raw", np.zeros(5, dtype=np.int32), "master.instances[0].raw"),
    "buffer-shape": ("master.instances.0.raw", np.zeros(7), "master.instances[0].raw"),
    "buffer-not-an-array": ("master.instances.0.cur", 3.0, "master.instances[0].cur"),
    "instance-name": ("master.instances.0.name", "intruder", "master.instances[0].name"),
    "kept-rows-shape": ("recorder.kept_rows", np.zeros((3, 2)), "recorder.kept_rows"),
    # an FMU state the FMU refuses: found after every check, still before the folder changes
    "fmu-state": ("master.instances.0.state", b"not a state", "state"),
}


@pytest.mark.parametrize("case", sorted(CRAFTED))
def test_a_crafted_checkpoint_value_is_refused_and_the_folder_unchanged(killed: Path, case: str) -> None:
    path, value, key = CRAFTED[case]
    _crafted(killed, _set(path, value))
    before = _snapshot(killed)
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert "checkpoint.npz" in line and key in line, line
    assert _snapshot(killed) == before  # signals.csv not cut, nothing written


def _rezip(folder: Path, members: dict[str, tuple[bytes, int]]) -> None:
    """checkpoint.npz rebuilt with ``members`` (name -> (bytes, compression)) put in place."""
    path = folder / "checkpoint.npz"
    with zipfile.ZipFile(path) as zf:
        old = {i.filename: (zf.read(i), zipfile.ZIP_STORED) for i in zf.infolist()}
    path.unlink()
    with zipfile.ZipFile(path, "w") as zf:
        for name, (data, compression) in {**old, **members}.items():
            zf.writestr(name, data, compress_type=compression)


def _npy(array: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


def test_a_deflate_bomb_part_is_refused_from_its_header(killed: Path) -> None:
    """A part deflated from 200 MB of zeros (a 1 MB file could reach gigabytes): refused
    before it is inflated, because a twin checkpoint stores its parts as they are."""
    bomb = _npy(np.zeros(25 * 2**20))  # 200 MB of float64, about 200 KB deflated
    _rezip(killed, {"p0.npy": (bomb, zipfile.ZIP_DEFLATED)})
    assert (killed / "checkpoint.npz").stat().st_size < 2 * 2**20
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert "checkpoint.npz" in line and "'p0' is compressed" in line, line


def test_a_header_claiming_a_trillion_elements_is_refused_before_reading(killed: Path) -> None:
    import io

    buf = io.BytesIO()  # a valid .npy header of shape (10^12,), then 8 bytes

    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    fake = buf.getvalue() + b"\0" * 8
    _rezip(killed, {"p0.npy": (fake, zipfile.ZIP_STORED)})
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert "checkpoint.npz" in line and "1000000000000 elements" in line, line


def test_a_manifest_nested_100_000_deep_is_refused(killed: Path) -> None:
    depth = 100_000
    raw = (
        b'{"format":"twin-checkpoint","version":1,"parts":{},"data":{"master":'
        + b"[" * depth
        + b"]" * depth
        + b"}}"
    )
    with open(killed / "checkpoint.npz", "wb") as f:
        np.savez(
            f,
            manifest=np.frombuffer(raw, dtype=np.uint8),
            manifest_sha256=np.frombuffer(hashlib.sha256(raw).hexdigest().encode(), dtype=np.uint8),
        )
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert "checkpoint.npz" in line and "nested more than 32 deep" in line, line


def test_a_completed_run_is_not_resumed(checkpointed: Path, tmp_path: Path) -> None:
    """A resume of a completed run says so (exit 2): its files are not rewritten."""
    out = tmp_path / "done"
    shutil.copytree(checkpointed, out)
    (out / "summary.json").write_text(json.dumps({"status": "completed"}))
    before = _snapshot(out)
    line = one_line(twin("resume", str(out), "--quiet"))
    assert "completed" in line and str(out) in line, line
    assert _snapshot(out) == before


def test_an_untouched_checkpoint_still_resumes(killed: Path) -> None:
    """The checks refuse only what is crafted: the run's own checkpoint resumes, completed."""
    proc = twin("resume", str(killed), "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((killed / "summary.json").read_text())["status"] == "completed"


# -- links planted where a command writes ---------------------------------------------------


@pytest.mark.parametrize(
    "name", [".twin.lock", "signals.csv", "errormodel.csv", "recording.rrd", "checkpoint.npz.tmp", "wear.png"]
)
def test_twin_run_writes_through_no_planted_link(tmp_path: Path, name: str) -> None:
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.write_bytes(VICTIM)
    (out / name).symlink_to(victim)
    line = one_line(twin("run", CONSTANT, "--quiet", "--force", "--out", str(out), *RUN_ARGS))
    assert str(out / name) in line and "symbolic link" in line, line
    assert victim.read_bytes() == VICTIM


@pytest.mark.parametrize(
    "name", ["signals.csv", "errormodel.csv", "recording.rrd", ".twin.lock", "error_budget.png"]
)
def test_twin_resume_writes_through_no_planted_link(killed: Path, tmp_path: Path, name: str) -> None:
    victim = tmp_path / "victim"
    victim.write_bytes((killed / name).read_bytes() if (killed / name).exists() else VICTIM)
    (killed / name).unlink(missing_ok=True)
    (killed / name).symlink_to(victim)
    before = victim.read_bytes()
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert str(killed / name) in line and "symbolic link" in line, line
    assert victim.read_bytes() == before


def test_twin_compensate_writes_through_no_planted_link(checkpointed: Path, tmp_path: Path) -> None:
    out, victim = tmp_path / "comp", tmp_path / "victim"
    out.mkdir()
    victim.write_bytes(VICTIM)
    for name in ("errormodel.csv", "flagged_rows.csv"):
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(victim)
        line = one_line(twin("compensate", str(checkpointed / "signals.csv"), "--out", str(out)))
        assert str(out / name) in line and "symbolic link" in line, line
        assert victim.read_bytes() == VICTIM
        (out / name).unlink()


def test_compensate_template_never_writes_through_a_dangling_link(tmp_path: Path) -> None:
    folder, victim = tmp_path / "tpl", tmp_path / "victim.toml"
    folder.mkdir()
    (folder / "LAB.toml").symlink_to(victim)  # dangling: exists() is False
    line = one_line(twin("compensate", "--template", str(folder)))
    assert "LAB.toml" in line and not victim.exists(), line


@pytest.mark.parametrize("planted", ["histogram.png", "runs"])
def test_twin_sweep_writes_through_no_planted_link(tmp_path: Path, planted: str) -> None:
    out, victim = tmp_path / "sweep", tmp_path / "victim"
    out.mkdir()
    if planted == "runs":
        victim.mkdir()
    else:
        victim.write_bytes(VICTIM)
    (out / planted).symlink_to(victim)
    spec = tmp_path / "s.toml"
    spec.write_text(
        f'[sweep]\nbase = "{CONSTANT}"\ndesign = "lhs"\nsamples = 2\nseed = 1\nrun_folders = true\n'
        'set = [\'scenario.duration = "2 min"\']\noutputs = ["drift_mm.predicted"]\n'
        '[problem]\nnames = ["input.thermal.t_room.value"]\nbounds = [[293.0, 294.0]]\n',
        encoding="utf-8",
    )
    line = one_line(twin("sweep", str(spec), "--out", str(out), "--quiet", "--workers", "1"))
    assert str(out / planted) in line and "symbolic link" in line, line
    assert (victim.read_bytes() == VICTIM) if planted != "runs" else not any(victim.iterdir())


# -- exit 2, not 1 -----------------------------------------------------------------------------


@pytest.mark.parametrize("where", ["afile", "/proc/x"])
def test_build_out_that_cannot_be_a_folder_is_bad_input(tmp_path: Path, where: str) -> None:
    target = tmp_path / where if where == "afile" else Path(where)
    if where == "afile":
        target.write_text("x")
    line = one_line(twin("build", "--out", str(target)))
    assert "--out" in line, line


def test_compensate_template_on_a_file_is_bad_input(tmp_path: Path) -> None:
    target = tmp_path / "afile"
    target.write_text("x")
    line = one_line(twin("compensate", "--template", str(target)))
    assert "--template" in line and str(target) in line, line


def test_a_crafted_override_in_run_json_is_said_of_run_json(killed: Path) -> None:
    meta = json.loads((killed / "run.json").read_text())
    (killed / "run.json").write_text(json.dumps({**meta, "overrides": ["scenario.bogus=1"]}))
    before = _snapshot(killed)
    line = one_line(twin("resume", str(killed), "--quiet"))
    assert line.startswith(f"twin: {killed / 'run.json'}: overrides of ") and "scenario.bogus" in line, line
    assert _snapshot(killed) == before
