"""SensorsDAQ physics: lag and low-pass step responses, quantization, noise statistics, zero
drift, range clipping, the load/torque/angle/vibration channels, the interference spikes and the
seeded noise, each checked against a closed form or a statistical band computed here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from twin.errormodel.sources import DEFAULT_TEMPERATURES

from .fmi_driver import Driver

POINTS = list(DEFAULT_TEMPERATURES)  # the paper's eight measuring points
T_IN = [f"t_{p}" for p in POINTS]
T_OUT = [f"t_{p}_meas" for p in POINTS]
QUIET = {
    "temp_noise": 0.0,
    "temp_resolution": 0.0,
    "probe_noise": 0.0,
    "probe_resolution": 0.0,
    "spike_rate": 0.0,
}
NEW_OUT = ["load_meas", "torque_meas", "angle_meas", "vibration_meas"]
T0 = 293.15


def start(
    fmu_paths: dict[str, Path], parameters: dict | None = None, inputs: dict | None = None, name: str = "inst"
) -> Driver:
    return Driver.started(fmu_paths["SensorsDAQ"], parameters, inputs, name)


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
        "spike_rate": 0.0,
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


@pytest.mark.parametrize(("position", "expected"), [(1e-3, 1.006e-3), (9e-3, 9.022e-3)])
def test_zero_and_span_drift_under_a_known_body_rise(
    position: float, expected: float, fmu_paths: dict[str, Path]
) -> None:
    """Zero drift 0.4 um/K and span drift 2e-4/K, the body warmed by 10 K, by hand:
    1 mm reads 1 mm + 4 um + 2e-3 x 1 mm = 1.006 mm; 9 mm reads 9 mm + 4 um + 18 um = 9.022 mm."""
    parameters = {**QUIET, "probe_zero_drift": 0.4e-6, "probe_span_drift": 2e-4}
    d = start(fmu_paths, parameters, {"t_probe_body": 298.0, "probe_true": position})
    d.step(1.0)
    assert d.get(["probe_meas"])[0] == position  # the body at its initial temperature: no drift
    d.set({"t_probe_body": 308.0})
    d.step(0.01)
    reading = d.get(["probe_meas"])[0]
    d.close()
    assert reading == pytest.approx(expected, rel=0, abs=1e-15)


def test_probe_body_thermometer_lags_like_the_others(fmu_paths: dict[str, Path]) -> None:
    """The thermometer a lab clamps on the probe body: the eight's first-order lag, on the
    probe body's temperature, and it leaves the eight channels' readings alone."""
    tau = 20.0
    d = start(fmu_paths, {**QUIET, "temp_tau": tau}, {**dict.fromkeys(T_IN, T0), "t_probe_body": T0})
    assert d.get(["t_probe_body_meas"])[0] == T0
    d.set({"t_probe_body": T0 + 10.0})
    h, n = 1.0, 60
    got = record(d, ["t_probe_body_meas", *T_OUT], n, h)
    d.close()
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose((got[:, 0] - T0) / 10.0, -np.expm1(-t / tau), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[:, 1:], T0)


def test_probe_body_thermometer_adds_noise_without_moving_the_other_streams(
    fmu_paths: dict[str, Path],
) -> None:
    """Its noise comes from a stream of its own: the same seed gives the eight temperatures and
    the probe the same bits whatever the probe body does, and the thermometer is noisy."""
    noisy = {"temp_noise": 0.02, "temp_resolution": 0.0, "probe_noise": 5e-8, "seed": 7}
    runs = []
    for body in (T0, T0 + 5.0):
        d = start(fmu_paths, noisy, {**dict.fromkeys(T_IN, T0), "t_probe_body": body, "probe_true": 4.805e-3})
        runs.append(record(d, ["t_probe_body_meas", "probe_meas", *T_OUT], 200, 0.01))
        d.close()
    np.testing.assert_array_equal(runs[0][:, 1:], runs[1][:, 1:])
    body_noise = runs[0][:, 0] - T0
    assert 0.015 < float(np.std(body_noise)) < 0.025


def test_default_zero_drift_is_the_priors_centre(fmu_paths: dict[str, Path]) -> None:
    """The drift's sign is unknown (facts 5/6): the nominal probe does not drift at all."""
    d = start(fmu_paths, QUIET, {"t_probe_body": T0, "probe_true": 4.805e-3})
    d.set({"t_probe_body": T0 + 10.0})
    d.step(0.01)
    reading = d.get(["probe_meas"])[0]
    d.close()
    assert reading == 4.805e-3


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


# ------------------------------------------------------------------ the first version's outputs

# The first version of this FMU (temperatures and probe only) printed these with repr(): seed 11,
# no quantization, t_bearing = 300 K, the rest at 293.15 K, probe at 4.805 mm; the samples at
# t = 0, 0.01, ..., 0.05 s of (t_bearing_meas, t_room_meas, probe_meas).
FIRST_VERSION = [
    (299.96853942217837, 293.1493840900851, 0.004805006268301706),
    (300.039840862193, 293.1961448833257, 0.004805074941218208),
    (299.9663586088012, 293.1525144319544, 0.004804989929603952),
    (299.9896956508877, 293.18673140872596, 0.00480501103192577),
    (299.9828525881189, 293.17348702388125, 0.004804977461339391),
    (299.97169522402334, 293.1323919985393, 0.004804992448014041),
]
NEW_INPUTS = {"load_true": 120e3, "torque_true": -85.0, "angle_true": 0.3, "vibration_true": 0.4e-6}


@pytest.mark.parametrize(
    ("parameters", "inputs"),
    [
        ({}, {}),  # everything new at its defaults
        (
            {"load_noise": 2e3, "torque_resolution": 0.0, "vibration_noise": 1e-6, "spike_size": 1e-4},
            NEW_INPUTS,
        ),
    ],
)
def test_old_outputs_are_bit_identical_to_the_first_version(
    parameters: dict[str, float], inputs: dict[str, float], fmu_paths: dict[str, Path]
) -> None:
    d = start(
        fmu_paths,
        {"seed": 11, "temp_resolution": 0.0, "probe_resolution": 0.0, **parameters},
        {"t_bearing": 300.0, "probe_true": 4.805e-3, **inputs},
    )
    names = ["t_bearing_meas", "t_room_meas", "probe_meas", "spike"]
    rows = np.vstack([d.get(names), record(d, names, 5, 0.01)])
    d.close()
    assert np.all(rows[:, 3] == 0.0)  # no spike in these samples
    assert [tuple(r) for r in rows[:, :3].tolist()] == FIRST_VERSION


OLD_OUT = [*T_OUT, "probe_meas", "probe_in_range"]


def _long_run(fmu_paths: dict[str, Path], parameters: dict[str, float], new_inputs: bool) -> np.ndarray:
    """2000 samples with every input moving; columns OLD_OUT, NEW_OUT, spike."""
    d = start(fmu_paths, {"seed": 3, **parameters}, {"probe_true": 4.805e-3})
    rows = []
    for k in range(2000):
        t = 0.01 * k
        values = {name: T0 + np.sin(0.5 * t + i) for i, name in enumerate(T_IN)}
        values |= {"t_probe_body": T0 + 0.5 * np.sin(0.2 * t), "probe_true": 4.805e-3 + 2e-6 * np.sin(3 * t)}
        if new_inputs:
            values |= {
                "load_true": 1e5 + 5e4 * np.sin(t),
                "torque_true": 80.0 * np.sin(2 * t),
                "angle_true": 0.43 * np.sin(1.05 * t),
                "vibration_true": 0.5e-6 * np.sin(250 * t),
            }
        d.set(values)
        d.step(0.01)
        rows.append(d.get([*OLD_OUT, *NEW_OUT, "spike"]))
    d.close()
    return np.array(rows)


def test_new_channels_and_spikes_leave_the_old_streams_alone(fmu_paths: dict[str, Path]) -> None:
    n_old = len(OLD_OUT)
    ref = _long_run(fmu_paths, {"spike_rate": 0.0}, new_inputs=False)
    other = _long_run(
        fmu_paths,
        {
            "spike_rate": 0.0,
            "load_noise": 1e3,
            "torque_noise": 2.0,
            "vibration_noise": 1e-6,
            "load_resolution": 0.0,
        },
        new_inputs=True,
    )
    assert other[:, :n_old].tobytes() == ref[:, :n_old].tobytes()
    spiky = _long_run(
        fmu_paths,
        {
            "spike_rate": 5.0,
            "load_noise": 1e3,
            "torque_noise": 2.0,
            "vibration_noise": 1e-6,
            "load_resolution": 0.0,
        },
        new_inputs=True,
    )
    on = spiky[:, -1] == 1.0
    assert 100 < on.sum() < 1000
    # off the spikes every old output is the first version's, on them only the probe reading moves
    assert spiky[~on, :n_old].tobytes() == ref[~on, :n_old].tobytes()
    keep = [i for i, name in enumerate(OLD_OUT) if name != "probe_meas"]
    assert spiky[:, keep].tobytes() == ref[:, keep].tobytes()
    assert np.mean(spiky[on, n_old - 2] != ref[on, n_old - 2]) > 0.9
    # and the spikes do not shift the noise of the new channels
    assert spiky[:, n_old:-1].tobytes() == other[:, n_old:-1].tobytes()


# ------------------------------------------------------------------ load, torque, angle, vibration


def test_new_noise_has_the_declared_std_and_is_white_and_independent(fmu_paths: dict[str, Path]) -> None:
    sigma = {"load_meas": 150.0, "torque_meas": 0.1, "vibration_meas": 0.02e-6, "probe_meas": 0.05e-6}
    true = {"load_meas": 150e3, "torque_meas": 85.0, "vibration_meas": 0.3e-6, "probe_meas": 4.805e-3}
    n = 20000
    params = {
        "load_resolution": 0.0,
        "torque_resolution": 0.0,
        "probe_resolution": 0.0,
        "spike_rate": 0.0,
        "seed": 9,
    }
    inputs = {"load_true": 150e3, "torque_true": 85.0, "vibration_true": 0.3e-6, "probe_true": 4.805e-3}
    d = start(fmu_paths, params, inputs)
    names = list(sigma)
    noise = (record(d, names, n, 0.01) - [true[k] for k in names]) / [sigma[k] for k in names]
    d.close()
    assert np.all(np.abs(noise.std(axis=0) - 1.0) < 0.03), noise.std(axis=0)
    assert np.all(np.abs(noise.mean(axis=0)) < 4.0 / np.sqrt(n))
    corr = np.corrcoef(noise.T)  # independent of each other and of the first stream (probe)
    assert np.max(np.abs(corr - np.eye(len(names)))) < 0.05
    lag1 = np.array([np.corrcoef(c[:-1], c[1:])[0, 1] for c in noise.T])
    assert np.all(np.abs(lag1) < 0.05)
    assert np.all(np.abs(np.mean(np.abs(noise) < 1.0, axis=0) - 0.6827) < 0.01)


@pytest.mark.parametrize(
    ("channel", "true", "sigma", "q"), [("load", 150e3, 150.0, 10.0), ("torque", 85.0, 0.1, 0.01)]
)
def test_load_and_torque_readings_are_the_noisy_value_quantized(
    channel: str, true: float, sigma: float, q: float, fmu_paths: dict[str, Path]
) -> None:
    out = f"{channel}_meas"

    def run(resolution: float) -> np.ndarray:
        params = {f"{channel}_noise": sigma, f"{channel}_resolution": resolution, "seed": 21}
        d = start(fmu_paths, params, {f"{channel}_true": true})
        rows = [d.get([out])[0]]
        for k in range(3000):  # a slow ramp on top of the noise
            d.set({f"{channel}_true": true + 0.01 * sigma * k})
            d.step(0.01)
            rows.append(d.get([out])[0])
        d.close()
        return np.array(rows)

    raw, quantized = run(0.0), run(q)  # same seed: the same noise draws
    ratio = quantized / q
    np.testing.assert_allclose(ratio, np.round(ratio), rtol=0, atol=1e-6)
    assert np.max(np.abs(quantized - raw)) <= q / 2 * (1 + 1e-9)
    np.testing.assert_allclose(quantized, q * np.round(raw / q), rtol=0, atol=1e-9 * q)
    assert len(np.unique(np.round(ratio))) > 100
    # the quantized noise around the ramp: std sqrt(sigma^2 + q^2/12)
    ramp = true + 0.01 * sigma * np.maximum(np.arange(3001) - 1, 0)
    assert np.std(quantized - ramp) == pytest.approx(np.sqrt(sigma**2 + q**2 / 12), rel=0.06)


def test_encoder_quantizes_the_angle_to_multiples_of_its_resolution(fmu_paths: dict[str, Path]) -> None:
    q = 2 * np.pi / 2**17
    assert q == pytest.approx(4.7936899621426287e-05, rel=1e-15)  # the default
    angles = 0.4363 * np.sin(np.linspace(0.0, 2 * np.pi, 1500)) + 1e-7 * np.arange(1500)
    got = {}
    for seed in (1, 2):
        d = start(fmu_paths, {"seed": seed}, {"angle_true": 0.0})
        rows = []
        for a in angles:
            d.set({"angle_true": a})
            d.step(0.01)
            rows.append(d.get(["angle_meas"])[0])
        d.close()
        got[seed] = np.array(rows)
    assert got[1].tobytes() == got[2].tobytes()  # no noise: the seed does not matter
    ratio = got[1] / q
    np.testing.assert_allclose(ratio, np.round(ratio), rtol=0, atol=1e-6)
    assert np.max(np.abs(got[1] - angles)) <= q / 2 * (1 + 1e-9)
    np.testing.assert_allclose(got[1], q * np.round(angles / q), rtol=0, atol=1e-15)
    assert len(np.unique(got[1])) > 1000
    # resolution 0: the angle passes through exactly
    d = start(fmu_paths, {"encoder_resolution": 0.0}, {"angle_true": 0.123456789})
    d.step(0.05)
    assert d.get(["angle_meas"])[0] == 0.123456789
    d.close()


def test_vibration_pickup_passes_the_vibration_through_with_noise(fmu_paths: dict[str, Path]) -> None:
    t = 0.01 * np.arange(1, 501)
    v = 0.5e-6 * np.sin(2 * np.pi * 40.0 * t) * np.exp(-t)  # a 40 Hz ringing: no lag at 100 Hz sampling
    for sigma in (0.0, 0.02e-6):
        d = start(fmu_paths, {"vibration_noise": sigma, "seed": 4}, {"vibration_true": 0.0})
        rows = []
        for x in v:
            d.set({"vibration_true": x})
            d.step(0.01)
            rows.append(d.get(["vibration_meas"])[0])
        d.close()
        got = np.array(rows)
        if sigma == 0.0:
            assert got.tobytes() == v.tobytes()  # exact passthrough, no lag, no quantization
        else:
            residual = got - v
            assert np.std(residual) == pytest.approx(sigma, rel=0.15)  # 500 samples
            assert abs(np.mean(residual)) < 4 * sigma / np.sqrt(len(v))


# ------------------------------------------------------------------ interference spikes


def _spike_run(
    fmu_paths: dict[str, Path], params: dict[str, float], n: int, h: float = 0.01, seed: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Probe offset from the true position (quiet probe: the spike alone) and the spike flag."""
    z = 5e-3
    d = start(
        fmu_paths,
        {**QUIET, "probe_bandwidth": 1.0, "solver_step": h, "seed": seed, **params},
        {"probe_true": z},
    )
    assert d.get(["probe_meas", "spike"]).tolist() == [z, 0.0]  # no spike at the start
    rows = record(d, ["probe_meas", "spike"], n, h)
    d.close()
    return rows[:, 0] - z, rows[:, 1]


def _split_spikes(offset: np.ndarray, flag: np.ndarray, n_d: int) -> tuple[np.ndarray, int]:
    """Spike values (one per spike, each checked to last exactly n_d samples at one value) and
    the number of steps at which a new spike could start (no spike on)."""
    values, k, n = [], 0, len(flag)
    while k < n:
        if flag[k] == 1.0:
            chunk = offset[k : k + n_d]
            assert np.all(flag[k : k + n_d] == 1.0), f"spike at sample {k} shorter than {n_d}"
            assert np.all(chunk == chunk[0]), f"spike at sample {k} is not flat"
            if values and k >= n_d and flag[k - 1] == 1.0:
                assert chunk[0] != values[-1]  # back to back: a new spike, not a long one
            values.append(chunk[0])
            k += n_d
        else:
            k += 1
    # every maximal run of flags is a whole number of spikes (the last may be cut by the end)
    edges = np.flatnonzero(np.diff(np.concatenate([[0.0], flag, [0.0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        assert (b - a) % n_d == 0 or b == n
    continuing = int(flag.sum()) - len(values)
    return np.array(values), n - continuing


def test_spike_flag_is_set_exactly_while_a_spike_is_on(fmu_paths: dict[str, Path]) -> None:
    offset, flag = _spike_run(fmu_paths, {"spike_rate": 5.0}, 5000)
    assert set(np.unique(flag)) == {0.0, 1.0}
    np.testing.assert_array_equal(flag == 1.0, offset != 0.0)


def test_spikes_have_the_declared_rate_size_sign_and_duration(fmu_paths: dict[str, Path]) -> None:
    rate, size, h, n = 2.0, 20e-6, 0.01, 30000
    offset, flag = _spike_run(
        fmu_paths, {"spike_rate": rate, "spike_size": size, "spike_duration": 0.05}, n, h
    )
    values, possible = _split_spikes(offset, flag, 5)
    k = len(values)
    # rate: a start has probability 1 - exp(-rate h) at every step with no spike on
    expected = -np.expm1(-rate * h) * possible
    assert abs(k - expected) < 4 * np.sqrt(expected), (k, expected)
    assert k / (possible * h) == pytest.approx(rate, rel=4 / np.sqrt(expected))
    # size: exponential magnitude of mean `size` (std = mean), P(|s| > size) = 1/e
    magnitude = np.abs(values)
    assert abs(magnitude.mean() - size) < 4 * size / np.sqrt(k)
    assert abs(np.mean(magnitude > size) - np.exp(-1)) < 4 * np.sqrt(np.exp(-1) * (1 - np.exp(-1)) / k)
    # sign: both equally likely
    assert abs(np.sum(values > 0) - k / 2) < 4 * np.sqrt(k) / 2


@pytest.mark.parametrize(
    ("duration", "h", "n_d"),
    [(0.05, 0.01, 5), (0.034, 0.01, 3), (0.001, 0.01, 1), (0.0, 0.01, 1), (0.3, 0.1, 3)],
)
def test_a_spike_lasts_its_duration_in_whole_steps_at_least_one(
    duration: float, h: float, n_d: int, fmu_paths: dict[str, Path]
) -> None:
    offset, flag = _spike_run(fmu_paths, {"spike_rate": 4.0, "spike_duration": duration}, 3000, h)
    values, _ = _split_spikes(offset, flag, n_d)
    assert len(values) > 30


def test_spike_rate_zero_means_no_spike_ever(fmu_paths: dict[str, Path]) -> None:
    offset, flag = _spike_run(fmu_paths, {"spike_rate": 0.0, "spike_size": 1e-3}, 20000)
    assert np.all(flag == 0.0) and np.all(offset == 0.0)
    offset, flag = _spike_run(fmu_paths, {"spike_rate": 50.0, "spike_size": 1e-3}, 2000)  # same seed
    assert flag.sum() > 500


def test_spikes_come_after_the_low_pass_and_before_quantization_and_clipping(
    fmu_paths: dict[str, Path],
) -> None:
    q, top = 1e-6, 10e-3
    params = {"spike_rate": 10.0, "spike_size": 0.3e-3, "probe_bandwidth": 0.01, "probe_noise": 0.0}
    params |= {"probe_resolution": q, "probe_range_min": 0.0, "probe_range_max": top, "seed": 2}
    d = start(fmu_paths, params, {"probe_true": 9.8e-3})
    rows = record(d, ["probe_meas", "probe_in_range", "spike"], 3000, 0.01)
    d.close()
    reading, in_range, on = rows[:, 0], rows[:, 1], rows[:, 2] == 1.0
    assert on.sum() > 300
    ratio = reading / q
    np.testing.assert_allclose(ratio, np.round(ratio), rtol=0, atol=1e-6)  # quantized, spikes too
    assert np.all((reading >= 0.0) & (reading <= top))
    assert np.any(reading[on] == top) and np.all(reading[~on] == 9.8e-3)  # clipped; off spike untouched
    # not low-passed (a 0.01 Hz filter would have flattened them to nothing): full size at once
    assert np.max(np.abs(reading[on] - 9.8e-3)) > 0.15e-3
    assert np.all(in_range == 1.0)  # a spike is interference, not an out-of-range head


def _spiky_run(fmu_paths: dict[str, Path], seed: int, name: str) -> np.ndarray:
    d = start(fmu_paths, {"seed": seed, "spike_rate": 5.0}, {**NEW_INPUTS, "probe_true": 4.805e-3}, name)
    rows = record(d, d.outputs(), 1000, 0.01)
    d.close()
    return rows


def test_same_seed_same_spikes_and_new_noise_different_seed_different(fmu_paths: dict[str, Path]) -> None:
    a = _spiky_run(fmu_paths, 42, "a")
    assert _spiky_run(fmu_paths, 42, "b").tobytes() == a.tobytes()
    c = _spiky_run(fmu_paths, 43, "c")
    outs = Driver(fmu_paths["SensorsDAQ"]).outputs()
    col = {name: i for i, name in enumerate(outs)}
    assert a[:, col["spike"]].sum() > 50 and c[:, col["spike"]].sum() > 50
    assert not np.array_equal(a[:, col["spike"]], c[:, col["spike"]])
    for name in ("load_meas", "torque_meas", "vibration_meas"):
        assert np.mean(a[:, col[name]] != c[:, col[name]]) > 0.5, name
    assert a[:, col["angle_meas"]].tobytes() == c[:, col["angle_meas"]].tobytes()  # no noise


@pytest.mark.parametrize("inner", [2, 3, 10, 17])
def test_samples_nobody_reads_are_skipped_without_changing_what_is_read(
    inner: int, fmu_paths: dict[str, Path]
) -> None:
    # doStep(n h) draws the noise of its first n - 1 samples without computing them (nobody
    # reads them): what it outputs is bit for bit what n doStep(h) output at the same time,
    # noise and spikes on, inputs moving between the communication steps
    outputs = [*T_OUT, "probe_meas", "load_meas", "torque_meas", "vibration_meas", "spike", "angle_meas"]
    params = {"solver_step": 0.01, "spike_rate": 50.0, "spike_duration": 0.03, "seed": 5}
    one, many = start(fmu_paths, params, name="one"), start(fmu_paths, params, name="many")
    spikes = 0
    for k in range(60):
        inputs = {
            **dict.fromkeys(T_IN, T0 + 0.1 * k),
            "probe_true": 4.805e-3 + 1e-6 * np.sin(k),
            "load_true": 2e5 + 100.0 * k,
            "torque_true": 30.0 * np.cos(k),
            "vibration_true": 1e-7 * k,
        }
        one.set(inputs), many.set(inputs)
        for _ in range(inner):
            one.step(0.01)
        many.step(0.01 * inner)
        got, want = many.get(outputs), one.get(outputs)
        assert np.array_equal(np.asarray(got), np.asarray(want)), (k, got, want)
        spikes += int(got[outputs.index("spike")])
    assert spikes > 0  # a spike was on at some of the compared samples


def test_noise_owed_over_long_unread_stretches_is_what_drawing_it_gives(fmu_paths: dict[str, Path]) -> None:
    # the first and third noise streams owe the draws of the samples nobody reads and advance
    # over them when one is read, by a jump of the generator where the stretch is long
    # (fmus/common/rng.c, RNG_JUMP_MIN steps): read after a few, hundreds or thousands of unread
    # communication steps, and through a saved and restored state, every sample read is bit for
    # bit the one an instance read at every step (which never owes more than a step) gives
    outputs = [*T_OUT, "probe_meas", "t_probe_body_meas", "load_meas", "vibration_meas", "spike"]
    params = {"solver_step": 0.001, "spike_rate": 20.0, "spike_duration": 0.002, "seed": 9}
    every, lazy = start(fmu_paths, params, name="every"), start(fmu_paths, params, name="lazy")
    gaps = [1, 700, 3, 2500, 2, 455, 456, 1200, 1200, 40]  # communication steps of 10 samples
    for k, gap in enumerate(gaps):
        inputs = {
            **dict.fromkeys(T_IN, T0 + 0.1 * k),
            "probe_true": 4.805e-3 + 1e-6 * np.sin(k),
            "t_probe_body": T0 + 0.2 * k,
            "load_true": 2e5 + 100.0 * k,
            "vibration_true": 1e-7 * k,
        }
        every.set(inputs), lazy.set(inputs)
        for _ in range(gap):
            every.step(0.01)
            every.get(outputs)
            lazy.step(0.01)
        if k == 4:  # a state saved while owing, handed to a fresh instance that goes on from it
            blob = lazy.slave.serializeFMUState(lazy.slave.getFMUState())
            lazy.close()
            lazy = start(fmu_paths, params, name="restored")
            lazy.slave.setFMUState(lazy.slave.deserializeFMUState(blob))
            lazy.time = every.time
        got, want = lazy.get(outputs), every.get(outputs)
        assert got.tobytes() == want.tobytes(), (k, gap, got, want)
    every.close(), lazy.close()
