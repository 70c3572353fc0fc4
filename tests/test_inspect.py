"""`twin inspect`: an FMU's variables like `fmpy info` (issue 14)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from twin.cli import main


def test_inspect_a_built_fmu_lists_every_variable_with_unit_and_range(
    fmu_paths: dict[str, Path], capsys
) -> None:
    from fmpy import read_model_description

    path = fmu_paths["HydraulicLoader"]
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("HydraulicLoader: FMI 2.0 (co-simulation)")
    md = read_model_description(str(path), validate=False)
    rows = {ln.split()[0]: ln.split() for ln in out[2:] if ln.strip()}
    assert set(rows) >= {v.name for v in md.modelVariables}
    assert rows["load_mean"][1:6] == ["parameter", "fixed", "Real", "N", "0.0"]
    assert "300000.0" in rows["load_mean"]


def test_inspect_a_model_by_name(capsys) -> None:
    assert main(["inspect", "FixtureMechanics", "--width", "0"]) == 0
    out = capsys.readouterr().out
    assert "t_detecting_frame_lower" in out and "liner_creep_ratio" in out


@pytest.mark.parametrize("width", ["-5", "x"])
def test_a_width_that_is_no_width_is_one_line(width: str, capsys) -> None:
    # -5 cut five characters off every description's end, silently
    assert main(["inspect", "FixtureMechanics", "--width", width]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"twin: inspect: argument --width: expected a number of characters (0 or more), got '{width}'"
    ]


@pytest.mark.parametrize(
    ("target", "word"),
    [
        ("FixtureMechanic", "did you mean 'FixtureMechanics'"),
        ("/etc/hostname", "not a readable"),
        ("nope.fmu", "not found"),
        ("/dev/zero", "/dev/zero: is not a regular file"),
        ("", "inspect: the target is empty"),
        (" ", "inspect: the target is empty"),
    ],
)
def test_inspect_bad_targets_get_one_line(target: str, word: str, capsys) -> None:
    assert main(["inspect", target]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0], err


@pytest.mark.parametrize(
    ("description", "word"),
    [
        (b"<x/>", "lacks an element or attribute FMI requires"),  # fmpy: 'NoneType' ... 'startswith'
        (b'<fmiModelDescription fmiVersion="2.0"/>', "'modelName' is required but missing"),  # the schema
    ],
)
def test_an_fmu_whose_model_description_lacks_what_fmi_requires_gets_one_line(
    description: bytes, word: str, tmp_path: Path, capsys
) -> None:
    fmu = tmp_path / "slip.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", description)
    assert main(["inspect", str(fmu)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {fmu}: not a readable FMI model description: "), err
    assert word in err[0] and "NoneType" not in err[0], err
