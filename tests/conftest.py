"""Shared fixtures: every FMU built once per session (from the content-hashed cache)."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.fmu.build import ensure_fmu, model_names


@pytest.fixture(scope="session", autouse=True)
def fmu_paths() -> dict[str, Path]:
    """Built before the first test (a no-op with a warm cache): a build says so on stderr, one
    line per model, and a test that reads a command's stderr line by line must not find those
    lines in it because it happened to be the first to need the FMUs (a fresh CI cache)."""
    from twin.cosim.native import ensure_stepper

    ensure_stepper()
    return {name: ensure_fmu(name) for name in model_names()}


@pytest.fixture(scope="session")
def lowpass_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An FMU the project did not write: tests/data/LowPass (its own C file, not the twin's FMU
    wrapper) built by fmpy's own cmake build and zipped as any FMU tool would."""
    import shutil

    from fmpy.build import build_platform_binary

    root = tmp_path_factory.mktemp("lowpass")
    unzipped = root / "LowPass"
    shutil.copytree(Path(__file__).parent / "data" / "LowPass", unzipped)
    (root / "build").mkdir()
    build_platform_binary(unzipped, build_dir=root / "build")
    archive = shutil.make_archive(str(root / "LowPass"), "zip", unzipped)
    return Path(shutil.move(archive, root / "LowPass.fmu"))


@pytest.fixture(scope="session")
def test_models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The test-only models of tests/data/models (Gain: direct feedthrough; Lag: none, in degC),
    built as the twin's own models are (its FMU wrapper, its build, the content-hashed cache),
    from a sources folder outside fmus/: a copy of fmus/common beside them."""
    import shutil

    from twin.fmu.sources import sources_dir

    root = tmp_path_factory.mktemp("models")
    shutil.copytree(sources_dir() / "common", root / "common")
    models = sorted((Path(__file__).parent / "data" / "models").iterdir())
    for folder in models:
        shutil.copytree(folder, root / folder.name)
    return {folder.name: ensure_fmu(folder.name, src=root) for folder in models}
