"""SensorsDAQ physics: lag and low-pass step responses, quantization, noise statistics, zero
drift, range clipping and the seeded noise, each checked against a closed form computed here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from .fmi_driver import Driver

POINTS = [
    "bearing_block",
    "heel_block",
    "bearing",
    "t_plate",
    "base",
    "long_pole",
    "detecting_frame",
    "room",
]
T_IN = [f"t_{p}" for p in POINTS]
T_OUT = [f"t_{p}_meas" for p in POINTS]
QUIET = {"temp_noise": 0.0, "temp_resolution": 0.0, "probe_noise": 0.0, "probe_resolution": 0.0}
T0 = 293.15


def start(
    fmu_paths: dict[str, Path],
    parameters: dict[str, float] | None = None,
    inputs: dict[str, float] | None = None,
    name: str = "inst",
) -> Driver:
    d = Driver(fmu_paths["SensorsDAQ"], name)
    d.init(parameters, inputs)
    return d


def record(d: Driver, names: list[str], n: int, h: float) -> np.ndarray:
    """Outputs after each of n communication steps of h seconds."""
    rows = []
    for _ in range(n):
        d.step(h)
        rows.append(d.get(names))
    return np.array(rows)


@pytest.mark.parametrize("solver_step", [0.01, 0.5])
def test_temperature_lag_step_response_is_exact(solver_step: float, fmu_paths: dict[str, Path]) -> None:
    tau = 20.0
    d = start(fmu_paths, {**QUIET, "solver_step": solver_step, "temp_tau": tau}, dict.fromkeys(T_IN, T0))
    np.testing.assert_array_equal(d.get(T_OUT), T0)  # in equilibrium at initialization
    d.set(dict.fromkeys(T_IN, T0 + 10.0))
    h, n = 1.0, 120
    got = (record(d, T_OUT, n, h) - T0) / 10.0
    d.close()
    t = h * np.arange(1, n + 1)
    expected = -np.expm1(-t / tau)
    np.testing.assert_allclose(got, np.repeat(expected[:, None], len(T_OUT), axis=1), rtol=0, atol=1e-12)


def test_probe_low_pass_step_response_is_exact(fmu_paths: dict[str, Path]) -> None:
    fc = 50.0
    d = start(fmu_paths, {**QUIET, "probe_bandwidth": fc}, {"probe_true": 4.805e-3})
    assert d.get(["probe_meas"])[0] == 4.805e-3
    d.set({"probe_true": 5.805e-3})
    h, n = 0.01, 30
    got = (record(d, ["probe_meas"], n, h)[:, 0] - 4.805e-3) / 1e-3
    d.close()
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose(got, -np.expm1(-2 * np.pi * fc * t), rtol=0, atol=1e-12)


def test_each_channel_reads_its_own_point(fmu_paths: dict[str, Path]) -> None:
    values = {name: T0 + k for k, name in enumerate(T_IN)}
    d = start(fmu_paths, QUIET, {**values, "probe_true": 3e-3})
    np.testing.assert_array_equal(d.get(T_OUT), list(values.values()))
    d.step(1.0)
    np.testing.assert_allclose(d.get(T_OUT), list(values.values()), rtol=0, atol=1e-12)
    assert d.get(["probe_meas", "probe_in_range"]).tolist() == [3e-3, 1.0]
    d.close()


def test_outputs_are_the_last_sample_not_a_feedthrough(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths)
    outs = d.outputs()
    before = d.get(outs)
    d.set({**dict.fromkeys(T_IN, T0 + 5.0), "probe_true": 6e-3, "t_probe_body": T0 + 5.0})
    assert d.get(outs).tobytes() == before.tobytes()
    d.step(0.01)
    assert not np.array_equal(d.get(outs), before)
    d.close()


def test_quantization_gives_multiples_of_the_resolution(fmu_paths: dict[str, Path]) -> None:
    qt, qp = 0.05, 1e-6
    params = {"temp_resolution": qt, "probe_resolution": qp, "temp_tau": 2.0, "probe_noise": 0.3e-6}
    d = start(fmu_paths, params, dict.fromkeys(T_IN, T0))
    temps, probe = [], []
    for k in range(400):  # slow ramps: the readings sweep through many quantization steps
        d.set({**dict.fromkeys(T_IN, T0 + 0.01 * k), "probe_true": 4.805e-3 + 0.05e-6 * k})
        d.step(0.05)
        temps.append(d.get(T_OUT))
        probe.append(d.get(["probe_meas"])[0])
    d.close()
    for values, q in ((np.array(temps), qt), (np.array(probe), qp)):
        ratio = values / q
        np.testing.assert_allclose(ratio, np.round(ratio), rtol=0, atol=1e-6)
        assert len(np.unique(np.round(ratio))) > 10


def test_quantization_error_is_at_most_half_a_step(fmu_paths: dict[str, Path]) -> None:
    q, tau, h = 0.1, 5.0, 0.5
    d = start(fmu_paths, {**QUIET, "temp_resolution": q, "temp_tau": tau, "solver_step": h}, {"t_room": T0})
    d.set({"t_room": T0 + 3.0})
    got = record(d, ["t_room_meas"], 60, h)[:, 0]
    d.close()
    lag = T0 + 3.0 * -np.expm1(-h * np.arange(1, 61) / tau)
    assert np.max(np.abs(got - lag)) <= q / 2 + 1e-9
    np.testing.assert_allclose(got, q * np.round(lag / q), rtol=0, atol=1e-9)


def test_noise_has_the_declared_std_and_is_white(fmu_paths: dict[str, Path]) -> None:
    sigma_t, sigma_p, n = 0.02, 0.05e-6, 20000
    params = {
        "temp_noise": sigma_t,
        "temp_resolution": 0.0,
        "probe_noise": sigma_p,
        "probe_resolution": 0.0,
        "seed": 7,
    }
    inputs = {**dict.fromkeys(T_IN, T0), "t_probe_body": T0, "probe_true": 4.805e-3}
    d = start(fmu_paths, params, inputs)
    samples = record(d, [*T_OUT, "probe_meas"], n, 0.01)  # one DAQ sample per internal step
    d.close()
    noise = (samples - [*[T0] * len(T_OUT), 4.805e-3]) / [*[sigma_t] * len(T_OUT), sigma_p]
    std = noise.std(axis=0)
    assert np.all(np.abs(std - 1.0) < 0.03), std
    assert np.all(np.abs(noise.mean(axis=0)) < 4.0 / np.sqrt(n))
    corr = np.corrcoef(noise.T)  # channels independent of each other
    assert np.max(np.abs(corr - np.eye(corr.shape[0]))) < 0.05
    lag1 = np.array([np.corrcoef(c[:-1], c[1:])[0, 1] for c in noise.T])  # white in time
    assert np.all(np.abs(lag1) < 0.05)
    # Gaussian: about 68.3 % within one sigma, 95.4 % within two
    assert abs(np.mean(np.abs(noise) < 1.0) - 0.6827) < 0.01
    assert abs(np.mean(np.abs(noise) < 2.0) - 0.9545) < 0.01


@pytest.mark.parametrize("drift", [-0.5e-6, 0.3e-6])
def test_zero_drift_follows_the_probe_body_temperature(drift: float, fmu_paths: dict[str, Path]) -> None:
    d = start(
        fmu_paths, {**QUIET, "probe_zero_drift": drift}, {"t_probe_body": 298.0, "probe_true": 4.805e-3}
    )
    d.step(1.0)
    before = d.get(["probe_meas"])[0]
    assert before == 4.805e-3  # the body at its initial temperature: no drift
    d.set({"t_probe_body": 308.0})  # probe body warmed by 10 K
    d.step(0.01)
    after = d.get(["probe_meas"])[0]
    d.close()
    assert after - before == pytest.approx(10.0 * drift, rel=1e-9, abs=1e-18)


def test_default_zero_drift_makes_the_reading_fall_as_the_probe_warms(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, QUIET, {"t_probe_body": T0, "probe_true": 4.805e-3})
    d.set({"t_probe_body": T0 + 10.0})
    d.step(0.01)
    reading = d.get(["probe_meas"])[0]
    d.close()
    assert reading == pytest.approx(4.805e-3 - 5e-6, rel=0, abs=1e-15)


def test_range_clips_the_reading_and_flags_it(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {"probe_range_min": 0.0, "probe_range_max": 10e-3}, {"probe_true": 4.805e-3})
    assert d.get(["probe_in_range"])[0] == 1.0
    for true, clipped in ((12e-3, 10e-3), (-1e-3, 0.0)):
        d.set({"probe_true": true})
        d.step(1.0)  # 50 filter time constants: the head has arrived
        assert d.get(["probe_meas", "probe_in_range"]).tolist() == [clipped, 0.0]
    d.set({"probe_true": 5e-3})
    d.step(1.0)
    reading, in_range = d.get(["probe_meas", "probe_in_range"])
    d.close()
    assert in_range == 1.0 and abs(reading - 5e-3) < 1e-6


def test_noise_at_the_range_end_is_clipped_but_stays_in_range(fmu_paths: dict[str, Path]) -> None:
    params = {"probe_range_max": 10e-3, "probe_noise": 1e-6, "probe_resolution": 0.0}
    d = start(fmu_paths, params, {"probe_true": 10e-3})
    rows = record(d, ["probe_meas", "probe_in_range"], 500, 0.01)
    d.close()
    assert np.all(rows[:, 0] <= 10e-3)
    assert 0.3 < np.mean(rows[:, 0] == 10e-3) < 0.7  # the upper half of the noise is clipped
    assert np.all(rows[:, 1] == 1.0)  # the noise-free reading is inside


def test_range_ends_out_of_order_are_rejected_at_initialization(fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["SensorsDAQ"])
    d.slave.setupExperiment(startTime=0.0)
    d.set({"probe_range_min": 5e-3, "probe_range_max": 1e-3})
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        d.slave.exitInitializationMode()
    # still in initialization mode: the host may correct the parameter and go on
    d.set({"probe_range_min": 0.0})
    d.slave.exitInitializationMode()
    d.close()


def _noisy_run(fmu_paths: dict[str, Path], seed: int, name: str) -> bytes:
    d = start(fmu_paths, {"seed": seed}, {"probe_true": 4.805e-3}, name)
    rows = record(d, d.outputs(), 200, 0.01)
    d.close()
    return rows.tobytes()


def test_same_seed_same_bytes_different_seed_different_noise(fmu_paths: dict[str, Path]) -> None:
    a = _noisy_run(fmu_paths, 42, "a")
    assert _noisy_run(fmu_paths, 42, "b") == a
    other = np.frombuffer(_noisy_run(fmu_paths, 43, "c"), dtype=float)
    assert np.mean(other != np.frombuffer(a, dtype=float)) > 0.5
