"""uncertainty.csv is written by the csv module with pandas' bytes (twin.pipeline.montecarlo
.write_samples): the file a run wrote through pandas before, checked against pandas itself."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin.pipeline.montecarlo import SAMPLE_COLUMNS, _csv_column, write_samples


def _pandas_way(path: Path, rows: list[dict]) -> None:
    """What write_samples did with pandas (main e0a56b6)."""
    frame = pd.DataFrame.from_records(list(rows))
    parts = sorted(c for c in frame.columns if c.startswith("thermal_parts_mm."))
    inputs = [c for c in frame.columns if c not in SAMPLE_COLUMNS and c not in parts]
    frame = frame.reindex(columns=[*SAMPLE_COLUMNS, *parts, *inputs])
    frame.to_csv(path, index=False)


def _rows(n: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        scale = 10.0 ** rng.integers(-22, 22)
        row = {
            "sample": i,
            "predictive": "prior" if i % 2 else "updated",
            "room_shape": ["exponential", "ramp", "s-curve"][i % 3],
            "status": "ok",
            "error": "",
            "drift_mm.probe": float(rng.normal() * scale),
            "drift_mm.predicted": float(rng.normal()),
            "thermal_parts_mm.z": float(rng.normal()),
            "thermal_parts_mm.a": -0.0 if i == 3 else float(rng.random()),
            "fmu.mechanics.parameters.alpha": float(rng.lognormal()) * 1e-5,
            "integral but float": float(i),
            "flag": bool(i % 2),
        }
        rows.append(row)
    return rows


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_same_bytes_as_pandas(tmp_path: Path, seed: int) -> None:
    rows = _rows(60, seed)
    # failed samples: figures missing, an error with a comma, quotes and a line break
    rows[5] = {k: v for k, v in rows[5].items() if not k.startswith(("drift_mm", "thermal_parts"))}
    rows[5].update(status="failed", error='FMU "mechanics": fmi2Error, at t = 3 s\nsecond line')
    rows[7]["drift_mm.predicted"] = math.nan
    rows[8]["fmu.mechanics.parameters.alpha"] = None
    rows[9]["only in some rows"] = 4  # ints with missing cells: pandas' float64
    rows[10]["only in some rows"] = 5
    rows[11]["a late key"] = "text"
    rows[12]["flag"] = None
    rows[13]["mixed"] = 1.5
    rows[14]["mixed"] = "x"
    for r in rows:
        r["float32 free, inf"] = math.inf if r["sample"] == 2 else -1e300
        # every row a float, one of them NaN: the column of floats alone (most of a run's)
        r["floats, a nan"] = math.nan if r["sample"] == 4 else r["sample"] / 7 - 3.0
    ours, theirs = tmp_path / "ours.csv", tmp_path / "theirs.csv"
    write_samples(ours, rows)
    _pandas_way(theirs, rows)
    assert ours.read_bytes() == theirs.read_bytes()


def test_no_rows_gives_the_header(tmp_path: Path) -> None:
    ours, theirs = tmp_path / "ours.csv", tmp_path / "theirs.csv"
    write_samples(ours, [])
    _pandas_way(theirs, [])
    assert ours.read_bytes() == theirs.read_bytes() == (",".join(SAMPLE_COLUMNS) + "\n").encode()


def test_no_pandas_import(tmp_path: Path) -> None:
    """Writing the samples loads neither pandas nor scipy.stats (the reason it is not pandas')."""
    code = (
        "import sys\nfrom pathlib import Path\nfrom twin.pipeline.montecarlo import write_samples\n"
        f"write_samples(Path({str(tmp_path / 'u.csv')!r}), [{{'sample': 0, 'x': 0.1}}])\n"
        "print('pandas' in sys.modules, 'scipy.stats' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]
    assert (tmp_path / "u.csv").read_text().splitlines()[1].endswith(",0.1")


def test_a_float_cell_is_numpy_s_text_of_the_double() -> None:
    """Python's shortest repr, which the cells take, is numpy's text of a float64 (pandas'):
    the same digits and the same notation, over every exponent and the edge cases."""
    rng = np.random.default_rng(32)
    values = rng.standard_normal(20_000) * 10.0 ** rng.integers(-320, 308, 20_000)
    edges = [
        0.0,
        -0.0,
        math.inf,
        -math.inf,
        1e16,
        9.999999999999998e15,
        1e-5,
        1e-4,
        5e-324,
        1.7976931348623157e308,
        0.1,
        1 / 3,
    ]
    values = np.concatenate([values, edges])
    assert _csv_column([float(v) for v in values]) == values.astype(str).tolist()
