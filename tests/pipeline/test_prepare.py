"""prepare: every check of a run made once, before anything runs or any file is touched."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from tests.runs import run_into
from twin.config.load import load_scenario, scenarios_dir
from twin.errors import ConfigError
from twin.pipeline import PreparedRun, RunOptions, prepare
from twin.validation import reports

PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"
SHORT = ['scenario.duration="10 min"']


def test_validate_is_prepare_without_a_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with prepare("constant-load", SHORT) as prepared:
        assert isinstance(prepared, PreparedRun) and prepared.folder is None
        assert prepared.plan.scenario is prepared.scenario  # the plan made once, for this scenario
        assert prepared.evaluation.reading == "sensors.probe_meas"  # [errormodel] checked into its config
    assert list(tmp_path.iterdir()) == []  # nothing written, no run folder


def test_a_scenario_value_is_prepared_as_its_file_is() -> None:
    scenario = load_scenario(PAPER, SHORT)
    with prepare(scenario) as a, prepare(PAPER, SHORT) as b:
        assert a.scenario == b.scenario and a.plan == b.plan and a.evaluation == b.evaluation


@pytest.mark.parametrize(
    ("options", "overrides", "source", "words"),
    [
        (RunOptions(checkpoint_every="1500 ms"), [], "--checkpoint-every", "multiple of scenario.step"),
        (RunOptions(samples=-1), [], "--uncertainty", "expected a number of samples"),
        (RunOptions(), ['errormodel.reading="sensors.probe_mea"'], "", "did you mean 'sensors.probe_meas'"),
        (RunOptions(), ["uncertainty.room_drift_K=-1"], "", "uncertainty.room_drift_K"),
        (RunOptions(reports=reports), ['reference.experiment="li2018"'], "", "reference.experiment"),
        (
            RunOptions(),
            ["fmu.thermal.parameters.hyd_share_oil=0.5"],
            "",
            "the FMU refuses them",
        ),  # shares > 1
    ],
)
def test_bad_input_is_refused_before_any_folder_is_made(
    tmp_path: Path, options: RunOptions, overrides: list[str], source: str, words: str
) -> None:
    out = tmp_path / "run"
    options = RunOptions(**{**options.__dict__, "folder": True, "out": out})
    with pytest.raises(ConfigError) as err:
        prepare(PAPER, [*SHORT, *overrides], options)
    assert words in str(err.value) and (not source or err.value.source == source), err.value
    assert not out.exists()


def test_an_earlier_run_is_refused_without_force_and_left_as_it_was(tmp_path: Path) -> None:
    out = tmp_path / "run"
    run_into("constant-load", out, SHORT)
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != ".twin.lock"}
    with pytest.raises(ConfigError, match="holds an earlier run") as err:
        prepare("constant-load", SHORT, RunOptions(folder=True, out=out))
    assert err.value.source == "--out"
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != ".twin.lock"} == before
    with prepare("constant-load", SHORT, RunOptions(folder=True, out=out, force=True)) as again:
        assert again.folder is not None  # replaced only when asked, the lock held once


def test_the_paper_report_follows_the_reference_table_not_the_scenario_name(tmp_path: Path) -> None:
    """The pipeline knows no scenario by name: a copy of the replay under another name is still
    compared with the paper, because its [reference] table says what it replays."""
    copy = tmp_path / "my-replay.toml"
    copy.write_text(f'extends = "{PAPER}"\n[scenario]\nname = "my-replay"\n', encoding="utf-8")
    summary = run_into(copy, tmp_path / "run", SHORT)
    data = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary.scenario == "my-replay" and data["drift_mm"]["paper_measured"] == pytest.approx(-0.021)
    assert set(data["thermal_parts_mm_truth"]) == {"bearing_block", "t_plate", "detecting_frame", "long_pole"}
    # the same scenario without [reference]: no paper beside it
    plain = dataclasses.replace(load_scenario(copy, SHORT), reference={})
    run_into(plain, tmp_path / "plain")
    data = json.loads((tmp_path / "plain" / "summary.json").read_text())
    assert "paper_measured" not in data["drift_mm"] and "paper" not in data


def test_outputs_found_by_role_not_by_model_name() -> None:
    with prepare("mil-endurance") as mil, prepare(PAPER) as paper:
        assert mil.plan.role_columns("swing_cycles") == ["oscillation.cycles"]
        assert "oscillation.cycles" in mil.keep()  # the wear plot's axis, kept in memory
        assert paper.plan.role_columns("swing_cycles") == []  # no drive in the replay
        assert paper.plan.roles(["thermal_dz.detecting_frame", "radial_load"]) == {
            "thermal_dz.detecting_frame": "mechanics.dz_detecting_frame"
        }
