"""What a default run's Monte Carlo in process imports: not Dask's distributed (only when a
cluster pays), not pandas, SALib or scipy (the draws, uncertainty.csv and the variance shares
are computed without them: scipy's import alone was a fifth of a CPU second of a default run);
and the worker's binaries check still refuses a point where the plugin failed."""

from __future__ import annotations

import subprocess
import sys

import pytest

from twin.errors import RunError
from twin.pipeline import shipping, worker_state
from twin.pipeline.point import point_task


def test_in_process_modules_leave_the_heavy_ones_out() -> None:
    code = (
        "import sys\n"
        "import twin.pipeline.run, twin.pipeline.point, twin.pipeline.montecarlo\n"
        "import twin.uncertainty.shares, twin.uncertainty.testers, twin.cli.run\n"
        "print(*(m in sys.modules for m in ('distributed', 'dask', 'pandas', 'SALib', 'scipy.stats')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"] * 5


def test_the_default_run_imports_no_scipy(tmp_path) -> None:
    """The whole default ``twin run`` (the paper replay with its 400 samples), in a process of
    its own as a user runs it: scipy, pandas, SALib and Dask stay out of it."""
    code = (
        "import sys\nfrom twin.cli import main\n"
        f"code = main(['run', '--out', {str(tmp_path / 'run')!r}, '--quiet'], own_process=True)\n"
        "print(code, *(m in sys.modules for m in ('scipy', 'pandas', 'SALib', 'distributed')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split()[-5:] == ["0", "False", "False", "False", "False"]


def test_a_worker_whose_binaries_failed_refuses_points() -> None:
    """The plugin's failure (damaged bytes) is what an in-process point's check reads."""
    plugin = shipping.BinariesPlugin((shipping.Artifact("x.fmu", b"damaged", "0" * 64),))
    try:
        with pytest.raises(RunError, match="sha256 mismatch"):
            plugin.setup(worker=None)
        with pytest.raises(RunError, match="sha256 mismatch"):
            worker_state.check_worker()
        record = point_task({"index": 3, "run": None})
        assert record["status"] == "failed" and "sha256 mismatch" in record["error"]
    finally:
        worker_state.PROBLEM.clear()
    worker_state.check_worker()  # a worker whose binaries installed runs its points
