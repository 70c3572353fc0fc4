"""The static plan: names resolved to indices once, from the model descriptions alone."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import twin.cosim.instances
import twin.cosim.plan
import twin.fmu.build
import twin.fmu.catalog
from twin.config.load import load_scenario
from twin.cosim.plan import BATCH_TICKS, ColumnKind, InputKind, make_plan
from twin.errors import ConfigError
from twin.seeds import instance_seed

from .test_master import LOOP_SYSTEM, scenario

BODY = (
    LOOP_SYSTEM
    + """
[input.thermal.q_hydraulic]
profile = "constant"
value = 100.0
[[event]]
at = "30 s"
action = "ramp"
target = "thermal.q_hydraulic"
value = 200.0
duration = "10 s"
[[event]]
at = "40 s"
action = "bias"
target = "sensors.t_room_meas"
value = 0.5
"""
)


def test_plan_resolves_inputs_columns_and_events_without_loading_an_fmu(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_fmu(*_: object) -> None:
        raise AssertionError("the plan must not build or load an FMU")

    for module, name in (
        (twin.fmu.build, "ensure_fmu"),
        (twin.fmu.catalog, "fmu"),
        (twin.cosim.instances, "FMUSlot"),
    ):
        monkeypatch.setattr(module, name, no_fmu)
    plan = make_plan(load_scenario(scenario(tmp_path, BODY, duration="2 min")))
    thermal, sensors = plan.instances
    assert (thermal.period_ticks, sensors.period_ticks, plan.n_ticks, plan.out_every) == (10, 1, 120, 1)

    inputs = {i.name: i for i in thermal.inputs}
    assert thermal.in_names == sorted(inputs)  # sorted by name, as the FMU sees them
    delayed = inputs["t_room"]
    assert (delayed.kind, delayed.src, delayed.initial) == (InputKind.DELAYED, 1, 295.0)
    assert sensors.outputs[delayed.idx] == "t_room_meas"
    fed = {i.name: i for i in sensors.inputs}["t_room"]
    assert (fed.kind, fed.src, thermal.outputs[fed.idx]) == (InputKind.CONNECTION, 0, "t_ambient")

    # every driven input has its own column; a profile drives its column from the start
    driven = [i for inst in plan.instances for i in inst.inputs if i.kind == InputKind.DRIVEN]
    assert [i.src for i in driven] == list(range(len(plan.driven)))
    assert plan.driven[inputs["q_hydraulic"].src] == ("profile", 0)
    others = [plan.driven[i.src] for i in driven if i.name != "q_hydraulic"]
    assert all(spec[0] == "constant" for spec in others)

    ramp, bias = plan.events
    assert (ramp.action, ramp.instance, ramp.column) == ("ramp", 0, inputs["q_hydraulic"].src)
    assert thermal.in_names[ramp.index] == "q_hydraulic"
    assert (bias.action, bias.instance, sensors.outputs[bias.index]) == ("bias", 1, "t_room_meas")

    # recorded: every output, then the driven inputs (never the connected ones)
    names = [c.meta.name for c in plan.columns]
    assert "thermal.q_hydraulic" in names and "sensors.t_room" not in names and "thermal.t_room" not in names
    assert (
        names.index("thermal.t_ambient")
        < names.index("thermal.q_hydraulic")
        < names.index("sensors.t_room_meas")
    )
    kinds = {c.meta.name: c.kind for c in plan.columns}
    assert (
        kinds["thermal.q_hydraulic"] == ColumnKind.INPUT and kinds["thermal.t_ambient"] == ColumnKind.OUTPUT
    )

    # the sensors' noise seed is derived from the scenario seed, set before the parameters
    assert sensors.parameters[0] == ("seed", instance_seed(3, 1))
    assert thermal.parameters == (("solver_step", 1.0),)  # ThermalNetwork has no seed
    # initialization goes variable by variable: the thermal network's t_ambient is read, then
    # the sensors' t_room is set from it; the loop back is delayed: no algebraic loop
    assert plan.loops == ()
    stages = [(s.inputs, s.outputs, s.cycles) for s in plan.init_stages]
    t_ambient, t_room = thermal.outputs.index("t_ambient"), sensors.in_names.index("t_room")
    assert stages == [((), ((0, t_ambient),), ()), (((1, t_room),), (), ())]


def test_batch_progress_and_checkpoint_ticks(tmp_path: Path) -> None:
    plan = make_plan(load_scenario(scenario(tmp_path, BODY, duration="20 h")))
    assert plan.n_ticks == 72_000
    assert list(plan.batch_limit_ticks()) == [BATCH_TICKS, 2 * BATCH_TICKS]
    marks = plan.progress_ticks()
    assert len(marks) == 100 and marks[0] == 720 and marks[-1] == plan.n_ticks
    assert list(plan.checkpoint_ticks(8 * 3600 * 10**9)) == [28_800, 57_600]  # never at the end
    assert list(plan.checkpoint_ticks(None)) == []


def test_an_event_off_the_step_grid_is_refused(tmp_path: Path) -> None:
    # it would never be applied (and hold up every event after it): say so instead
    body = BODY.replace('at = "30 s"', 'at = "30.5 s"')
    sc = load_scenario(scenario(tmp_path, body, duration="2 min"))
    with pytest.raises(ConfigError, match="not on the step grid"):
        make_plan(sc)


def test_a_plan_made_like_another_of_its_structure_equals_the_one_made_from_scratch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from twin.config.spec import Profile

    base = load_scenario(scenario(tmp_path, BODY, duration="2 min"))
    like = make_plan(base)
    # a sample: other parameter values, another profile, another seed (the seed is generated)
    sample = (
        base.with_parameter("thermal", "solver_step", 0.5)
        .with_input(Profile("thermal.q_hydraulic", "ramp", {"start": 90.0, "end": 120.0, "duration": 60.0}))
        .with_seed(11)
    )
    fresh = make_plan(sample)
    assert make_plan(sample, like) == fresh
    assert fresh != like  # the parameters and the seed did change
    assert fresh.instances[1].parameters[0] == ("seed", instance_seed(11, 1))

    # another structure (one more parameter set, or a connection gone) is made from scratch:
    # a plan like the base's would be wrong, so reading the descriptions again must happen
    calls: list[str] = []
    real = twin.cosim.plan.model_variables
    monkeypatch.setattr(twin.cosim.plan, "model_variables", lambda m: calls.append(m) or real(m))
    assert make_plan(sample, like) == fresh and calls == []
    seeded = sample.with_parameter("sensors", "seed", 5)
    assert make_plan(seeded, like) == make_plan(seeded) and calls
    assert make_plan(seeded, like).instances[1].parameters[-1] == ("seed", 5)
    unfed = dataclasses.replace(sample, connections=tuple(c for c in sample.connections if c.delay))
    assert make_plan(unfed, like) == make_plan(unfed) != fresh
