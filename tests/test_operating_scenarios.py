"""The operating scenarios end to end: compensation and credibility of the on-line wear curve.

Acceptance (loading/oscillation issue): in every operating scenario the compensation removes
at least 90 % of the RMS detecting error (reading minus true wear); the endurance run ends
with a true wear inside the MIL limit and the compensated curve within 2 um RMS of it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.pipeline import RunSummary, run

pytestmark = pytest.mark.slow

MIL_WEAR_LIMIT_MM = 0.152  # facts.md 4


def check_summary(run_summary: RunSummary) -> None:
    assert run_summary.status == "completed"
    summary = run_summary.results
    for key in ("true", "compensated"):
        assert isinstance(summary["wear_mm"][key], float)
    for group, key in (("compensation", "residual_rms_um"), ("compensation", "residual_max_um"),
                       ("credibility", "frechet_um"), ("credibility", "ra_um")):  # fmt: skip
        pair = summary[group][key]
        assert set(pair) == {"before", "after"} and all(v >= 0 for v in pair.values())
    rms = summary["compensation"]["residual_rms_um"]
    assert rms["after"] <= 0.1 * rms["before"], rms  # at least 90 % of the RMS error removed
    # the compensated curve is also closer to the true one by the Frechet distance
    assert summary["credibility"]["frechet_um"]["after"] < summary["credibility"]["frechet_um"]["before"]


@pytest.mark.parametrize("name", ["constant-load", "sine-load", "trapezoid-load", "day-night"])
def test_compensation_removes_90_percent_of_the_detecting_error(name: str, tmp_path: Path) -> None:
    summary = run(load_scenario(scenarios_dir() / f"{name}.toml"), tmp_path)
    check_summary(summary)
    # every factor of the scenario is present
    figures = summary.figures()
    assert figures["error_parts_rms_um.thermal"] > 1.0
    assert figures["error_parts_rms_um.fluctuating"] > 0.1
    if name in ("sine-load", "trapezoid-load"):
        assert figures["error_parts_rms_um.loading"] > 5.0


def test_mil_endurance_run(tmp_path: Path) -> None:
    summary = run(load_scenario(scenarios_dir() / "mil-endurance.toml"), tmp_path)
    check_summary(summary)
    assert 0.0 < summary.results["wear_mm"]["true"] < MIL_WEAR_LIMIT_MM
    assert summary.results["compensation"]["residual_rms_um"]["after"] <= 2.0
    assert summary.timing.macro_steps == 1_500_000  # the swing resolved at 0.1 s
