"""Faults of `twin run` (issue 13): bad output folders, two runs on one folder, stale files of an
earlier run, a full disk mid-run, Ctrl-C at the start and after the co-simulation. Each through
the real command in a subprocess (the signals, limits and locks are process-wide)."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twin.config.load import scenarios_dir
from twin.outputs import read_signals_csv

pytestmark = pytest.mark.slow

TWIN = [sys.executable, "-c", "import sys; from twin.entry import main; sys.exit(main())"]
PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"
MIL = scenarios_dir() / "mil-endurance.toml"


def _twin(*args: str, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*TWIN, *args], capture_output=True, text=True, timeout=300, **kw)


def _one_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("twin: "), err
    return lines[0]


@pytest.mark.parametrize(
    ("out", "word"),
    [
        ("", "empty"),
        ("   ", "empty"),
        ("{file}", "is a file"),
        ("{file}/sub", "is a file"),
        ("/proc/twin-out", "special file system"),
        ("/proc/self", "special file system"),
        ("/sys/twin-out", "special file system"),
        ("/dev/null", "special file system"),
        ("/dev/shm/../null", "special file system"),
    ],
    ids=[
        "empty",
        "blank",
        "existing-file",
        "under-a-file",
        "proc",
        "proc-self",
        "sys",
        "dev-null",
        "dev-dotdot",
    ],
)
@pytest.mark.parametrize("command", ["run", "compensate", "sweep"])
def test_a_bad_output_folder_is_refused_before_anything_runs(
    command: str, out: str, word: str, tmp_path: Path
) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    out = out.format(file=afile)
    args = {
        "run": ["run", str(PAPER), "--uncertainty", "0"],
        "compensate": ["compensate", str(tmp_path / "lab.csv")],
        "sweep": ["sweep", str(scenarios_dir() / "sweeps" / "room-swing-x-load.toml")],
    }[command]
    (tmp_path / "lab.csv").write_text("time,x\n0,1\n")
    r = _twin(*args, "--out", out, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    line = _one_line(r.stderr)
    assert "--out" in line and word in line, line
    assert afile.read_text() == "x"
    assert not (tmp_path / "runs").exists() and not (tmp_path / "sweeps").exists()


def test_a_second_run_on_a_folder_in_use_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "run"
    first = subprocess.Popen(
        [*TWIN, "run", str(MIL), "--out", str(out), "--quiet"], stderr=subprocess.PIPE, text=True
    )
    try:
        lock = out / ".twin.lock"
        deadline = time.monotonic() + 60
        while not (lock.exists() and lock.read_text().strip() == str(first.pid)):
            assert time.monotonic() < deadline and first.poll() is None, "the first run never took the lock"
            time.sleep(0.05)
        second = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out))
        assert second.returncode == 2
        line = _one_line(second.stderr)
        assert f"in use by another twin process (pid {first.pid})" in line, line
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=120)
    assert first.returncode == 130  # interrupted, its rows intact and its own
    rows = read_signals_csv(out / "signals.csv")
    assert len(rows) > 0 and "mechanics.wear_depth_true" in rows


def test_a_reused_folder_keeps_no_file_of_an_earlier_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    for stale in ("uncertainty.csv", "errormodel.csv", "checkpoint.npz", "recording.rrd"):
        (out / stale).write_text("from an earlier run")
    (out / "notes.txt").write_text("the lab's own notes")
    refused = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet")
    assert refused.returncode == 2 and "--force" in _one_line(refused.stderr)
    assert (out / "uncertainty.csv").read_text() == "from an earlier run"  # nothing touched
    r = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet", "--force")
    assert r.returncode == 0, r.stderr
    assert not (out / "uncertainty.csv").exists() and not (out / "checkpoint.npz").exists()
    assert (out / "errormodel.csv").read_text() != "from an earlier run"
    assert (out / "recording.rrd").read_bytes() != b"from an earlier run"
    assert (out / "notes.txt").read_text() == "the lab's own notes"  # not twin's: left alone


def _file_size_limit(limit: int):
    def apply() -> None:
        # a write beyond the limit then fails with EFBIG, as one on a full disk with ENOSPC
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


def test_a_full_disk_mid_run_keeps_every_whole_row_and_says_so(tmp_path: Path) -> None:
    out = tmp_path / "run"
    r = subprocess.run(
        [*TWIN, "run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=_file_size_limit(400_000),
    )
    assert r.returncode == 1
    line = _one_line(r.stderr)
    assert "disk full" in line and "signals.csv" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed: disk full"
    text = (out / "signals.csv").read_bytes()
    assert 100_000 < len(text) <= 400_000 and text.endswith(b"\n")  # cut back to whole rows
    table = read_signals_csv(out / "signals.csv")
    assert len(table) > 100 and table.time[-1] < 28800.0


@pytest.mark.parametrize("delay", [0.05, 0.15, 0.3])
def test_ctrl_c_in_the_first_moments_exits_130_in_one_line(delay: float, tmp_path: Path) -> None:
    p = subprocess.Popen(
        [*TWIN, "run", str(PAPER), "--out", str(tmp_path / "run")],
        stderr=subprocess.PIPE,
        text=True,
        stdout=subprocess.DEVNULL,
    )
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    assert _one_line(err).startswith("twin: ")


def test_ctrl_c_after_the_co_simulation_exits_130_and_keeps_the_runs_outputs(tmp_path: Path) -> None:
    # the paper's replay: after its run, the Monte Carlo of its uncertainty (several seconds)
    out = tmp_path / "run"
    p = subprocess.Popen(
        [*TWIN, "run", str(PAPER), "--out", str(out), "--quiet"], stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 120
    while not (out / "summary.json").exists():
        assert time.monotonic() < deadline and p.poll() is None, "the run did not finish"
        time.sleep(0.05)
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    assert "interrupted by SIGINT after the co-simulation" in _one_line(err)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and "interval_90" not in summary["drift_mm"]
    assert not (out / "uncertainty.csv").exists()
    assert len(read_signals_csv(out / "signals.csv")) == 2881


def test_the_lock_file_names_the_holder_and_a_finished_run_releases_it(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet").returncode == 0
    assert (out / ".twin.lock").read_text().strip().isdigit()
    # released: the next run takes it
    assert (
        _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet", "--force").returncode
        == 0
    )
    assert os.path.getsize(out / "summary.json") > 0
