"""recording.rrd: passes `rerun rrd verify`, values round-trip, the blueprint is in the file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from twin.outputs.rerun_rec import (
    BUDGET_VIEW_NAME,
    RecordingWriter,
    entity_path,
    read_recording,
    write_recording,
)
from twin.signals.table import Signal, SignalTable

from .sample import BUDGET


def _verify(path: Path) -> subprocess.CompletedProcess[str]:
    # `python -m rerun_cli` runs the CLI bundled with the rerun-sdk of this interpreter
    # (the same binary as the venv's `rerun` script), whatever is on PATH.
    return subprocess.run(
        [sys.executable, "-m", "rerun_cli", "rrd", "verify", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def _blueprint_rows(path: Path) -> list[dict[str, list]]:
    reader = RrdReader(path)
    (store,) = reader.blueprints()
    rows = []
    for chunk in reader.stream(store=store).to_chunks():
        batch = chunk.to_record_batch()
        rows.append({n: batch.column(n).to_pylist() for n in batch.schema.names if ":" in n})
    return rows


def test_rrd_verifies_and_values_round_trip(table: SignalTable, tmp_path: Path) -> None:
    path = write_recording(table, tmp_path / "recording.rrd", recording_name="test", budget_columns=BUDGET)
    result = _verify(path)
    assert result.returncode == 0, result.stderr
    series = read_recording(path)
    assert set(series) == {entity_path(table.meta[n]) for n in table.names()}
    t, values = series["/thermal/t_base"]
    np.testing.assert_array_equal(t, table.time)
    np.testing.assert_array_equal(values, table["thermal.t_base"])
    # lengths are recorded in µm: the metres times 1e6, the same multiplication, so exactly
    np.testing.assert_array_equal(series["/errormodel/e_total"][1], table["errormodel.e_total"] * 1e6)


def test_blueprint_has_error_budget_first_and_one_view_per_subsystem_and_unit(
    table: SignalTable, tmp_path: Path
) -> None:
    path = write_recording(table, tmp_path / "recording.rrd", budget_columns=BUDGET)
    rows = _blueprint_rows(path)
    views = {r["ViewBlueprint:display_name"][0][0]: r for r in rows if "ViewBlueprint:display_name" in r}
    # no view mixes units: the sample's thermal signals are K, its probe and errormodel ones m
    # (µm); the budget's columns (all the errormodel ones) are in the budget's view only; the
    # probe's reading (1.25 mm) and range (1e300 m) are views apart (issue 33)
    assert set(views) == {
        BUDGET_VIEW_NAME,
        "thermal [K]",
        "probe [µm] up to 1.26e+03",
        "probe [µm] up to 9.99e+305",
    }
    assert all(v["ViewBlueprint:class_identifier"][0] == ["TimeSeries"] for v in views.values())
    queries = [r["ViewContents:query"][0] for r in rows if "ViewContents:query" in r]
    assert ["+ /errormodel/e_total", *(f"+ /errormodel/{n.split('.')[1]}" for n in BUDGET[1:])] in queries
    assert ["+ /thermal/t_base", "+ /thermal/t_spindle"] in queries
    # The root container is vertical with the budget view first and the larger share.
    (root,) = [r for r in rows if r.get("ContainerBlueprint:row_shares")]
    assert root["ContainerBlueprint:row_shares"][0] == [3.0, 2.0]
    assert root["ContainerBlueprint:contents"][0][0].startswith("view/")


def test_static_series_names_and_units(table: SignalTable, tmp_path: Path) -> None:
    path = write_recording(table, tmp_path / "recording.rrd")
    static = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.is_static:
            batch = chunk.to_record_batch()
            static.setdefault(chunk.entity_path, {}).update(
                {n: batch.column(n).to_pylist()[0] for n in batch.schema.names if n != "rerun.controls.RowId"}
            )
    meta = static["/thermal/t_base"]
    assert meta["SeriesLines:names"] == ["t_base [K]"]
    # AnyValues components keep their plain names.
    assert (meta["signal"], meta["unit"], meta["description"]) == (["thermal.t_base"], ["K"], ["base plate"])
    assert (meta["si_unit"], meta["to_si"]) == (["K"], [1.0])
    length = static["/probe/reading"]
    assert length["SeriesLines:names"] == ["reading [µm]"]
    assert (length["unit"], length["si_unit"], length["to_si"]) == (["µm"], ["m"], [1e-6])
    assert not any(k.startswith("Scalars") for k in meta)  # the samples themselves are not static


def test_streaming_writer_matches_the_table(table: SignalTable, tmp_path: Path) -> None:
    signals = [table.meta[n] for n in table.names()]
    path = tmp_path / "stream.rrd"
    with RecordingWriter(path, signals, budget_columns=BUDGET) as writer:
        for lo in range(0, len(table), 100):
            writer.append(table.time[lo : lo + 100], {n: v[lo : lo + 100] for n, v in table.columns.items()})
    assert writer.rows == len(table)
    assert _verify(path).returncode == 0
    t, values = read_recording(path)["/probe/reading"]
    np.testing.assert_array_equal(t, table.time)
    np.testing.assert_array_equal(values, table["probe.reading"] * 1e6)


def _chunks(path: Path) -> dict[tuple[str, bool], list[tuple[tuple, dict[str, str]]]]:
    """Every chunk of a recording's data store by entity and staticness: its fields (name,
    type, metadata) and its columns' values (as text: NaN equals NaN), the row ids and the
    recording's start time left out (new for every recording)."""
    out: dict[tuple[str, bool], list[tuple[tuple, dict[str, str]]]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path == "/__properties":
            continue
        batch = chunk.to_record_batch()
        fields = tuple(
            (f.name, str(f.type), tuple(sorted((f.metadata or {}).items())))
            for f in batch.schema
            if "RowId" not in f.name
        )
        values = {n: repr(batch.column(n).to_pylist()) for n in batch.schema.names if "RowId" not in n}
        out.setdefault((chunk.entity_path, chunk.is_static), []).append((fields, values))
    return out


def test_the_series_are_sent_as_send_columns_sends_them(
    table: SignalTable, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the writer builds the Arrow arrays rr.send_columns would (without its conversions): the
    # recording holds the same chunks, fields and values as one written through rerun's API,
    # which is what a rerun without the native sender gets
    from twin.outputs import rerun_rec

    assert rerun_rec._bindings() is not None  # the rerun installed here has it
    signals = [table.meta[n] for n in table.names()]
    table.columns["thermal.t_base"][3] = np.nan  # a gap stays a gap
    ours = write_recording(table, tmp_path / "ours.rrd", recording_name="same")
    monkeypatch.setattr(rerun_rec, "_bindings", lambda: None)
    with RecordingWriter(tmp_path / "api.rrd", signals, recording_name="same") as writer:
        writer.append(table.time, dict(table.columns))
    theirs = _chunks(tmp_path / "api.rrd")
    assert _chunks(ours) == theirs
    assert len([k for k in theirs if not k[1]]) == len(signals)  # one series per signal
    assert _verify(ours).returncode == 0
    assert _verify(tmp_path / "api.rrd").returncode == 0


def test_sim_time_is_rounded_to_whole_nanoseconds(tmp_path: Path) -> None:
    table = SignalTable(time=np.array([0.0, 0.1, 0.3, 86400.7]))
    table.add(Signal("x.a", "m", "x"), np.arange(4.0))
    t, _ = read_recording(write_recording(table, tmp_path / "r.rrd"))["/x/a"]
    np.testing.assert_array_equal(t, table.time)  # truncation would give 0.299999999


def test_entity_paths() -> None:
    assert entity_path(Signal("thermal.t_base", "K", "thermal")) == "/thermal/t_base"
    assert entity_path(Signal("loading.f_radial", "N", "mechanics")) == "/mechanics/loading.f_radial"


def test_bad_budget_column_and_entity_collision(tmp_path: Path) -> None:
    signals = [Signal("x.a", "m", "x")]
    with pytest.raises(ValueError, match="not among the signals"):
        RecordingWriter(tmp_path / "a.rrd", signals, budget_columns=["x.b"])
    with pytest.raises(ValueError, match="both map to"):
        RecordingWriter(tmp_path / "b.rrd", [Signal("x.a", "m", "x"), Signal("a", "m", "x")])


# rerun-sdk 0.41 can leave a flush unanswered for ever when its file writer stops on a full
# disk just after the flush was queued (tests/test_run_faults.py fills a disk under a real run,
# where it happened in about half the runs); these stand-ins for the stream give its answers
# for certain: "timed out" from a writer that stopped, or from one still writing.
TIMED_OUT = "Flush timed out - not all log messages were sent"


class _Stream:
    """Answers each flush with a limit by "timed out", writing ``grow`` bytes to ``path``
    first; a flush without a limit (as rerun's default) is answered."""

    def __init__(self, path: Path, grow: int, answered_after: int | None = None) -> None:
        self.path, self.grow, self.answered_after = path, grow, answered_after
        self.flushes: list[float | None] = []

    def flush(self, *, timeout_sec: float | None = None) -> None:
        self.flushes.append(timeout_sec)
        if timeout_sec is None or (
            self.answered_after is not None and len(self.flushes) > self.answered_after
        ):
            return
        with open(self.path, "ab") as f:
            f.write(b"x" * self.grow)
        raise RuntimeError(TIMED_OUT)


@pytest.fixture
def rrd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A recording's file (its first bytes), and flushes that wait 10 ms at a time."""
    from twin.outputs import rerun_rec

    monkeypatch.setattr(rerun_rec, "FLUSH_CHECK_S", 0.01)
    monkeypatch.setattr(rerun_rec, "STALL_S", 0.01)
    path = tmp_path / "r.rrd"
    path.write_bytes(b"RRF2")
    return path


def test_a_flush_left_unanswered_on_a_full_disk_ends_in_its_os_error(rrd: Path) -> None:
    import errno
    import resource

    from twin.outputs import rerun_rec

    stream = _Stream(rrd, grow=0)
    limits = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (rrd.stat().st_size, limits[1]))  # the file is full
    try:
        with pytest.raises(rerun_rec._Stuck) as stuck:
            rerun_rec._flush(stream, rrd)  # type: ignore[arg-type]
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, limits)
    assert stream.flushes == [0.01]  # not asked again: a second flush may never be queued
    assert stuck.value.error.errno == errno.EFBIG and stuck.value.error.filename == str(rrd)
    assert rrd.read_bytes() == b"RRF2"


def test_an_unanswered_flush_on_a_disk_with_room_is_waited_for_as_before(rrd: Path) -> None:
    from twin.outputs import rerun_rec

    stream = _Stream(rrd, grow=0)
    rerun_rec._flush(stream, rrd)  # type: ignore[arg-type]
    assert stream.flushes == [0.01, None]  # not this bug: waited for without a limit
    assert rrd.read_bytes() == b"RRF2"  # the byte written to find out is cut off again


def test_a_slow_flush_is_waited_for_while_the_file_grows(rrd: Path) -> None:
    from twin.outputs import rerun_rec

    stream = _Stream(rrd, grow=100, answered_after=3)
    rerun_rec._flush(stream, rrd)  # type: ignore[arg-type]
    assert stream.flushes == [0.01] * 4


def test_a_long_chunk_goes_in_slices(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from twin.outputs import rerun_rec

    monkeypatch.setattr(rerun_rec, "CHUNK_ROWS", 100)
    table = SignalTable(np.arange(250.0))
    signal = Signal("thermal.t_base", "K", "thermal")
    table.add(signal, np.linspace(293.0, 300.0, 250))
    write_recording(table, tmp_path / "r.rrd")
    sizes = [
        chunk.num_rows
        for chunk in RrdReader(tmp_path / "r.rrd").stream().to_chunks()
        if not chunk.is_static and chunk.entity_path == entity_path(signal)
    ]
    assert sorted(sizes) == [50, 100, 100]
    t, v = read_recording(tmp_path / "r.rrd")[entity_path(signal)]
    np.testing.assert_array_equal(t, table.time)
    np.testing.assert_allclose(v, table["thermal.t_base"])


_BACKLOG = """
import sys
import numpy as np
from twin.outputs.rerun_rec import RecordingWriter
from twin.signals.table import Signal

def status_mb(key):  # VmHWM, not ru_maxrss: that keeps the forking parent's peak
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024

signals = [Signal(f"thermal.t_{i}", "K", "thermal") for i in range(40)]
columns = {s.name: np.random.default_rng(i).random(8192) for i, s in enumerate(signals)}
with RecordingWriter(sys.argv[1], signals) as writer:
    writer.append(np.arange(8192) * 10.0, columns)
    settled = status_mb("VmRSS")
    for k in range(1, 16):
        writer.append((np.arange(8192) + 8192 * k) * 10.0, columns)
    grown = status_mb("VmHWM") - settled
print(f"{grown:.1f}")
"""


def test_rows_sent_faster_than_rerun_writes_them_are_not_held_in_memory(tmp_path: Path) -> None:
    """16 blocks of 8192 rows x 40 columns (2.6 MB each) sent back to back: rerun queues what
    it is sent without a bound, and the blocks waiting there kept 55-100 MB more (measured)
    until written; the writer waits for the rows before, so memory stays flat."""
    rrd = tmp_path / "r.rrd"
    done = subprocess.run(
        [sys.executable, "-c", _BACKLOG, str(rrd)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) < 30.0  # MB above the first block's; without the wait: 55-100 MB
    t, _ = read_recording(rrd)[entity_path(Signal("thermal.t_0", "K", "thermal"))]
    np.testing.assert_array_equal(t, np.arange(16 * 8192) * 10.0)


_FULL_DISK = """
import errno, os, sys
from pathlib import Path
from twin.outputs import rerun_rec

folder = Path(sys.argv[1])
rrd = folder / "r.rrd"
rrd.write_bytes(b"RRF2")
with open(folder / "filler", "wb", buffering=0) as filler:  # the disk filled up
    try:
        while True:
            filler.write(b"x" * 4096)
    except OSError as exc:
        assert exc.errno == errno.ENOSPC, exc
full = rerun_rec._full(rrd)
os.remove(folder / "filler")
print(full.errno == errno.ENOSPC, full.filename == str(rrd), rrd.read_bytes() == b"RRF2",
      sorted(p.name for p in folder.iterdir()), rerun_rec._full(rrd))
"""


def test_a_full_disk_is_found_without_writing_into_the_recording(tmp_path: Path) -> None:
    """On a full disk (a 64 kB tmpfs in a private mount namespace), one byte to a new file beside
    the recording fails with ENOSPC: a flush rerun will never answer is known at its first
    timeout, not after the recording stalled for 8 s; the recording is not touched (rerun may
    be writing it) and the probe's file is gone; with room again, nothing is found."""
    import shutil

    folder = tmp_path / "disk"
    folder.mkdir()
    prefix = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c"]
    script = 'mount -t tmpfs -o size=64k tmpfs "$0" && exec "$@"'
    probe = subprocess.run([*prefix, script, str(folder), "true"], capture_output=True, check=False)
    if shutil.which("unshare") is None or probe.returncode != 0:
        pytest.skip(f"no private tmpfs here (unshare: {probe.stderr.decode(errors='replace').strip()})")
    done = subprocess.run(
        [*prefix, script, str(folder), sys.executable, "-c", _FULL_DISK, str(folder)],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "True", "['r.rrd']", "None"]
