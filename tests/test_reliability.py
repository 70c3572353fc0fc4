"""A run never loses its results: FMU faults, interruption, kill and resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from twin.outputs import read_signals_csv

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
CONSTANT = str(REPO / "scenarios" / "constant-load.toml")


def twin(*args: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "twin", *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kwargs,
    )


def finish(proc: subprocess.Popen, timeout: float = 600) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


@pytest.mark.parametrize(
    "fault, call", [("error", "fmi2DoStep"), ("discard", "fmi2DoStep"), ("nan", "fmi2GetReal")]
)
def test_fmu_fault_stops_the_run_with_everything_recorded(tmp_path: Path, fault: str, call: str) -> None:
    scenario = tmp_path / "fault.toml"
    scenario.write_text(
        f'extends = "{CONSTANT}"\n[scenario]\nduration = "20 min"\n'
        f'[[event]]\nat = "10 min"\naction = "fault"\ntarget = "mechanics"\nfault = "{fault}"\n'
    )
    code, _, err = finish(twin("run", str(scenario), "--quiet", "--out", str(tmp_path / "run")))
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert "mechanics" in lines[0] and call in lines[0] and "t = 600 s" in lines[0]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "failed" and "mechanics" in summary["error"]
    table = read_signals_csv(tmp_path / "run" / "signals.csv")
    assert table.time[-1] == 600.0  # every row up to the failing step (1 s output interval)
    assert np.all(np.isfinite(table["mechanics.probe_true"]))
    proc = subprocess.run([sys.executable, "-m", "rerun_cli", "rrd", "verify", str(tmp_path / "run" / "recording.rrd")],
                          capture_output=True, check=False)  # fmt: skip
    assert proc.returncode == 0


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_flushes_everything_and_marks_the_run_interrupted(tmp_path: Path, sig: int, code: int) -> None:
    out = tmp_path / "run"
    proc = twin("run", CONSTANT, "--quiet", "--out", str(out), "--set", 'scenario.duration="24 h"')
    csv = out / "signals.csv"
    deadline = time.monotonic() + 120
    while not (csv.exists() and csv.stat().st_size > 200_000) and time.monotonic() < deadline:
        time.sleep(0.1)
    proc.send_signal(sig)
    rc, _, err = finish(proc)
    assert rc == code, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert signal.Signals(sig).name in summary["error"]
    table = read_signals_csv(csv)
    assert 100 < len(table) < 86_400
    assert summary["sim_end_s"] >= table.time[-1]


def test_killed_run_resumes_to_the_same_signals_byte_for_byte(tmp_path: Path) -> None:
    duration = ["--set", 'scenario.duration="10 h"', "--set", 'scenario.output_interval="10 s"']
    full, part = tmp_path / "full", tmp_path / "part"
    code, _, err = finish(twin("run", CONSTANT, "--quiet", "--out", str(full), *duration))
    assert code == 0, err
    proc = twin("run", CONSTANT, "--quiet", "--out", str(part), "--checkpoint-every", "1 h", *duration)
    checkpoint = part / "checkpoint.npz"
    deadline = time.monotonic() + 120
    while not checkpoint.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    assert not (part / "summary.json").exists(), "the run ended before it could be killed"
    # what the kill left is parseable up to its last complete row
    assert len(read_signals_csv(part / "signals.csv")) > 0
    code, _, err = finish(twin("resume", str(part), "--quiet"))
    assert code == 0, err
    assert (part / "signals.csv").read_bytes() == (full / "signals.csv").read_bytes()
    a = json.loads((full / "summary.json").read_text())
    b = json.loads((part / "summary.json").read_text())
    assert a["compensation"] == b["compensation"] and a["wear_mm"] == b["wear_mm"]
    # continued from a checkpoint (whole hours), not run again from the start
    resumed = b["timing"]["resumed_from_s"]
    assert a["timing"]["resumed_from_s"] == 0 and 0 < resumed < 36_000 and resumed % 3600 == 0
    proc = subprocess.run([sys.executable, "-m", "rerun_cli", "rrd", "verify", str(part / "recording.rrd")],
                          capture_output=True, check=False)  # fmt: skip
    assert proc.returncode == 0
    # the recording holds every row once: the rows before the checkpoint, replayed from the
    # CSV, and those after it (a recording made with its first new rows replayed one block twice)
    from twin.outputs.rerun_rec import read_recording

    whole, resumed = read_recording(full / "recording.rrd"), read_recording(part / "recording.rrd")
    assert resumed.keys() == whole.keys()
    for path, (t, v) in whole.items():
        np.testing.assert_array_equal(resumed[path][0], t, err_msg=path)
        np.testing.assert_array_equal(resumed[path][1], v, err_msg=path)


def test_resume_without_checkpoint_is_bad_input(tmp_path: Path) -> None:
    code, _, err = finish(twin("resume", str(tmp_path)))
    assert code == 2 and "Traceback" not in err and "run.json" in err


def _checkpointed(tmp_path: Path, scenario: Path) -> Path:
    """A finished 20-min run of ``scenario`` that saved checkpoints (its folder)."""
    out = tmp_path / "run"
    args = ("--set", 'scenario.duration="20 min"', "--checkpoint-every", "10 min")
    code, _, err = finish(twin("run", str(scenario), "--quiet", "--out", str(out), *args))
    assert code == 0, err
    assert (out / "checkpoint.npz").is_file()
    return out


def test_resume_of_a_crafted_checkpoint_exits_2_and_runs_nothing(tmp_path: Path) -> None:
    """A run folder from someone else: its checkpoint replaced by a pickle whose loading would
    create a marker file, then by an archive carrying a pickled object array: ``twin resume``
    refuses both with one line and exit 2, and the marker never appears."""
    import pickle

    out = _checkpointed(tmp_path, Path(CONSTANT))
    marker = tmp_path / "payload-ran"

    class Payload:
        def __reduce__(self) -> tuple:
            return (os.system, (f"touch {marker}",))

    for crafted in ("pickle", "object-array", "legacy"):
        (out / "checkpoint.npz").unlink(missing_ok=True)
        if crafted == "pickle":
            (out / "checkpoint.npz").write_bytes(pickle.dumps(Payload()))
        elif crafted == "object-array":
            with open(out / "checkpoint.npz", "wb") as f:
                np.savez(f, manifest=np.array([Payload()], dtype=object))
        else:
            (out / "checkpoint.pkl").write_bytes(pickle.dumps(Payload()))
        code, _, err = finish(twin("resume", str(out), "--quiet"))
        assert code == 2, err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        assert not marker.exists(), f"{crafted}: the payload ran"


def test_resume_of_an_edited_scenario_is_refused(tmp_path: Path) -> None:
    scenario = tmp_path / "s.toml"
    scenario.write_text(Path(CONSTANT).read_text().replace('extends = "', f'extends = "{REPO}/scenarios/'))
    out = _checkpointed(tmp_path, scenario)
    (out / "summary.json").unlink()  # as if killed after the checkpoint
    code, _, err = finish(twin("resume", str(out), "--quiet"))  # unchanged: resumes
    assert code == 0, err
    scenario.write_text(scenario.read_text().replace("[scenario]\n", "[scenario]\nseed = 2\n"))
    (out / "summary.json").unlink()  # killed again: a completed run is not resumed at all
    code, _, err = finish(twin("resume", str(out), "--quiet"))
    assert code == 2 and "changed since the checkpoint" in err and "Traceback" not in err, err


def test_resume_refuses_a_checkpoint_interval_run_would_not_write(tmp_path: Path) -> None:
    """run.json's checkpoint_every_ns is null or a positive multiple of the step (0.1 s) as
    `twin run` writes it; 0, -1, 1 ns or half a step would have switched the resumed run's
    checkpoints off without a word."""
    out = _checkpointed(tmp_path, Path(CONSTANT))
    (out / "summary.json").unlink()  # as if killed after the checkpoint
    meta = json.loads((out / "run.json").read_text())
    assert meta["checkpoint_every_ns"] == 600 * 10**9  # what run writes
    signals = (out / "signals.csv").read_bytes()
    for bad in (0, -1, 1, 50_000_000):
        (out / "run.json").write_text(json.dumps({**meta, "checkpoint_every_ns": bad}))
        code, _, err = finish(twin("resume", str(out), "--quiet"))
        assert code == 2, err
        assert err.strip().splitlines() == [
            f"twin: {out / 'run.json'}: checkpoint_every_ns: must be null or a positive multiple of "
            f"scenario.step (100000000 ns), got {bad}"
        ]
        assert not (out / "summary.json").exists() and (out / "signals.csv").read_bytes() == signals
    (out / "run.json").write_text(json.dumps({**meta, "checkpoint_every_ns": None}))  # no more checkpoints
    code, _, err = finish(twin("resume", str(out), "--quiet"))
    assert code == 0, err
