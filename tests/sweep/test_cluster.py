"""Acceptance of ``twin sweep`` on real Dask clusters.

- the same sweep through ``--scheduler`` (a ``dask scheduler`` and two ``dask worker``
  processes with empty caches and no compiler), on the default local cluster and on one
  worker gives identical tables;
- a sweep killed with SIGKILL halfway and completed with ``--resume`` gives the table of an
  uninterrupted run;
- a worker dying in a point: the point is retried once, then recorded as failed;
- a Saltelli sweep of the paper's thermal experiment finds the room's temperature rise the
  dominant input of the probe's drift, as the physics says.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cloudpickle
import pandas as pd
import pytest

from tests.sweep.helpers import child_env, run_sweep_cli, stop, sweep_cmd, write_spec
from twin.pipeline import RunControls
from twin.pipeline.cluster import StudyOptions
from twin.pipeline.point import point_task
from twin.sweep.runner import run_sweep
from twin.sweep.spec import load_spec

# 40 points of the paper's replay shortened to an hour; a conductance drawn from a normal
# distribution partly below zero makes some points fail on the client (outside the physical
# range), which must be recorded identically too. (A bounded distribution reaching below zero
# is refused before any point runs: the sweep checks its ends. A normal one has none.)
BODY = """design = "lhs"
samples = 40
seed = 11
set = ['scenario.duration = "60 min"']
outputs = ["drift_mm.probe", "drift_mm.predicted", "compensation.residual_rms_um.after"]

[problem]
names = ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift",
         "fmu.thermal.parameters.g_detecting_frame_room"]
bounds = [[0.0, 9.0], [-0.3e-6, 0.3e-6], [4.0, 3.0]]
dists = ["unif", "unif", "norm"]
"""
N_POINTS = 40


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_spec(tmp_path_factory.mktemp("spec") / "paper-lhs.toml", BODY)


def _table(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out / "results.parquet")


@pytest.fixture(scope="module")
def reference(spec: Path, tmp_path_factory: pytest.TempPathFactory) -> pd.DataFrame:
    """The sweep on the default local cluster (one worker per core)."""
    out = tmp_path_factory.mktemp("local") / "out"
    done = run_sweep_cli(spec, out)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "" and done.stderr == ""  # --quiet and no terminal: nothing printed
    return _table(out)


def test_reference_has_every_point_ok_or_failed_with_its_reason(reference: pd.DataFrame) -> None:
    assert list(reference["point"]) == list(range(N_POINTS))
    failed = reference[reference["status"] == "failed"]
    ok = reference[reference["status"] == "ok"]
    assert 0 < len(failed) < N_POINTS // 2
    assert (failed["fmu.thermal.parameters.g_detecting_frame_room"] < 0).all()
    assert failed["error"].str.contains("outside the physical range").all()
    assert failed["drift_mm.probe"].isna().all()
    assert ok["drift_mm.probe"].notna().all() and (ok["error"] == "").all()
    assert reference["seed"].nunique() == N_POINTS  # a seed of its own per point


def test_scheduler_local_cluster_and_one_worker_give_identical_tables(
    spec: Path, reference: pd.DataFrame, dask_cluster: dict, tmp_path: Path, private_cache: Path
) -> None:
    remote = run_sweep_cli(spec, tmp_path / "remote", "--scheduler", str(dask_cluster["address"]))
    assert remote.returncode == 0, remote.stderr
    one = run_sweep_cli(spec, tmp_path / "one", "--workers", "1")
    assert one.returncode == 0, one.stderr
    pd.testing.assert_frame_equal(_table(tmp_path / "remote"), reference)
    pd.testing.assert_frame_equal(_table(tmp_path / "one"), reference)
    # the workers could only run points with the client's binaries, shipped byte for byte
    client_files = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in private_cache.iterdir()}
    for cache in dask_cluster["caches"]:
        shipped = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in cache.iterdir()}
        assert shipped == client_files


def test_scheduler_file_reaches_the_same_cluster(
    spec: Path, reference: pd.DataFrame, dask_cluster: dict, tmp_path: Path
) -> None:
    """``--scheduler-file`` reads the address ``dask scheduler --scheduler-file`` wrote."""
    scheduler_file = Path(str(dask_cluster["logs"])) / "scheduler.json"
    done = run_sweep_cli(spec, tmp_path / "by-file", "--scheduler-file", str(scheduler_file))
    assert done.returncode == 0, done.stderr
    pd.testing.assert_frame_equal(_table(tmp_path / "by-file"), reference)


def _rows(out: Path) -> int:
    try:
        return len(_table(out))
    except (FileNotFoundError, OSError, ValueError):
        return 0


def test_sigkill_halfway_then_resume_gives_the_uninterrupted_table(
    spec: Path, reference: pd.DataFrame, tmp_path: Path
) -> None:
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        sweep_cmd(spec, out, "--workers", "1"), env=child_env(), start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 180
        while _rows(out) == 0 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its local cluster, mid-run
        proc.wait(timeout=30)
    finally:
        stop(proc)
    kept = _rows(out)
    assert 0 < kept < N_POINTS, f"not killed halfway: {kept} of {N_POINTS} rows"
    again = run_sweep_cli(spec, out)
    assert again.returncode == 2 and "already holds a sweep" in again.stderr
    resumed = run_sweep_cli(spec, out, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    pd.testing.assert_frame_equal(_table(out), reference)
    # the kept points were not run again (the table would be the same if they had been)
    assert json.loads((out / "summary.json").read_text())["timing"]["points_run"] == N_POINTS - kept


def _crashing(payload: dict, *, log: str, always: bool) -> dict:
    """Kill the worker process running this point: every time, or on the first try only."""
    with open(log, "a") as f:
        f.write(f"{payload['index']}\n")
    if always or Path(log).read_text().count("\n") == 1:
        os._exit(1)
    return point_task(payload)


@pytest.mark.parametrize(("always", "status"), [(True, "failed"), (False, "ok")])
def test_a_worker_dying_in_a_point_is_retried_once(tmp_path: Path, always: bool, status: str) -> None:
    spec = load_spec(write_spec(tmp_path / "one.toml", BODY.replace("samples = 40", "samples = 1")))
    log = tmp_path / "tries.log"
    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers need not import tests
    task = functools.partial(_crashing, log=str(log), always=always)
    summary = run_sweep(spec, tmp_path / "out", RunControls(), StudyOptions(workers=1), task=task)
    row = _table(tmp_path / "out").iloc[0]
    assert log.read_text().split() == ["0", "0"]  # two tries, no third
    assert row["status"] == status and summary[status] == 1
    if always:
        assert row["error"].startswith("KilledWorker: a worker died while running this point (2 tries)")


def _quick_or_crashing(payload: dict, *, log: str, crash: int) -> dict:
    """A 20-ms point that records its try; point ``crash`` kills its worker every time."""
    with open(log, "a") as f:
        f.write(f"{payload['index']}\n")
    if payload["index"] == crash:
        os._exit(1)
    time.sleep(0.02)
    return {
        "index": payload["index"],
        "status": "ok",
        "error": "",
        "figures": {},
        "files": {},
        "point_s": 0.02,
    }


def test_a_crashing_point_in_a_batch_costs_its_neighbours_only_a_rerun(tmp_path: Path) -> None:
    """Short points travel in batches; when a batch's worker dies (twice: one retry), each of
    its points runs again alone, so only the crashing point is recorded as failed."""
    body = BODY.replace("samples = 40", "samples = 24").replace(
        "outputs = [", "# outputs = ["
    )  # the points return no figures
    # no point may fail on the client here: the conductance drawn far from zero
    spec = load_spec(write_spec(tmp_path / "b.toml", body.replace("[4.0, 3.0]", "[8.0, 1.0]")))
    log = tmp_path / "tries.log"
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    task = functools.partial(_quick_or_crashing, log=str(log), crash=20)
    summary = run_sweep(spec, tmp_path / "out", RunControls(), StudyOptions(workers=1), task=task)
    table = _table(tmp_path / "out")
    tries = log.read_text().split()
    assert list(table["point"]) == list(range(24)) and summary["ok"] == 23 and summary["failed"] == 1
    assert table.loc[20, "error"].startswith("KilledWorker: a worker died while running this point (2 tries)")
    assert tries.count("20") == 4  # twice in its batch, twice alone
    assert len(tries) < 24 + 2 * 16 + 4  # a batch's other points ran once in it and again alone, no more
    assert max(tries.count(str(i)) for i in range(24) if i != 20) <= 3


SOBOL = """design = "saltelli"
samples = 16
seed = 5
set = ['scenario.duration = "60 min"']
outputs = ["drift_mm.probe", "temperature_rise_C.detecting_frame"]

[problem]
names = ["input.thermal.t_room.rise", "input.thermal.q_hydraulic.value", "fmu.sensors.parameters.probe_noise"]
bounds = [[0.0, 9.0], [200.0, 400.0], [0.0, 1e-7]]
dists = ["unif", "unif", "unif"]
"""


def test_sobol_finds_the_room_the_dominant_input_of_the_thermal_drift(tmp_path: Path) -> None:
    """No load, no motion: the detecting frame follows the room air and, through the share of
    the embedded station's heat that reaches its bottom (scenarios/base/tester-geometry.toml
    [hydraulic_station]), the station's idle heat; the probe's white noise averages out of a
    drift read off 5-min fits. So the room carries most of the variance of the frame's rise,
    the station's heat a clear part of it (about a third over 200-400 W against a 0-9 K room),
    the noise none; and the room nearly all of the probe's drift."""
    spec = load_spec(write_spec(tmp_path / "sobol.toml", SOBOL))
    summary = run_sweep(spec, tmp_path / "out")
    assert summary["points"] == 16 * (3 + 2) and summary["failed"] == 0
    room, heat, noise = spec.names
    frame = summary["indices"]["temperature_rise_C.detecting_frame"]
    assert frame["ST"][room] > 0.5 and frame["ST"][room] > 1.5 * frame["ST"][heat]
    assert frame["ST"][heat] > 0.1 and frame["ST"][noise] < 0.01
    found = summary["indices"]["drift_mm.probe"]
    assert found["ST"][room] > 0.8
    assert found["ST"][room] > 5 * max(found["ST"][heat], found["ST"][noise])
    assert {"S1_conf", "ST_conf"} <= set(found)
    for png in ("sensitivity.png", "scatter.png", "histogram.png"):
        assert (tmp_path / "out" / png).read_bytes().startswith(b"\x89PNG")


def test_a_terminal_gets_a_progress_bar_and_sigterm_keeps_what_finished(tmp_path: Path) -> None:
    """On a terminal: where the sweep runs, the dashboard, a bar of points done and failed;
    SIGTERM stops it with exit 143, the table keeping every point that finished. (400 points:
    a point takes about 0.1 s, so the 40 of the other tests could all finish before the signal.)"""
    import pty
    import select

    n_points = 400
    spec = write_spec(tmp_path / "paper-lhs.toml", BODY.replace("samples = 40", f"samples = {n_points}"))
    out = tmp_path / "term"
    master, slave = pty.openpty()
    cmd = [c for c in sweep_cmd(spec, out, "--workers", "1") if c != "--quiet"]
    proc = subprocess.Popen(
        cmd, env=child_env(), stdin=slave, stdout=slave, stderr=slave, start_new_session=True
    )
    os.close(slave)
    text = b""
    try:
        deadline = time.monotonic() + 180
        while b"failed=" not in text and proc.poll() is None and time.monotonic() < deadline:
            if select.select([master], [], [], 0.5)[0]:
                text += os.read(master, 65536)
        proc.send_signal(signal.SIGTERM)  # the sweep's process only, as a service manager would
        while proc.poll() is None and time.monotonic() < deadline:
            if select.select([master], [], [], 0.5)[0]:
                try:
                    text += os.read(master, 65536)
                except OSError:
                    break
        proc.wait(timeout=60)
    finally:
        stop(proc)
        os.close(master)
    shown = text.decode(errors="replace")
    assert proc.returncode == 143, shown[-2000:]
    assert "dashboard: http://" in shown and "points:" in shown and "failed=" in shown
    assert "sweep interrupted by SIGTERM" in shown
    assert 0 < _rows(out) < n_points


def test_run_folders_come_back_from_the_workers(tmp_path: Path) -> None:
    body = BODY.replace("samples = 40", "samples = 3").replace('"60 min"', '"20 min"')
    spec = load_spec(
        write_spec(tmp_path / "f.toml", body.replace("seed = 11", "seed = 11\nrun_folders = true"))
    )
    run_sweep(spec, tmp_path / "with", RunControls(), StudyOptions(workers=1))
    plain = load_spec(write_spec(tmp_path / "p.toml", body))
    run_sweep(plain, tmp_path / "without", RunControls(), StudyOptions(workers=1))
    # the whole pipeline's run folder, and the same figures as the in-memory point
    pd.testing.assert_frame_equal(_table(tmp_path / "with"), _table(tmp_path / "without"))
    table = _table(tmp_path / "with")
    for i, status in zip(table["point"], table["status"], strict=True):
        folder = tmp_path / "with" / "runs" / f"point-{i:06d}"
        if status == "ok":
            assert {"signals.csv", "summary.json", "errormodel.csv"} <= {p.name for p in folder.iterdir()}
        else:
            assert not folder.exists()
    assert (table["status"] == "ok").any()
