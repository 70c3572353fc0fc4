"""The run folder: run.json, the checkpoint file, and the sinks it makes for a run."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from twin.errors import CheckpointError, ConfigError
from twin.outputs.csv import write_signals_csv
from twin.outputs.plots import BudgetColumns
from twin.outputs.run_folder import (
    CHECKPOINT_FILE,
    LEGACY_CHECKPOINT,
    LOCK_FILE,
    RUN_FILE,
    RUN_OUTPUTS,
    SIGNALS_CSV,
    Checkpoint,
    RunFolder,
    RunMeta,
    RunOutputs,
)

from .sample import PARTS, make_table


def test_start_writes_run_json_and_drops_an_old_checkpoint(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path / "a" / "run")
    folder.make()
    folder.file(CHECKPOINT_FILE).write_bytes(b"old")
    folder.start(RunMeta("/abs/s.toml", ("scenario.seed=3",), "reference", 3_600_000_000_000))
    assert not folder.file(CHECKPOINT_FILE).exists()
    assert json.loads(folder.file(RUN_FILE).read_text()) == {
        "scenario": "/abs/s.toml",
        "overrides": ["scenario.seed=3"],
        "loop": "reference",
        "checkpoint_every_ns": 3_600_000_000_000,
        "experiment": {},
        "record": None,
        "formats": [],
        "fmi_logging": False,
    }


def test_resumable_needs_run_json_and_a_checkpoint(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path)
    with pytest.raises(ConfigError, match=r"no run\.json: not a run folder"):
        folder.resumable()
    folder.start(RunMeta("/abs/s.toml"))
    with pytest.raises(ConfigError, match=r"no checkpoint\.npz: the run saved no checkpoint"):
        folder.resumable()
    folder.save_checkpoint(Checkpoint({"tick": 1}, {}, "s"))
    assert folder.resumable() == RunMeta("/abs/s.toml")


@pytest.mark.parametrize(
    "text",
    ["{", "[]", '{"scenario": 5}', '{"scenario": "/a.toml", "overrides": "x"}', '{"scenario": "/a", "loop": "x"}',
     '{"scenario": "/a", "checkpoint_every_ns": 1.5}', "\udcff"],
)  # fmt: skip
def test_malformed_run_json_is_one_line(tmp_path: Path, text: str) -> None:
    folder = RunFolder(tmp_path)
    folder.save_checkpoint(Checkpoint({"tick": 1}, {}, "s"))
    folder.file(RUN_FILE).write_text(text, encoding="utf-8", errors="surrogateescape")
    with pytest.raises(ConfigError) as err:
        folder.resumable()
    assert str(err.value).startswith(str(folder.file(RUN_FILE))) and "\n" not in str(err.value)


def _saved(tmp_path: Path, fingerprint: str = "f1") -> RunFolder:
    folder = RunFolder(tmp_path)
    folder.file(SIGNALS_CSV).write_bytes(b"time\n0.5\n1.5\n")  # 13 bytes, a header and two rows
    master = {
        "tick": 7,
        "instances": [{"state": b"\x00\x01fmu", "raw": np.arange(4.0)}],
        "driven": [("constant", 1.5)],
    }
    recorder = {"csv_position": [13, 1.5], "kept_time": np.arange(3.0), "kept_rows": np.zeros((3, 0))}
    folder.save_checkpoint(Checkpoint(master, recorder, "constant-load", fingerprint))
    return folder


def test_checkpoint_round_trip_as_checked_data(tmp_path: Path) -> None:
    folder = _saved(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [CHECKPOINT_FILE, SIGNALS_CSV]  # no temporary left
    with np.load(folder.file(CHECKPOINT_FILE), allow_pickle=False) as archive:  # plain arrays only
        assert {"manifest", "manifest_sha256"} <= set(archive.files)
    back = folder.load_checkpoint("constant-load", "f1", 0)
    assert back.master["tick"] == 7 and back.scenario == "constant-load" and back.fingerprint == "f1"
    assert back.master["instances"][0]["state"] == b"\x00\x01fmu"
    assert back.master["driven"] == [["constant", 1.5]]
    np.testing.assert_array_equal(back.master["instances"][0]["raw"], np.arange(4.0))
    np.testing.assert_array_equal(back.recorder["kept_time"], np.arange(3.0))
    assert back.recorder["kept_rows"].shape == (3, 0) and back.recorder["csv_position"] == [13, 1.5]
    with pytest.raises(CheckpointError, match="belongs to another scenario"):
        folder.load_checkpoint("sine-load", "f1", 0)
    with pytest.raises(CheckpointError, match=r"scenario .* changed since the checkpoint"):
        folder.load_checkpoint("constant-load", "f2", 0)
    with pytest.raises(CheckpointError, match=r"recorder.kept_rows: expected float64 of shape \(3, 2\)"):
        folder.load_checkpoint("constant-load", "f1", 2)  # a run keeping two columns
    folder.file(SIGNALS_CSV).write_bytes(b"time\n0.5\n1.5")
    with pytest.raises(CheckpointError, match=r"13 is not within signals.csv's rows \(bytes 5 to 12\)"):
        folder.load_checkpoint("constant-load", "f1", 0)


def _rewrite(path: Path, change: Callable[[dict[str, np.ndarray]], None]) -> None:
    with np.load(path, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    change(arrays)
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def _flip_part(a: dict[str, np.ndarray]) -> None:
    part = a["p0"].copy()
    part.view(np.uint8)[0] ^= 1
    a["p0"] = part


def _new_manifest(edit: Callable[[dict], None]) -> Callable[[dict[str, np.ndarray]], None]:
    def change(a: dict[str, np.ndarray]) -> None:
        manifest = json.loads(a["manifest"].tobytes())
        edit(manifest)
        raw = json.dumps(manifest).encode()
        a["manifest"] = np.frombuffer(raw, dtype=np.uint8)
        a["manifest_sha256"] = np.frombuffer(hashlib.sha256(raw).hexdigest().encode(), dtype=np.uint8)

    return change


BREAKS = {
    "a part's bit flipped": (_flip_part, "part p0: SHA-256 does not match"),
    "the manifest edited": (
        lambda a: a.update(manifest=a["manifest"][:-1]),
        "manifest's SHA-256 does not match",
    ),
    "a part removed": (lambda a: a.pop("p1"), "parts differ from the manifest"),
    "a part added": (lambda a: a.update(p99=np.zeros(2)), "parts differ from the manifest"),
    "an object array": (
        lambda a: a.update(p0=np.array([object()], dtype=object)),
        "dtype object is not a plain numeric array",
    ),
    "another version": (_new_manifest(lambda m: m.update(version=99)), "version 99"),
    "another format": (_new_manifest(lambda m: m.update(format="x")), "not a twin checkpoint"),
    "a dangling reference": (
        _new_manifest(lambda m: m["data"].update(master={"$bytes": "p77"})),
        "missing part",
    ),
    "a shape lie": (_new_manifest(lambda m: m["parts"]["p0"].update(shape=[1])), "dtype or shape differs"),
    "no manifest": (lambda a: a.pop("manifest"), "no manifest"),
}


@pytest.mark.parametrize("how", sorted(BREAKS))
def test_a_changed_checkpoint_is_refused(tmp_path: Path, how: str) -> None:
    folder = _saved(tmp_path)
    change, message = BREAKS[how]
    _rewrite(folder.file(CHECKPOINT_FILE), change)
    with pytest.raises(CheckpointError, match=message):
        folder.load_checkpoint("constant-load", "f1", 0)


@pytest.mark.parametrize("junk", [b"", b"PK\x03\x04junk", b"\x80\x05K\x01.", b"x" * 1000])
def test_a_file_that_is_no_checkpoint_is_refused(tmp_path: Path, junk: bytes) -> None:
    folder = RunFolder(tmp_path)
    folder.file(CHECKPOINT_FILE).write_bytes(junk)
    with pytest.raises(CheckpointError):
        folder.load_checkpoint("s", "f", 0)


class _Payload:
    """A pickle that, if it were ever loaded, would create a marker file."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return (Path.touch, (self.marker,))


def test_a_pickled_checkpoint_is_never_read(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path / "run")
    folder.start(RunMeta("/abs/s.toml"))
    marker = tmp_path / "pwned"
    folder.file(LEGACY_CHECKPOINT).write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(CheckpointError, match="is a pickle"):
        folder.resumable()
    # the same payload where the checkpoint lives now: refused as no checkpoint, never unpickled
    folder.file(CHECKPOINT_FILE).write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(CheckpointError):
        folder.load_checkpoint("s", "f", 0)
    # and a payload inside an otherwise valid archive (an object array holds a pickle)
    with open(folder.file(CHECKPOINT_FILE), "wb") as f:
        np.savez(f, manifest=np.array([_Payload(marker)], dtype=object))
    with pytest.raises(CheckpointError):
        folder.load_checkpoint("s", "f", 0)
    assert not marker.exists()


def test_resumed_sinks_cut_the_csv_back_to_the_checkpoint(tmp_path: Path) -> None:
    table = make_table(rows=20)
    folder = RunFolder(tmp_path)
    write_signals_csv(table, folder.file(SIGNALS_CSV))
    text = folder.file(SIGNALS_CSV).read_bytes()
    cut = text.index(b"\n", len(text) // 2) + 1
    ckpt = Checkpoint({}, {"csv_position": [cut, 0.0]}, "sample")
    plot = BudgetColumns("probe.reading", "errormodel.e_total", PARTS, [])
    sinks = folder.run_sinks(RunOutputs("sample", (), (), plot), resume=ckpt)
    # nothing is cut before the FMUs have taken their saved states: the CSV's sink opens after
    assert folder.file(SIGNALS_CSV).read_bytes() == text
    sinks[0].open([table.meta[n] for n in table.names()])
    sinks[0].fail(RuntimeError("stop"))
    assert folder.file(SIGNALS_CSV).read_bytes() == text[:cut]
    assert [type(s).__name__ for s in sinks] == [
        "SignalsCsvSink",
        "RecordingSink",
        "DerivedCsvSink",
        "ErrorBudgetSink",
        "SummarySink",  # last: its presence means the run is over
    ]


def test_a_short_runs_recording_closes_after_its_plots_when_a_helper_draws_them(tmp_path: Path) -> None:
    from twin.outputs.plot_process import PlotProcess

    folder = RunFolder(tmp_path)
    plot = BudgetColumns("probe.reading", "errormodel.e_total", PARTS, [])
    helper = PlotProcess()  # never started: only the order is asked of it

    def order(outputs: RunOutputs, process: PlotProcess | None) -> tuple[list[str], bool]:
        sinks = folder.run_sinks(outputs, plot_process=process)
        (recording,) = [s for s in sinks if type(s).__name__ == "RecordingSink"]
        return [type(s).__name__ for s in sinks], recording.hold

    written_at_once = ["SignalsCsvSink", "RecordingSink", "DerivedCsvSink", "ErrorBudgetSink", "SummarySink"]
    # a short run whose plots the helper draws: its rows wait in the recording's sink, which is
    # written once the plots are drawn (its memory after the helper's), summary.json still last
    assert order(RunOutputs("sample", (), (), plot), helper) == (
        ["SignalsCsvSink", "DerivedCsvSink", "ErrorBudgetSink", "RecordingSink", "SummarySink"],
        True,
    )
    # a long run's recording is written while it steps, and a run drawing its own plots has no
    # helper to wait for: the recording is written as the rows come, before the plots
    assert order(RunOutputs("sample", (), (), plot, long=True), helper) == (written_at_once, False)
    assert order(RunOutputs("sample", (), (), plot), None) == (written_at_once, False)


def _another_process_can_lock(folder: RunFolder) -> bool:
    probe = (
        "import fcntl, os, sys; fcntl.flock(os.open(sys.argv[1], os.O_RDWR), fcntl.LOCK_EX | fcntl.LOCK_NB)"
    )
    return (
        subprocess.run([sys.executable, "-c", probe, str(folder.file(LOCK_FILE))], check=False).returncode
        == 0
    )


def test_the_lock_is_held_until_it_is_let_go_and_refuses_a_second_holder(tmp_path: Path) -> None:
    command, other = RunFolder(tmp_path / "run"), RunFolder(tmp_path / "run")
    command.lock()
    command.lock()  # taken once: a second call holds nothing more
    assert command.file(LOCK_FILE).read_text() == f"{os.getpid()}\n"
    assert not _another_process_can_lock(command)
    with pytest.raises(ConfigError, match=f"in use by another twin process \\(pid {os.getpid()}\\)"):
        other.lock()  # a second holder, even in this process: a run is prepared once
    command.unlock()
    command.unlock()  # idempotent
    assert _another_process_can_lock(command)


def test_start_removes_an_earlier_runs_files_and_leftovers_but_not_the_users(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path)
    names = [*RUN_OUTPUTS, ".summary.json.77.deadbeef.tmp", ".run.json.1.00000000.tmp"]
    for name in [*names, "notes.txt", ".notes.txt.1.tmp", "summary.json.bak"]:
        folder.file(name).write_text("earlier")
    folder.start(RunMeta("/abs/s.toml"))
    left = {".notes.txt.1.tmp", RUN_FILE, "notes.txt", "summary.json.bak"}
    assert {p.name for p in tmp_path.iterdir()} == left
