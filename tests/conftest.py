"""Shared fixtures: every FMU built once per session (from the content-hashed cache)."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.fmu.build import ensure_fmu, model_names


@pytest.fixture(scope="session")
def fmu_paths() -> dict[str, Path]:
    return {name: ensure_fmu(name) for name in model_names()}
