"""``twin sweep`` end to end on what it is given: a misspelt output refused before the cluster
starts (leaving nothing behind), failed points named in the last line, progress lines in a
log, and ``--resume`` refused whenever anything that decides a row changed, naming it.

The base scenario is a copy of the shipped scenarios in the test's folder, so a test can edit
one of the files the base reads (a parameter file) as a user would.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from tests.sweep.helpers import child_env, write_spec
from twin.config.load import scenarios_dir

# a conductance drawn from a wide normal distribution: about a third of the points fall below
# zero and fail on the client, named in the last line
BODY = """design = "lhs"
samples = 6
seed = 3
set = ['scenario.duration = "20 min"']
outputs = ["drift_mm.probe", "{second}"]

[problem]
names = ["input.thermal.t_room.rise", "fmu.thermal.parameters.g_detecting_frame_room"]
bounds = [[0.0, 9.0], [4.0, 10.0]]
dists = ["unif", "norm"]
"""


def _sweep(spec: Path, out: Path, *args: str) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "twin", "sweep", str(spec), "--out", str(out), "--workers", "1", *args]
    return subprocess.run(cmd, env=child_env(), capture_output=True, text=True, timeout=240, check=False)


@pytest.fixture
def scenarios(tmp_path: Path) -> Path:
    copy = tmp_path / "scenarios"
    shutil.copytree(scenarios_dir(), copy, ignore=shutil.ignore_patterns("sweeps"))
    return copy


def test_a_misspelt_output_is_refused_before_the_cluster_and_leaves_nothing(
    scenarios: Path, tmp_path: Path
) -> None:
    base = scenarios / "li2017-thermal-experiment.toml"
    spec = write_spec(tmp_path / "s.toml", BODY.format(second="drift_mm.predictd"), base=base)
    out = tmp_path / "out"
    bad = _sweep(spec, out)
    lines = bad.stderr.strip().splitlines()
    assert bad.returncode == 2 and len(lines) == 1, bad.stderr
    assert lines[0].startswith(f"twin: {spec}: sweep.outputs: no figure 'drift_mm.predictd' (did you mean")
    assert "scheduler" not in bad.stdout  # refused before any cluster
    assert not out.exists()

    # corrected, into the same folder: runs; the failed points are named, progress is plain lines
    spec.write_text(spec.read_text().replace("predictd", "predicted"))
    good = _sweep(spec, out)
    assert good.returncode == 0, good.stderr
    table = pd.read_parquet(out / "results.parquet")
    failed = list(table["point"][table["status"] != "ok"])
    assert 0 < len(failed) < 6
    last = good.stdout.strip().splitlines()[-1]
    assert f"failed points: {', '.join(map(str, failed))} (errors in results.csv)" in last
    assert "points: 6/6 done" in good.stderr and "\r" not in good.stderr

    # --resume with anything that decides a row changed is refused, naming it
    def refused(what: str) -> None:
        again = _sweep(spec, out, "--resume")
        lines = again.stderr.strip().splitlines()
        assert again.returncode == 2 and len(lines) == 1, again.stderr
        assert f"--resume: holds another study ({what}" in lines[0], lines[0]

    text = spec.read_text()
    spec.write_text(text.replace('"20 min"', '"21 min"'))
    refused("sweep.set")
    spec.write_text(text.replace("samples = 6", "samples = 7"))
    refused("design")
    spec.write_text(text.replace('outputs = ["drift_mm.probe", ', "outputs = ["))
    refused("sweep.outputs")
    spec.write_text(text)
    network = scenarios / "calibration" / "li2017-thermal-network.toml"
    original = network.read_text()
    network.write_text(original + "\n# a comment decides no row\n")
    assert _sweep(spec, out, "--resume").returncode == 0  # nothing changed that decides a row
    first = re.search(r"value = ([0-9.eE+-]+)", original)
    assert first is not None
    edited = original[: first.start(1)] + repr(1.01 * float(first.group(1))) + original[first.end(1) :]
    network.write_text(edited)
    refused("file ")
    assert "li2017-thermal-network.toml, base scenario changed" in _sweep(spec, out, "--resume").stderr
