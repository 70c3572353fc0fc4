"""The error-budget PNG: a real PNG of the fixed size, identical bytes for identical input."""

from __future__ import annotations

import struct
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from twin.outputs.plots import DPI, FIGSIZE_IN, error_budget_png
from twin.signals.table import SignalTable

from .sample import PARTS, make_table

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _draw(table: SignalTable, path: Path) -> Path:
    return error_budget_png(
        table,
        path,
        reading="probe.reading",
        predicted="errormodel.e_total",
        parts=PARTS,
        temperatures=["thermal.t_base", "thermal.t_spindle"],
        title="Paper experiment: error budget",
    )


def test_png_signature_and_size(table: SignalTable, tmp_path: Path) -> None:
    path = _draw(table, tmp_path / "budget.png")
    assert path == tmp_path / "budget.png"
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (round(FIGSIZE_IN[0] * DPI), round(FIGSIZE_IN[1] * DPI))
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (height, width)
    # Something was drawn: a good share of the pixels are not white.
    assert np.mean(pixels[..., :3].min(axis=-1) < 0.9) > 0.02


def test_same_input_same_bytes_and_no_software_stamp(tmp_path: Path) -> None:
    a = _draw(make_table(), tmp_path / "a.png").read_bytes()
    b = _draw(make_table(), tmp_path / "b.png").read_bytes()
    assert a == b
    assert b"matplotlib" not in a.lower()
    assert a != _draw(make_table(seed=8), tmp_path / "c.png").read_bytes()


def test_short_and_long_runs_draw(tmp_path: Path) -> None:
    # 4 h switches the axis to hours; 1 row must not fail either.
    long = make_table(rows=1441, seed=3)  # 10 s steps -> 4 h
    assert _draw(long, tmp_path / "long.png").read_bytes()[:8] == PNG_SIGNATURE
    one = make_table(rows=1)
    assert _draw(one, tmp_path / "one.png").read_bytes()[:8] == PNG_SIGNATURE


def test_missing_column_is_named(table: SignalTable, tmp_path: Path) -> None:
    with pytest.raises(KeyError, match=r"thermal\.nope"):
        error_budget_png(
            table,
            tmp_path / "x.png",
            reading="probe.reading",
            predicted="errormodel.e_total",
            parts=PARTS,
            temperatures=["thermal.nope"],
            title="x",
        )
    assert not (tmp_path / "x.png").exists()
