"""twin.files: the one helper every writer of an output folder goes through."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from twin.errors import ConfigError
from twin.files import write_text_atomic
from twin.outputs.guard import open_output, output_dir, refuse_links


def test_open_output_refuses_a_link_and_a_fifo_and_writes_a_regular_file(tmp_path: Path) -> None:
    victim = tmp_path / "victim"
    victim.write_text("outside")
    (tmp_path / "link").symlink_to(victim)
    for mode in ("w", "a", "r+"):
        with pytest.raises(ConfigError, match="is a symbolic link"):
            open_output(tmp_path / "link", mode)  # type: ignore[arg-type]
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(ConfigError, match="not a regular file"):
        open_output(tmp_path / "fifo")  # would block forever without a reader
    assert victim.read_text() == "outside"
    with open_output(tmp_path / "new") as f:
        f.write(b"abc")
    with open_output(tmp_path / "new", "a") as f:
        f.write(b"d")
    assert (tmp_path / "new").read_bytes() == b"abcd"


def test_an_atomic_write_replaces_a_planted_link_and_leaves_no_temporary(tmp_path: Path) -> None:
    victim = tmp_path / "victim"
    victim.write_text("outside")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "summary.json").symlink_to(victim)
    write_text_atomic(tmp_path / "out" / "summary.json", "{}")
    assert victim.read_text() == "outside"
    assert not (tmp_path / "out" / "summary.json").is_symlink()
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["summary.json"]


def test_folders_and_links(tmp_path: Path) -> None:
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "runs").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ConfigError, match="is a symbolic link"):
        output_dir(tmp_path / "runs")
    with pytest.raises(ConfigError, match="runs: is a symbolic link"):
        refuse_links(tmp_path, ["signals.csv", "runs"])
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ConfigError, match=r"--template .*afile: is a file, expected a folder"):
        output_dir(tmp_path / "afile", "--template")
    assert output_dir(tmp_path / "a" / "b").is_dir()
