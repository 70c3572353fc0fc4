"""The operating scenarios end to end: compensation and credibility of the on-line wear curve.

Goal (loading/oscillation issue): in every operating scenario the compensation removes at least
90 % of the RMS detecting error (reading minus true wear); the endurance run ends with a true wear
inside the MIL limit and the compensated curve within 2 um RMS of it.

Honest figures since the tester is richer than the error model (issue 12): the liner creeps
under the held load, softens as it warms and has a hysteresis loop, and parts no sensor sees
change temperature. `twin identify` fits a creep spectrum on a static load hold (the error
model's own generic form, not the FMU's) and, since the pole-heating experiment, separates the
long pole's growth from the frame's. Measured (RMS after, % removed): constant-load 0.44 um,
94.7 %; sine 1.22 um, 96.6 %; trapezoid 0.85 um, 97.0 %; day-night 0.39 um, 97.3 %; MIL
endurance 0.38 um, 97.4 % (its goal: 2 um). The tests assert the goals, which these meet with
a margin.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.runs import run_into
from twin.config.load import load_scenario, scenarios_dir
from twin.pipeline import RunSummary

pytestmark = pytest.mark.slow

MIL_WEAR_LIMIT_MM = 0.152  # facts.md 4


def check_summary(run_summary: RunSummary, removed: float = 0.9) -> None:
    assert run_summary.status == "completed"
    summary = run_summary.results
    for key in ("true", "compensated"):
        assert isinstance(summary["wear_mm"][key], float)
    for group, key in (("compensation", "residual_rms_um"), ("compensation", "residual_max_um"),
                       ("credibility", "frechet_um"), ("credibility", "ra_um")):  # fmt: skip
        pair = summary[group][key]
        assert set(pair) == {"before", "after"} and all(v >= 0 for v in pair.values())
    rms = summary["compensation"]["residual_rms_um"]
    assert rms["after"] <= (1.0 - removed) * rms["before"], (
        rms
    )  # at least this share of the RMS error removed
    # the compensated curve is also closer to the true one by the Frechet distance
    assert summary["credibility"]["frechet_um"]["after"] < summary["credibility"]["frechet_um"]["before"]


#: the share of the RMS detecting error each scenario's compensation removes at least (see above)
REMOVED = {"constant-load": 0.9, "sine-load": 0.9, "trapezoid-load": 0.9, "day-night": 0.9}


@pytest.mark.parametrize("name", sorted(REMOVED))
def test_compensation_removes_the_detecting_error(name: str, tmp_path: Path) -> None:
    summary = run_into(load_scenario(scenarios_dir() / f"{name}.toml"), tmp_path)
    check_summary(summary, REMOVED[name])
    # every factor of the scenario is present
    figures = summary.figures()
    assert figures["error_parts_rms_um.thermal"] > 1.0
    assert figures["error_parts_rms_um.fluctuating"] > 0.1
    if name in ("sine-load", "trapezoid-load"):
        assert figures["error_parts_rms_um.loading"] > 5.0


def test_mil_endurance_run(tmp_path: Path) -> None:
    summary = run_into(load_scenario(scenarios_dir() / "mil-endurance.toml"), tmp_path)
    check_summary(summary, 0.9)
    assert 0.0 < summary.results["wear_mm"]["true"] < MIL_WEAR_LIMIT_MM
    # the goal: the compensated curve within 2 um RMS of the true wear (measured 0.38 um)
    assert summary.results["compensation"]["residual_rms_um"]["after"] <= 2.0
    assert summary.timing.macro_steps == 1_500_000  # the swing resolved at 0.1 s
