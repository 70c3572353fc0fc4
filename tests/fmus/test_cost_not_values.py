"""The optimized build of the FMUs (link-time optimization, hidden symbols: twin.fmu.build.OPTIMIZE)
and the wrapper's deferred outputs change the cost of a call, never a value.

Inlining across the wrapper, the model and the shared code keeps every operation and its order
(no -ffast-math, no FMA contraction on baseline x86-64), so the tester's signals must be equal
bit for bit to those of the same sources built with fmpy's settings alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.cosim.master import run_scenario
from twin.fmu.build import build_fmu

from .fmi_driver import Driver

TESTER = scenarios_dir() / "base" / "tester-system.toml"
#: the two with the most calls across files: the noise draws (rng.c) and the outputs that a set
#: of an input defers (the mechanics' direct feedthrough)
PLAIN = {"sensors": "SensorsDAQ", "mechanics": "FixtureMechanics"}


@pytest.mark.slow
def test_the_optimized_build_gives_the_plain_builds_bits(tmp_path: Path) -> None:
    plain = [f'fmu.{i}.model="{build_fmu(m, tmp_path / i, optimize=False)}"' for i, m in PLAIN.items()]
    times = ['scenario.duration="10 min"', 'scenario.output_interval="0.1 s"']
    optimized = run_scenario(load_scenario(TESTER, times)).table
    reference = run_scenario(load_scenario(TESTER, [*times, *plain])).table
    assert optimized is not None and reference is not None
    assert list(optimized.columns) == list(reference.columns)
    assert len(optimized.time) == 6001
    for name in optimized.columns:
        assert np.array_equal(optimized[name], reference[name]), name
    # the sensors saw the load and the probe move: the comparison is not of constants
    assert np.ptp(optimized["sensors.angle_meas"]) > 0.8
    assert np.ptp(optimized["mechanics.probe_true"]) > 0.0


def test_a_set_input_shows_in_the_outputs_at_the_next_get(fmu_paths: dict[str, Path]) -> None:
    """The wrapper computes the outputs when they are read after a set (not at the set): a get
    after the set sees the new input through the direct feedthrough at once."""
    mech = Driver.started(fmu_paths["FixtureMechanics"])
    mech.step(0.1)
    before = mech.get(["probe_true", "dz_t_plate"])
    mech.set({"t_t_plate": 303.15})
    after = mech.get(["probe_true", "dz_t_plate"])
    assert after[1] > before[1] and after[0] != before[0]
    mech.set({"t_t_plate": 293.15})
    assert np.array_equal(mech.get(["probe_true", "dz_t_plate"]), before)
    mech.close()


def test_a_state_taken_right_after_a_set_is_accepted_back(fmu_paths: dict[str, Path]) -> None:
    """A state taken between a set and any get holds the outputs its inputs give: handed to
    another instance it passes the check of its outputs against its states and gives the same
    outputs there."""
    fmu = fmu_paths["FixtureMechanics"]
    a, b = Driver.started(fmu, name="a"), Driver.started(fmu, name="b")
    a.step(0.1)
    a.set({"t_t_plate": 303.15, "radial_load": 150e3})
    state = a.slave.getFMUstate()
    b.step(0.1)
    b.slave.setFMUstate(state)  # raises on fmi2Error: a refused state
    names = a.outputs()
    assert np.array_equal(b.get(names), a.get(names))
    a.slave.freeFMUstate(state)
    a.close()
    b.close()


def _daq(fmu: Path, name: str) -> Driver:
    return Driver.started(fmu, parameters={"seed": 7, "spike_rate": 2.0}, name=name)


def test_a_daq_sample_read_late_is_the_sample_read_at_once(fmu_paths: dict[str, Path]) -> None:
    """SensorsDAQ takes a step's last sample when its outputs are read: read after every step or
    only after the last one, the same inputs give the same outputs, bit for bit."""
    fmu = fmu_paths["SensorsDAQ"]
    every, last = _daq(fmu, "every"), _daq(fmu, "last")
    names = every.outputs()
    seen = []
    for k in range(50):
        inputs = {"probe_true": 0.004 + 1e-6 * k, "t_bearing": 293.15 + 0.1 * k, "load_true": 1e3 * k}
        for d in (every, last):
            d.set(inputs)
            d.step(0.1)
        seen.append(every.get(names))
    assert np.array_equal(last.get(names), seen[-1])
    assert len({tuple(s) for s in seen}) == 50  # every sample differs: the noise is on
    for d in (every, last):
        d.close()


def test_a_daq_state_taken_before_its_sample_is_read(fmu_paths: dict[str, Path]) -> None:
    """A state taken right after a step (its sample not read yet) holds that sample: another
    instance given it shows the same outputs and continues with the same draws."""
    fmu = fmu_paths["SensorsDAQ"]
    a, b = _daq(fmu, "a"), _daq(fmu, "b")
    a.set({"probe_true": 0.0045})
    a.step(0.1)
    state = a.slave.getFMUstate()
    b.step(0.1)
    b.slave.setFMUstate(state)
    names = a.outputs()
    assert np.array_equal(b.get(names), a.get(names))
    b.time = a.time
    for d in (a, b):
        d.step(0.3)
    assert np.array_equal(b.get(names), a.get(names))
    a.slave.freeFMUstate(state)
    for d in (a, b):
        d.close()


def test_initialization_mode_computes_again_after_a_set(fmu_paths: dict[str, Path]) -> None:
    """The outputs initialization mode computed for a get are kept until something is set: a set
    after a get is seen by the next get and by fmi2ExitInitializationMode."""
    mech = Driver(fmu_paths["FixtureMechanics"])
    mech.slave.setupExperiment(startTime=0.0)
    mech.slave.enterInitializationMode()
    first = mech.get(["probe_true"])
    assert np.array_equal(mech.get(["probe_true"]), first)
    mech.set({"probe_preload": 0.002})
    second = mech.get(["probe_true"])
    assert second[0] != first[0]
    mech.set({"probe_preload": 0.003})
    mech.slave.exitInitializationMode()
    reference = Driver.started(fmu_paths["FixtureMechanics"], parameters={"probe_preload": 0.003}, name="ref")
    assert np.array_equal(mech.get(mech.outputs()), reference.get(reference.outputs()))
    assert mech.get(["probe_true"])[0] != second[0]
    mech.close()
    reference.close()
