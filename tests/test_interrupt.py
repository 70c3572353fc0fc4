"""The first SIGINT or SIGTERM ends every command within 5 s, whatever it is doing: one line
on stderr (no traceback), exit 130 or 143, no process of the command left, and "interrupted"
in the summary.json it writes (twin.cli.interrupt).

Each test starts the real command (``python -m twin``, a process group of its own), waits
until its output or its processes show the phase, then sends the signal at a seeded random
moment within it: to the whole group as a terminal's Ctrl-C does, or to the command alone as
a batch system's SIGTERM may.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import psutil
import pytest

from twin.config.load import scenarios_dir
from twin.fmu import toolchain, workdir

TWIN = [sys.executable, "-m", "twin"]
#: the contract: the command has ended this long after the first signal
LIMIT_S = 5.0
#: processes of a compile (twin build, a first use)
COMPILERS = {
    "cmake",
    "make",
    "gmake",
    "ninja",
    "cc",
    "gcc",
    "cc1",
    "c++",
    "g++",
    "cc1plus",
    "as",
    "ld",
    "collect2",
}
PROGRESS = re.compile(r"^uncertainty: (\d+)/(\d+) samples \(\d+ %\), \d+\.\d s$")


class Command:
    """A twin command in a process group of its own, its stdout read line by line as it comes."""

    def __init__(self, args: list[str], cwd: Path, env: dict[str, str] | None = None) -> None:
        self.proc = subprocess.Popen(
            [*TWIN, *args],
            cwd=cwd,
            env={**os.environ, **(env or {})},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        self.lines: list[str] = []
        self.started = time.monotonic()
        self.seen: set[int] = set()  # every process of the command seen so far
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def processes(self) -> list[psutil.Process]:
        """The command and every process it started (by parent chain or process group)."""
        found = {}
        try:
            me = psutil.Process(self.proc.pid)
            found[me.pid] = me
            for child in me.children(recursive=True):
                found[child.pid] = child
        except psutil.Error:
            pass
        for proc in psutil.process_iter():
            try:
                if os.getpgid(proc.pid) == self.proc.pid:
                    found[proc.pid] = proc
            except (OSError, psutil.Error):
                pass
        self.seen |= set(found)
        return list(found.values())

    def wait_for(self, what: str, ready: Callable[[], bool], timeout: float = 60.0) -> None:
        """Wait until ``ready()`` (the phase has begun); fails if the command ended first."""
        deadline = time.monotonic() + timeout
        while not ready():
            self.processes()
            if self.proc.poll() is not None:
                _out, err = self.proc.communicate()
                pytest.fail(f"ended ({self.proc.returncode}) before {what}: {self.lines} {err}")
            if time.monotonic() > deadline:
                self.kill()
                pytest.fail(f"no {what} within {timeout} s: {self.lines}")
            time.sleep(0.02)

    def line(self, pattern: str) -> Callable[[], bool]:
        return lambda: any(re.search(pattern, line) for line in self.lines)

    def compiling(self) -> bool:
        for proc in self.processes():
            try:
                if proc.name() in COMPILERS:
                    return True
            except psutil.Error:
                pass
        return False

    def interrupt(self, sig: signal.Signals, delay: float, group: bool = True) -> float:
        """Send ``sig`` after ``delay`` s, then wait for the command's end; the seconds it took."""
        time.sleep(delay)
        self.processes()
        assert self.proc.poll() is None, f"the command ended before the signal: {self.lines}"
        sent = time.monotonic()
        if group:
            os.killpg(self.proc.pid, sig)
        else:
            self.proc.send_signal(sig)
        try:
            self.proc.wait(timeout=LIMIT_S + 10)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(f"still running {LIMIT_S + 10} s after {sig.name}")
        return time.monotonic() - sent

    def stderr(self) -> list[str]:
        assert self.proc.stderr is not None
        self._reader.join(timeout=5)
        return [line for line in self.proc.stderr.read().splitlines() if line.strip()]

    def kill(self) -> None:
        for proc in self.processes():
            with contextlib.suppress(psutil.Error):
                proc.kill()


#: the line each FMU (and the stepper) built prints on stderr before it compiles
BUILD_PROGRESS = "twin: building "


def assert_ended(cmd: Command, sig: signal.Signals, took: float) -> str:
    """The contract of one interruption; returns the one line (the build's progress lines,
    one per FMU compiled before the signal, are progress, not the interruption's say)."""
    err = [line for line in cmd.stderr() if not line.startswith(BUILD_PROGRESS)]
    code = {signal.SIGINT: 130, signal.SIGTERM: 143}[sig]
    assert cmd.proc.returncode == code, (cmd.proc.returncode, err)
    assert took < LIMIT_S, f"took {took:.2f} s"
    assert len(err) == 1, err
    assert err[0].startswith("twin: ") and "interrupted" in err[0] and "Traceback" not in err[0], err
    assert sig.name in err[0], err
    time.sleep(0.3)  # an orphan killed at the end is reaped meanwhile
    left = []
    for pid in cmd.seen | {p.pid for p in cmd.processes()}:
        try:
            proc = psutil.Process(pid)
            # a zombie has ended (a container's first process may never reap an orphan)
            if proc.status() != psutil.STATUS_ZOMBIE:
                left.append((pid, proc.cmdline()[:3]))
        except psutil.Error:
            pass
    assert not left, left
    return err[0]


def summary_status(folder: Path) -> str | None:
    path = folder / "summary.json"
    return json.loads(path.read_text())["status"] if path.exists() else None


def assert_study_kept(out: Path, line: str) -> None:
    """A study's folder, once made, says "interrupted"; one stopped before it made its folder
    (its cluster still starting) has recorded nothing, and its line names no folder."""
    if out.exists():
        assert summary_status(out) == "interrupted", line
        assert str(out) in line, line
    else:
        assert str(out) not in line, line


def short_run(out: Path, samples: int, minutes: int) -> list[str]:
    return [
        "run",
        "--out",
        str(out),
        "--uncertainty",
        str(samples),
        "--set",
        f"scenario.duration={minutes} min",
    ]


# ----------------------------------------------------------------------------- the phases


def test_twin_build_interrupted_while_compiling(tmp_path: Path) -> None:
    rng = random.Random(331)
    cmd = Command(
        ["build", "--out", str(tmp_path / "fmus")], tmp_path, {"TWIN_CACHE_DIR": str(tmp_path / "cache")}
    )
    cmd.wait_for("a compiler", cmd.compiling)
    took = cmd.interrupt(signal.SIGINT, rng.uniform(0.0, 1.0))
    assert_ended(cmd, signal.SIGINT, took)
    for fmu in (tmp_path / "fmus").glob("*"):  # what was built whole may stay, nothing half
        assert fmu.suffix == ".fmu" and zipfile.is_zipfile(fmu), fmu


def test_first_use_compile_interrupted_by_sigterm_to_the_command_alone(tmp_path: Path) -> None:
    rng = random.Random(332)
    out, cache, scratch = tmp_path / "run", tmp_path / "cache", tmp_path / "tmp"
    scratch.mkdir()
    cmd = Command(
        short_run(out, 0, minutes=2), tmp_path, {"TWIN_CACHE_DIR": str(cache), "TMPDIR": str(scratch)}
    )
    cmd.wait_for("a compiler", cmd.compiling)
    took = cmd.interrupt(signal.SIGTERM, rng.uniform(0.0, 1.0), group=False)
    assert_ended(cmd, signal.SIGTERM, took)
    assert not out.exists()  # the folder is made after the build
    # the build's scratch folders outlive the command (it leaves without its teardown); the
    # next build removes them, and they hold nothing of a finished FMU
    private = scratch / f"twin-{os.getuid()}"
    left = [*cache.glob(f"{toolchain.SCRATCH}*"), *private.glob("pid-*")]
    assert left, "the build had no scratch folder"
    toolchain.clean_scratch(cache)
    workdir.clean_stale(private)
    assert not [*cache.glob(f"{toolchain.SCRATCH}*"), *private.glob("pid-*")]


def test_a_build_starts_no_cmake_once_its_children_are_ended(tmp_path: Path) -> None:
    """Ending the command's processes closes its builds first: its main thread, running on,
    cannot start the next FMU's cmake after the last look for processes (a build interrupted
    between two FMUs left one running, with its make, after the command had ended)."""
    code = (
        "from pathlib import Path\n"
        "from twin.cli import interrupt\n"
        "from twin.errors import BuildError\n"
        "from twin.fmu import toolchain\n"
        "interrupt.end_children()\n"
        "try:\n"
        f"    toolchain.run_cmake(Path({str(tmp_path)!r}), Path({str(tmp_path / 'build')!r}), 'a test')\n"
        "except BuildError as exc:\n"
        "    print(exc)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    # refused before cmake started (a cmake started on an empty folder fails its configure)
    assert r.stdout.strip() == "building a test: not started, the command is ending", r.stdout
    assert not (tmp_path / "build").exists()


def test_a_signal_while_the_toolchain_module_is_still_loading_ends_the_command() -> None:
    """A signal in the imports can find twin.fmu.toolchain in sys.modules with its body not yet
    run (its own imports under way): the ending, which closes the builds, raised there, the
    watcher died, and the main thread parked for good at its next park() (the command hung;
    a Ctrl-C 0.2 s after the start did so once in CI). The module as the import leaves it
    while its body runs, then the signal: the command ends with its one line."""
    code = (
        "import os, signal, sys, time, types\n"
        "from twin.cli import interrupt\n"
        "interrupt.install()\n"
        "sys.modules['twin.fmu.toolchain'] = types.ModuleType('twin.fmu.toolchain')\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(LIMIT)\n"
        "interrupt.park()\n"
    ).replace("LIMIT", repr(LIMIT_S))
    started = time.monotonic()
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    took = time.monotonic() - started
    assert r.returncode == 130, (r.returncode, r.stderr)
    assert r.stderr.strip() == "twin: interrupted by SIGINT", r.stderr
    assert took < LIMIT_S, took


def test_monte_carlo_start_interrupted(tmp_path: Path) -> None:
    rng = random.Random(333)
    out = tmp_path / "run"
    # 60 prior and 60 updated samples of 40 h: seconds of Monte Carlo, a signal within 0.8 s of
    # its first line finds it running
    cmd = Command(short_run(out, 60, minutes=2400), tmp_path)
    cmd.wait_for("the Monte Carlo's start", cmd.line(r"^uncertainty: 60 prior samples"))
    took = cmd.interrupt(signal.SIGINT, rng.uniform(0.0, 0.8))
    line = assert_ended(cmd, signal.SIGINT, took)
    assert summary_status(out) == "interrupted", line
    assert "Monte Carlo" in json.loads((out / "summary.json").read_text())["error"]
    assert not (out / "uncertainty.csv").exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_monte_carlo_interrupted_and_a_second_signal_changes_nothing(
    tmp_path: Path, sig: signal.Signals
) -> None:
    rng = random.Random(334 + sig)
    out = tmp_path / "run"
    # 64 prior and 64 updated samples of 40 h: seconds of Monte Carlo in process (2 min samples
    # all finish within a tenth of a second of the first)
    cmd = Command(short_run(out, 64, minutes=2400), tmp_path)
    cmd.wait_for("the Monte Carlo's progress", cmd.line(PROGRESS.pattern))
    delay = rng.uniform(0.0, 1.0)
    second = threading.Timer(delay + rng.uniform(0.05, 0.5), lambda: _signal_group(cmd, sig))
    second.start()
    took = cmd.interrupt(sig, delay)
    second.join()
    line = assert_ended(cmd, sig, took)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", line
    assert f"interrupted by {sig.name}" in summary["error"] and "Monte Carlo" in summary["error"]
    assert "interval_90" not in summary["drift_mm"]  # the run's own figures are kept
    assert (out / "signals.csv").stat().st_size > 0


def _signal_group(cmd: Command, sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(cmd.proc.pid, sig)


def test_nominal_run_interrupted(tmp_path: Path) -> None:
    rng = random.Random(335)
    out = tmp_path / "run"
    cmd = Command(short_run(out, 0, minutes=2400), tmp_path)
    cmd.wait_for("the run's signals", lambda: (out / "signals.csv").exists())
    took = cmd.interrupt(signal.SIGINT, rng.uniform(0.0, 1.0), group=False)
    line = assert_ended(cmd, signal.SIGINT, took)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", line
    assert "SIGINT" in summary["error"]


def test_sweep_interrupted(tmp_path: Path) -> None:
    rng = random.Random(336)
    spec = tmp_path / "tiny.toml"
    base = scenarios_dir() / "sine-load.toml"
    spec.write_text(
        f'[sweep]\nbase = "{base}"\ndesign = "grid"\nseed = 1\nset = ["scenario.duration = \\"20 min\\""]\n'
        'outputs = ["drift_mm.probe"]\n\n[grid]\n"fmu.hydraulic.parameters.load_amplitude" = '
        f"{[float(x) for x in range(0, 60_000, 2_000)]}\n"
    )
    out = tmp_path / "sweep"
    cmd = Command(["sweep", str(spec), "--out", str(out), "--workers", "2"], tmp_path)
    cmd.wait_for("the sweep's cluster", cmd.line(r"^scheduler tcp://"))
    took = cmd.interrupt(signal.SIGINT, rng.uniform(0.0, 3.0))
    line = assert_ended(cmd, signal.SIGINT, took)
    assert_study_kept(out, line)


def test_identify_interrupted(tmp_path: Path) -> None:
    rng = random.Random(337)
    target = tmp_path / "coefficients.toml"
    cmd = Command(["identify", "--out", str(target)], tmp_path)

    def experiments() -> bool:  # the first calibration experiment has loaded an FMU's library
        with contextlib.suppress(psutil.Error):
            return any("ThermalNetwork-" in m.path for m in psutil.Process(cmd.proc.pid).memory_maps())
        return False

    # no line until the end: the nine experiments and the fits take about a second
    cmd.wait_for("the calibration experiments", experiments)
    took = cmd.interrupt(signal.SIGTERM, rng.uniform(0.0, 0.3))
    assert_ended(cmd, signal.SIGTERM, took)
    assert not target.exists()


def test_heldout_interrupted(tmp_path: Path) -> None:
    rng = random.Random(338)
    out = tmp_path / "heldout"
    cmd = Command(["heldout", "--testers", "2", "--out", str(out)], tmp_path)
    cmd.wait_for("the testers' start", cmd.line(r"^heldout: 2 testers x"))
    took = cmd.interrupt(signal.SIGINT, rng.uniform(0.0, 2.0))
    line = assert_ended(cmd, signal.SIGINT, took)
    assert_study_kept(out, line)


# ----------------------------------------------------------------------------- the progress


@pytest.mark.slow  # two runs with their Monte Carlo: a few seconds, twice that on a busy machine
def test_monte_carlo_progress_without_a_terminal(tmp_path: Path) -> None:
    r = subprocess.run(
        [*TWIN, *short_run(tmp_path / "a", 20, minutes=2)], cwd=tmp_path, capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    assert "\r" not in r.stdout and "\r" not in r.stderr
    told = [PROGRESS.match(line) for line in r.stdout.splitlines()]
    counts = [int(m.group(1)) for m in told if m]
    # the default run is the updated tester's: 20 prior and 20 updated samples, a line per tenth
    assert counts == [4, 8, 12, 16, 20, 24, 28, 32, 36, 40], r.stdout
    assert "failed" not in r.stdout, r.stdout  # a 2 min run's samples run (their room has two points)
    quiet = subprocess.run(
        [*TWIN, *short_run(tmp_path / "b", 2, minutes=2), "--quiet"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert quiet.returncode == 0 and quiet.stdout == "" and quiet.stderr == "", quiet


def test_progress_tells_each_tenth_once() -> None:
    from twin.pipeline.montecarlo import Progress

    lines: list[str] = []
    progress = Progress(64, lines.append, start=time.perf_counter())
    for done in range(1, 65):
        progress.done(done)
    assert [int(PROGRESS.match(x).group(1)) for x in lines] == [7, 13, 20, 26, 32, 39, 45, 52, 58, 64]
    few: list[str] = []
    small = Progress(3, few.append)
    for done in (1, 2, 3):
        small.done(done)
    assert [x.split()[1] for x in few] == ["1/3", "2/3", "3/3"]
