"""The plots' own process: the same bytes as drawing in the run's process, a run that still gets
its plots when the helper cannot start or dies, a failing plot as one RunError, a malformed job
refused, and no helper left behind."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twin.errors import RunError
from twin.outputs import plots
from twin.outputs.plot_process import PlotProcess, columns_json, thinned
from twin.outputs.plot_sinks import ErrorBudgetSink, WearPlotSink
from twin.outputs.plots import BudgetColumns
from twin.outputs.sink import Outcome
from twin.pipeline import RunControls
from twin.pipeline.stages import OutputsLog, write_outputs
from twin.signals.table import Signal, SignalTable

from .sample import PARTS, make_table

TITLE = "a run: predicted error and its parts"


def _table() -> SignalTable:
    # more rows than the plots draw whole: the plots thin it, and so must the helper's input
    table = make_table(rows=5003)
    n = len(table.time)
    table.add(Signal("errormodel.wear_compensated", "m", "errormodel"), np.linspace(0.0, 3e-5, n))
    table.add(Signal("mechanics.wear_depth_true", "m", "mechanics"), np.linspace(0.0, 3.1e-5, n))
    table.add(Signal("oscillation.cycles", "1", "oscillation"), np.arange(n) * 1.7)
    return table


def _columns() -> BudgetColumns:
    return BudgetColumns(
        reading="probe.reading",
        predicted="errormodel.e_total",
        parts=PARTS,
        temperatures={"base": "thermal.t_base", "spindle": "thermal.t_spindle", "room": "thermal.t_room"},
        compensated="errormodel.wear_compensated",
        true_wear="mechanics.wear_depth_true",
        cycles="oscillation.cycles",
        wear_limit_m=1.52e-4,
        # what only a scenario gives (a factor off, a replayed experiment): through JSON too
        disabled=("fluctuating",),
        measured_drift_m=-2.1e-5,
        measured_by="Li et al. 2017",
    )


def _outcome(table: SignalTable) -> Outcome:
    return Outcome(table, (), lambda: {})


def _draw_both(tmp: Path, process: PlotProcess | None) -> dict[str, bytes]:
    """Both plots of the sample into the new folder ``tmp``; name -> bytes."""
    tmp.mkdir()
    sinks = [
        ErrorBudgetSink(tmp / "error_budget.png", _columns(), TITLE, process),
        WearPlotSink(tmp / "wear.png", _columns(), "a run: wear against swing cycles", process),
    ]
    outcome = _outcome(_table())
    for sink in sinks:
        sink.open([])
    for sink in sinks:
        sink.close(outcome)
    return {p.name: p.read_bytes() for p in sorted(tmp.glob("*.png"))}


@pytest.fixture
def here(tmp_path: Path) -> dict[str, bytes]:
    """The plots drawn in this process, as a run without a helper draws them."""
    return _draw_both(tmp_path / "here", None)


def test_the_helper_draws_the_same_bytes_as_the_run_itself(
    here: dict[str, bytes], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # from here on, drawing in this process fails: the files below come from the helper alone
    monkeypatch.setattr(plots, "save_png", lambda *a: pytest.fail("drawn in the run's process"))
    process = PlotProcess()
    process.start()
    helper = _draw_both(tmp_path / "helper", process)
    assert sorted(helper) == ["error_budget.png", "wear.png"]
    assert helper == here
    assert not process.running  # both sinks closed: the helper ended


def test_a_plot_sent_when_the_outcome_is_known_is_drawn_meanwhile_and_waited_for_at_close(
    here: dict[str, bytes], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(plots, "save_png", lambda *a: pytest.fail("drawn in the run's process"))
    out = tmp_path / "sent"
    out.mkdir()
    process = PlotProcess()
    process.start()
    budget = ErrorBudgetSink(out / "error_budget.png", _columns(), TITLE, process)
    wear = WearPlotSink(out / "wear.png", _columns(), "a run: wear against swing cycles", process)
    outcome = _outcome(_table())
    assert budget.begin(outcome)
    assert process.pending == out / "error_budget.png"
    # one plot at a time: a second one would fill the pipe and block the run until the first
    # is drawn; it is sent at its close instead
    assert not wear.begin(outcome)
    budget.close(outcome)
    assert process.pending is None
    wear.close(outcome)
    assert {p.name: p.read_bytes() for p in sorted(out.glob("*.png"))} == here
    assert not process.running


def test_a_stop_after_a_plot_was_sent_waits_for_it_and_skips_the_plots_not_sent(
    here: dict[str, bytes], tmp_path: Path
) -> None:
    out = tmp_path / "stopped"
    out.mkdir()
    process = PlotProcess()
    process.start()
    sinks = [
        ErrorBudgetSink(out / "error_budget.png", _columns(), TITLE, process),
        WearPlotSink(out / "wear.png", _columns(), "a run: wear against swing cycles", process),
    ]
    asked: list[str] = []

    def stop() -> str | None:  # Ctrl-C comes in once the plots are handed out
        asked.append("stop?")
        return "SIGINT" if len(asked) > 2 else None

    table = _table()
    log = OutputsLog()
    write_outputs(sinks, Outcome(table, (), dict), RunControls(stop=stop), log)
    assert log.skipped == ["wear.png"]
    assert {p.name: p.read_bytes() for p in out.glob("*.png")} == {
        "error_budget.png": here["error_budget.png"]
    }
    for sink in sinks:
        sink.fail(RuntimeError("the run is over"))  # as the run lets its sinks go
    assert not process.running


@pytest.mark.parametrize("when", ["while it draws", "once it is drawn"])
def test_a_run_that_fails_after_sending_its_plot_abandons_it(tmp_path: Path, when: str) -> None:
    import time

    out = tmp_path / "failed"
    out.mkdir()
    process = PlotProcess()
    process.start()
    budget = ErrorBudgetSink(out / "error_budget.png", _columns(), TITLE, process)
    assert budget.begin(_outcome(_table()))
    if when == "once it is drawn":
        deadline = time.monotonic() + 60
        while not (out / "error_budget.png").exists():
            assert time.monotonic() < deadline, "the helper never drew the plot"
            time.sleep(0.02)
    budget.fail(OSError(28, "No space left on device"))  # say recording.rrd failed to close
    assert not process.running
    assert list(out.iterdir()) == []  # neither the PNG nor a temporary file of it


def test_a_sent_plot_whose_helper_dies_is_drawn_in_the_run(here: dict[str, bytes], tmp_path: Path) -> None:
    out = tmp_path / "died"
    out.mkdir()
    process = PlotProcess()
    process.start()
    budget = ErrorBudgetSink(out / "error_budget.png", _columns(), TITLE, process)
    outcome = _outcome(_table())
    assert budget.begin(outcome)
    assert process._proc is not None
    process._proc.kill()
    budget.close(outcome)
    assert (out / "error_budget.png").read_bytes() == here["error_budget.png"]


def test_the_thinned_table_draws_exactly_the_samples_the_plot_draws() -> None:
    from twin.outputs.plots import drawn_rows

    table = _table()
    names = [n for n in _columns().budget_names() if n in table]
    thin = thinned(table, names)
    rows = drawn_rows(table, names)
    assert len(thin.time) < len(table.time)  # thinned: more rows than the plots draw whole
    np.testing.assert_array_equal(thin.time, table.time[rows])
    for name in names:
        np.testing.assert_array_equal(thin[name], table[name][rows])
    # the plot of the thinned table picks the same rows again: all of them
    np.testing.assert_array_equal(thin.time[drawn_rows(thin, names)], thin.time)


def test_a_helper_that_cannot_start_leaves_the_plots_to_the_run(
    here: dict[str, bytes], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "executable", str(tmp_path / "no-such-python"))
    process = PlotProcess()
    process.start()
    assert not process.running
    assert _draw_both(tmp_path / "no-helper", process) == here


def test_a_helper_that_dies_leaves_the_plots_to_the_run(here: dict[str, bytes], tmp_path: Path) -> None:
    process = PlotProcess()
    process.start()
    assert process._proc is not None
    process._proc.kill()
    process._proc.wait()
    assert _draw_both(tmp_path / "killed", process) == here


def test_a_plot_the_helper_cannot_draw_is_one_run_error(tmp_path: Path) -> None:
    process = PlotProcess().use()
    process.start()
    try:
        table = thinned(_table(), ["probe.reading"])
        bad = dataclasses.replace(_columns(), predicted="errormodel.not_there")
        with pytest.raises(
            RunError, match=r"budget\.png: the plot failed: KeyError: .*errormodel\.not_there"
        ):
            process.send("budget", tmp_path / "budget.png", table, columns_json(bad), TITLE)
            process.answer()
        assert not (tmp_path / "budget.png").exists()
        assert process.running  # a failed plot does not end the helper: the next one is drawn
        good = thinned(_table(), ["probe.reading", "mechanics.wear_depth_true", "errormodel.wear_compensated",
                                  "oscillation.cycles"])  # fmt: skip
        assert process.send("wear", tmp_path / "wear.png", good, columns_json(_columns()), "wear")
        assert process.answer()
        assert (tmp_path / "wear.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    finally:
        process.close()
    assert not process.running
    process.close()  # idempotent


@pytest.mark.parametrize(
    "job",
    [
        b"not json\n",
        b'{"kind": "pickle", "n": 0, "names": [], "columns": {}}\n',
        b'{"kind": "budget", "n": -1, "names": [], "columns": {}}\n',
        b'{"kind": "budget", "n": 10, "names": ["a"], "columns": {}}\n' + b"\x00" * 16,  # short
    ],
)
def test_the_helper_refuses_a_malformed_job_in_one_line_and_ends(job: bytes) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "twin.outputs.plot_process"],
        input=job,
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 2
    (line,) = done.stdout.decode().splitlines()
    answer = json.loads(line)
    assert answer["ok"] is False and answer["error"].startswith("unreadable job")


def _stand_in(code: str) -> PlotProcess:
    """A PlotProcess whose helper is ``python -c code`` (what the real helper does before it
    reads its input, imports matplotlib, made to last)."""
    process = PlotProcess()
    process._started = True
    process._proc = subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE
    )
    return process


def test_a_plot_is_sent_without_waiting_for_the_helper_to_read_it() -> None:
    import threading

    # a helper still importing matplotlib reads nothing; the job is bigger than the pipe
    process = _stand_in("import time; time.sleep(60)")
    helper = process._proc
    assert helper is not None
    sent: list[bool] = []
    sender = threading.Thread(
        target=lambda: sent.append(
            process.send("budget", Path("b.png"), thinned(_table(), ["probe.reading"]), {}, TITLE)
        )
    )
    sender.start()
    sender.join(timeout=30)
    assert not sender.is_alive() and sent == [True], "send waited for the helper to read the job"
    process.abandon()  # the run failed: the helper is stopped, its job's writer ends
    assert helper.poll() is not None and not process.running


def test_a_helper_never_sent_a_plot_is_stopped_at_close_not_waited_for() -> None:
    # bad input, or a run that failed before its plots: closing the input of a helper still
    # importing matplotlib would wait for that import; a stand-in that would leave cleanly
    # (exit 0) once its input closes shows which way it went
    process = _stand_in("import sys; sys.stdin.buffer.read()")
    helper = process._proc
    assert helper is not None
    process.close()
    assert helper.returncode == -9  # SIGKILL, not the clean exit on a closed input


def test_the_helper_ends_with_its_last_user() -> None:
    process = PlotProcess()
    process.use()
    process.use()
    process.start()
    assert process.running
    process.release()
    assert process.running
    process.release()
    assert not process.running


def test_a_ctrl_c_or_sigterm_is_the_runs_to_handle_not_the_helpers() -> None:
    import os
    import signal
    import time

    process = PlotProcess()
    process.start()
    assert process._proc is not None
    time.sleep(1.0)  # past its start, where it ignores SIGINT and SIGTERM
    os.kill(process._proc.pid, signal.SIGINT)
    os.kill(process._proc.pid, signal.SIGTERM)  # a batch system stops the whole process group
    time.sleep(0.3)
    assert process.running
    process.close()
    assert not process.running


def test_the_last_plot_ends_the_helper_once_answered(
    here: dict[str, bytes], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The only sink's plot closes the helper's input behind it: the helper ends as soon as it
    has answered, without waiting for the run to release it (its memory beside the run's)."""
    monkeypatch.setattr(plots, "save_png", lambda *a: pytest.fail("drawn in the run's process"))
    out = tmp_path / "last"
    out.mkdir()
    process = PlotProcess()
    process.start()
    helper = process._proc
    assert helper is not None
    budget = ErrorBudgetSink(out / "error_budget.png", _columns(), TITLE, process)
    outcome = _outcome(_table())
    assert budget.begin(outcome)
    assert helper.wait(timeout=30) == 0  # ended on its own: the sink still holds the process
    assert process.users == 1 and process.pending == out / "error_budget.png"
    budget.close(outcome)  # reads the answer the helper left
    assert (out / "error_budget.png").read_bytes() == here["error_budget.png"]
    assert not process.running
