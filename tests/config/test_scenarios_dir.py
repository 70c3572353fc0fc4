"""Every scenario shipped in scenarios/ loads and validates."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main
from twin.config.load import scenarios_dir

SCENARIOS = sorted(scenarios_dir().glob("*.toml"))


def test_there_are_scenarios() -> None:
    assert any(p.name == "li2017-thermal-experiment.toml" for p in SCENARIOS)


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_scenario_validates(path: Path, capsys) -> None:
    code = main(["validate", str(path)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert captured.err == ""
    assert captured.out.startswith(f"{path}: ok (")
