"""The FMUs at the edges of their ranges and of what hosts do (a hostile review, 2026-11-25).

Each case was a defect: a state the FMU reached refused when handed back, Inf handed out with
fmi2OK, a network at room temperature drifting, a summed host clock refused. Each test fails on
the code before its fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from twin.fmu.build import model_names

from .fmi_driver import Driver
from .test_thermal_network import Q_FRIC, Q_HYD, Network

#: a network made stiff through its sensor node: 1 J/K on 1 kW/K to the room at 3600 s steps
#: takes 24 squarings of the step map's exponential, the most the FMU allows (model.c)
STIFF = {"c_sensor": 1.0, "g_sensor_room": 1000.0, "solver_step": 3600.0}
HOUR = 3600.0


def restore_own_state(d: Driver) -> None:
    """Hand the instance its own state back, as a pointer and as bytes (raises if refused)."""
    state = d.slave.getFMUstate()
    try:
        d.slave.setFMUstate(state)
        data = d.slave.serializeFMUstate(state)
        d.slave.deSerializeFMUstate(data)
    finally:
        d.slave.freeFMUstate(state)


def test_a_stiff_network_at_room_temperature_stays_there(fmu_paths: dict[str, Path]) -> None:
    # no heat in and every node at the room's temperature: nothing may change. The squarings'
    # rounding (2^24 eps) used to move the nodes by 3e-4 K in 20 h and make energy from nothing
    d = Driver.started(fmu_paths["ThermalNetwork"], STIFF, {"t_room": 293.15})
    net = Network(d, STIFF)
    for _ in range(20):
        d.step(HOUR)
    temps = d.get([f"t_{n}" for n in net.nodes])
    stored, put_in, lost = d.get(["energy_stored", "energy_in", "energy_lost"])
    d.close()
    assert np.max(np.abs(temps - 293.15)) < 1e-9, temps
    assert put_in == 0.0 and abs(stored) < 1e-3 and abs(lost) < 1e-3, (stored, lost)


def test_a_stiff_network_reaches_the_analytic_steady_state_and_keeps_its_energy_balance(
    fmu_paths: dict[str, Path],
) -> None:
    # the accuracy the limit of 24 squarings was chosen for (model.c: TN_MAX_SQUARINGS)
    d = Driver.started(
        fmu_paths["ThermalNetwork"], STIFF, {"t_room": 295.0, "q_hydraulic": Q_HYD, "q_friction": Q_FRIC}
    )
    net = Network(d, STIFF)
    for _ in range(60 * 24):  # 60 days: every time constant long decayed
        d.step(HOUR)
    got = d.get([f"t_{n}" for n in net.nodes])
    stored, put_in, lost = d.get(["energy_stored", "energy_in", "energy_lost"])
    d.close()
    np.testing.assert_allclose(got, net.steady_state(295.0, Q_HYD, Q_FRIC), rtol=0, atol=2e-7)
    # within 1e-8 of the heat that went through (2.1 GJ in, nearly all of it lost again)
    assert abs(stored - (put_in - lost)) <= 1e-8 * put_in, (stored, put_in, lost)


def test_a_network_too_stiff_for_its_step_is_refused_with_the_step_that_works(
    fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    d = Driver(fmu_paths["ThermalNetwork"])
    d.slave.setupExperiment(startTime=0.0)
    d.set({"c_sensor": 0.001, "g_sensor_room": 1e5, "solver_step": 3600.0})  # 41 squarings
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        d.slave.exitInitializationMode()
    # still in initialization mode: the step the message names is accepted
    d.set({"solver_step": 3600.0 * 2.0 ** (24 - 41)})
    d.slave.exitInitializationMode()
    d.step(3600.0 * 2.0 ** (24 - 41))
    d.close()


def test_a_stiff_network_at_the_coldest_room_gives_its_own_state_back(fmu_paths: dict[str, Path]) -> None:
    # the room at its declared minimum and the nodes at it: rounding took a node below the
    # minimum, and the state the FMU had just reached was refused as impossible
    params = {"c_sensor": 0.1, "g_sensor_room": 10.0, "solver_step": 60.0}
    d = Driver.started(fmu_paths["ThermalNetwork"], params, {"t_room": 173.15})
    for _ in range(10):
        d.step(60.0)
        restore_own_state(d)
    assert min(d.get([o for o in d.outputs() if o.startswith("t_")])) >= 173.15 - 1e-9
    d.close()


def test_parameters_that_overflow_an_output_are_refused_in_initialization_mode(
    fmu_paths: dict[str, Path],
) -> None:
    # each in its range, together a spring of 1e-307 N/m under a 100 kg pole: the pole's
    # position is Inf. It was handed out with fmi2OK, and leaving initialization mode moved the
    # instance to 'error', where the parameter could no longer be corrected
    d = Driver(fmu_paths["FixtureMechanics"])
    d.slave.setupExperiment(startTime=0.0)
    d.set({"k_spring": 1e-307, "k_head": 0.0, "m_pole": 100.0, "f_spring0": 0.0, "f_head0": 0.0})
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        d.get(["z_pole_top"])
    with pytest.raises(FMICallException):
        d.slave.exitInitializationMode()
    d.set({"k_spring": 2000.0})
    assert np.isfinite(d.get(["z_pole_top"])).all()
    d.slave.exitInitializationMode()
    d.step(0.1)
    d.close()


def test_a_subnormal_swing_gives_its_own_state_back(fmu_paths: dict[str, Path]) -> None:
    # an amplitude of 5e-324 rad (in [0, pi]) made the state check's bound on the sliding
    # distance underflow to 0 while the distance itself was 5e-324 m
    params = {"amplitude": 5e-324, "frequency": 17.3128, "solver_step": 1.0, "q_avg_window": 2.0}
    d = Driver.started(fmu_paths["OscillationDrive"], params, {"radial_load": 1e6})
    d.step(1.0)
    assert d.get(["sliding_distance"])[0] > 0.0
    restore_own_state(d)
    d.close()


@pytest.mark.parametrize("model", model_names())
def test_a_state_saved_after_an_injected_nan_is_given_back(model: str, fmu_paths: dict[str, Path]) -> None:
    # fault_inject = 3: the step returns fmi2OK with a NaN output, on purpose (masters' tests);
    # the state saved then must come back as it was saved, NaN included
    d = Driver.started(fmu_paths[model], inputs={"fault_inject": 3.0})
    d.step(float(d.vars["solver_step"].start))
    before = d.get(d.outputs())
    assert np.isnan(before).sum() == 1
    restore_own_state(d)
    np.testing.assert_array_equal(d.get(d.outputs()), before)
    d.close()


@pytest.mark.parametrize("model", model_names())
def test_a_host_clock_off_by_rounding_is_accepted_and_a_skipped_step_is_not(
    model: str, fmu_paths: dict[str, Path]
) -> None:
    # a host that sums its steps (tc += h, the FMI 2.0 standard's example master) drifts from
    # the FMU's exact clock: 2e-8 s after 10^5 steps of 0.1 s, which used to be refused
    d = Driver.started(fmu_paths[model])
    h = float(d.vars["solver_step"].start)
    for k in range(3):
        drift = (-1) ** k * 0.49 * h  # less than half an internal step: the same step
        d.slave.doStep(currentCommunicationPoint=k * h + drift, communicationStepSize=h)
    before = d.get(d.outputs())
    for off in (0.51 * h, -0.51 * h, h, -h):  # half a step or more: a step skipped or repeated
        with pytest.raises(FMICallException):
            d.slave.doStep(currentCommunicationPoint=3 * h + off, communicationStepSize=h)
    np.testing.assert_array_equal(d.get(d.outputs()), before)  # a refusal changes nothing
    d.slave.doStep(currentCommunicationPoint=3 * h, communicationStepSize=h)  # the FMU's time is exact
    d.close()
