"""Each of the five error parts appears alone when only its cause is switched on.

All runs start from the tester system with every cause switched off: constant room, no
station or friction heat, constant load without ripple, drive stopped, an aligned probe,
no interference and noise-free sensors. Then one cause at a time is switched on.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.runs import run_into
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import default_path, load_coefficients
from twin.errormodel.evaluate import PARTS
from twin.errormodel.sources import CREEP_COEFFICIENTS, load_history
from twin.outputs import read_signals_csv

pytestmark = pytest.mark.slow

QUIET = [
    'scenario.duration="10 min"',
    'scenario.output_interval="0.5 s"',
    "fmu.hydraulic.parameters.q_idle=0.0",
    "fmu.hydraulic.parameters.k_heat_load=0.0",
    "fmu.hydraulic.parameters.ripple_fraction=0.0",
    "fmu.hydraulic.parameters.load_mean=0.0",
    "input.oscillation.drive_on.value=0.0",
    "fmu.mechanics.parameters.sensor_tilt=0.0",
    "fmu.mechanics.parameters.abbe_offset=0.0",
    "fmu.mechanics.parameters.spindle_runout=0.0",
    "fmu.oscillation.parameters.vibration_amplitude=0.0",
    "fmu.oscillation.parameters.vibration_noise=0.0",
    "fmu.sensors.parameters.spike_rate=0.0",
    "fmu.sensors.parameters.temp_noise=0.0",
    "fmu.sensors.parameters.temp_resolution=0.0",
    "fmu.sensors.parameters.probe_noise=0.0",
    "fmu.sensors.parameters.probe_resolution=0.0",
    "fmu.sensors.parameters.load_noise=0.0",
    "fmu.sensors.parameters.load_resolution=0.0",
    "fmu.sensors.parameters.torque_noise=0.0",
    "fmu.sensors.parameters.vibration_noise=0.0",
]


def parts_of(tmp_path: Path, *switch_on: str, tilt: float = 0.0) -> tuple[dict[str, np.ndarray], object]:
    # the model knows this tester's probe alignment (a lab's alignment check): the committed
    # identified coefficients with the probe's scale cos(tilt)
    coefficients = load_coefficients(default_path()).with_values(probe_scale=float(np.cos(tilt)))
    coefficients.write(tmp_path / "coefficients.toml")
    model = f'errormodel.coefficients="{tmp_path / "coefficients.toml"}"'
    sc = load_scenario(scenarios_dir() / "base" / "tester-system.toml", [*QUIET, *switch_on, model])
    run_into(sc, tmp_path)
    table = read_signals_csv(tmp_path / "signals.csv")
    model = read_signals_csv(tmp_path / "errormodel.csv")
    assert np.array_equal(model.time, table.time)
    for name in model.names():
        table.add(model.meta[name], model[name])
    return {p: table[f"errormodel.e_{p}"] for p in PARTS}, table


#: numerical zero: the start values come from least-squares lines (rounding ~1e-19 m)
ZERO = 1e-13


def assert_alone(parts: dict[str, np.ndarray], active: str) -> None:
    for p, values in parts.items():
        if p == active:
            assert np.max(np.abs(values)) > 1e-8, f"{active} part did not appear"
        else:
            assert np.max(np.abs(values)) < ZERO, f"{p} part is not zero: max {np.max(np.abs(values)):.3g} m"


def test_everything_off_gives_no_error(tmp_path: Path) -> None:
    parts, table = parts_of(tmp_path)
    for p, values in parts.items():
        assert np.max(np.abs(values)) < ZERO, p
    assert np.max(np.abs(table["errormodel.reading_change"])) < ZERO


def test_loading_alone_follows_the_load(tmp_path: Path) -> None:
    parts, table = parts_of(
        tmp_path,
        "fmu.hydraulic.parameters.profile=1",
        "fmu.hydraulic.parameters.load_mean=150e3",
        "fmu.hydraulic.parameters.load_amplitude=50e3",
        "fmu.hydraulic.parameters.load_frequency=0.005",
    )
    assert_alone(parts, "loading")
    load = table["sensors.load_meas"]
    coefficients = load_coefficients(default_path())
    identified = coefficients.coefficients["load_compliance"]
    loading = parts["loading"]
    # the elastic compliance times the load's change, plus the identified creep spectrum over
    # the load's history
    spectrum = np.array([coefficients.coefficients[n].value for n in CREEP_COEFFICIENTS])
    creep_model = spectrum @ load_history(table.time, load)
    np.testing.assert_allclose(
        loading - loading[0], identified.value * (load - load[0]) + creep_model, rtol=0, atol=1e-12
    )
    assert 0.05e-6 < creep_model[-1] < 0.5e-6  # 10 min of 150 kN held: a small creep, predicted
    # and it explains the reading: the compensated wear stays at the true (zero) wear, within
    # what the identified compliance's error (a few standard errors) makes of the load swing
    # the liner as built is richer than the model: its 1 um hysteresis loop (play operator,
    # half-width 0.5 um) stays in the compensated wear, and its creep under the held 150 kN
    # (0.1 x 22 x (1 - exp(-600/7200)) = 0.18 um in this 10 min run) is predicted by a spectrum
    # of another form (bounded here by the creep itself); the identified compliance's own error
    # adds a few standard errors times the load swing
    hysteresis, creep = 0.5e-6, 0.1 * 0.4e-3 * (150e3 / 8.8e-4) / 3.1e9 * -np.expm1(-600 / 7200)
    bound = hysteresis + creep + 0.05e-6 + 5 * identified.std_error * np.ptp(load)
    assert np.max(np.abs(table["errormodel.wear_compensated"])) < bound


def test_thermal_alone_follows_the_room(tmp_path: Path) -> None:
    parts, _ = parts_of(
        tmp_path,
        'input.thermal.t_room={profile = "ramp", start = 293.15, end = 298.15, duration = "10 min"}',
    )
    assert_alone(parts, "thermal")


def test_fluctuating_alone_from_runout_and_vibration(tmp_path: Path) -> None:
    parts, table = parts_of(
        tmp_path,
        "input.oscillation.drive_on.value=1.0",
        "fmu.mechanics.parameters.spindle_runout=3e-6",
        "fmu.oscillation.parameters.vibration_amplitude=0.5e-6",
    )
    assert_alone(parts, "fluctuating")
    # the runout follows the encoder's angle: cos(angle - phase) - cos(angle0 - phase)
    # 3 um x (cos(angle - 0.3) - cos(0.3)) over +-25 deg spans 0.78 um, plus the vibration
    assert np.ptp(parts["fluctuating"]) > 0.7e-6
    assert np.max(np.abs(table["errormodel.wear_compensated"])) < 0.2e-6


def test_positioning_alone_from_a_tilted_probe(tmp_path: Path) -> None:
    parts, table = parts_of(
        tmp_path,
        "fmu.mechanics.parameters.sensor_tilt=0.05",
        'event=[{at = "1 min", action = "ramp", target = "mechanics.wear_offset", value = 50e-6, duration = "5 min"}]',
        tilt=0.05,
    )
    assert_alone(parts, "positioning")
    # cosine error: the probe reads the 50 um as 50 cos(0.05) um
    # (to 1e-3: the probe's linearity bow, 0.05 % of its range, moves the identified scale a little)
    assert parts["positioning"][-1] == pytest.approx(-50e-6 * (1 - np.cos(0.05)), rel=1e-3)
    assert table["errormodel.wear_compensated"][-1] == pytest.approx(50e-6, abs=0.01e-6)  # the bow: 3 nm


def test_interference_alone_from_spikes(tmp_path: Path) -> None:
    parts, table = parts_of(
        tmp_path,
        'scenario.output_interval="0.1 s"',  # every DAQ sample, so every spike is recorded
        "fmu.sensors.parameters.spike_rate=0.02",
        "fmu.sensors.parameters.spike_duration=0.1",
    )
    assert_alone(parts, "interference")
    spikes = table["sensors.spike"] > 0
    assert spikes.sum() > 5
    # the filter found exactly the spikes
    np.testing.assert_array_equal(parts["interference"] != 0.0, spikes)
