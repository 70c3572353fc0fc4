"""The paper's record with a short chain and its emulator, derived once for the session: the
update's and the next experiment's tests share it (the emulator takes ~150 twin runs)."""

from __future__ import annotations

import dataclasses

import pytest

from twin.calibration import update as U
from twin.calibration.emulator import derive, twin_drift
from twin.config.load import load_scenario, scenarios_dir

RECORD = scenarios_dir() / "records" / "li2017.toml"
#: a short chain: enough for the posterior's centre and spread to within ~10 %
SHORT = {"walkers": 72, "steps": 3000, "burn": 1000, "thin": 5}


@pytest.fixture(scope="session")
def paper_emulator() -> dict:
    """The paper's record (short chain, 8 held draws), its scenario, prior and emulator roles,
    forward runs and emulator."""
    record = dataclasses.replace(U.load_record(RECORD, sampler=SHORT), held_samples=8)
    scenario = load_scenario(record.scenario)
    prior, roles = U.sampled_rows(record, scenario)
    run = twin_drift(scenario)
    nominal = {n: float(scenario.nominal(n)) for n in prior.names}
    emulator = derive(run, nominal, prior.scales(), roles)
    return {
        "record": record,
        "scenario": scenario,
        "prior": prior,
        "roles": roles,
        "run": run,
        "nominal": nominal,
        "emulator": emulator,
    }
