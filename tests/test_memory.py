"""Peak memory does not grow with the length of a run (outputs stream to disk)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

# the child's own peak, VmHWM: its ru_maxrss would start from this (pytest's) process's peak,
# hundreds of MB by the time this test runs, above both runs' peaks, and no growth could show
CHILD = """
import sys
from twin.cli import main
code = main(sys.argv[1:])
with open("/proc/self/status") as status:
    print("MAXRSS_KB", next(line.split()[1] for line in status if line.startswith("VmHWM:")))
sys.exit(code)
"""


def peak_rss_kb(tmp_path: Path, duration: str) -> int:
    out = tmp_path / duration.replace(" ", "")
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            CHILD,
            "run",
            "scenarios/constant-load.toml",
            "--quiet",
            "--out",
            str(out),
            "--set",
            f'scenario.duration="{duration}"',
            "--set",
            'scenario.output_interval="10 s"',
        ],
        cwd=Path(__file__).resolve().parents[1],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return int(proc.stdout.split("MAXRSS_KB")[1].split()[0])


def test_peak_memory_of_a_ten_times_longer_run_stays_within_20_percent(tmp_path: Path) -> None:
    short = peak_rss_kb(tmp_path, "1 h")
    long = peak_rss_kb(tmp_path, "10 h")
    print(f"peak RSS: 1 h {short / 1024:.0f} MiB, 10 h {long / 1024:.0f} MiB")
    assert long <= 1.2 * short
