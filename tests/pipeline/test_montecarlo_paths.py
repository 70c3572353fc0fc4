"""A run's Monte Carlo in process (its samples' FMUs stepped together) and on Dask give the same
samples, byte for byte: where a sample runs is a matter of time, never of its figures."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from twin.cli import main

#: the module (twin.pipeline re-exports its function ``run`` under the same name)
run_module = importlib.import_module("twin.pipeline.run")
ARGS = [
    "run",
    "li2017-thermal-experiment",
    "--uncertainty",
    "30",
    "--set",
    'scenario.duration="30 min"',
]


def test_in_process_and_on_dask_the_samples_are_the_same(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    assert main([*ARGS, "--out", str(tmp_path / "here")]) == 0
    # a cluster that costs nothing to start pays at once: after the second batch in process
    # (3 samples each: a tenth), the other 24 go to Dask
    monkeypatch.setattr(run_module, "CLUSTER_START_S", 0.0)
    capfd.readouterr()
    assert main([*ARGS, "--out", str(tmp_path / "dask")]) == 0
    said = capfd.readouterr()
    assert "uncertainty: the other 24 samples on Dask" in said.out + said.err
    here = (tmp_path / "here" / "uncertainty.csv").read_bytes()
    dask = (tmp_path / "dask" / "uncertainty.csv").read_bytes()
    assert here.count(b"\n") == 1 + 30
    assert here == dask
    assert b",failed," not in here


def test_a_cluster_pays_when_its_workers_save_more_than_its_start() -> None:
    pays = run_module._cluster_pays
    start = run_module.CLUSTER_START_S
    assert not pays(100, 0.01, cores=2)  # 1 s in process: 0.35 s to save
    assert pays(1000, 4 * start / 1000, cores=2)  # 4x the start in process: 1.4x it saved
    assert not pays(1000, 2 * start / 1000, cores=2)  # 2x: 0.7x it saved
    assert not pays(10_000, 1.0, cores=1)  # one core: nothing to share out
