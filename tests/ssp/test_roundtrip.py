"""Every shipped scenario through its SSP archive: ``twin export-ssp`` then ``twin run X.ssp``
writes the same files as ``twin run X.toml``, its ``signals.csv`` and ``errormodel.csv`` byte for
byte. None of them has a scheduled event or a delayed connection (the friction loop needs no
delay), so each exports whole, without ``--lossy``: what is refused, and what ``--lossy`` does,
is in ``test_export.py``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from twin.cli import main
from twin.config.load import scenarios_dir

SHIPPED = sorted(p.stem for p in scenarios_dir().glob("*.toml"))
SHORT = 'scenario.duration="10 min"'


def _run(source: Path | str, out: Path, *sets: str) -> Path:
    args = ["run", str(source), "--out", str(out), "--quiet", "--uncertainty", "0"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    return out


def _summary(folder: Path) -> object:
    """summary.json without what differs between two runs of the same system (timings, the
    file's name)."""

    def strip(node: object) -> object:
        if isinstance(node, dict):
            return {k: strip(v) for k, v in node.items() if k not in ("timing", "wall_s", "scenario_file")}
        return node

    return strip(json.loads((folder / "summary.json").read_text()))


def test_every_shipped_scenario_is_covered() -> None:
    assert len(SHIPPED) >= 6 and "li2017-thermal-experiment" in SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_scenario_round_trips_through_its_archive(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    ssp = tmp_path / f"{name}.ssp"
    capsys.readouterr()
    code = main(["export-ssp", name, "-o", str(ssp), "--set", SHORT])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 0 and err == [], err
    from_toml = _run(name, tmp_path / "toml", SHORT)
    from_ssp = _run(ssp, tmp_path / "ssp")
    assert sorted(p.name for p in from_ssp.iterdir()) == sorted(p.name for p in from_toml.iterdir())
    for file in ("signals.csv", "errormodel.csv"):
        assert (from_ssp / file).read_bytes() == (from_toml / file).read_bytes(), file
    ssp_summary, toml_summary = _summary(from_ssp), _summary(from_toml)
    assert ssp_summary == toml_summary


@pytest.mark.slow
def test_the_paper_replays_monte_carlo_runs_the_same_from_the_archive(tmp_path: Path) -> None:
    """Its [uncertainty] table, spreads file and parameters' standard errors travel, and the
    seeds the export writes for other masters are the twin's derived ones (each sample's own
    seed reaches the FMUs): two samples give the same uncertainty.csv from either file."""
    ssp = tmp_path / "paper.ssp"
    assert main(["export-ssp", "li2017-thermal-experiment", "-o", str(ssp), "--set", SHORT]) == 0
    runs = {}
    for label, source, sets in (("toml", "li2017-thermal-experiment", [SHORT]), ("ssp", ssp, [])):
        args = ["run", str(source), "--out", str(tmp_path / label), "--quiet", "--uncertainty", "2"]
        for s in sets:
            args += ["--set", s]
        assert main(args) == 0
        runs[label] = tmp_path / label
    assert (runs["ssp"] / "uncertainty.csv").read_bytes() == (runs["toml"] / "uncertainty.csv").read_bytes()
    assert _summary(runs["ssp"]) == _summary(runs["toml"])
