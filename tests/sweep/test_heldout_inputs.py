"""``twin heldout --resume`` shares the sweep's store and its record of inputs: a held-out
run's record names each file it reads (its scenarios' parameter files among them), so a
resume after one of them changed is refused naming it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from twin.config.load import scenarios_dir
from twin.errors import ConfigError
from twin.pipeline.results import ResultStore
from twin.validation.heldout import inputs, load_heldout


def test_a_changed_file_of_a_held_out_scenario_is_named(tmp_path: Path) -> None:
    copy = tmp_path / "scenarios"
    shutil.copytree(scenarios_dir(), copy, ignore=shutil.ignore_patterns("sweeps"))
    path = copy / "validation" / "heldout.toml"
    before = inputs(load_heldout(path, testers=2))
    assert {"testers", "seed", "twin version", "FMU sources"} <= set(before)
    files = [k for k in before if k.startswith("file ")]
    assert any(k.endswith("heldout.toml") for k in files) and any(
        k.endswith("base/priors.toml") for k in files
    )
    network = copy / "calibration" / "li2017-thermal-network.toml"
    assert f"file {network}" in before  # read by a held-out scenario through its parameter files

    network.write_text(network.read_text() + "\n# a comment decides no row\n")
    assert inputs(load_heldout(path, testers=2)) == before
    network.write_text(network.read_text().replace("value = ", "value = 1", 1))
    after = inputs(load_heldout(path, testers=2))
    assert [k for k in after if after[k] != before[k]] == [f"file {network}"]
    assert inputs(load_heldout(path, testers=3))["testers"] != before["testers"]

    out = tmp_path / "out"
    store = ResultStore(out, ["tester"], {"fingerprint": "f", "inputs": before}, resume=False, size=4)
    store.start()
    with pytest.raises(ConfigError, match=f"--resume: holds another study \\(file {network} changed"):
        ResultStore(out, ["tester"], {"fingerprint": "f", "inputs": after}, resume=True, size=4)
