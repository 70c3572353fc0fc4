"""A Monte Carlo batch's samples evaluated together (:func:`evaluate_many`: the factors run once
over the records stacked end to end) give each sample the numbers of its own evaluation, bit for
bit, whichever factors run; records that cannot be stacked are refused, not evaluated wrongly."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from tests.test_compensate_streaming import TOML, record
from twin.errormodel.evaluate import evaluate, evaluate_many
from twin.errormodel.settings import EvaluationConfig
from twin.errormodel.sources import MechanicalCoefficients
from twin.pipeline.compensation import compensation_config
from twin.signals.table import Signal, SignalTable

#: every identified coefficient away from zero, so that each factor's part is not zeros: the
#: liner's creep reads the load's history, the runout the encoder's angle from its start
MECHANICS = MechanicalCoefficients(
    load_compliance=2e-10,
    spindle_runout=3e-6,
    runout_phase=0.3,
    probe_scale=0.9998,
    clamp_rotation=-1e-7,
    creep_compliance_15min=3e-12,
    creep_compliance_1h=5e-12,
    creep_compliance_4h=1e-11,
    creep_compliance_16h=2e-12,
)


def _config(tmp_path: Path, **changes: object) -> EvaluationConfig:
    (tmp_path / "lab.toml").write_text(TOML)
    cfg, _ = compensation_config(tmp_path / "lab.toml")
    return dataclasses.replace(cfg, **changes)


def _table(seed: int, n: int = 600) -> SignalTable:
    cols = record(n, seed)
    table = SignalTable(time=cols["time"])
    for name, values in cols.items():
        if name != "time":
            table.add(Signal(name, "", "measured"), values)
    return table


def _text(summary: dict) -> str:
    """Every number's shortest repr: equal texts are equal doubles (NaN included)."""
    return json.dumps(summary, sort_keys=True)


@pytest.mark.parametrize(
    "changes",
    [
        {"mechanics": MECHANICS},  # all five factors
        {"mechanics": MECHANICS, "credibility": False},  # a Monte Carlo sample's
        {"mechanics": None},  # the identified factors zero
        {"mechanics": MECHANICS, "factors": ("thermal", "positioning", "interference"), "true_wear": ""},
    ],
    ids=["all-factors", "no-credibility", "unidentified", "thermal-positioning-no-wear"],
)
def test_each_record_gets_the_numbers_of_its_own_evaluation(tmp_path: Path, changes: dict) -> None:
    cfg = _config(tmp_path, **changes)
    tables = [_table(seed) for seed in (3, 4, 5, 6)]
    alone = [_text(evaluate(t, cfg, columns=False).summary) for t in tables]
    together = [_text(s) for s in evaluate_many(tables, cfg)]
    assert together == alone
    # the records differ (each its own noise and spikes), so a mix-up would show
    assert len(set(alone)) == len(alone)
    # one record alone is the same too
    assert [_text(s) for s in evaluate_many(tables[1:2], cfg)] == alone[1:2]
    # every part of e_z runs: none of the factors is the zero it would be without its sensor
    parts = json.loads(alone[0])["error_parts_rms_um"]
    on = set(cfg.factors) - ({"loading", "fluctuating", "positioning"} if cfg.mechanics is None else set())
    assert {k for k, v in parts.items() if v > 0} == on


def test_records_that_do_not_stack_are_refused(tmp_path: Path) -> None:
    cfg = _config(tmp_path, mechanics=MECHANICS)
    a, b = _table(3), _table(4)
    shifted = _table(4)
    shifted.time = shifted.time + 1.0  # another time axis
    with pytest.raises(ValueError, match="one time axis"):
        evaluate_many([a, shifted], cfg)
    with pytest.raises(ValueError, match="one time axis"):
        evaluate_many([a, _table(4, n=599)], cfg)  # another length
    fewer = b.subset([n for n in b.names() if n != "vibration"])
    with pytest.raises(ValueError, match="one set of columns"):
        evaluate_many([a, fewer], cfg)
    short = [_table(3, n=1), _table(4, n=1)]
    with pytest.raises(ValueError, match="two rows"):
        evaluate_many(short, cfg)
    with pytest.raises(ValueError, match="no record"):
        evaluate_many([], cfg)
