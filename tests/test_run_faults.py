"""Faults of `twin run` (issue 13): bad output folders, two runs on one folder, stale files of an
earlier run, a full disk mid-run, Ctrl-C at the start and after the co-simulation. Each through
the real command in a subprocess (the signals, limits and locks are process-wide)."""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twin.config.load import scenarios_dir
from twin.outputs import read_signals_csv

pytestmark = pytest.mark.slow

TWIN = [sys.executable, "-c", "import sys; from twin.cli import console; sys.exit(console())"]
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


#: bad output folders: (name, what the one line says). {file} is an existing file, {ro} a
#: folder on a read-only mount, {locked} a folder without write permission (mode 555)
BAD_OUT = {
    "empty": ("", "empty"),
    "blank": ("   ", "empty"),
    "existing-file": ("{file}", "is a file"),
    "under-a-file": ("{file}/sub", "is a file"),
    "proc": ("/proc/twin-out", "special file system"),
    "proc-self": ("/proc/self", "special file system"),
    "sys": ("/sys/twin-out", "special file system"),
    "dev-null": ("/dev/null", "special file system"),
    "dev-dotdot": ("/dev/shm/../null", "special file system"),
    "read-only-mount": ("{ro}", "not writable"),
    "under-a-read-only-mount": ("{ro}/run", "not writable"),
    "no-write-permission": ("{locked}", "not writable"),
    "under-no-write-permission": ("{locked}/run", "not writable"),
}
#: each command that writes into a folder it is given: its arguments before the folder, and
#: the option the one line names
WRITERS = {
    "run": (["run", str(PAPER), "--uncertainty", "0", "--out"], "--out"),
    "compensate": (["compensate", "lab.csv", "--out"], "--out"),
    "sweep": (["sweep", str(scenarios_dir() / "sweeps" / "room-swing-x-load.toml"), "--out"], "--out"),
    "heldout": (["heldout", "--out"], "--out"),
    "resume": (["resume"], "resume"),
}


def _read_only_mount(folder: Path) -> list[str]:
    """A command prefix that runs the rest with ``folder`` mounted read-only (a private mount
    namespace of an unprivileged user namespace: no root needed, nothing seen outside)."""
    prefix = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c"]
    script = 'mount --bind -o ro "$0" "$0" && exec "$@"'
    probe = subprocess.run([*prefix, script, str(folder), "true"], capture_output=True, check=False)
    if shutil.which("unshare") is None or probe.returncode != 0:
        pytest.skip(f"no read-only mount here (unshare: {probe.stderr.decode(errors='replace').strip()})")
    return [*prefix, script, str(folder)]


@pytest.mark.parametrize("case", list(BAD_OUT))
@pytest.mark.parametrize("command", list(WRITERS))
def test_a_bad_output_folder_is_refused_before_anything_runs(command: str, case: str, tmp_path: Path) -> None:
    out, word = BAD_OUT[case]
    afile, ro, locked = tmp_path / "afile", tmp_path / "ro", tmp_path / "locked"
    afile.write_text("x")
    ro.mkdir()
    locked.mkdir(mode=0o555)
    (tmp_path / "lab.csv").write_text("time,x\n0,1\n")
    prefix: list[str] = []
    if "{ro}" in out:
        prefix = _read_only_mount(ro)
    if "{locked}" in out and os.geteuid() == 0:
        pytest.skip("root writes into a mode-555 folder (the read-only mount cases cover root)")
    args, option = WRITERS[command]
    r = subprocess.run(
        [*prefix, *TWIN, *args, out.format(file=afile, ro=ro, locked=locked)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert r.returncode == 2, r.stderr
    line = _one_line(r.stderr)
    assert f"twin: {option}: " in line and word in line, line
    assert afile.read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "lab.csv", "locked", "ro"]
    assert not any(ro.iterdir()) and not any(locked.iterdir())


def _wait_for(what: str, ready, proc: subprocess.Popen, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        assert time.monotonic() < deadline and proc.poll() is None, f"{what} never came"
        time.sleep(0.01)


def test_a_second_run_on_a_folder_in_use_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "run"
    first = subprocess.Popen(
        [*TWIN, "run", str(MIL), "--out", str(out), "--quiet"], stderr=subprocess.PIPE, text=True
    )
    try:
        lock = out / ".twin.lock"
        _wait_for(
            "the first run's lock",
            lambda: lock.exists() and lock.read_text().strip() == str(first.pid),
            first,
        )
        second = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--force")
        assert second.returncode == 2
        line = _one_line(second.stderr)
        assert line == f"twin: run folder {out} is in use by another twin process (pid {first.pid})", line
        # twin resume takes the same lock, before it reads anything in the folder
        resumed = _twin("resume", str(out))
        assert resumed.returncode == 2
        assert f"in use by another twin process (pid {first.pid})" in _one_line(resumed.stderr)
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=120)
    assert first.returncode == 130  # interrupted, its rows intact and its own
    rows = read_signals_csv(out / "signals.csv")
    assert len(rows) > 0 and "mechanics.wear_depth_true" in rows
    assert json.loads((out / "summary.json").read_text())["scenario"] == "mil-endurance"


def test_the_lock_is_held_through_the_monte_carlo_and_ctrl_c_there_marks_the_summary(tmp_path: Path) -> None:
    # the paper's replay: after its run (summary.json written) comes the Monte Carlo of its
    # uncertainty (about 20 s), which still writes into the folder (uncertainty.csv, summary)
    out = tmp_path / "run"
    p = subprocess.Popen(
        [*TWIN, "run", str(PAPER), "--out", str(out), "--quiet"], stderr=subprocess.PIPE, text=True
    )
    try:
        _wait_for("the run's summary", (out / "summary.json").exists, p)
        second = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--force")
        assert second.returncode == 2 and f"(pid {p.pid})" in _one_line(second.stderr)
    finally:
        p.send_signal(signal.SIGINT)
        err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    line = _one_line(err)
    assert "interrupted by SIGINT during the uncertainty's Monte Carlo" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and "Monte Carlo" in summary["error"]
    assert "interval_90" not in summary["drift_mm"] and "predicted" in summary["drift_mm"]
    assert not (out / "uncertainty.csv").exists()
    assert len(read_signals_csv(out / "signals.csv")) == 2881
    assert len(read_signals_csv(out / "errormodel.csv")) == 2881


def test_a_reused_folder_keeps_no_file_of_an_earlier_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    stale = ("uncertainty.csv", "errormodel.csv", "checkpoint.npz", "recording.rrd", "error_budget.png")
    for name in stale:
        (out / name).write_text("from an earlier run")
    # what kills left of atomic writes: twin's own temporary files
    leftovers = (".summary.json.4242.0123abcd.tmp", "checkpoint.npz.tmp")
    for name in leftovers:
        (out / name).write_text("half")
    (out / "notes.txt").write_text("the lab's own notes")
    (out / ".notes.txt.1.tmp").write_text("the lab's editor's")
    refused = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet")
    assert refused.returncode == 2 and "--force" in _one_line(refused.stderr)
    assert (out / "uncertainty.csv").read_text() == "from an earlier run"  # nothing touched
    r = _twin("run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet", "--force")
    assert r.returncode == 0, r.stderr
    for name in ("uncertainty.csv", "checkpoint.npz", *leftovers):
        assert not (out / name).exists(), name
    for name in ("errormodel.csv", "recording.rrd", "error_budget.png"):
        assert (out / name).read_bytes() != b"from an earlier run", name
    assert (out / "notes.txt").read_text() == "the lab's own notes"  # not twin's: left alone
    assert (out / ".notes.txt.1.tmp").read_text() == "the lab's editor's"


def _file_size_limit(limit: int):
    def apply() -> None:
        # a write beyond the limit then fails with EFBIG, as one on a full disk with ENOSPC
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


def _limited_run(
    out: Path, limit: int, env: dict[str, str] | None = None
) -> tuple[subprocess.CompletedProcess[str], str]:
    r = subprocess.run(
        [*TWIN, "run", str(PAPER), "--uncertainty", "0", "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=_file_size_limit(limit),
        env=env,
    )
    assert r.returncode == 1, r.stderr
    line = _one_line(r.stderr)
    assert line.startswith("twin: disk full (File too large) while writing "), line
    return r, line


def test_a_full_disk_mid_run_keeps_every_whole_row_and_says_so(tmp_path: Path) -> None:
    out = tmp_path / "run"
    _, line = _limited_run(out, 400_000)
    assert f"while writing {out / 'signals.csv'};" in line and "summary.json says so" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed: disk full" and "signals.csv" in summary["error"]
    text = (out / "signals.csv").read_bytes()
    assert 100_000 < len(text) <= 400_000 and text.endswith(b"\n")  # cut back to whole rows
    table = read_signals_csv(out / "signals.csv")
    assert len(table) > 100 and table.time[-1] < 28800.0
    assert not list(out.glob(".*.tmp"))


def test_a_full_disk_while_the_recording_is_written_says_so_in_one_line(tmp_path: Path) -> None:
    # 4 MB: signals.csv (3.0 MB) fits, recording.rrd (6.5 MB) does not; rerun writes it from its
    # own thread and logs its failure itself, which stays off stderr
    out = tmp_path / "run"
    _, line = _limited_run(out, 4_000_000)
    assert f"while writing {out / 'recording.rrd'};" in line, line
    assert json.loads((out / "summary.json").read_text())["status"] == "failed: disk full"
    assert len(read_signals_csv(out / "signals.csv")) == 2881  # every row
    assert 0 < (out / "recording.rrd").stat().st_size <= 4_000_000
    # a short run's recording is written once its plot is drawn (twin.outputs.recording_sink),
    # by the helper where there are two cores: the plot is whole, from before the failure;
    # drawn in this process it comes after the recording, and a failed run draws nothing new.
    # Either way no cut file is left (a PNG is written whole or not at all)
    png = out / "error_budget.png"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores >= 2:
        data = png.read_bytes()
        assert data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")
    else:
        assert not png.exists()
    assert not list(out.glob(".*.tmp"))


def test_a_disk_too_full_for_the_summary_says_that_too(tmp_path: Path) -> None:
    # 100 bytes: not even run.json (143 bytes) fits, nor the disk-full summary
    out = tmp_path / "run"
    _, line = _limited_run(out, 100)
    assert f"while writing {out / 'run.json'};" in line and "summary.json could not be written either" in line
    assert not (out / "summary.json").exists() and not list(out.glob(".*.tmp"))


def test_a_full_disk_while_the_fmus_libraries_are_cached_names_the_cache(tmp_path: Path) -> None:
    # a new cache with the built FMUs and the stepper in it, but none of the FMUs' libraries
    # taken out yet: the run's first write is one of them (larger than 12 kB)
    from twin.fmu.toolchain import LIBRARY_SUFFIX, private_cache_dir

    cache = tmp_path / "cache"
    cache.mkdir(mode=0o700)
    for f in private_cache_dir().iterdir():
        if f.name.endswith((".fmu", ".fmu.sha256")) or f.name.startswith("twin_stepper-"):
            shutil.copy(f, cache / f.name)
    assert list(cache.glob("*.fmu")) and list(cache.glob(f"twin_stepper-*{LIBRARY_SUFFIX}"))
    out = tmp_path / "run"
    _, line = _limited_run(out, 12_000, {**os.environ, "TWIN_CACHE_DIR": str(cache)})
    assert f"while writing {cache} (the library of " in line and ".fmu)" in line, line
    # the libraries are taken out when the FMUs' own checks initialize them, before the run
    # folder is made: nothing of the run was begun
    assert not out.exists()


#: the twin, started as the console script starts it, by a wrapper that says when twin.cli is
#: imported. The wrapper holds SIGINT blocked from its first line: a signal in its own lines (the
#: interpreter's start, the import, its print and call, where no program can catch one: on a busy
#: machine a KeyboardInterrupt there ended the wrapper, exit -2) waits for twin, whose
#: watcher takes it as soon as it starts; from twin.cli's main on, it is twin's
UP = [
    sys.executable,
    "-c",
    "import signal, sys; signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}); "
    "from twin.cli import console; print('up', flush=True); sys.exit(console())",
]


@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM"])
def test_a_signal_that_came_before_the_watcher_started_ends_the_run_in_one_line(
    name: str, tmp_path: Path
) -> None:
    # sent and pending before twin.cli's main (blocked, as it is once install() begins): the
    # watcher must take it when it starts. Blocked after the watcher started, the signal came to
    # the main thread meanwhile (a KeyboardInterrupt racing the watcher: exit 1) or, pending
    # there, was never taken (exit 0, a whole run)
    out = tmp_path / "run"
    signum = int(signal.Signals[name])
    p = subprocess.run(
        [
            sys.executable,
            "-c",
            f"import os, signal, sys; signal.pthread_sigmask(signal.SIG_BLOCK, {{{signum}}}); "
            f"os.kill(os.getpid(), {signum}); from twin.cli import console; sys.exit(console())",
            "run",
            str(PAPER),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == {"SIGINT": 130, "SIGTERM": 143}[name], p.stderr
    assert _one_line(p.stderr).startswith(f"twin: interrupted by {name}")
    if out.exists():  # the run had begun (a slow watcher): it keeps what it recorded and says so
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "interrupted" and name in summary["error"]


@pytest.mark.parametrize("delay", [0.0, 0.1, 0.15, 0.2, 0.25, 0.3, 0.6])
def test_ctrl_c_in_the_first_moments_exits_130_in_one_line(delay: float, tmp_path: Path) -> None:
    out = tmp_path / "run"
    p = subprocess.Popen(
        [*UP, "run", str(PAPER), "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert p.stdout is not None and p.stdout.readline() == "up\n"
    time.sleep(delay)  # in the imports (0.25 s), loading the scenario, the FMUs, the run
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    assert "interrupted" in _one_line(err)
    if out.exists():  # the run had begun: it keeps what it recorded and says so
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "interrupted" and "SIGINT" in summary["error"]


def test_ctrl_c_on_a_terminal_while_the_fmus_build_exits_130_and_writes_nothing(tmp_path: Path) -> None:
    # an empty cache: the five FMUs build (about 12 s); a terminal's Ctrl-C reaches the whole
    # process group, so cmake dies too: that broken build is an interruption, not a build error
    out = tmp_path / "run"
    p = subprocess.Popen(
        [*UP, "run", str(PAPER), "--out", str(out), "--uncertainty", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env={**os.environ, "TWIN_CACHE_DIR": str(tmp_path / "cache")},
    )
    assert p.stdout is not None and p.stdout.readline() == "up\n"
    time.sleep(1.5)
    os.killpg(p.pid, signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    # the FMUs whose build began before the signal said so, one line each; then the end's line
    progress = [line for line in err.splitlines() if line.startswith("twin: building ")]
    assert _one_line("\n".join(line for line in err.splitlines() if line not in progress)) == (
        "twin: interrupted by SIGINT"
    )
    assert not out.exists()  # the folder is made after the build


def test_ctrl_c_while_the_error_model_runs_exits_130_and_keeps_the_data(tmp_path: Path) -> None:
    # signals.csv's last row (t = 28800 s) is written when the co-simulation ends; then come
    # the error model, errormodel.csv and the plot, before the Monte Carlo. Rows every 5 s
    # (5761, more than FLUSH_ROWS): the run writes them as it goes, not after its plots as it
    # does a run whose rows all come at once (the replay's 2881 at 10 s)
    out = tmp_path / "run"
    csv = out / "signals.csv"
    every_5_s = ["--set", 'scenario.output_interval="5 s"']
    p = subprocess.Popen(
        [*TWIN, "run", str(PAPER), "--out", str(out), "--quiet", *every_5_s],
        stderr=subprocess.PIPE,
        text=True,
    )

    def last_row_written() -> bool:
        if not csv.exists() or csv.stat().st_size < 10_000:
            return False
        with open(csv, "rb") as f:
            f.seek(-10_000, os.SEEK_END)  # more than a row (about 1.5 kB)
            return f.read().rstrip(b"\n").rsplit(b"\n", 1)[-1].startswith(b"28800,")

    try:
        _wait_for("the co-simulation's last row", last_row_written, p)
    finally:
        p.send_signal(signal.SIGINT)
        err = p.communicate(timeout=120)[1]
    assert p.returncode == 130, err
    line = _one_line(err)
    assert "interrupted by SIGINT after the co-simulation" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and "after the co-simulation" in summary["error"]
    assert "interval_90" not in summary["drift_mm"] and not (out / "uncertainty.csv").exists()
    assert len(read_signals_csv(csv)) == 5761  # every row, and the error model's on them
    assert len(read_signals_csv(out / "errormodel.csv")) == 5761
    assert "predicted" in summary["drift_mm"]
    # the plot only draws errormodel.csv: left out once the signal came (then named in the summary)
    assert (out / "error_budget.png").exists() != ("error_budget.png" in summary["error"])


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


def test_a_plot_that_fails_after_the_run_leaves_a_summary_saying_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # a plot that could not be drawn (a coefficients file of 1e308 made its matrix singular)
    # ended the run after its data was written, and the folder was left without summary.json
    from twin.cli import main
    from twin.outputs import plot_process, plots

    def singular(*_args: object, **_kw: object) -> None:
        raise ValueError("Singular matrix")

    monkeypatch.setattr(plot_process.PlotProcess, "started", classmethod(lambda cls: None))  # drawn here
    monkeypatch.setattr(plots, "budget_figure", singular)
    out = tmp_path / "run"
    argv = ["run", "constant-load", "--set", 'scenario.duration="2 min"', "--out", str(out), "--quiet"]
    assert main(argv) == 1
    line = _one_line(capsys.readouterr().err)
    assert line.startswith("twin: error_budget.png: the plot failed: ValueError: Singular matrix;"), line
    assert f"everything recorded is in {out}; summary.json says so" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary == {
        "scenario": "constant-load",
        "status": "failed",
        "error": "error_budget.png: the plot failed: ValueError: Singular matrix",
    }
    assert len(read_signals_csv(out / "signals.csv")) == 121  # every row of the 2 min
    assert not (out / "error_budget.png").exists() and not list(out.glob(".*.tmp"))
