"""The master's semantics: integer clock, multi-rate zero-order hold, events, failures."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from twin.config.load import load_scenario
from twin.cosim.master import run_scenario

ROOM = """
[input.thermal.t_room]
profile = "ramp"
start = 293.15
end = 303.15
duration = "1 h"
"""


#: a slow thermal network and fast sensors closed through a delayed loop: the system the
#: plan and checkpoint tests build on (each adds its own driven input and events)
LOOP_SYSTEM = """
[fmu.thermal]
model = "ThermalNetwork"
period = "10 s"
unconnected = "a test system: the inputs nothing feeds keep their start values"
parameters = { solver_step = 1.0 }
[fmu.sensors]
model = "SensorsDAQ"
period = "1 s"
unconnected = "a test system: the inputs nothing feeds keep their start values"
[connections]
"thermal.t_ambient" = "sensors.t_room"
[[delay]]
from = "sensors.t_room_meas"
to = "thermal.t_room"
initial = 295.0
"""


def scenario(
    tmp_path: Path, body: str, *, duration: str = "1 h", step: str = "1 s", interval: str = "1 s"
) -> Path:
    text = f"""
[scenario]
name = "t"
duration = "{duration}"
step = "{step}"
output_interval = "{interval}"
seed = 3
{body}
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def test_output_times_are_exact_multiples(tmp_path: Path) -> None:
    path = scenario(
        tmp_path,
        '[fmu.thermal]\nmodel = "ThermalNetwork"\nperiod = "0.1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\nparameters = { solver_step = 0.1 }\n'
        + ROOM,
        duration="10 min",
        step="0.1 s",
        interval="0.3 s",
    )
    result = run_scenario(load_scenario(path))
    assert result.status == "completed"
    k = np.arange(len(result.table))
    # t_k = k * h computed from integers: no drift after 2000 rows (a summed float would drift)
    assert np.array_equal(result.table.time, k * 300_000_000 / 1e9)
    assert result.table.time[-1] == 600.0
    assert result.macro_steps == 6000 and result.fmu_steps == 6000


def test_slow_fmu_output_is_held_between_its_steps(tmp_path: Path) -> None:
    body = (
        '[fmu.thermal]\nmodel = "ThermalNetwork"\nperiod = "60 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        '[fmu.sensors]\nmodel = "SensorsDAQ"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        "[connections]\n"
        '"thermal.t_ambient" = "sensors.t_room"\n' + ROOM
    )
    result = run_scenario(load_scenario(scenario(tmp_path, body)))
    t = result.table.time
    ambient = result.table["thermal.t_ambient"]
    # the slow FMU's output changes only at its own communication points; it is read after
    # each step, which ran on the input held from the step's start (Jacobi): the pass-through
    # output at t shows the room of the previous communication point
    previous = np.maximum(60.0 * np.floor(t / 60.0) - 60.0, 0.0)
    held = 293.15 + 10.0 * np.minimum(previous / 3600.0, 1.0)
    np.testing.assert_allclose(ambient, held, rtol=0, atol=1e-9)
    # ... while its input (recorded as driven) follows the ramp at every one of them
    room = result.table["thermal.t_room"]
    on_grid = t % 60.0 == 0.0
    np.testing.assert_allclose(room[on_grid], 293.15 + 10.0 * np.minimum(t[on_grid] / 3600.0, 1.0), atol=1e-9)
    assert result.fmu_steps == 60 + 3600


def test_jacobi_exchange_uses_values_at_the_start_of_the_step(tmp_path: Path) -> None:
    # sensors read thermal.t_ambient: a step change of the room at 30 min reaches the
    # thermal output at the end of thermal's step (30:10), and the sensor's input from then on
    body = (
        '[fmu.thermal]\nmodel = "ThermalNetwork"\nperiod = "10 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        '[fmu.sensors]\nmodel = "SensorsDAQ"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        "parameters = { temp_noise = 0.0, temp_resolution = 0.0, temp_tau = 1e-3 }\n"
        '[connections]\n"thermal.t_ambient" = "sensors.t_room"\n'
        '[input.thermal.t_room]\nprofile = "constant"\nvalue = 293.15\n'
        '[[event]]\nat = "30 min"\naction = "set"\ntarget = "thermal.t_room"\nvalue = 300.0\n'
    )
    result = run_scenario(load_scenario(scenario(tmp_path, body)))
    t = result.table.time
    ambient = result.table["thermal.t_ambient"]
    assert np.all(ambient[t <= 1800.0] == 293.15)
    assert np.all(ambient[t >= 1810.0] == 300.0)
    meas = result.table["sensors.t_room_meas"]
    # the sensor steps from 1810 s with the new input, so its output shows it from 1811 s
    assert np.all(np.abs(meas[t <= 1810.0] - 293.15) < 1e-9)
    assert np.all(np.abs(meas[t >= 1811.0] - 300.0) < 1e-9)
    assert result.table["thermal.t_room"][t == 1800.0][0] == 300.0


def test_ramp_and_bias_events(tmp_path: Path) -> None:
    body = (
        '[fmu.thermal]\nmodel = "ThermalNetwork"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        '[input.thermal.q_hydraulic]\nprofile = "constant"\nvalue = 100.0\n'
        '[[event]]\nat = "10 min"\naction = "ramp"\ntarget = "thermal.q_hydraulic"\nvalue = 400.0\nduration = "10 min"\n'
        '[[event]]\nat = "40 min"\naction = "bias"\ntarget = "thermal.t_base"\nvalue = 2.5\n'
    )
    result = run_scenario(load_scenario(scenario(tmp_path, body)))
    t = result.table.time
    q = result.table["thermal.q_hydraulic"]
    expected = np.where(t < 600, 100.0, 100.0 + 300.0 * np.clip((t - 600.0) / 600.0, 0.0, 1.0))
    np.testing.assert_allclose(q, expected, atol=1e-9)
    base = result.table["thermal.t_base"]
    jump = base[t == 2400.0][0] - base[t == 2399.0][0]
    assert jump == pytest.approx(2.5, abs=1e-3)  # bias appears at the event, on top of a slow drift


@pytest.mark.parametrize("loop", ["fast", "python"])
def test_an_fmu_failure_keeps_the_rows_recorded_before_it(tmp_path: Path, loop: str) -> None:
    # a sensor bias at 20 min pushes a connected value past the receiving input's range: the
    # loader cannot foresee it, the FMU refuses it at run time
    body = (
        '[fmu.sensors]\nmodel = "SensorsDAQ"\nperiod = "10 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        '[fmu.mechanics]\nmodel = "FixtureMechanics"\nperiod = "10 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        '[connections]\n"sensors.probe_meas" = "mechanics.wear_offset"\n'
        '[[event]]\nat = "20 min"\naction = "bias"\ntarget = "sensors.probe_meas"\nvalue = 0.01\n'
    )
    result = run_scenario(load_scenario(scenario(tmp_path, body, interval="10 s")), loop=loop)
    assert result.status == "failed"
    assert result.error is not None
    msg = str(result.error)
    assert "mechanics" in msg and "fmi2SetReal" in msg and "outside its range" in msg and "t = 1200 s" in msg
    t = result.table.time
    assert t[-1] == 1190.0 and len(t) == 120  # the failing exchange at 1200 s is not a row
    assert np.all(np.isfinite(result.table["mechanics.probe_true"]))


@pytest.mark.parametrize(
    "fault, call", [("error", "fmi2DoStep"), ("discard", "fmi2DoStep"), ("nan", "fmi2GetReal")]
)
def test_both_loops_stop_at_a_fault_with_the_same_error_and_rows(
    tmp_path: Path, fault: str, call: str
) -> None:
    body = (
        '[fmu.mechanics]\nmodel = "FixtureMechanics"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        f'[[event]]\nat = "1 min"\naction = "fault"\ntarget = "mechanics"\nfault = "{fault}"\n'
    )
    sc = load_scenario(scenario(tmp_path, body, duration="3 min"))
    fast, py = run_scenario(sc, loop="fast"), run_scenario(sc, loop="python")
    assert fast.status == py.status == "failed"
    assert str(fast.error) == str(py.error)
    assert "mechanics" in str(fast.error) and call in str(fast.error) and "t = 60 s" in str(fast.error)
    assert fast.end_ns == py.end_ns == 60 * 10**9 and fast.macro_steps == py.macro_steps == 60
    assert fast.table.time.tobytes() == py.table.time.tobytes() and fast.table.time[-1] == 60.0
    for name in fast.table.names():
        assert fast.table[name].tobytes() == py.table[name].tobytes(), name


#: sensors -> thermal -> sensors, closed through a delay whose first value is 295 K
DELAYED_LOOP = (
    '[fmu.thermal]\nmodel = "ThermalNetwork"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
    '[fmu.sensors]\nmodel = "SensorsDAQ"\nperiod = "1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
    "parameters = { temp_noise = 0.0, temp_resolution = 0.0, temp_tau = 1e-3 }\n"
    '[connections]\n"thermal.t_ambient" = "sensors.t_room"\n'
    '[[delay]]\nfrom = "sensors.t_room_meas"\nto = "thermal.t_room"\ninitial = 295.0\n'
)


def test_delayed_connection_breaks_a_loop_with_its_initial_value(tmp_path: Path) -> None:
    # sensors -> thermal -> sensors: allowed only through a delay; the first exchange of the
    # delayed input sees the declared initial value
    body = DELAYED_LOOP
    result = run_scenario(load_scenario(scenario(tmp_path, body, duration="1 min")))
    assert result.status == "completed"
    ambient = result.table["thermal.t_ambient"]
    assert ambient[0] == 295.0  # initialization took the delay's initial value
    assert math.isfinite(ambient[-1])


@pytest.mark.parametrize(
    "scenario_file, overrides",
    [
        ("li2017-thermal-experiment.toml", ['scenario.duration="20 min"']),
        (
            "base/tester-system.toml",
            [
                'scenario.duration="3 min"',
                'scenario.output_interval="0.5 s"',
                'event=[{at = "1 min", action = "bias", target = "sensors.load_meas", value = 500.0},'
                ' {at = "90 s", action = "ramp", target = "oscillation.drive_on", value = 0.0, duration = "20 s"}]',
            ],
        ),
    ],
)
def test_fast_loop_and_python_loop_give_identical_signals(scenario_file: str, overrides: list[str]) -> None:
    from twin.config.load import scenarios_dir

    sc = load_scenario(scenarios_dir() / scenario_file, overrides)
    fast = run_scenario(sc, loop="fast")
    py = run_scenario(sc, loop="python")
    assert fast.status == py.status == "completed"
    assert (fast.macro_steps, fast.fmu_steps) == (py.macro_steps, py.fmu_steps)
    assert fast.table.names() == py.table.names()
    assert fast.table.time.tobytes() == py.table.time.tobytes()
    for name in fast.table.names():
        assert fast.table[name].tobytes() == py.table[name].tobytes(), name


@pytest.mark.parametrize("loop", ["fast", "python"])
def test_a_transformed_connection_gives_factor_times_output_plus_offset(tmp_path: Path, loop: str) -> None:
    """A connection's factor and offset (a unit conversion, an SSP LinearTransformation) reach
    the input, directly and through a delay, in both loops alike; the identity copies."""
    import dataclasses

    body = DELAYED_LOOP
    sc = load_scenario(scenario(tmp_path, body, duration="5 min"))

    def with_transform(factor: float, offset: float):
        connections = tuple(dataclasses.replace(c, factor=factor, offset=offset) for c in sc.connections)
        return run_scenario(dataclasses.replace(sc, connections=connections), loop=loop)

    plain, identity, halved = (
        run_scenario(sc, loop=loop),
        with_transform(1.0, 0.0),
        with_transform(0.5, 150.0),
    )
    assert plain.status == identity.status == halved.status == "completed"
    for name in plain.table.names():
        assert plain.table[name].tobytes() == identity.table[name].tobytes(), name
    ambient, room_meas = halved.table["thermal.t_ambient"], halved.table["sensors.t_room_meas"]
    assert ambient[0] == 295.0  # the delay's initial value, as given (never transformed)
    assert room_meas[0] == 0.5 * 295.0 + 150.0  # the direct connection at initialization
    assert ambient[2] == 0.5 * room_meas[0] + 150.0  # through the delay, one exchange late
    # the loop x -> 0.5 x + 150 settles at its fixed point, 300 K
    assert abs(ambient[-1] - 300.0) < 1e-6 and abs(room_meas[-1] - 300.0) < 1e-6


@pytest.mark.parametrize(
    ("k0", "k1", "every"), [(0, 100, 10), (3, 47, 4), (-7, 9, 3), (5, 6, 10), (8, 20, 0)]
)
def test_the_driven_matrix_holds_the_ticks_that_read_it(k0: int, k1: int, every: int) -> None:
    from twin.cosim.state import driven_row, driven_ticks

    ticks = driven_ticks(k0, k1, every)
    assert len(ticks) >= 1  # the loops always get a row to point at
    for k in range(k0, k1):
        row = driven_row(k, k0, every)
        assert 0 <= row < len(ticks)
        if every and k % every == 0:
            assert ticks[row] == k
    if every:
        assert list(ticks[ticks < k1]) == [k for k in range(k0, k1) if k % every == 0]
