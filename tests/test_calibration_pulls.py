"""The committed thermal calibration keeps every fitted value within its prior (issue 30): no
value pulled beyond 3 prior sigma, and the data met (each rise within 0.3 K). Read from the
committed report, so it is checked without rerunning the fit (tests/test_calibrate.py reruns it)."""

from __future__ import annotations

import json
import math

import pytest

from twin.calibration.thermal import BODIES, PRIORS
from twin.config.load import default_scenario_path
from twin.paper import TEMPERATURE_RISE_K

REPORT = default_scenario_path().parent / "calibration" / "li2017-thermal-network.json"


def _report() -> dict:
    return json.loads(REPORT.read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", sorted(PRIORS))
def test_no_calibrated_value_is_beyond_three_prior_sigma(name: str) -> None:
    p = _report()["parameters"][name]
    assert p["prior_rel_sigma"] == PRIORS[name][0]  # the report is the code's current priors
    pull = math.log(p["value"] / p["drawing"]) / p["prior_rel_sigma"]
    assert abs(pull) <= 3.0, (
        f"{name}: {p['value']:.4g} vs drawing {p['drawing']:.4g}, {pull:+.2f} prior sigma"
    )


def test_the_committed_fit_meets_each_rise_within_0_3_K() -> None:
    rises = _report()["rises_K"]
    assert set(rises) == set(BODIES)
    for body in BODIES:
        assert rises[body]["twin"] == pytest.approx(TEMPERATURE_RISE_K[body], abs=0.3), body
