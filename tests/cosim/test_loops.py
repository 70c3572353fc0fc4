"""Loops between FMUs, as their ModelStructure makes them (issue 29).

- A loop through outputs without direct feedthrough (two first-order lags) runs with no delay,
  as libcosim runs it: the same values bit for bit, from initialization to the end.
- A true algebraic loop (two gains, direct feedthrough all round) is solved by fixed-point
  iteration at initialization and at every communication point, to its closed form.
- One the master cannot solve is refused naming its cycle: across instances of different periods
  before anything runs (exit 2), or not converging (at initialization: exit 2; mid-run: the run
  fails with the loop named).

The FMUs are the test-only models of tests/data/models, built with the twin's own wrapper.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import twin.cosim.loops
from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.config.loops import algebraic_loops, strongly_connected
from twin.cosim.instances import close_slots, open_slots
from twin.cosim.loops import LoopError, initialize
from twin.cosim.master import Master, run_scenario
from twin.cosim.plan import Plan, make_plan
from twin.cosim.state import make_state
from twin.fmu import catalog

STEP = 0.1


def _write(tmp_path: Path, body: str, *, duration: str = "10 s", name: str = "loop") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(
        f'[scenario]\nname = "{name}"\nduration = "{duration}"\nstep = "{STEP} s"\n'
        f'output_interval = "{STEP} s"\nseed = 1\n' + body
    )
    return path


# ----------------------------------------------------------------- no direct feedthrough


def _lags(models: dict[str, Path]) -> str:
    return f"""
[fmu.a]
model = "{models["Lag"]}"
period = "{STEP} s"
parameters = {{ T = 1.0, x0 = 100.0 }}
[fmu.b]
model = "{models["Lag"]}"
period = "{STEP} s"
parameters = {{ T = 3.0, x0 = 0.0 }}
[connections]
"a.y" = "b.u"
"b.y" = "a.u"
"""


def _libcosim_lags(models: dict[str, Path], steps: int) -> np.ndarray:
    """The same two lags, parameters, connections and step in libcosim: a.y and b.y after each step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_step_size(step_size=round(STEP * 1e9))
    slaves, index, refs = [], {}, {}
    for name, params in (("a", {"T": 1.0, "x0": 100.0}), ("b", {"T": 3.0, "x0": 0.0})):
        slaves.append(CosimLocalSlave(fmu_path=str(models["Lag"]), instance_name=name))
        index[name] = execution.add_local_slave(local_slave=slaves[-1])
        refs[name] = {v.name.decode(): v.reference for v in execution.slave_variables(index[name])}
        for p, value in params.items():
            assert execution.real_initial_value(index[name], refs[name][p], value)
    assert (
        execution.connect_real_variables(index["a"], refs["a"]["y"], index["b"], refs["b"]["u"]) is not False
    )
    assert (
        execution.connect_real_variables(index["b"], refs["b"]["y"], index["a"], refs["a"]["u"]) is not False
    )
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    rows = []
    for _ in range(steps):
        assert execution.step()
        rows.append([observer.last_real_values(index[n], [refs[n]["y"]])[0] for n in ("a", "b")])
    return np.array(rows)


def test_a_loop_without_direct_feedthrough_needs_no_delay(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    scenario = load_scenario(_write(tmp_path, _lags(test_models)))
    plan = make_plan(scenario)
    assert plan.loops == ()  # the loader accepts it, and it is no algebraic loop
    assert not any(c.delay for c in scenario.connections)
    ours = {loop: run_scenario(scenario, loop=loop).table for loop in ("fast", "python")}
    assert ours["fast"] is not None and ours["python"] is not None
    for name in ("a.y", "b.y"):
        assert ours["fast"][name].tobytes() == ours["python"][name].tobytes()
    table = ours["fast"]
    assert (table["a.y"][0], table["b.y"][0]) == (100.0, 0.0)
    # the two lags meet: a cools, b warms, each from what the other had at the start of its step
    assert table["a.y"][-1] < 100.0 and table["b.y"][-1] > 0.0


def test_the_loop_without_a_delay_equals_libcosims_run_bit_for_bit(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    table = run_scenario(load_scenario(_write(tmp_path, _lags(test_models)))).table
    assert table is not None
    theirs = _libcosim_lags(test_models, steps=len(table) - 1)  # libcosim is read after each step
    ours = np.column_stack([table["a.y"], table["b.y"]])[1:]
    assert theirs.shape == ours.shape == (100, 2)
    np.testing.assert_array_equal(theirs, ours)  # tolerance 0: the same arithmetic, step by step
    assert np.ptp(ours[:, 0]) > 10.0  # and the values move


def test_the_tester_systems_friction_loop_has_no_direct_feedthrough() -> None:
    """The shipped tester closes friction heat -> bearing temperature -> friction heat without
    a [[delay]]: no output on it depends on an input at a communication point."""
    scenario = load_scenario(scenarios_dir() / "base" / "tester-system.toml")
    assert not any(c.delay for c in scenario.connections)
    assert any(c.src == "oscillation.q_friction_avg" for c in scenario.connections)
    plan = make_plan(scenario)
    assert plan.loops == ()
    # in initialization mode FMI's default (no dependencies: every input) closes it formally;
    # it is iterated there, once, and converges at once
    cycles = [c.name for s in plan.init_stages for c in s.cycles]
    assert cycles == [
        "oscillation.q_friction_avg -> thermal.q_friction -> thermal.t_bearing -> oscillation.t_bearing"
        " -> oscillation.q_friction_avg"
    ]
    assert catalog.description("OscillationDrive").feedthrough["q_friction_avg"] == ()
    assert catalog.description("ThermalNetwork").feedthrough["t_bearing"] == ()


# ----------------------------------------------------------------- true algebraic loops

K_A, K_B = 0.5, -0.8


def _gains(models: dict[str, Path], *, period_b: str = f"{STEP} s", extra: str = "") -> str:
    return f"""
[fmu.a]
model = "{models["Gain"]}"
period = "{STEP} s"
[fmu.b]
model = "{models["Gain"]}"
period = "{period_b}"
[input.a.k]
profile = "constant"
value = {K_A}
[input.b.k]
profile = "constant"
value = {K_B}
[input.a.w]
profile = "ramp"
start = 1.0
end = 3.0
duration = "10 s"
[input.b.w]
profile = "sine"
mean = 0.5
amplitude = 1.0
period = "4 s"
[connections]
"a.y" = "b.u"
"b.y" = "a.u"
{extra}"""


def test_an_algebraic_loop_is_solved_to_its_closed_form_at_every_step(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    scenario = load_scenario(_write(tmp_path, _gains(test_models)))
    plan = make_plan(scenario)
    assert [loop.name for loop in plan.loops] == ["a.y -> b.u -> b.y -> a.u -> a.y"]
    fast, python = (run_scenario(scenario, loop=loop).table for loop in ("fast", "python"))
    assert fast is not None and python is not None
    assert all(fast[n].tobytes() == python[n].tobytes() for n in fast.names())  # one loop runs it
    w_a, w_b = fast["a.w"], fast["b.w"]
    y_a = (K_A * w_b + w_a) / (1.0 - K_A * K_B)
    y_b = K_B * y_a + w_b
    assert len(fast) == 101 and np.ptp(y_a) > 1.0  # every row, initialization and the end included
    np.testing.assert_allclose(fast["a.y"], y_a, rtol=1e-11, atol=0)
    np.testing.assert_allclose(fast["b.y"], y_b, rtol=1e-11, atol=1e-12)
    # without the iteration each gain would see the other's output of the step before (Jacobi)
    jacobi = K_A * fast["b.y"][:-1] + w_a[1:]
    assert np.abs(jacobi - y_a[1:]).max() > 1e-3


def test_a_delay_stays_a_choice_for_an_algebraic_loop(test_models: dict[str, Path], tmp_path: Path) -> None:
    body = _gains(test_models).replace('"b.y" = "a.u"\n', "")
    body += '[[delay]]\nfrom = "b.y"\nto = "a.u"\ninitial = 0.0\n'
    scenario = load_scenario(_write(tmp_path, body))
    assert make_plan(scenario).loops == ()  # the delay breaks it: nothing to iterate
    table = run_scenario(scenario).table
    assert table is not None
    assert table["a.y"][0] == K_A * 0.0 + table["a.w"][0]  # a.u holds the delay's initial value
    closed = (K_A * table["b.w"] + table["a.w"]) / (1.0 - K_A * K_B)
    assert np.abs(table["a.y"] - closed).max() > 1e-3  # the delay changes the answer


def test_an_algebraic_loop_across_periods_is_refused_naming_it(
    test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = _write(tmp_path, _gains(test_models, period_b="0.2 s"))
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"{path}: connections: algebraic loop a.y -> b.u -> b.y -> a.u -> a.y" in lines[0]
    assert "different periods (a 100 ms, b 200 ms)" in lines[0] and "[[delay]]" in lines[0]


def test_a_loop_that_does_not_converge_at_initialization_is_refused(
    test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    body = _gains(test_models).replace(f"value = {K_B}", "value = -2.5")  # k_a k_b = -1.25
    path = _write(tmp_path, body)
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert (
        "connections: algebraic loop a.y -> b.u -> b.y -> a.u -> a.y did not converge at initialization"
        in lines[0]
    )


def test_a_loop_that_stops_converging_mid_run_fails_the_run_naming_it(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    extra = '[[event]]\nat = "2 s"\naction = "set"\ntarget = "b.k"\nvalue = -2.5\n'
    result = Master(make_plan(load_scenario(_write(tmp_path, _gains(test_models, extra=extra))))).run()
    assert result.status == "failed"
    assert isinstance(result.error, LoopError)
    assert str(result.error).startswith(
        "algebraic loop a.y -> b.u -> b.y -> a.u -> a.y did not converge at t = 2 s"
    )
    assert result.table is not None and len(result.table) == 20  # every row before it is kept


def test_the_test_models_pass_fmpy_validate(test_models: dict[str, Path]) -> None:
    from fmpy.validation import validate_fmu

    for path in test_models.values():
        assert validate_fmu(str(path)) == []


def test_strongly_connected_components_come_in_dependency_order() -> None:
    graph = {"x": ["a"], "a": ["b"], "b": ["c"], "c": ["a", "d"], "d": ["e"], "e": [], "f": ["f"]}
    found = strongly_connected(graph)
    assert sorted(found) == [["a", "b", "c"], ["d"], ["e"], ["f"], ["x"]]
    at = {tuple(c): n for n, c in enumerate(found)}
    assert at[("x",)] < at[("a", "b", "c")] < at[("d",)] < at[("e",)]


def test_a_loop_is_named_by_its_shortest_cycle(test_models: dict[str, Path], tmp_path: Path) -> None:
    scenario = load_scenario(_write(tmp_path, _gains(test_models)))
    fmus = {f.name: f for f in scenario.fmus}
    [cycle] = algebraic_loops(fmus, scenario.connections)
    assert (cycle.inputs, cycle.outputs) == (("a.u", "b.u"), ("a.y", "b.y"))
    assert cycle.instances == ("a", "b")


def test_a_run_with_an_algebraic_loop_resumes_from_a_checkpoint_byte_for_byte(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    from twin.cosim import RunControls

    plan = make_plan(load_scenario(_write(tmp_path, _gains(test_models))))
    snaps: list[dict] = []
    full = Master(plan, controls=RunControls(checkpoint_every_ns=4 * 10**9, on_checkpoint=snaps.append)).run()
    assert full.status == "completed" and [s["tick"] for s in snaps] == [40, 80]
    rest = Master(make_plan(plan.scenario), resume=snaps[0]).run()
    assert full.table is not None and rest.table is not None
    for name in full.table.names():
        assert rest.table[name].tobytes() == full.table[name][40:].tobytes(), name


# ----------------------------------------------------------------- initialization


def _initialized(plan: Plan) -> list[np.ndarray]:
    """Every instance's inputs set and outputs visible after :func:`initialize`."""
    slots = open_slots(plan)
    try:
        state = make_state(plan)
        initialize(plan, state, slots)
        return [np.concatenate([b.in_port.values, b.cur]) for b in state.buffers]
    finally:
        close_slots(slots)


@pytest.mark.parametrize("name", ["base/tester-system.toml", "li2017-thermal-experiment.toml"])
def test_an_instance_leaves_initialization_once_its_inputs_are_set_with_the_same_values(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The thermal network works its initial state out again when it leaves initialization
    mode: each instance leaves as soon as its inputs are set, never before one of them (its
    cycle's iteration included), and the values are those of every instance leaving at the end."""
    plan = make_plan(load_scenario(scenarios_dir() / name))
    leaving = twin.cosim.loops._leaving(plan)
    early = set().union(*leaving)
    (thermal,) = [i.index for i in plan.instances if i.name == "thermal"]
    assert thermal in early
    for s, instances in enumerate(leaving):
        for i in instances:
            later = [
                v
                for stage in plan.init_stages[s + 1 :]
                for v in (*stage.inputs, *(x for c in stage.cycles for x in c.inputs))
            ]
            now = [v for c in plan.init_stages[s].cycles for v in c.inputs]
            assert all(j != i for j, _ in later + now), (plan.instances[i].name, s)
    if name.startswith("base/"):  # its friction loop is iterated: thermal leaves after that stage
        (cycle_stage,) = [s for s, stage in enumerate(plan.init_stages) if stage.cycles]
        assert thermal in leaving[cycle_stage + 1]
    now = _initialized(plan)
    monkeypatch.setattr(twin.cosim.loops, "_leaving", lambda p: [set() for _ in p.init_stages])
    at_the_end = _initialized(plan)
    assert all(np.array_equal(a, b) for a, b in zip(now, at_the_end, strict=True))
