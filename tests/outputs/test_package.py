"""The package exports its public functions; rerun and matplotlib load only when used, and
pandas not at all in a `twin run`."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import twin.outputs


def test_public_api_is_exported() -> None:
    for name in twin.outputs.__all__:
        assert callable(getattr(twin.outputs, name)), name


def test_importing_the_package_does_not_import_rerun_or_matplotlib() -> None:
    code = "import sys, twin.outputs; print('rerun' in sys.modules, 'matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_twin_run_does_not_import_pandas(tmp_path: Path) -> None:
    """pyarrow would import it (0.17 s, 43 MB) only to ask whether rerun's lists are pandas
    objects (twin.outputs.rerun_rec.arrow_without_pandas_lookup)."""
    args = ["run", "li2017-thermal-experiment", "--uncertainty", "0", "--quiet", "--out", str(tmp_path / "r")]
    code = f"import sys; from twin.cli import main; rc = main({args!r}); print(rc, 'pandas' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "False"]
    assert (tmp_path / "r" / "recording.rrd").stat().st_size > 0
