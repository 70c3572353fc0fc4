"""Hostile CSVs and scenario values, through the real command line: each is exit 2 and one
line naming the file and what is wrong, within seconds and bounded memory."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest

from twin.signals.csv import LINE_BYTES, MAX_COLUMNS

from .cli import REPO, one_line, twin

CONSTANT = REPO / "scenarios" / "constant-load.toml"


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``twin compensate --template``'s folder: a LAB.toml and the header of a lab's record."""
    folder = tmp_path_factory.mktemp("lab") / "tpl"
    assert twin("compensate", "--template", str(folder)).returncode == 0
    return folder


def _compensate(lab: Path, csv: Path) -> subprocess.CompletedProcess[str]:
    return twin("compensate", str(csv), "--config", str(lab / "LAB.toml"), "--out", str(csv.parent / "out"))


def test_a_row_without_a_line_break_is_refused_at_the_line_limit(lab: Path, tmp_path: Path) -> None:
    """20 MB without a line break (a 1 GB one the same: the reader stops at the limit)."""
    header, row = (lab / "lab.csv").read_text().splitlines()[:2]  # a good row, then the long line
    csv = tmp_path / "long.csv"
    csv.write_bytes(f"{header}\n{row}\n".encode() + b"1" * (20 * LINE_BYTES))
    line = one_line(_compensate(lab, csv))
    assert str(csv) in line and "line 3: longer than 1 MB without a line break" in line, line


def test_a_100_000_column_csv_is_refused_in_seconds(lab: Path, tmp_path: Path) -> None:
    header = (lab / "lab.csv").read_text().splitlines()[0]
    csv = tmp_path / "wide.csv"
    extra = 100_000
    csv.write_text(header + "," + ",".join(f"c{i}" for i in range(extra)) + "\n")
    started = time.perf_counter()
    line = one_line(_compensate(lab, csv))
    assert time.perf_counter() - started < 30  # 116 s before the cap and the linear check
    assert f"more than the {MAX_COLUMNS}" in line and str(csv) in line, line


def test_a_repeated_column_in_a_wide_header_is_found_linearly(lab: Path, tmp_path: Path) -> None:
    header = (lab / "lab.csv").read_text().splitlines()[0]
    csv = tmp_path / "twice.csv"
    names = [f"c{i}" for i in range(MAX_COLUMNS - 20)] + ["c7"]
    csv.write_text(header + "," + ",".join(names) + "\n")
    line = one_line(_compensate(lab, csv))
    assert "['c7'] appear twice" in line, line


def _scenario(tmp_path: Path, text: str) -> Path:
    """constant-load with ``text`` after its ``[scenario]`` line (its extends made absolute)."""
    body = CONSTANT.read_text().replace('extends = "', f'extends = "{REPO}/scenarios/')
    path = tmp_path / "s.toml"
    path.write_text(body.replace("[scenario]\n", f"[scenario]\n{text}\n", 1))
    return path


def test_a_nul_byte_in_a_string_is_refused(tmp_path: Path) -> None:
    line = one_line(twin("validate", str(CONSTANT), "--set", 'scenario.description="a\\u0000b"'))
    assert "scenario.description: a NUL character" in line, line
    path = _scenario(tmp_path, 'seed = 4\n[fmu.sensors.parameters]\n"probe\\u0000x" = 1')
    line = one_line(twin("validate", str(path)))
    assert str(path) in line and "a NUL character (\\u0000) in a key" in line, line


def test_a_file_that_is_not_utf8_is_refused(tmp_path: Path) -> None:
    path = _scenario(tmp_path, "seed = 4")
    path.write_bytes(b"# caf\xe9 (Latin-1)\n" + path.read_bytes())
    line = one_line(twin("validate", str(path)))
    assert str(path) in line and "not UTF-8" in line, line


def test_a_1_ns_step_is_refused_by_the_tick_bound(tmp_path: Path) -> None:
    path = _scenario(tmp_path, 'step = "1 ns"')
    line = one_line(twin("validate", str(path)))
    assert "scenario.step: 1 ns over 2 h is 7.2e+12 steps, more than the 1e+09" in line, line


@pytest.mark.parametrize(
    ("room", "said"),
    [
        ("input.nope.x", "no profile drives nope.x in scenario"),
        ("thermal", "expected 'input.<instance>.<variable>'"),
    ],
)
def test_a_heldout_room_key_is_checked_before_any_tester_runs(tmp_path: Path, room: str, said: str) -> None:
    shipped = REPO / "scenarios" / "validation" / "heldout.toml"
    text = shipped.read_text().replace('room = "input.thermal.t_room"', f'room = "{room}"', 1)
    text = text.replace('"../', f'"{shipped.parent.parent}/')
    path = tmp_path / "heldout.toml"
    path.write_text(text)
    started = time.perf_counter()
    line = one_line(twin("heldout", str(path), "--testers", "1", "--out", str(tmp_path / "ho")))
    assert time.perf_counter() - started < 60 and not (tmp_path / "ho").exists()
    assert "heldout.room" in line and said in line, line


def test_unknown_geometry_keys_are_refused_before_any_file_is_written(tmp_path: Path) -> None:
    import shutil

    folder = tmp_path / "scenarios"
    shutil.copytree(REPO / "scenarios" / "base", folder / "base")
    geometry = folder / "base" / "tester-geometry.toml"
    text = geometry.read_text().replace(
        "[surfaces]\n", '[surfaces]\nh_convecton = { value = 5.0, source = "typo" }\n', 1
    )
    geometry.write_text(text + "\n[bogus_table]\nx = 1\n")
    derived = {p.name: p.read_bytes() for p in (folder / "base").glob("geometry-*.toml")}
    proc = twin("geometry", "--scenarios", str(folder))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == [
        f"twin: {geometry}: bogus_table.x: unknown key",
        f"twin: {geometry}: surfaces.h_convecton: unknown key (did you mean 'surfaces.h_convection'?)",
    ]
    assert {p.name: p.read_bytes() for p in (folder / "base").glob("geometry-*.toml")} == derived


def test_a_misspelt_drift_window_in_lab_toml_is_named_with_its_close_match(lab: Path, tmp_path: Path) -> None:
    config = tmp_path / "LAB.toml"
    config.write_text((lab / "LAB.toml").read_text().replace("drift_window = ", "drift_windw = ", 1))
    proc = twin("compensate", str(lab / "lab.csv"), "--config", str(config), "--out", str(tmp_path / "out"))
    line = one_line(proc)
    assert "errormodel.drift_windw: unknown key (did you mean 'drift_window'?)" in line, line
