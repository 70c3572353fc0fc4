"""The pipeline's stages, alone and composed: the same numbers whichever way a run is made."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import twin.pipeline.stages as stages
from tests.runs import run_into
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.evaluate import PARTS
from twin.errors import RunError
from twin.outputs.csv import read_signals_csv
from twin.outputs.sink import Outcome, Sink
from twin.paper import TEMPERATURE_RISE_K
from twin.pipeline import (
    RunControls,
    RunSummary,
    evaluate_run,
    prepare_scenario,
    run_point,
    simulate,
    summarize,
    write_outputs,
)
from twin.pipeline.stages import OutputsLog
from twin.signals.recorder import FLUSH_ROWS
from twin.signals.table import Block, Signal

pytestmark = pytest.mark.slow

SHORT = ['scenario.duration="20 min"']


def short_scenario(*overrides: str):
    return load_scenario(scenarios_dir() / "constant-load.toml", [*SHORT, *overrides])


@pytest.fixture(scope="module")
def folder_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RunSummary]:
    out = tmp_path_factory.mktemp("run")
    return out, run_into(short_scenario(), out)


def without_timing(figures: dict[str, float]) -> dict[str, float]:
    return {k: v for k, v in figures.items() if not k.startswith("timing.") or k.endswith("_steps")}


def test_summary_json_is_the_run_summary_to_json(folder_run: tuple[Path, RunSummary]) -> None:
    out, summary = folder_run
    text = (out / "summary.json").read_text(encoding="utf-8")
    assert text == summary.to_json()
    assert RunSummary.from_dict(json.loads(text)).to_json() == text
    assert summary.status == "completed" and summary.line().startswith("constant-load: completed; drift")


def test_figures_are_flat_numbers_of_the_summary(folder_run: tuple[Path, RunSummary]) -> None:
    _, summary = folder_run
    figures = summary.figures()
    assert all(isinstance(v, float) for v in figures.values())
    data = summary.to_dict()
    assert figures["drift_mm.predicted"] == data["drift_mm"]["predicted"]
    assert figures["drift_mm.probe"] == data["drift_mm"]["probe"]
    for part in (*PARTS, "total"):
        assert figures[f"error_parts_mm.{part}"] == data["error_parts_mm"][part]
    for key in ("residual_rms_um", "residual_max_um"):
        for when in ("before", "after"):
            assert figures[f"compensation.{key}.{when}"] == data["compensation"][key][when]
    assert figures["wear_mm.true"] == data["wear_mm"]["true"]
    for point in TEMPERATURE_RISE_K:
        assert figures[f"temperature_rise_C.{point}"] == data["temperature_rise_C"][point]
    assert figures["timing.cosim_s"] == data["timing"]["cosim_s"]
    assert figures["timing.macro_steps"] == data["timing"]["macro_steps"] == 12_000  # 20 min at 0.1 s
    # the paper's values are the same in every run, which sensors were read is no figure
    assert not [k for k in figures if "paper" in k or k.startswith("sensors_used")]
    # a sample's figures: the same numbers in the same order, without the run's time and timings
    results = [(k, v) for k, v in figures.items() if not k.startswith("timing.") and k != "sim_end_s"]
    assert list(summary.figures(timings=False).items()) == results


def test_run_point_gives_the_runs_figures_and_writes_no_file(
    folder_run: tuple[Path, RunSummary], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, summary = folder_run
    monkeypatch.chdir(tmp_path)
    point = run_point(prepare_scenario(short_scenario()))
    assert list(tmp_path.iterdir()) == []
    assert without_timing(point.figures()) == without_timing(summary.figures())
    assert pickle.loads(pickle.dumps(point)).figures() == point.figures()  # a worker sends it back


def test_evaluating_for_the_numbers_alone_gives_the_same_numbers_and_adds_no_column() -> None:
    """A sample's evaluation (``columns=False``) leaves its table as simulated and gives the
    results of the evaluation that adds the model's columns, to the bit."""
    simulation = simulate(prepare_scenario(short_scenario()))
    kept = simulation.table.names()
    alone = evaluate_run(simulation, columns=False)
    assert alone.columns == () and simulation.table.names() == kept
    full = evaluate_run(simulation)
    assert "errormodel.e_z" in full.columns and "errormodel.e_z" in simulation.table
    assert json.dumps(alone.results) == json.dumps(full.results)


def test_stages_one_by_one_make_the_runs_files(folder_run: tuple[Path, RunSummary], tmp_path: Path) -> None:
    out, summary = folder_run
    prepared = prepare_scenario(short_scenario())
    events: list[str] = []

    class Tail(Sink):
        """A sink of its own: the last row of each column, and what the run told it."""

        path = Path("tail")

        def open(self, signals: list[Signal]) -> None:
            events.append("open")
            self.names = [s.name for s in signals]

        def write(self, block: Block) -> None:
            events.append("write")
            self.last = {n: float(v[-1]) for n, v in block.columns.items()}

        def close(self, outcome: Outcome) -> None:
            events.append("close")
            self.outcome = outcome

        def fail(self, error: BaseException) -> None:
            events.append("fail")

    tail = Tail()
    simulation = simulate(prepared, [tail])
    assert simulation.result.status == "completed" and simulation.table.names()
    evaluated = evaluate_run(simulation)
    assert evaluated.table is simulation.table and "errormodel.e_z" in evaluated.columns
    made = summarize(simulation, evaluated)
    write_outputs(
        [tail], Outcome(evaluated.table, evaluated.columns, made.to_dict), RunControls(), OutputsLog()
    )
    assert events[0] == "open" and events[-1] == "close" and set(events[1:-1]) == {"write"}
    signals = read_signals_csv(out / "signals.csv")
    assert tail.names == signals.names()
    assert tail.last == {n: float(signals[n][-1]) for n in signals.names()}
    model = read_signals_csv(out / "errormodel.csv")
    assert tail.outcome.columns == tuple(model.names())
    np.testing.assert_array_equal(tail.outcome.table["errormodel.e_z"], model["errormodel.e_z"])
    assert tail.outcome.summary()["drift_mm"] == summary.to_dict()["drift_mm"]


def test_a_run_that_breaks_after_simulating_keeps_its_rows_and_a_summary_saying_why(
    folder_run: tuple[Path, RunSummary], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out, _ = folder_run

    def broken(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("the error model broke")

    monkeypatch.setattr(stages, "evaluate_run", broken)
    with pytest.raises(RunError, match="RuntimeError: the error model broke; everything recorded is in"):
        run_into(short_scenario(), tmp_path)
    # every row, though the run held them all back for after its plots (fewer than FLUSH_ROWS)
    assert len(read_signals_csv(tmp_path / "signals.csv")) < FLUSH_ROWS
    assert (tmp_path / "signals.csv").read_bytes() == (out / "signals.csv").read_bytes()
    assert not (tmp_path / "errormodel.csv").exists()
    # as when an FMU fails: the folder says the run failed, and why
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["error"] == "RuntimeError: the error model broke"
    from twin.outputs.rerun_rec import read_recording

    assert read_recording(tmp_path / "recording.rrd")  # closed, so readable


# In a process of its own: an FMU's error message goes through fmpy's process-global logger
# proxy, which a test that registers its own logger (tests/properties/test_fmu_ranges.py)
# leaves pointing at a callback it has freed by then.
POINT = """
import json, sys
from twin.config.load import load_scenario
from twin.pipeline import prepare_scenario, run_point
point = run_point(prepare_scenario(load_scenario(sys.argv[1])))
print(json.dumps({"status": point.status, "error": point.error, "sim_end_s": point.sim_end_s,
                  "figures": sorted(point.figures())}))
"""


def test_run_point_of_a_failing_fmu_reports_the_failure(tmp_path: Path) -> None:
    scenario = tmp_path / "fault.toml"
    base = scenarios_dir() / "constant-load.toml"
    scenario.write_text(
        f'extends = "{base}"\n[scenario]\nduration = "20 min"\n'
        '[[event]]\nat = "10 min"\naction = "fault"\ntarget = "mechanics"\nfault = "error"\n'
    )
    proc = subprocess.run(
        [sys.executable, "-c", POINT, str(scenario)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr  # a failing FMU does not raise
    point = json.loads(proc.stdout)
    assert point["status"] == "failed" and "mechanics" in point["error"]
    assert point["sim_end_s"] == 600.0
    assert "drift_mm.predicted" in point["figures"]  # the rows up to the failure were evaluated
    assert os.listdir(tmp_path) == ["fault.toml"]
