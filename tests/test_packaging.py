"""pyproject.toml ships every package and every file the twin reads at run time.

The FMU sources and the scenarios are package data mapped from the top of the tree, which
makes the package list explicit: these tests fail when a new package or a new kind of source
file would be left out of a wheel. .ci/run proves the whole thing with a non-editable install.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from twin.fmu import catalog

ROOT = Path(__file__).resolve().parents[1]
SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _folder(package: str) -> Path:
    """The source folder setuptools takes ``package`` from."""
    mapped = SETUPTOOLS["package-dir"]
    if package in mapped:
        return ROOT / mapped[package]
    return ROOT / mapped[""] / Path(*package.split("."))


def _shipped(package: str) -> set[Path]:
    """Files of ``package`` that its package-data globs select."""
    folder = _folder(package)
    return {p for g in SETUPTOOLS["package-data"].get(package, []) for p in folder.glob(g) if p.is_file()}


def test_every_python_package_under_src_is_listed() -> None:
    src = ROOT / "src"
    found = {
        ".".join(d.relative_to(src).parts)
        for d in [src / "twin", *(src / "twin").rglob("*")]
        if d.is_dir() and any(d.glob("*.py"))
    }
    assert found <= set(SETUPTOOLS["packages"]), (
        f"add to [tool.setuptools] packages: {found - set(SETUPTOOLS['packages'])}"
    )


@pytest.mark.parametrize("model", catalog.model_names(ROOT / "fmus"))
def test_every_file_an_fmu_is_built_from_is_package_data(model: str) -> None:
    m = catalog.model(model, ROOT / "fmus")
    shipped = {p.name for p in _shipped("twin.fmu.sources") if p.parent.name in (model, "common")}
    assert set(m.files()) <= shipped


def test_every_scenario_file_is_package_data() -> None:
    scenarios = {p for p in (ROOT / "scenarios").rglob("*.toml")}
    assert scenarios and scenarios <= _shipped("twin.config.scenarios")
    assert {"base", "calibration"} <= {p.parent.name for p in scenarios}


def test_the_stepper_sources_are_package_data() -> None:
    native = _folder("twin") / "cosim" / "native"
    sources = {p for p in native.iterdir() if p.is_file()}
    assert native / "CMakeLists.txt" in sources
    assert sources <= _shipped("twin")


def test_fmpy_is_pinned_to_a_tested_range() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    (fmpy,) = [d for d in project["dependencies"] if d.startswith("fmpy")]
    assert ">=" in fmpy and "<" in fmpy.replace("<=", "")
