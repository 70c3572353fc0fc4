"""The run folder: run.json, the checkpoint file, and the sinks it makes for a run."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from twin.errors import ConfigError
from twin.outputs.csv import write_signals_csv
from twin.outputs.plots import BudgetColumns
from twin.outputs.run_folder import CHECKPOINT_FILE, RUN_FILE, SIGNALS_CSV, Checkpoint, RunFolder, RunMeta

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
    }


def test_resumable_needs_run_json_and_a_checkpoint(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path)
    with pytest.raises(ConfigError, match=r"no run\.json: not a run folder"):
        folder.resumable()
    folder.start(RunMeta("/abs/s.toml"))
    with pytest.raises(ConfigError, match=r"no checkpoint\.pkl: the run saved no checkpoint"):
        folder.resumable()
    folder.save_checkpoint(Checkpoint({"tick": 1}, {}, "s"))
    assert folder.resumable() == RunMeta("/abs/s.toml")


def test_checkpoint_round_trip_in_the_pickle_format(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path)
    ckpt = Checkpoint({"tick": 7}, {"csv_position": [10, 1.5], "kept_time": np.arange(3.0)}, "constant-load")
    folder.save_checkpoint(ckpt)
    assert sorted(p.name for p in tmp_path.iterdir()) == [CHECKPOINT_FILE]  # no temporary left
    with open(folder.file(CHECKPOINT_FILE), "rb") as f:
        raw = pickle.load(f)
    assert list(raw) == ["master", "recorder", "scenario"]
    back = folder.load_checkpoint("constant-load")
    assert back.master == {"tick": 7} and back.scenario == "constant-load"
    np.testing.assert_array_equal(back.recorder["kept_time"], np.arange(3.0))
    with pytest.raises(ConfigError, match="belongs to another scenario"):
        folder.load_checkpoint("sine-load")


def test_resumed_sinks_cut_the_csv_back_to_the_checkpoint(tmp_path: Path) -> None:
    table = make_table(rows=20)
    folder = RunFolder(tmp_path)
    write_signals_csv(table, folder.file(SIGNALS_CSV))
    text = folder.file(SIGNALS_CSV).read_bytes()
    cut = text.index(b"\n", len(text) // 2) + 1
    ckpt = Checkpoint({}, {"csv_position": [cut, 0.0]}, "sample")
    plot = BudgetColumns("probe.reading", "errormodel.e_total", PARTS, [])
    sinks = folder.run_sinks(name="sample", late_signals=[], budget_view=[], plot=plot, resume=ckpt)
    assert folder.file(SIGNALS_CSV).read_bytes() == text[:cut]
    assert [type(s).__name__ for s in sinks] == [
        "SignalsCsvSink",
        "RecordingSink",
        "DerivedCsvSink",
        "ErrorBudgetSink",
        "SummarySink",  # last: its presence means the run is over
    ]
