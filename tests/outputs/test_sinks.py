"""The sinks of a run and the tee that feeds them, without a co-simulation.

The sample table plays a run: its recorded columns stream through a TeeRecorder in the
master's batches, its ``errormodel.*`` columns are the outcome's derived columns.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import twin.signals.recorder as recorder_module
from twin.outputs.csv import DerivedCsvSink, SignalsCsvSink, read_signals_csv, write_signals_csv
from twin.outputs.plot_sinks import ErrorBudgetSink
from twin.outputs.plots import BudgetColumns
from twin.outputs.recording_sink import RecordingSink
from twin.outputs.rerun_rec import entity_path, read_recording, recorded_unit
from twin.outputs.sink import Outcome, Sink
from twin.outputs.summary import SummarySink
from twin.signals.recorder import TeeRecorder
from twin.signals.table import Block, Signal, SignalTable

from .sample import PARTS, make_table

DERIVED = ("errormodel.e_total", *PARTS.values())
PLOT = BudgetColumns("probe.reading", "errormodel.e_total", PARTS, ["thermal.t_base", "thermal.no_such"])


class Log(Sink):
    """A sink that writes down what it is told."""

    def __init__(self, events: list[tuple[str, Any]] | None = None, name: str = "log") -> None:
        self.events = events if events is not None else []
        self.name = name
        self.path = Path(name)

    def open(self, signals: list[Signal]) -> None:
        self.events.append((self.name, "open", [s.name for s in signals]))

    def write(self, block: Block) -> None:
        self.events.append((self.name, "write", block.time.copy(), dict(block.columns)))

    def close(self, outcome: Outcome) -> None:
        self.events.append((self.name, "close", outcome.summary()))

    def fail(self, error: BaseException) -> None:
        self.events.append((self.name, "fail", error))


def recorded(table: SignalTable) -> tuple[list[Signal], SignalTable]:
    """The sample's recorded part (what a master would record) and its derived part."""
    names = [n for n in table.names() if n not in DERIVED]
    return [table.meta[n] for n in names], table.subset(names)


def stream(rec: TeeRecorder, table: SignalTable, batch: int = 50) -> None:
    """Feed ``table`` to ``rec`` as the master does: open, batches of rows (in a reused array), close."""
    rec.open([table.meta[n] for n in table.names()])
    rows = np.empty((batch, len(table.names())))
    for start in range(0, len(table), batch):
        stop = min(start + batch, len(table))
        for j, name in enumerate(table.names()):
            rows[: stop - start, j] = table[name][start:stop]
        rec.append(table.time[start:stop], rows[: stop - start])
    rec.close()


def test_tee_hands_every_row_to_each_sink_in_flush_sized_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(recorder_module, "FLUSH_ROWS", 200)
    _, table = recorded(make_table())
    events: list[tuple[str, Any]] = []
    rec = TeeRecorder([Log(events, "a"), Log(events, "b")], keep={"probe.reading"}.__contains__)
    stream(rec, table)
    assert [e[:2] for e in events[:2]] == [("a", "open"), ("b", "open")]
    writes = [e for e in events if e[1] == "write"]
    # blocks of at least FLUSH_ROWS rows (the master's batches are 50), the rest at close
    sizes = [len(e[2]) for e in writes if e[0] == "a"]
    assert sizes == [200, 200, 200, 121]
    for sink in ("a", "b"):
        got = [e for e in writes if e[0] == sink]
        np.testing.assert_array_equal(np.concatenate([e[2] for e in got]), table.time)
        for name in table.names():
            np.testing.assert_array_equal(np.concatenate([e[3][name] for e in got]), table[name])
    assert not [e for e in events if e[1] in ("close", "fail")]  # the sinks close with the outcome
    kept = rec.table()
    assert kept.names() == ["probe.reading"]
    np.testing.assert_array_equal(kept["probe.reading"], table["probe.reading"])


def test_tee_flushes_after_flush_seconds_even_with_few_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(recorder_module, "FLUSH_SECONDS", 0.0)
    _, table = recorded(make_table(rows=120))
    log = Log()
    stream(TeeRecorder([log]), table, batch=40)
    assert [len(e[2]) for e in log.events if e[1] == "write"] == [40, 40, 40]


def test_tee_holding_the_last_rows_gives_a_short_runs_rows_when_asked() -> None:
    # every row within FLUSH_ROWS and FLUSH_SECONDS: twin run writes them once the plots are sent
    _, table = recorded(make_table())
    log = Log()
    rec = TeeRecorder([log], hold_last=True)
    stream(rec, table)
    assert [e[1] for e in log.events] == ["open"]
    rec.flush()
    writes = [e for e in log.events if e[1] == "write"]
    assert [len(e[2]) for e in writes] == [len(table)]
    np.testing.assert_array_equal(writes[0][2], table.time)
    rec.flush()  # nothing left: nothing written twice
    assert len([e for e in log.events if e[1] == "write"]) == 1


def test_tee_holds_nothing_of_a_run_whose_rows_went_to_the_files_already(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a long run's files are open by its end: its last rows go at once, not beside the error model
    monkeypatch.setattr(recorder_module, "FLUSH_ROWS", 200)
    _, table = recorded(make_table())
    log = Log()
    stream(TeeRecorder([log], hold_last=True), table)
    assert [len(e[2]) for e in log.events if e[1] == "write"] == [200, 200, 200, 121]


class Full(Log):
    """A sink on a full disk: each write is noted, then fails."""

    def write(self, block: Block) -> None:
        super().write(block)
        raise OSError(28, "No space left on device")


def test_tee_hands_a_failing_block_to_no_sink_twice() -> None:
    _, table = recorded(make_table(rows=30))

    first, full = Log(name="csv"), Full(name="rrd")
    rec = TeeRecorder([first, full])
    with pytest.raises(OSError):
        stream(rec, table)
    rec.flush()  # as the run's failure path does: the block is not handed to the CSV again
    assert [e[0] for e in first.events + full.events if e[1] == "write"] == ["csv", "rrd"]


class Gated(Log):
    """A sink whose writes (of ``rows`` rows; any, by default) wait for ``release``, noting
    the thread each write comes from."""

    def __init__(self, rows: int | None = None) -> None:
        super().__init__()
        self.rows, self.release = rows, threading.Event()
        self.threads: list[str] = []

    def write(self, block: Block) -> None:
        self.threads.append(threading.current_thread().name)
        if self.rows is None or len(block.time) == self.rows:
            assert self.release.wait(10.0)
        super().write(block)


def test_tee_writes_a_chunk_while_the_run_goes_and_waits_for_it_before_the_next(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a chunk handed on while the run goes is written by a thread: append returns before the
    # sink is done; the next chunk, a checkpoint and the run's end wait for it
    monkeypatch.setattr(recorder_module, "FLUSH_ROWS", 100)
    _, table = recorded(make_table(rows=300))
    slow = Gated()
    release, writing = slow.release, slow.threads
    rec = TeeRecorder([slow])
    rec.open([table.meta[n] for n in table.names()])
    names = table.names()
    rows = np.column_stack([table[n] for n in names])
    rec.append(table.time[:100], rows[:100])  # a whole chunk: handed to the writer thread
    assert not [e for e in slow.events if e[1] == "write"]  # append did not wait for the sink
    release.set()
    rec.append(table.time[100:250], rows[100:250])  # waits for the first chunk, hands on the next
    rec.checkpoint()  # waits for the chunk being written: every row written is in the files
    writes = [e for e in slow.events if e[1] == "write"]
    assert [len(e[2]) for e in writes] == [100, 150]
    assert writing[0] != threading.main_thread().name
    rec.append(table.time[250:], rows[250:])
    rec.close()  # the rest written here, before the sinks are closed
    np.testing.assert_array_equal(np.concatenate([e[2] for e in slow.events if e[1] == "write"]), table.time)


def test_a_long_runs_last_rows_are_written_while_the_caller_goes_on_and_flush_waits_for_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(recorder_module, "FLUSH_ROWS", 100)
    _, table = recorded(make_table(rows=250))
    slow = Gated(rows=50)  # the last rows, handed on at close
    release = slow.release
    rec = TeeRecorder([slow], hold_last=True)
    stream(rec, table, batch=50)  # 100, 100 while it runs; the last 50 at close
    assert [len(e[2]) for e in slow.events if e[1] == "write"] == [100, 100]  # close did not wait
    release.set()
    rec.flush()  # what twin run does before any sink closes
    writes = [e for e in slow.events if e[1] == "write"]
    np.testing.assert_array_equal(np.concatenate([e[2] for e in writes]), table.time)


def test_tee_raises_a_failed_write_of_its_thread_and_writes_nothing_after_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a full disk under the writer thread: the next rows raise its error (as a write that failed
    # at once would) and are not written; the run's failure path hands nothing on after it
    monkeypatch.setattr(recorder_module, "FLUSH_ROWS", 100)
    _, table = recorded(make_table(rows=300))

    first, full = Log(name="csv"), Full(name="rrd")
    rec = TeeRecorder([first, full])
    with pytest.raises(OSError, match="No space left"):
        stream(rec, table, batch=100)
    rec.flush()  # the run's failure path (stages._hand_on)
    assert [e[0] for e in first.events + full.events if e[1] == "write"] == ["csv", "rrd"]
    assert [len(e[2]) for e in first.events if e[1] == "write"] == [100]


def test_the_held_rows_go_to_the_files_after_the_plots_start_and_before_any_file_closes() -> None:
    from twin.pipeline import RunControls
    from twin.pipeline.stages import OutputsLog, write_outputs

    _, table = recorded(make_table(rows=30))
    events: list[tuple[str, Any]] = []

    class Plot(Log):
        def begin(self, outcome: Outcome) -> bool:
            self.events.append((self.name, "begin"))
            return True

    rec = TeeRecorder([Log(events, "csv"), Plot(events, "png")], hold_last=True)
    stream(rec, table)
    write_outputs(rec.sinks, Outcome(None, (), dict), RunControls(), OutputsLog(), held=rec)
    assert [e[:2] for e in events] == [
        ("csv", "open"),
        ("png", "open"),
        ("png", "begin"),
        ("csv", "write"),
        ("png", "write"),
        ("csv", "close"),
        ("png", "close"),
    ]


@pytest.mark.parametrize("stopped", [False, True])
def test_a_stop_while_a_plot_is_drawn_writes_the_data_files_after_it_before_waiting(stopped: bool) -> None:
    from twin.pipeline import RunControls
    from twin.pipeline.stages import OutputsLog, write_outputs

    events: list[tuple[str, Any]] = []
    begun: list[bool] = []

    class Plot(Log):
        skippable = True

        def begin(self, outcome: Outcome) -> bool:
            begun.append(True)
            return True

    # in a short run's order: the recording after the plot it waits for, the summary last
    sinks = [Log(events, "csv"), Plot(events, "png"), Log(events, "rec"), Log(events, "summary")]
    controls = RunControls(stop=lambda: "SIGINT" if stopped and begun else None)
    log = OutputsLog()
    write_outputs(sinks, Outcome(None, (), dict), controls, log)
    closed = [e[0] for e in events if e[1] == "close"]
    if stopped:  # the begun plot is still waited for, after the data it would have held up
        assert closed == ["csv", "rec", "png", "summary"]
    else:
        assert closed == ["csv", "png", "rec", "summary"]
    assert log.skipped == []


def test_tee_without_sinks_keeps_only_the_kept_columns() -> None:
    _, table = recorded(make_table())
    rec = TeeRecorder(keep={"thermal.t_base", "probe.reading"}.__contains__)
    stream(rec, table)
    kept = rec.table()
    assert kept.names() == ["thermal.t_base", "probe.reading"]


def test_tee_checkpoint_says_where_each_sink_stands_and_resumes_the_kept_rows(tmp_path: Path) -> None:
    _, table = recorded(make_table(rows=100))
    keep = {"probe.reading"}.__contains__
    rec = TeeRecorder([SignalsCsvSink(tmp_path / "signals.csv"), Log()], keep=keep)
    stream(rec, table)
    part = rec.checkpoint()
    assert list(part) == ["csv_position", "kept_time", "kept_rows"]  # the checkpoint's format
    assert part["csv_position"] == [(tmp_path / "signals.csv").stat().st_size, float(table.time[-1])]
    np.testing.assert_array_equal(part["kept_rows"][:, 0], table["probe.reading"])
    again = TeeRecorder(keep=keep, resume=part)
    again.open([table.meta[n] for n in table.names()])
    np.testing.assert_array_equal(again.table()["probe.reading"], table["probe.reading"])


def run_sinks(tmp_path: Path) -> list[Any]:
    return [
        SignalsCsvSink(tmp_path / "signals.csv"),
        RecordingSink(
            tmp_path / "recording.rrd",
            recording_name="sample",
            late_signals=[make_table().meta[n] for n in DERIVED],
            budget_columns=list(DERIVED),
        ),
        DerivedCsvSink(tmp_path / "errormodel.csv"),
        ErrorBudgetSink(tmp_path / "error_budget.png", PLOT, "sample"),
        SummarySink(tmp_path / "summary.json"),
    ]


def test_a_runs_sinks_write_the_streamed_rows_and_the_outcome(tmp_path: Path) -> None:
    full = make_table()
    _, table = recorded(full)
    sinks = run_sinks(tmp_path)
    stream(TeeRecorder(sinks), table)
    asked: list[int] = []

    def summary() -> dict[str, Any]:
        asked.append(1)
        # made when the last sink asks: every other file is written by then
        assert (tmp_path / "error_budget.png").exists() and (tmp_path / "errormodel.csv").exists()
        return {"scenario": "sample", "status": "completed"}

    outcome = Outcome(full, DERIVED, summary)
    for sink in sinks:
        sink.close(outcome)
    assert len(asked) == 1
    # streamed in blocks, the CSV has the bytes of the table written at once
    write_signals_csv(table, tmp_path / "whole.csv")
    assert (tmp_path / "signals.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    derived = read_signals_csv(tmp_path / "errormodel.csv")
    assert derived.names() == list(DERIVED)
    np.testing.assert_array_equal(derived["errormodel.e_total"], full["errormodel.e_total"])
    series = read_recording(tmp_path / "recording.rrd")
    for name in ("probe.reading", "errormodel.e_total"):  # streamed, and derived after the run
        t, v = series[entity_path(full.meta[name])]
        np.testing.assert_array_equal(t, full.time)
        np.testing.assert_array_equal(v, full[name] * 1e6)  # lengths recorded in µm
    assert (tmp_path / "error_budget.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((tmp_path / "summary.json").read_text()) == {
        "scenario": "sample",
        "status": "completed",
    }


def test_without_an_error_model_only_the_rows_and_the_summary_are_written(tmp_path: Path) -> None:
    _, table = recorded(make_table())
    sinks = run_sinks(tmp_path)
    stream(TeeRecorder(sinks), table)
    for sink in sinks:
        sink.close(Outcome(None, (), lambda: {"status": "failed"}))
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "recording.rrd",
        "signals.csv",
        "signals.units.json",
        "summary.json",
    ]
    series = read_recording(tmp_path / "recording.rrd")
    assert entity_path(table.meta["probe.reading"]) in series


def test_the_recording_is_made_with_its_first_rows_or_when_the_run_ends_without_any(tmp_path: Path) -> None:
    signals, _ = recorded(make_table())
    sink = RecordingSink(tmp_path / "recording.rrd", recording_name="r", budget_columns=["probe.reading"])
    sink.open(signals)
    assert not (tmp_path / "recording.rrd").exists()  # rerun loads with the first rows
    sink.fail(RuntimeError("the run broke before its first rows"))
    assert read_recording(tmp_path / "recording.rrd") == {}  # a whole (footed) recording, empty
    with pytest.raises(ValueError, match="budget columns"):  # checked at open, not with the rows
        RecordingSink(tmp_path / "b.rrd", recording_name="r", budget_columns=["no.such"]).open(signals)


def _held_sink(tmp_path: Path, full: SignalTable) -> RecordingSink:
    sink = RecordingSink(
        tmp_path / "recording.rrd", recording_name="r", late_signals=[full.meta[n] for n in DERIVED]
    )
    sink.hold = True
    return sink


def _assert_recorded(path: Path, full: SignalTable, names: tuple[str, ...]) -> None:
    series = read_recording(path)
    for name in names:
        t, v = series[entity_path(full.meta[name])]
        np.testing.assert_array_equal(t, full.time)
        np.testing.assert_array_equal(v, full[name] * recorded_unit(full.meta[name])[1])


def _held_rows(tmp_path: Path, rows: int) -> tuple[SignalTable, RecordingSink]:
    """A held recording's sink once the outputs began and the run's rows were handed to it."""
    full = make_table(rows=rows)
    _, table = recorded(full)
    sink = _held_sink(tmp_path, full)
    rec = TeeRecorder([sink], hold_last=True)
    stream(rec, table, batch=7)
    assert sink.begin(Outcome(full, DERIVED, dict)) is False  # nothing of it made elsewhere
    rec.flush()  # the rows the run held for its outputs
    return full, sink


def test_a_held_recording_is_written_when_it_closes_with_the_rows_and_the_outcome(tmp_path: Path) -> None:
    import sys

    full, sink = _held_rows(tmp_path, 40)
    # rerun is loaded with the rows (beside the plots' drawing), the file is not begun
    assert "twin.outputs.rerun_rec" in sys.modules
    assert not (tmp_path / "recording.rrd").exists()
    sink.close(Outcome(full, DERIVED, dict))
    _assert_recorded(
        tmp_path / "recording.rrd", full, ("probe.reading", "thermal.t_base", "errormodel.e_total")
    )


def test_rows_that_came_while_the_run_went_are_written_as_they_came_held_or_not(tmp_path: Path) -> None:
    full = make_table(rows=40)
    _, table = recorded(full)
    sink = _held_sink(tmp_path, full)
    sink.open([table.meta[n] for n in table.names()])
    sink.write(Block(table.time[:10], {n: table[n][:10] for n in table.names()}))  # while it runs
    assert (tmp_path / "recording.rrd").exists()  # streamed: a killed run keeps them
    outcome = Outcome(full, DERIVED, dict)
    sink.begin(outcome)
    sink.write(Block(table.time[10:], {n: table[n][10:] for n in table.names()}))  # the file is open
    sink.close(outcome)
    _assert_recorded(tmp_path / "recording.rrd", full, ("probe.reading", "errormodel.e_total"))


def test_a_held_recording_keeps_its_rows_and_the_outcome_when_the_run_fails_before_it_closes(
    tmp_path: Path,
) -> None:
    full, sink = _held_rows(tmp_path, 25)
    sink.fail(RuntimeError("the plot failed"))  # before the sink's close, as a plot's failure would
    sink.fail(RuntimeError("again"))  # harmless
    # as a recording written before the plots: the rows, and the error model's columns
    _assert_recorded(tmp_path / "recording.rrd", full, ("probe.reading", "errormodel.e_total"))


def test_a_held_recording_writes_nothing_more_on_a_full_disk(tmp_path: Path) -> None:
    import errno

    full, sink = _held_rows(tmp_path, 25)
    sink.fail(OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "errormodel.csv")))
    sink.close(Outcome(full, DERIVED, dict))  # after a failure: nothing either
    # the rows are in signals.csv; the space left is the failed summary's
    assert not (tmp_path / "recording.rrd").exists()


def test_fail_keeps_what_was_written_and_writes_nothing_new(tmp_path: Path) -> None:
    _, table = recorded(make_table())
    sinks = run_sinks(tmp_path)
    stream(TeeRecorder(sinks), table)
    error = RuntimeError("the error model broke")
    for sink in sinks:
        sink.fail(error)
        sink.fail(error)  # twice, or after close: harmless
    assert len(read_signals_csv(tmp_path / "signals.csv")) == len(table)
    assert not (tmp_path / "summary.json").exists() and not (tmp_path / "errormodel.csv").exists()
    series = read_recording(tmp_path / "recording.rrd")  # closed: readable to its end
    np.testing.assert_array_equal(series[entity_path(table.meta["probe.reading"])][0], table.time)
