"""`twin compensate --out`: its own earlier output folder is written again as it is, another
command's (a run's run.json, a run's, sweep's or held-out test's summary.json) only with
--force: one line and exit 2 otherwise, and nothing there changed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.test_compensate_bad_input import GOOD_TOML, lab_csv
from twin.cli import main

#: what another command left in a folder (name -> text)
OTHERS = {
    "a run's": {"run.json": "{}", "summary.json": json.dumps({"scenario": "x", "status": "completed"})},
    "a run's without its summary": {"run.json": "{}"},
    "a sweep's": {"summary.json": json.dumps({"design": "grid", "points": 4})},
    "a damaged summary": {"summary.json": "{not json"},
}


def _compensate(tmp_path: Path, out: Path, *extra: str) -> int:
    (tmp_path / "lab.csv").write_text(lab_csv(), encoding="utf-8")
    (tmp_path / "lab.toml").write_text(GOOD_TOML, encoding="utf-8")
    csv, toml = str(tmp_path / "lab.csv"), str(tmp_path / "lab.toml")
    return main(["compensate", csv, "--config", toml, "--out", str(out), *extra])


@pytest.mark.parametrize("case", list(OTHERS))
def test_another_commands_folder_is_refused_without_force(case: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    for name, text in OTHERS[case].items():
        (out / name).write_text(text, encoding="utf-8")
    assert _compensate(tmp_path, out) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: --out: {out} holds another command's outputs ("), err
    assert "--force" in err[0]
    assert sorted(p.name for p in out.iterdir()) == sorted(OTHERS[case])  # nothing written
    assert all((out / n).read_text(encoding="utf-8") == t for n, t in OTHERS[case].items())
    # --force: the compensation's files written there, others' left as they are
    assert _compensate(tmp_path, out, "--force") == 0
    assert "input_rows" in json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert (out / "errormodel.csv").exists()
    if "run.json" in OTHERS[case]:
        assert (out / "run.json").read_text(encoding="utf-8") == "{}"


def test_its_own_earlier_folder_is_written_again_without_force(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _compensate(tmp_path, out) == 0
    (out / "errormodel.csv").write_text("stale", encoding="utf-8")  # to see it written again
    assert _compensate(tmp_path, out) == 0
    assert "input_rows" in json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert (out / "errormodel.csv").read_text(encoding="utf-8").startswith("time,")


def test_a_folder_of_other_files_is_written_into(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    assert _compensate(tmp_path, out) == 0
    assert (out / "notes.txt").read_text(encoding="utf-8") == "mine"


@pytest.mark.parametrize("name", ["errormodel.csv", "flagged_rows.csv", "a link to errormodel.csv"])
def test_an_input_that_is_one_of_the_outputs_is_refused_and_kept(name: str, tmp_path: Path, capsys) -> None:
    """The input would be cut while it is read (exit 0 and a shorter record, seen by a hostile
    test): refused before anything is written, the input as it was, --force or not."""
    out = tmp_path / "out"
    out.mkdir()
    text = lab_csv()
    (tmp_path / "lab.toml").write_text(GOOD_TOML, encoding="utf-8")
    if name.startswith("a link"):
        (tmp_path / "lab.csv").write_text(text, encoding="utf-8")
        (out / "errormodel.csv").symlink_to(tmp_path / "lab.csv")
        csv = tmp_path / "lab.csv"
    else:
        csv = out / name
        csv.write_text(text, encoding="utf-8")
    for extra in ([], ["--force"]):
        args = ["compensate", str(csv), "--config", str(tmp_path / "lab.toml"), "--out", str(out), *extra]
        assert main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("twin: --out: the input "), err
        assert "which this command writes" in err[0]
        assert csv.read_text(encoding="utf-8") == text
        assert not (out / "summary.json").exists()
