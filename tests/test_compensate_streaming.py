"""`twin compensate` streams its file (issue 13): read in blocks, evaluated in chunks, written as it
goes; the numbers are those of the whole record evaluated at once, whatever the chunk ends."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from twin.errormodel.evaluate import evaluate
from twin.errormodel.sources import DEFAULT_TEMPERATURES
from twin.outputs.csv import write_signals_csv
from twin.pipeline.compensation import compensate, compensation_config
from twin.signals.table import Signal, SignalTable

SENSORS = ("load", "torque", "angle", "vibration")
TOML = (
    "[errormodel]\n"
    'reading = "probe"\ntrue_wear = "wear"\n'
    + "".join(f'{s} = "{s}"\n' for s in SENSORS)
    + 'factors = ["thermal", "loading", "fluctuating", "positioning", "interference"]\n'
    + 'drift_window = "2 min"\n'
    + "temperatures = { "
    + ", ".join(f'{p} = "T{i}"' for i, p in enumerate(DEFAULT_TEMPERATURES))
    + " }\n"
)


def record(n: int, seed: int = 3) -> dict[str, np.ndarray]:
    """A lab's record at 1 s with every sensor, noise and spikes the robust filter takes out."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float) + 0.5
    rise = 4.0 * (1 - np.exp(-t / 900.0))
    cols = {"time": t}
    for i in range(8):
        cols[f"T{i}"] = 293.15 + (0.6 + 0.1 * i) * rise + 0.01 * rng.standard_normal(n)
    wear = 1e-6 * np.sqrt(t / 60.0)
    # heavy-tailed noise: many samples near the filter's threshold, so a window cut short at a
    # chunk end would flag differently
    probe = 4.8e-3 - 2e-6 * rise - wear + 4e-7 * rng.standard_t(2, n)
    spikes = rng.choice(n, size=max(1, n // 150), replace=False)
    probe[spikes] += 2e-5 * rng.choice([-1.0, 1.0], size=spikes.size)
    cols["probe"] = probe
    cols["load"] = 5000 + 400 * np.sin(t / 50) + rng.standard_normal(n)
    cols["torque"] = 2 + 0.3 * np.sin(t / 70) + 0.01 * rng.standard_normal(n)
    cols["angle"] = np.mod(t * 0.3, 2 * np.pi)
    cols["vibration"] = 1e-7 * rng.standard_normal(n)
    cols["wear"] = wear
    return cols


def write_csv(path: Path, cols: dict[str, np.ndarray]) -> None:
    lines = [",".join(cols)]
    lines += [",".join(repr(float(v[k])) for v in cols.values()) for k in range(len(cols["time"]))]
    path.write_text("\n".join(lines) + "\n")


def whole(tmp_path: Path, cols: dict[str, np.ndarray], toml: str = TOML) -> tuple[bytes, dict]:
    """errormodel.csv and the summary numbers of the record evaluated at once, in memory
    (the configuration written to ``tmp_path / "lab.toml"``)."""
    (tmp_path / "lab.toml").write_text(toml)
    cfg, _ = compensation_config(tmp_path / "lab.toml")
    table = SignalTable(time=cols["time"])
    for name, values in cols.items():
        if name != "time":
            table.add(Signal(name, "", "measured"), values.copy())
    evaluation = evaluate(table, cfg)
    names = [n for n in table.names() if n.startswith("errormodel.")]
    write_signals_csv(table.subset(names), tmp_path / "whole.csv", sidecar=False)
    return (tmp_path / "whole.csv").read_bytes(), evaluation.summary


def _same_numbers(streamed: dict, reference: dict, path: str = "") -> None:
    """Every number of the summary the same; RMS values (a running sum) to 1e-12."""
    assert set(streamed) == set(reference), path
    for key, ref in reference.items():
        got, where = streamed[key], f"{path}.{key}"
        if isinstance(ref, dict):
            _same_numbers(got, ref, where)
        elif "rms" in where and "residual" not in where:
            assert got == pytest.approx(ref, rel=1e-12, abs=1e-18), where
        else:
            assert got == ref, where


@pytest.mark.parametrize(
    ("rows", "block_bytes", "chunk_rows"),
    [
        (3000, 1 << 22, 1 << 15),
        (3000, 997, 7),
        (3000, 4096, 64),
        (3000, 1, 1000),
        (3000, 50_000, 41),
        (15, 64, 3),
    ],
    ids=["one-chunk", "tiny-blocks-7-rows", "4k-blocks-64-rows", "byte-by-byte", "odd-sizes", "short-record"],
)
def test_a_streamed_file_gives_the_whole_records_numbers(
    rows: int, block_bytes: int, chunk_rows: int, tmp_path: Path
) -> None:
    cols = record(rows)
    reference_csv, reference = whole(tmp_path, cols)
    write_csv(tmp_path / "lab.csv", cols)
    summary = compensate(
        tmp_path / "lab.csv",
        tmp_path / "lab.toml",
        tmp_path / "out",
        block_bytes=block_bytes,
        chunk_rows=chunk_rows,
    )
    # every result of every row, bit for bit, across the chunk ends (the filter's windows, the
    # first row every series is taken relative to)
    assert (tmp_path / "out" / "errormodel.csv").read_bytes() == reference_csv
    assert reference["interference_spikes"] > 0 or rows < 100  # the filter had spikes to find
    streamed = {k: v for k, v in summary.items() if k in reference}
    _same_numbers(streamed, reference)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["drift_mm"] == reference["drift_mm"]


@pytest.mark.parametrize("window", ['"1 s"', '"10 s"', '"40 min"', '"2 h"'])
def test_drift_windows_across_chunk_ends(window: str, tmp_path: Path) -> None:
    # a window of a few rows, of many chunks, and longer than the record (head and tail overlap)
    cols = record(2500, seed=5)
    (tmp_path / "w").mkdir()
    toml = TOML.replace('drift_window = "2 min"', f"drift_window = {window}")
    _, reference = whole(tmp_path / "w", cols, toml)
    write_csv(tmp_path / "lab.csv", cols)
    summary = compensate(
        tmp_path / "lab.csv", tmp_path / "w" / "lab.toml", tmp_path / "out", block_bytes=3000, chunk_rows=13
    )
    _same_numbers({k: v for k, v in summary.items() if k in reference}, reference)
