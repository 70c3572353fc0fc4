"""What runs of one structure share of their set-up (twin.cosim.plan.shared): the stepper's
arrays and the initialization order, made once for plans made ``like`` another, and a pooled
instance's parameter types; each run's rows stay bit for bit those of its run alone."""

from __future__ import annotations

import dataclasses

import numpy as np

from twin.config.load import load_scenario, scenarios_dir
from twin.config.spec import NS_PER_S, Scenario
from twin.cosim import make_plan
from twin.cosim.batch import run_batch
from twin.cosim.loops import _order
from twin.cosim.master import Master
from twin.cosim.native import _structure
from twin.cosim.plan import shared
from twin.fmu import catalog
from twin.fmu.pool import SlotPool
from twin.fmu.slot import FMUSlot
from twin.uncertainty.rooms import shaped, smooth_drift

PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"


def _samples(n: int, minutes: int) -> list[Scenario]:
    """What a Monte Carlo's samples change: parameters, the noise seed, the room's profile."""
    base = dataclasses.replace(load_scenario(PAPER), duration_ns=minutes * 60 * NS_PER_S)
    out = []
    for i in range(n):
        sample = base.with_seed(200 + i).with_parameters(
            "mechanics", {"alpha_base": 11e-6 + 2e-7 * i, "alpha_heel_block": 11e-6 - 1e-7 * i}
        )
        drift = smooth_drift(np.random.default_rng(i), 1.0)
        shape = ("exponential", "ramp", "s-curve")[i % 3]
        out.append(sample.with_input(shaped(sample, "thermal.t_room", shape, drift, "test: a room each")))
    return out


def test_plans_made_like_another_share_their_setup_and_run_bit_for_bit_alone() -> None:
    scenarios = _samples(4, 20)
    like: list = []
    for s in scenarios:
        like.append(make_plan(s, like[-1] if like else None))
    alone = [make_plan(s) for s in scenarios]  # each from scratch: parts of its own
    # what the copies share is made once; a plan of other parts gets its own
    assert all(_structure(p) is _structure(like[0]) for p in like)
    assert all(_order(p) is _order(like[0]) for p in like)
    assert _structure(alone[1]) is not _structure(like[1])
    keep = {c.meta.name for c in like[0].columns}
    pool = SlotPool(per_key=4)
    first = run_batch(like, keep, pool)
    again = run_batch(like, keep, pool)  # pooled instances: their parameter types kept
    assert pool.reused >= 3 * len(like)
    for runs in (first, again):
        assert runs.alone == [] and sorted(runs.results) == list(range(len(like)))
        for i, plan in enumerate(alone):
            ref, got = Master(plan).run().table, runs.results[i].table
            assert ref.time.tobytes() == got.time.tobytes()
            assert ref.names() == got.names()
            for name in ref.names():
                assert ref[name].tobytes() == got[name].tobytes(), (i, name)
    # the check can fail: the copies differ
    probes = {first.results[i].table["sensors.probe_meas"].tobytes() for i in range(len(like))}
    assert len(probes) == len(like)


def test_shared_makes_again_for_other_objects_of_equal_value() -> None:
    made: list[int] = []

    def make() -> int:
        made.append(1)
        return len(made)

    a, b = ("x", 1), ("y", 2)
    assert shared("probe", (a, b), make) == 1
    assert shared("probe", (a, b), make) == 1  # the same objects: made once
    assert shared("probe", (tuple(["x", 1]), b), make) == 2  # equal, not the same: made again
    assert shared("another probe", (a, b), make) == 3  # what is made is part of the key


def test_a_pooled_instance_given_other_names_sets_them() -> None:
    """set_values keeps the types of the names set last: other names are worked out again."""
    slot = FMUSlot(catalog.fmu("FixtureMechanics"), "shared-setup-probe")
    try:
        heel = slot.vr("alpha_heel_block")
        base = slot.vr("alpha_base")
        ref = slot.vr("reference_at_start")
        slot.setup(0.0)
        slot.set_values([("alpha_heel_block", 1.25e-5), ("reference_at_start", False)])
        slot.set_values([("alpha_heel_block", 1.5e-5), ("reference_at_start", True)])  # same names
        slot.enter_initialization()  # the FMU reads its variables back from here on
        assert slot._slave.getReal([heel]) == [1.5e-5]
        assert slot._slave.getBoolean([ref]) == [True]
        slot.set_values([("alpha_base", 1.75e-5), ("alpha_heel_block", 1.0e-5)])  # other names
        assert slot._slave.getReal([base, heel]) == [1.75e-5, 1.0e-5]
        assert slot._slave.getBoolean([ref]) == [True]
    finally:
        slot.close()
