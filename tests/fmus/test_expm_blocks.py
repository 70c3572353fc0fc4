"""ThermalNetwork's step matrices come from the exponential of its augmented matrix worked out
in four blocks (model.c, expm_blocks): the very doubles of the whole matrix's exponential
(linalg.c, la_expm), which it replaced for its cost (most of an instance's set-up, once per
Monte Carlo sample), so no run's numbers changed with it.

A C program (expm/expm_blocks_check.c) compiled with the model's sources compares the two on
random networks and steps, built as the FMU is built (-O3) and without optimization."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.fmus.sanitized import WARNINGS, compiler, model_tree

CHECK = Path(__file__).resolve().parent / "expm" / "expm_blocks_check.c"


def _build(tmp_path: Path, optimize: str) -> Path:
    cc = compiler()
    if cc is None:
        pytest.fail("no C compiler: the FMUs cannot be built here either (apt-get install -y gcc)")
    work = tmp_path / "src"
    # the model's files but model.c, which the check includes for its static functions
    sources = [str(p) for p in model_tree("ThermalNetwork", work) if p.name != "model.c"]
    exe = tmp_path / f"check{optimize}"
    cmd = [cc, optimize, *WARNINGS, "-I", str(work), str(CHECK), *sources, "-o", str(exe), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    return exe


@pytest.mark.parametrize(("optimize", "trials"), [("-O3", 1000), ("-O0", 200)])
def test_the_four_blocks_are_the_whole_exponential_s_doubles(
    tmp_path: Path, optimize: str, trials: int
) -> None:
    exe = _build(tmp_path, optimize)
    same = subprocess.run([str(exe), str(trials), "7"], capture_output=True, text=True, check=False)
    assert same.returncode == 0, same.stdout + same.stderr
    counts = dict(kv.split("=") for kv in same.stdout.split())
    assert counts["checked"] == str(trials) and counts["mismatches"] == "0"
    lo, hi = (int(x) for x in counts["squarings"].split(".."))
    assert lo <= 2 and hi >= 20  # from a short step on a slow network to a long one on a stiff one
    # the comparison can fail: one ulp off in one entry of A moves the exponential's doubles
    nudged = subprocess.run([str(exe), "50", "7", "nudge"], capture_output=True, text=True, check=False)
    assert nudged.returncode == 1 and "mismatches=0" not in nudged.stdout, nudged.stdout
