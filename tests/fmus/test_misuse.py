"""Misuse of every FMU returns fmi2Error with a logged reason, and never crashes the host.

Each misuse runs in a child process: a segfault or abort would show up as a failed child.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from twin.fmu.build import model_names

REPO = Path(__file__).resolve().parents[2]

# case -> words the FMU's log message must contain
MISUSES = {
    "unknown_vr_get": "unknown value reference",
    "unknown_vr_set": "unknown value reference",
    "nan_input": "not finite",
    "inf_input": "not finite",
    "parameter_out_of_range": "outside its range",
    "set_output": "cannot be set",
    "fixed_parameter_after_init": "fixed after initialization",
    "do_step_before_init": "not allowed in state 'instantiated'",
    "do_step_in_init_mode": "not allowed in state 'initialization mode'",
    "negative_step": "invalid step size",
    "nan_step": "invalid step size",
    "step_not_multiple_of_internal_step": "not a multiple",
    "wrong_communication_point": "does not match",
    "do_step_after_terminate": "not allowed in state 'terminated'",
    "set_after_terminate": "not allowed in state 'terminated'",
    "terminate_twice": "not allowed in state 'terminated'",
    "init_twice": "not allowed in state 'step complete'",
    "input_derivatives": "not supported",
}


def probe(fmu: Path, case: str) -> subprocess.CompletedProcess[str]:
    # a temporary directory of its own, removed after it: the probe unpacks the FMU with fmpy,
    # which leaves its folder there (and a probe that crashes would leave it anyway)
    with tempfile.TemporaryDirectory(prefix="twin-misuse-") as tmp:
        return subprocess.run(
            [sys.executable, "-m", "tests.fmus.misuse_probe", str(fmu), case],
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
            env={**os.environ, "TMPDIR": tmp},
        )


@pytest.mark.parametrize("model", model_names())
@pytest.mark.parametrize("case", sorted(MISUSES))
def test_misuse_returns_error_and_logs_why(model: str, case: str, fmu_paths: dict[str, Path]) -> None:
    proc = probe(fmu_paths[model], case)
    assert proc.returncode == 0, f"child died: rc={proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    assert "STATUS 3" in proc.stdout, proc.stdout + proc.stderr  # fmi2Error
    assert MISUSES[case] in proc.stdout, proc.stdout


@pytest.mark.parametrize("model", model_names())
def test_wrong_guid_gives_no_instance(model: str, fmu_paths: dict[str, Path]) -> None:
    proc = probe(fmu_paths[model], "wrong_guid")
    assert proc.returncode == 0, proc.stderr
    assert "STATUS null-instance" in proc.stdout
    assert "does not match" in proc.stdout
