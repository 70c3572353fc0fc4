"""Helpers of the sweep tests: child processes of ``twin sweep`` and sweep files."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import twin
from twin.config.load import scenarios_dir
from twin.fmu.build import fmu_sources_dir

BIN = Path(sys.executable).parent
SRC = Path(twin.__file__).resolve().parents[1]
PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"


def child_env(**extra: str) -> dict[str, str]:
    """The environment of a child process: this source tree, these FMU sources."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["TWIN_FMU_SOURCES"] = str(fmu_sources_dir())
    env.update(extra)
    return env


def sweep_cmd(spec: Path, out: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "twin", "sweep", str(spec), "--out", str(out), "--quiet", *args]


def run_sweep_cli(
    spec: Path, out: Path, *args: str, timeout: float = 240
) -> subprocess.CompletedProcess[str]:
    """``python -m twin sweep`` in a child process (its own session, killed on timeout)."""
    proc = subprocess.Popen(
        sweep_cmd(spec, out, *args),
        env=child_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        stdout, stderr = proc.communicate()
        pytest.fail(f"sweep timed out after {timeout} s: {stderr[-2000:]}")
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


def write_spec(path: Path, body: str, base: Path = PAPER) -> Path:
    """A sweep file at ``path`` over ``base`` (written as a path relative to the file)."""
    rel = os.path.relpath(base, path.parent)
    path.write_text(f'[sweep]\nbase = "{rel}"\n{body}', encoding="utf-8")
    return path


def stop(proc: subprocess.Popen[bytes]) -> None:
    """End a child and everything it started (its own session): TERM, then KILL."""
    if proc.poll() is None:
        with_signal(proc, signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            with_signal(proc, signal.SIGKILL)
            proc.wait(timeout=15)


def with_signal(proc: subprocess.Popen[bytes], signum: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signum)
