"""The package exports its public functions; rerun and matplotlib load only when used, and
pandas not at all in a `twin run`, which settles its process for the run."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import twin.outputs


def test_public_api_is_exported() -> None:
    for name in twin.outputs.__all__:
        assert callable(getattr(twin.outputs, name)), name


def test_importing_the_package_does_not_import_rerun_or_matplotlib() -> None:
    code = "import sys, twin.outputs; print('rerun' in sys.modules, 'matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_a_runs_recording_loads_rerun_with_its_first_rows(tmp_path: Path) -> None:
    # not when the run opens its outputs: a run that fails its checks or its set-up never pays it
    code = (
        "import sys, numpy as np, pathlib\n"
        "from twin.outputs.recording_sink import RecordingSink\n"
        "from twin.signals.table import Block, Signal\n"
        f"sink = RecordingSink(pathlib.Path({str(tmp_path / 'r.rrd')!r}), recording_name='r')\n"
        "sink.open([Signal('probe.reading', 'm', 'probe')])\n"
        "opened = 'rerun' in sys.modules\n"
        "sink.write(Block(np.arange(3.0), {'probe.reading': np.zeros(3)}))\n"
        "print(opened, 'rerun' in sys.modules)\n"
        "sink.fail(RuntimeError('done'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "True"]


@pytest.mark.parametrize(
    ("call", "settled"),
    [
        ("from twin.cli import console; sys.exit(console())", True),
        ("from twin.cli import main; sys.exit(main())", False),
    ],
    ids=["the command's own process", "a program calling twin.cli.main"],
)
def test_twin_run_settles_its_own_process_and_leaves_a_callers_alone(
    tmp_path: Path, call: str, settled: bool
) -> None:
    """What twin.cli.process.settle sets (each measured in benchmarks/bench_phases.py):
    pyarrow's buffers come from the system allocator, and the imports are frozen for the GC;
    only where the process is the command's own."""
    args = [
        "twin",
        "run",
        "li2017-thermal-experiment",
        "--uncertainty",
        "0",
        "--quiet",
        "--out",
        str(tmp_path / "r"),
    ]
    # what the process holds once the command is over: printed by an exit handler, since the
    # console script's process ends as soon as the command returns (after its exit handlers)
    code = (
        "import atexit, gc, sys\n"
        "def report():\n"
        "    import pyarrow\n"
        "    print(pyarrow.default_memory_pool().backend_name, gc.get_freeze_count() > 0, "
        "'pandas' in sys.modules)\n"
        "atexit.register(report)\n"
        f"sys.argv = {args!r}\n"
        f"{call}\n"
    )
    env = {
        k: v for k, v in os.environ.items() if k not in ("ARROW_DEFAULT_MEMORY_POOL", "MIMALLOC_PURGE_DELAY")
    }
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    pool, frozen, pandas = done.stdout.split()
    assert (pool, frozen) == (("system", "True") if settled else ("mimalloc", "False"))
    assert pandas == "False"  # the recording's conversions to Arrow did not load it (pandas_free)
    assert (tmp_path / "r" / "recording.rrd").stat().st_size > 0


def test_a_recording_leaves_pyarrow_working_with_pandas_once_pandas_loads() -> None:
    """While a recording is written pyarrow does not import pandas (it takes it for missing);
    once pandas is imported, pyarrow converts pandas' objects as pandas' again: a categorical
    stays a dictionary, a time zone stays (twin.outputs.pandas_free)."""
    code = (
        "import sys, pyarrow as pa, numpy as np\n"
        "from twin.outputs.pandas_free import without_pandas\n"
        "with without_pandas():\n"
        "    pa.array(['a', 'b']); pa.array(np.arange(3.0))\n"
        "print('pandas' in sys.modules)\n"
        "import pandas as pd\n"
        "print(pa.array(pd.Categorical(['a', 'b', 'a'])).type)\n"
        "print(pa.array(pd.Series(pd.to_datetime(['2020-01-01', None]).tz_localize('UTC'))).type)\n"
        "print(type(pd.__spec__.loader).__name__)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == [
        "False",
        "dictionary<values=large_string, indices=int8, ordered=0>",
        "timestamp[us, tz=UTC]",
        "SourceFileLoader",
    ]


def test_a_long_runs_recording_loads_rerun_beside_the_co_simulation(tmp_path: Path) -> None:
    """A long run's sink (preload) begins importing rerun in a thread when the run opens its
    outputs, before any rows: the import goes on while the co-simulation steps. Its rows
    then wait for that import and are written as any."""
    code = (
        "import sys, time, numpy as np, pathlib\n"
        "from twin.outputs.recording_sink import RecordingSink\n"
        "from twin.signals.table import Block, Signal\n"
        f"sink = RecordingSink(pathlib.Path({str(tmp_path / 'r.rrd')!r}), recording_name='r')\n"
        "sink.preload = True\n"
        "sink.open([Signal('probe.reading', 'm', 'probe')])\n"
        "deadline = time.monotonic() + 120\n"
        "while 'twin.outputs.rerun_rec' not in sys.modules and time.monotonic() < deadline:\n"
        "    time.sleep(0.01)\n"
        "print('twin.outputs.rerun_rec' in sys.modules)\n"
        "sink.write(Block(np.arange(3.0), {'probe.reading': np.zeros(3)}))\n"
        "sink.fail(RuntimeError('done'))\n"
        "from twin.outputs.rerun_rec import read_recording\n"
        f"print(len(read_recording({str(tmp_path / 'r.rrd')!r})['/probe/reading'][0]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "3"]
