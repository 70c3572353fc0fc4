"""HydraulicLoader physics: servo step and frequency responses, the four command profiles, pump
ripple, cylinder pressure and station heat, each checked against a closed form computed here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from scipy.linalg import expm

from .fmi_driver import Driver

NO_RIPPLE = {"ripple_fraction": 0.0}
# a servo so fast against the 1 ms internal step that one step settles it (critically damped:
# the residue after one step is (1 + omega_n h) exp(-omega_n h) ~ 3e-26): the load then equals
# the command held over the previous internal step
FAST_SERVO = {"servo_frequency": 1e4, "servo_damping": 1.0, "solver_step": 1e-3, **NO_RIPPLE}


def start(
    fmu_paths: dict[str, Path], parameters: dict | None = None, inputs: dict | None = None, name: str = "inst"
) -> Driver:
    return Driver.started(fmu_paths["HydraulicLoader"], parameters, inputs, name)


def record(d: Driver, names: list[str], n: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and outputs after each of n communication steps of h seconds (t = t0 + k h)."""
    t0, times, rows = d.time, [], []
    for k in range(n):
        d.slave.doStep(currentCommunicationPoint=t0 + k * h, communicationStepSize=h)
        times.append(t0 + (k + 1) * h)
        rows.append(d.get(names))
    d.time = t0 + n * h
    return np.array(times), np.array(rows)


def step_response(t: np.ndarray, f_n: float, zeta: float) -> np.ndarray:
    """Closed-form unit step response of w^2 / (s^2 + 2 zeta w s + w^2) from rest."""
    wn = 2 * np.pi * f_n
    if zeta < 1.0:
        sigma, wd = zeta * wn, wn * np.sqrt(1 - zeta**2)
        return 1 - np.exp(-sigma * t) * (np.cos(wd * t) + sigma / wd * np.sin(wd * t))
    if zeta == 1.0:
        return 1 - np.exp(-wn * t) * (1 + wn * t)
    r1, r2 = -wn * (zeta - np.sqrt(zeta**2 - 1)), -wn * (zeta + np.sqrt(zeta**2 - 1))
    return 1 + (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r1 - r2)


# ------------------------------------------------------------------ servo dynamics


@pytest.mark.parametrize(
    ("f_n", "zeta", "solver_step", "h"),
    [
        (15.0, 0.7, 1e-3, 0.01),  # the defaults: underdamped
        (15.0, 0.7, 0.05, 0.05),  # internal step longer than 1/omega_n: still exact, stable
        (15.0, 0.2, 1e-3, 0.002),  # lightly damped: a large overshoot
        (15.0, 2.0, 1e-3, 0.01),  # overdamped
    ],
)
def test_constant_command_gives_the_analytic_step_response(
    f_n: float, zeta: float, solver_step: float, h: float, fmu_paths: dict[str, Path]
) -> None:
    load = 200e3
    params = {"load_mean": load, "servo_frequency": f_n, "servo_damping": zeta, "solver_step": solver_step}
    d = start(fmu_paths, {**params, **NO_RIPPLE})
    outs = ["radial_load", "load_command", "load_ripple", "pressure"]
    assert d.get(outs).tolist() == [0.0, load, 0.0, 0.0]  # unloaded at rest, commanded at once
    t, rows = record(d, outs, round(3.0 / h), h)
    d.close()
    expected = load * step_response(t, f_n, zeta)
    np.testing.assert_allclose(rows[:, 0], expected, rtol=1e-9, atol=1e-9 * load)
    if zeta < 1.0:  # the overshoot is really there
        overshoot = np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2))
        assert rows[:, 0].max() > load * (1 + 0.5 * overshoot)
    assert rows[-1, 0] == pytest.approx(load, rel=1e-9)  # settled at the command
    np.testing.assert_array_equal(rows[:, 1], load)
    np.testing.assert_array_equal(rows[:, 2], 0.0)
    np.testing.assert_allclose(rows[:, 3], rows[:, 0] / 0.005, rtol=1e-15)


def test_start_at_command_starts_in_steady_state(fmu_paths: dict[str, Path]) -> None:
    load = 150e3
    d = start(fmu_paths, {"load_mean": load, "start_at_command": True, **NO_RIPPLE}, {"load_offset": 10e3})
    assert d.get(["radial_load"])[0] == load + 10e3
    _, rows = record(d, ["radial_load"], 100, 0.01)
    d.close()
    np.testing.assert_allclose(rows[:, 0], load + 10e3, rtol=1e-12)


@pytest.mark.parametrize("f", [0.5, 2.0])
def test_sine_command_has_the_analytic_frequency_response(f: float, fmu_paths: dict[str, Path]) -> None:
    mean, amp, f_n, zeta, h = 100e3, 50e3, 15.0, 0.7, 1e-3
    params = {
        "profile": 1,
        "load_mean": mean,
        "load_amplitude": amp,
        "load_frequency": f,
        "servo_frequency": f_n,
        "servo_damping": zeta,
        "solver_step": h,
        **NO_RIPPLE,
    }
    d = start(fmu_paths, params)
    record(d, [], round(2.0 / h), h)  # transients decay as exp(-zeta omega_n t) = exp(-132) by 2 s
    n = round(2.0 / f / h)  # two whole periods, sampled every internal step
    _, rows = record(d, ["radial_load", "load_command"], n, h)
    d.close()
    t = 2.0 + h * np.arange(1, n + 1)
    w = 2 * np.pi * f
    np.testing.assert_allclose(rows[:, 1], mean + amp * np.sin(w * t), rtol=0, atol=1e-9 * amp)
    basis = np.column_stack([np.ones_like(t), np.sin(w * t), np.cos(w * t)])
    (c, a, b), *_ = np.linalg.lstsq(basis, rows[:, 0], rcond=None)
    assert c == pytest.approx(mean, rel=1e-10)  # unit static gain
    gain, phase = np.hypot(a, b) / amp, np.arctan2(b, a)
    # exact: the command is sampled at the start of each internal step and held (zero-order
    # hold), so the sampled output is the discrete system's response at z = exp(j w h)
    wn = 2 * np.pi * f_n
    aug = np.zeros((3, 3))
    aug[0, 1], aug[1, 0], aug[1, 1], aug[1, 2] = 1.0, -(wn**2), -2 * zeta * wn, wn**2
    e = expm(aug * h)
    discrete = np.linalg.solve(np.exp(1j * w * h) * np.eye(2) - e[:2, :2], e[:2, 2])[0]
    assert gain == pytest.approx(abs(discrete), rel=1e-9)
    assert phase == pytest.approx(np.angle(discrete), abs=1e-9)
    # the continuous servo's analytic response, times the hold's sinc(w h / 2) gain and
    # half-step delay
    analytic = wn**2 / (wn**2 - w**2 + 2j * zeta * wn * w)
    assert gain == pytest.approx(abs(analytic), rel=1e-5)
    assert gain == pytest.approx(abs(analytic) * np.sinc(w * h / (2 * np.pi)), rel=1e-7)
    assert phase == pytest.approx(np.angle(analytic) - w * h / 2, abs=1e-6)
    assert phase < -0.04  # a real lag, not a tautology


# ------------------------------------------------------------------ profiles

TRAPEZOID = {
    "profile": 2,
    "load_low": 20e3,
    "load_high": 200e3,
    "t_ramp_up": 0.5,
    "t_dwell_high": 1.0,
    "t_ramp_down": 0.25,
    "t_dwell_low": 0.75,
}


def trapezoid(t: np.ndarray, p: dict[str, float]) -> np.ndarray:
    up, high, down, low = p["t_ramp_up"], p["t_dwell_high"], p["t_ramp_down"], p["t_dwell_low"]
    lo, hi = p["load_low"], p["load_high"]
    tau = np.mod(t, up + high + down + low)
    return np.interp(
        tau, [0.0, up, up + high, up + high + down, up + high + down + low], [lo, hi, hi, lo, lo]
    )


def test_trapezoid_corners_are_at_the_exact_times(fmu_paths: dict[str, Path]) -> None:
    h = 1e-3
    d = start(fmu_paths, {**TRAPEZOID, **FAST_SERVO})
    assert d.get(["load_command"])[0] == 20e3  # starts at load_low
    t, rows = record(d, ["load_command", "radial_load"], round(5.0 / h), h)
    d.close()
    command, load = rows[:, 0], rows[:, 1]
    np.testing.assert_allclose(command, trapezoid(t, TRAPEZOID), rtol=0, atol=1e-9 * 200e3)
    # the command is held over each internal step: the settled servo shows it one step later
    np.testing.assert_allclose(load[1:], command[:-1], rtol=0, atol=1e-9 * 200e3)
    corners = {
        0.25: 110e3,  # half way up
        0.5: 200e3,  # end of ramp up
        1.0: 200e3,  # dwell
        1.5: 200e3,  # end of dwell high, ramp down starts
        1.625: 110e3,  # half way down
        1.75: 20e3,  # end of ramp down
        2.2: 20e3,  # dwell low
        2.5: 20e3,  # period: ramp up starts again
        2.75: 110e3,
        3.0: 200e3,
        4.25: 20e3,
        5.0: 20e3,
    }
    for tc, value in corners.items():
        k = round(tc / h) - 1
        assert t[k] == pytest.approx(tc, abs=1e-12)
        assert command[k] == pytest.approx(value, rel=1e-9), tc
        if k + 1 < len(load):
            assert load[k + 1] == pytest.approx(value, rel=1e-9), tc
    # just before and after a corner the ramp has the right slope: 180 kN in 0.5 s up, 0.25 s down
    k = round(0.5 / h) - 1
    assert command[k] - command[k - 1] == pytest.approx(180e3 / 0.5 * h, rel=1e-6)
    k = round(1.5 / h) - 1
    assert command[k + 1] - command[k] == pytest.approx(-180e3 / 0.25 * h, rel=1e-6)


def test_trapezoid_without_ramps_is_a_square_wave(fmu_paths: dict[str, Path]) -> None:
    p = {**TRAPEZOID, "t_ramp_up": 0.0, "t_ramp_down": 0.0, "t_dwell_high": 0.3, "t_dwell_low": 0.2}
    d = start(fmu_paths, {**p, **FAST_SERVO})
    assert d.get(["load_command"])[0] == 200e3  # no ramp: high from t = 0
    t, rows = record(d, ["load_command"], 1000, 1e-3)
    d.close()
    expected = np.where(np.mod(t + 1e-9, 0.5) < 0.3, 200e3, 20e3)
    np.testing.assert_array_equal(rows[:, 0], expected)


TABLE = {
    "profile": 3,
    "table_n": 4,
    "table_t_1": 1.0,
    "table_f_1": 10e3,
    "table_t_2": 2.0,
    "table_f_2": 50e3,
    "table_t_3": 4.0,
    "table_f_3": 50e3,
    "table_t_4": 5.0,
    "table_f_4": 0.0,
}


def test_table_interpolates_linearly_and_holds_its_ends(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {**TABLE, **NO_RIPPLE})
    assert d.get(["load_command"])[0] == 10e3  # before the first point: its value
    t, rows = record(d, ["load_command"], 700, 0.01)
    d.close()
    tt = [TABLE[f"table_t_{k}"] for k in range(1, 5)]
    ff = [TABLE[f"table_f_{k}"] for k in range(1, 5)]
    np.testing.assert_allclose(rows[:, 0], np.interp(t, tt, ff), rtol=0, atol=1e-9 * 50e3)
    by_time = dict(zip(np.round(t, 6), rows[:, 0], strict=True))
    assert by_time[0.5] == 10e3
    assert by_time[1.5] == pytest.approx(30e3, rel=1e-9)
    assert by_time[3.0] == pytest.approx(50e3, rel=1e-12)
    assert by_time[4.5] == pytest.approx(25e3, rel=1e-9)
    assert by_time[5.0] == pytest.approx(0.0, abs=1e-6)
    assert by_time[7.0] == 0.0  # held after the last point


def test_points_beyond_table_n_are_ignored(fmu_paths: dict[str, Path]) -> None:
    p = {**TABLE, "table_n": 2, "table_t_3": -5.0, "table_f_3": 300e3}
    d = start(fmu_paths, p)  # the unused third point may be anything
    t, rows = record(d, ["load_command"], 300, 0.01)
    d.close()
    np.testing.assert_allclose(rows[:, 0], np.interp(t, [1.0, 2.0], [10e3, 50e3]), rtol=0, atol=1e-6)


def test_load_offset_adds_to_the_command_at_once(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {**TRAPEZOID, **FAST_SERVO})
    d.step(0.25)
    before = d.get(["load_command", "radial_load"])
    d.set({"load_offset": -15e3})
    after = d.get(["load_command", "radial_load"])
    assert after[0] == pytest.approx(before[0] - 15e3, rel=1e-12)  # direct feedthrough
    assert after[1] == before[1]  # the actual load needs a step to follow
    assert after[0] == pytest.approx(110e3 - 15e3, rel=1e-9)  # 0.25 s: half way up the ramp
    d.step(0.001)
    load = d.get(["radial_load"])[0]
    d.close()
    assert load == pytest.approx(after[0], rel=1e-9)  # the fast servo took the held command


# ------------------------------------------------------------------ ripple, pressure, heat


def test_ripple_has_the_declared_amplitude_and_frequency(fmu_paths: dict[str, Path]) -> None:
    load, h = 200e3, 1e-4
    # the default ripple: 0.5 % of the load at 217.5 Hz
    params = {"load_mean": load, "start_at_command": True, "solver_step": h}
    d = start(fmu_paths, params)
    t, rows = record(d, ["radial_load", "load_ripple", "pressure"], round(2.0 / h), h)
    d.close()
    total, ripple, pressure = rows.T
    np.testing.assert_allclose(ripple, 0.005 * load * np.sin(2 * np.pi * 217.5 * t), rtol=0, atol=1e-9 * load)
    np.testing.assert_allclose(total - ripple, load, rtol=1e-12)  # the servo is undisturbed
    np.testing.assert_allclose(pressure, total / 0.005, rtol=1e-15)
    spectrum = np.abs(np.fft.rfft(ripple)) * 2 / len(ripple)
    freqs = np.fft.rfftfreq(len(ripple), h)
    peak = np.argmax(spectrum)
    assert freqs[peak] == pytest.approx(217.5)
    assert spectrum[peak] == pytest.approx(0.005 * load, rel=1e-6)
    assert np.sum(spectrum**2) - spectrum[peak] ** 2 < 1e-12 * spectrum[peak] ** 2  # one line only


def test_ripple_is_zero_without_load(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths)  # the defaults: station idling, no load (the paper's thermal experiment)
    _, rows = record(d, ["radial_load", "load_ripple", "pressure", "q_station"], 100, 0.01)
    d.close()
    np.testing.assert_array_equal(rows[:, :3], 0.0)
    np.testing.assert_array_equal(rows[:, 3], 300.0)  # q_idle


@pytest.mark.parametrize(("mean", "offset"), [(200e3, 0.0), (50e3, -250e3)])
def test_station_heat_is_idle_plus_load_loss(mean: float, offset: float, fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {"load_mean": mean, "start_at_command": True}, {"load_offset": offset})
    _, rows = record(d, ["radial_load", "q_station"], 200, 0.01)
    d.close()
    load, q = rows.T
    np.testing.assert_allclose(q, 300.0 + 2e-3 * np.abs(load), rtol=1e-14)
    assert np.abs(load).min() > 190e3  # 200 kN (pushing or pulling) with 0.5 % ripple
    # 300 W idle + 400 W at 200 kN, the ripple moving it by at most 0.5 %
    assert np.all(np.abs(q - 700.0) <= 2e-3 * 0.005 * 200e3 * (1 + 1e-9))


def test_station_off_stops_command_and_heat(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {"load_mean": 200e3, "start_at_command": True}, {"load_offset": 5e3})
    d.step(0.5)
    assert d.get(["q_station"])[0] > 700.0
    d.set({"station_on": 0.0})
    np.testing.assert_array_equal(d.get(["load_command", "q_station"]), [0.0, 0.0])  # at once
    _, rows = record(d, ["radial_load", "load_command", "q_station", "pressure"], 300, 0.01)
    d.close()
    np.testing.assert_array_equal(rows[:, 1:3], 0.0)
    # the load falls to zero with the servo's own step response, ripple included
    assert abs(rows[-1, 0]) < 1e-9 and abs(rows[-1, 3]) < 1e-6
    t = 0.01 * np.arange(1, 301)
    envelope = 205e3 * (1 - step_response(t, 15.0, 0.7))
    # while it falls, it follows the analytic decay apart from the 0.5 % ripple
    assert np.all(np.abs(rows[:, 0] - envelope) <= 0.005 * np.abs(envelope) * (1 + 1e-9) + 1e-6)


def test_station_off_at_start(fmu_paths: dict[str, Path]) -> None:
    d = start(fmu_paths, {"load_mean": 200e3}, {"station_on": 0.0})
    _, rows = record(d, d.outputs(), 50, 0.01)
    d.close()
    np.testing.assert_array_equal(rows, 0.0)


# ------------------------------------------------------------------ parameter checks


def _exit_init_fails(fmu_paths: dict[str, Path], params: dict[str, float]) -> Driver:
    d = Driver(fmu_paths["HydraulicLoader"])
    d.slave.setupExperiment(startTime=0.0)
    d.set(params)
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        d.slave.exitInitializationMode()
    assert exc.value.status == 3  # fmi2Error
    return d


def test_trapezoid_without_duration_is_rejected(
    fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    zero = {"t_ramp_up": 0.0, "t_dwell_high": 0.0, "t_ramp_down": 0.0, "t_dwell_low": 0.0}
    d = _exit_init_fails(fmu_paths, {**TRAPEZOID, **zero})
    assert "trapezoid period" in capsys.readouterr().out
    # still in initialization mode: the host may correct the parameter and go on
    d.set({"t_dwell_high": 1.0})
    d.slave.exitInitializationMode()
    assert d.get(["load_command"])[0] == 200e3
    d.close()
    # only the active profile's data is checked
    d = start(fmu_paths, {**TRAPEZOID, **zero, "profile": 0, "load_mean": 1e3})
    assert d.get(["load_command"])[0] == 1e3
    d.close()


@pytest.mark.parametrize("bad_t2", [1.0, 0.5])  # equal to table_t_1, before it
def test_table_times_not_increasing_are_rejected(
    bad_t2: float, fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    d = _exit_init_fails(fmu_paths, {**TABLE, "table_t_2": bad_t2})
    assert "table_t_2" in capsys.readouterr().out
    d.set({"table_t_2": 2.0})
    d.slave.exitInitializationMode()
    d.close()


def test_later_table_point_out_of_order_is_rejected(fmu_paths: dict[str, Path]) -> None:
    d = _exit_init_fails(fmu_paths, {**TABLE, "table_t_4": 4.0})
    d.slave.freeInstance()


@pytest.mark.parametrize(
    ("name", "value"), [("profile", 4), ("table_n", 9), ("table_n", 1), ("station_on", 1.5)]
)
def test_values_outside_their_range_are_refused(name: str, value: float, fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["HydraulicLoader"])
    d.slave.setupExperiment(startTime=0.0)
    with pytest.raises(FMICallException):
        d.set({name: value})
    d.slave.freeInstance()
