"""The parts of a sweep without a cluster: the point function, the table on disk, the
analysis, the shipping of binaries, the worker's task."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.sweep.helpers import PAPER
from twin.config.load import load_scenario
from twin.errors import ConfigError, RunError
from twin.pipeline import RunSummary, Timing, prepare_scenario, run_point, shipping
from twin.pipeline.cluster import MAX_BATCH, TASK_SECONDS, TASKS_PER_THREAD_LEFT, _Batcher
from twin.pipeline.point import figures, point_task
from twin.pipeline.results import CSV, META, TABLE, ResultStore
from twin.sweep.analysis import indices, rank_correlations, statistics
from twin.sweep.spec import Spec


def test_a_points_figures_are_its_results_numbers_only() -> None:
    results = {
        "drift_mm": {"predicted": -0.02, "probe": -0.021, "paper_measured": -0.021},
        "sensors_used": {"load": True},
        "compensation": {"residual_rms_um": {"before": 5.0, "after": None}},
    }
    timing = Timing(cosim_s=1.0, write_s=0.0, total_s=1.0, macro_steps=1, fmu_steps=1, realtime_factor=1.0)
    flat = figures(RunSummary("x", "x.toml", "completed", 0, 60.0, timing, results=results))
    assert flat.keys() == {
        "drift_mm.predicted",
        "drift_mm.probe",
        "compensation.residual_rms_um.before",
        "compensation.residual_rms_um.after",
    }
    assert np.isnan(flat["compensation.residual_rms_um.after"])


def test_run_point_gives_the_run_s_figures_in_memory() -> None:
    scenario = load_scenario(PAPER, ['scenario.duration = "20 min"'])
    point = figures(run_point(prepare_scenario(scenario)))
    assert point["drift_mm.probe"] != 0.0  # the room and the station warm the tester: the reading moves
    # 20 min of a tester richer than the model: the compensation need not help yet (the paper's
    # full 480 min run is where it is judged); both residuals are real numbers of at most a few um
    for k in ("compensation.residual_rms_um.after", "compensation.residual_rms_um.before"):
        assert 0.0 < point[k] < 3.0, k
    assert point == figures(
        run_point(prepare_scenario(scenario))
    )  # same scenario, same seed: the same numbers


def test_point_task_records_a_failure_on_one_line() -> None:
    record = point_task({"index": 3, "run": None})
    assert record["index"] == 3 and record["status"] == "failed"
    assert record["error"].startswith("AttributeError: ") and "\n" not in record["error"]
    assert record["figures"] == {} and record["peak_rss_mb"] > 0


def test_short_points_travel_in_batches_long_ones_alone() -> None:
    batcher = _Batcher()
    assert batcher.size(remaining=1000, threads=2) == 1  # nothing timed yet: one per task
    for _ in range(4):
        batcher.took({"status": "ok", "point_s": 0.05})
    batcher.took({"status": "failed", "point_s": 9.0})  # a failure's time says nothing
    assert batcher.size(remaining=1000, threads=2) == int(TASK_SECONDS / 0.05)
    assert batcher.size(remaining=40, threads=2) == 40 // (TASKS_PER_THREAD_LEFT * 2)  # share the rest
    assert batcher.size(remaining=3, threads=2) == 1
    quick = _Batcher()
    quick.took({"status": "ok", "point_s": 1e-6})
    assert quick.size(remaining=10**6, threads=1) == MAX_BATCH
    slow = _Batcher()
    slow.took({"status": "ok", "point_s": 8.0})
    assert slow.size(remaining=10**6, threads=1) == 1


# ------------------------------------------------------------------------------ the table


def _row(i: int, status: str = "ok") -> dict:
    row = {
        "point": i,
        "seed": 100 + i,
        "x": i / 10,
        "status": status,
        "error": "" if status == "ok" else "E: x",
    }
    if status == "ok":
        row.update({"b.out": float(i), "a.out": 2.0 * i})
    return row


def test_store_writes_complete_tables_and_resumes(tmp_path: Path) -> None:
    meta = {"fingerprint": "abc"}
    store = ResultStore(tmp_path, ["x"], meta, resume=False)
    store.start()
    for i in (2, 0, 1):
        store.add(_row(i, "failed" if i == 1 else "ok"))
    store.flush(force=True)
    table = pd.read_parquet(tmp_path / TABLE)
    assert list(table.columns) == ["point", "seed", "x", "status", "error", "a.out", "b.out"]
    assert list(table["point"]) == [0, 1, 2] and np.isnan(table["a.out"][1])
    assert pd.read_csv(tmp_path / CSV, keep_default_na=False)["error"].tolist() == ["", "E: x", ""]
    assert json.loads((tmp_path / META).read_text()) == meta
    with pytest.raises(ConfigError, match="already holds a sweep"):
        ResultStore(tmp_path, ["x"], meta, resume=False)
    with pytest.raises(ConfigError, match="holds another study"):
        ResultStore(tmp_path, ["x"], {"fingerprint": "other"}, resume=True)
    again = ResultStore(tmp_path, ["x"], meta, resume=True)
    assert again.done == {0, 1, 2}
    pd.testing.assert_frame_equal(again.table(), table)


def _stored(folder: Path, inputs: dict[str, str]) -> dict[str, object]:
    meta = {"fingerprint": "f", "inputs": inputs}
    store = ResultStore(folder, ["x"], meta, resume=False, size=3)
    store.start()
    for i in range(2):
        store.add(_row(i))
    store.flush(force=True)
    return meta


def test_a_resume_names_every_input_that_changed(tmp_path: Path) -> None:
    inputs = {"sweep.set": "a", "file base.toml": "b", "FMU sources": "c"}
    meta = _stored(tmp_path, inputs)
    assert ResultStore(tmp_path, ["x"], meta, resume=True, size=3).done == {0, 1}
    for key in inputs:
        other = {"fingerprint": "f", "inputs": inputs | {key: "changed"}}
        with pytest.raises(
            ConfigError, match=f"--resume: holds another study \\({key} changed since it ran\\)"
        ):
            ResultStore(tmp_path, ["x"], other, resume=True, size=3)


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda d: (d / META).write_text("{"), "sweep.json: not a sweep's record"),
        (lambda d: (d / META).write_text("[]"), "sweep.json: not a sweep's record .a JSON list"),
        (lambda d: (d / TABLE).write_bytes(b"garbage" * 10), "results.parquet: not a results table"),
        (lambda d: pd.DataFrame({"point": [0], "seed": [1]}).to_parquet(d / TABLE), "no 'status' column"),
        (lambda d: _table(d, [999, -1]), "point 999 is not a point of this study .0 to 2."),
        (lambda d: _table(d, ["a", "b"]), "point 'a' is not a point of this study"),
        (lambda d: _table(d, [1, 1]), "point 1 appears twice"),
    ],
)
def test_a_damaged_folder_is_one_line_on_resume(tmp_path: Path, damage: object, message: str) -> None:
    meta = _stored(tmp_path, {"design": "d"})
    damage(tmp_path)  # type: ignore[operator]
    with pytest.raises(ConfigError, match=message) as info:
        ResultStore(tmp_path, ["x"], meta, resume=True, size=3)
    assert "\n" not in str(info.value)


def _table(folder: Path, points: list[object]) -> None:
    rows = {"point": points, "seed": [0] * len(points), "x": [0.0] * len(points)}
    rows |= {"status": ["ok"] * len(points), "error": [""] * len(points)}
    pd.DataFrame(rows).to_parquet(folder / TABLE)


def test_the_store_keeps_numbers_packed_not_a_dict_per_row(tmp_path: Path) -> None:
    import tracemalloc

    store = ResultStore(tmp_path, ["x"], {"fingerprint": "f"}, resume=False)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for i in range(20_000):
        store.add(_row(i) | {f"f{k}": float(k) for k in range(20)})
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    # 24 numbers a row at 8 bytes each, plus the point's index: a dict per row would be ~3 KB
    assert grown / 20_000 < 400, grown / 20_000
    assert store.table()["f3"].sum() == 3.0 * 20_000


def test_store_writes_at_most_about_once_a_second(tmp_path: Path) -> None:
    store = ResultStore(tmp_path, ["x"], {"fingerprint": "f"}, resume=False)
    store.start()
    store.add(_row(0))
    store.flush()
    first = (tmp_path / TABLE).stat().st_mtime_ns
    store.add(_row(1))
    store.flush()  # within the interval: not yet written
    assert (tmp_path / TABLE).stat().st_mtime_ns == first and len(pd.read_parquet(tmp_path / TABLE)) == 1
    store.flush(force=True)
    assert len(pd.read_parquet(tmp_path / TABLE)) == 2


# ------------------------------------------------------------------------------ analysis


def test_statistics_quantiles_ignore_failed_points() -> None:
    stats = statistics(pd.Series([*range(101), np.nan]))
    assert stats["n"] == 101 and stats["q05"] == 5.0 and stats["q50"] == 50.0 and stats["q95"] == 95.0


def _linear_spec(design: str, n: int) -> tuple[Spec, pd.DataFrame]:
    """y = 4 x1 + x2 on uniform [0, 1] inputs, x3 unused: S1 = ST = 16/17, 1/17, 0."""
    problem = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[0.0, 1.0]] * 3, "dists": ["unif"] * 3}
    spec = Spec(
        path=Path("s.toml"),
        name="s",
        scenario=load_scenario(PAPER),  # a design of its own: the scenario is not read
        design=design,
        samples=n,
        seed=1,
        problem=problem,
    )
    from twin.sweep.design import matrix

    x = matrix(spec)
    table = pd.DataFrame(x, columns=problem["names"])
    table["status"] = "ok"
    table["y"] = 4 * x[:, 0] + x[:, 1]
    return spec, table


def test_sobol_indices_of_a_known_function() -> None:
    spec, table = _linear_spec("saltelli", 1024)
    found = indices(spec, table, ["y"], len(table))["y"]
    assert found["S1"]["x1"] == pytest.approx(16 / 17, abs=0.05)
    assert found["ST"]["x2"] == pytest.approx(1 / 17, abs=0.02)
    assert abs(found["ST"]["x3"]) < 0.01 and found["ST_conf"]["x1"] > 0


def test_morris_ranks_a_known_function() -> None:
    spec, table = _linear_spec("morris", 20)
    found = indices(spec, table, ["y"], len(table))["y"]
    assert found["mu_star"]["x1"] == pytest.approx(4.0) and found["mu_star"]["x2"] == pytest.approx(1.0)
    assert found["mu_star"]["x3"] == pytest.approx(0.0)


@pytest.mark.parametrize("design", ["saltelli", "morris"])
def test_failed_points_take_their_block_out_and_are_named(design: str) -> None:
    spec, table = _linear_spec(design, 512 if design == "saltelli" else 20)
    table.loc[3, "status"] = "failed"
    table.loc[3, "y"] = np.nan
    found = indices(spec, table.iloc[:-1], ["y"], len(table))["y"]  # the last point did not run
    assert found["failed_points"] == [3, len(table) - 1]
    n = len(table) // (5 if design == "saltelli" else 4)
    assert found["blocks_used"] == f"{n - 2} of {n}"
    if design == "saltelli":
        assert found["S1"]["x1"] == pytest.approx(16 / 17, abs=0.06)
    else:
        assert found["mu_star"]["x1"] == pytest.approx(4.0)


def test_indices_are_skipped_naming_the_points_only_without_two_whole_blocks() -> None:
    spec, table = _linear_spec("saltelli", 2)
    table.loc[[1, 7], "status"] = "failed"
    found = indices(spec, table, ["y"], len(table))["y"]
    assert found["skipped"].startswith("points 1, 7 failed or gave no value: 0 of 2 whole blocks left")


def test_pawn_ranks_a_two_sided_driver_that_spearman_misses() -> None:
    """y = (x1 - 0.5)^2 + 0.05 x2: x1 drives y at both ends of its range, its rank correlation
    is about zero; PAWN ranks it first, far above the dummy's noise floor, x3 (unused) not."""
    from twin.sweep.analysis import pawn_indices

    spec, table = _linear_spec("lhs", 400)
    table["point"] = range(len(table))
    table["y"] = (table["x1"] - 0.5) ** 2 + 0.05 * table["x2"]
    ranks = rank_correlations(table, spec.names, "y")
    assert abs(ranks["x1"]) < 0.15 and abs(ranks["x2"]) > abs(ranks["x1"])
    found = pawn_indices(spec, table, "y")
    assert max(found["pawn"], key=found["pawn"].get) == "x1"
    assert found["pawn"]["x1"] > 3 * found["pawn_dummy"]
    assert found["pawn"]["x3"] < 2 * found["pawn_dummy"]


# ------------------------------------------------------------------------------ shipping


def _artifact(name: str, data: bytes) -> shipping.Artifact:
    return shipping.Artifact(name, data, hashlib.sha256(data).hexdigest())


def test_install_checks_every_file_before_writing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = shipping.collect()  # from the client's cache
    monkeypatch.setenv("TWIN_CACHE_DIR", str(tmp_path / "cache"))  # into a worker's empty one
    written = shipping.install(real)
    assert {p.name for p in written} == {a.name for a in real}
    assert shipping.install(real) == []  # already there, same bytes: nothing rewritten
    (tmp_path / "cache" / real[0].name).write_bytes(b"a local build")
    assert [p.name for p in shipping.install(real)] == [real[0].name]  # the client's bytes win
    damaged = shipping.Artifact(real[0].name, b"other bytes", real[0].sha256)
    with pytest.raises(RunError, match="sha256 mismatch"):
        shipping.install((damaged,))
    with pytest.raises(RunError, match="not a plain file name"):
        shipping.install((_artifact("../escape.so", b"x"),))
    with pytest.raises(RunError, match="differs from the client's"):
        shipping.install(real[1:])  # a worker whose twin expects a binary the client did not send


def test_a_workers_peak_memory_is_its_own_not_its_starters() -> None:
    """A process started by one holding 300 MB reports its own peak: ru_maxrss would report
    the starter's, and a worker's growth would not show under it."""
    import subprocess
    import sys

    child = "from twin.pipeline.cluster import peak_rss_mb; print(peak_rss_mb())"
    parent = (
        "import subprocess, sys\n"
        "held = bytearray(300 * 2**20)\n"
        "held[::4096] = b'x' * len(held[::4096])\n"
        f"print(subprocess.run([sys.executable, '-c', {child!r}], capture_output=True, text=True, check=True).stdout)"
    )
    done = subprocess.run([sys.executable, "-c", parent], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert 5.0 < float(done.stdout) < 150.0  # twin.pipeline.cluster and its imports: about 60 MB


def test_a_points_run_folder_never_follows_a_planted_symlink(tmp_path: Path) -> None:
    from twin.sweep.runner import _write_folder

    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    (out / "runs").symlink_to(outside)
    with pytest.raises(ConfigError, match="runs: is a symbolic link"):
        _write_folder(out, 3, {"summary.json": b"{}"})
    assert list(outside.iterdir()) == []
    (out / "runs").unlink()
    folder = out / "runs" / "point-000003"
    folder.mkdir(parents=True)
    (folder / "summary.json").symlink_to(outside / "victim.json")
    _write_folder(out, 3, {"summary.json": b"{}", "../escape.txt": b"x"})
    assert (folder / "summary.json").read_bytes() == b"{}" and not (folder / "summary.json").is_symlink()
    assert list(outside.iterdir()) == [] and not (out / "runs" / "escape.txt").exists()
