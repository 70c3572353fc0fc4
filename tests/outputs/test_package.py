"""The package exports its public functions; rerun and matplotlib load only when used."""

from __future__ import annotations

import subprocess
import sys

import twin.outputs


def test_public_api_is_exported() -> None:
    for name in twin.outputs.__all__:
        assert callable(getattr(twin.outputs, name)), name


def test_importing_the_package_does_not_import_rerun_or_matplotlib() -> None:
    code = "import sys, twin.outputs; print('rerun' in sys.modules, 'matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]
