"""OscillationDrive physics against hand calculations: the swing's closed forms, the exact
sliding distance and friction heat of whole cycles (facts.md 4), the friction law and its
clipping, the block-averaged heat, stopping and restarting the drive, and the seeded vibration."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from .fmi_driver import Driver

BETA = math.radians(25.0)  # default half swing [facts 4]
F_DEFAULT = 10.0 / 60.0  # default frequency, Hz [facts 4]
D_K, WIDTH = 0.040, 0.022  # default ball diameter and liner width, m
R = D_K / 2
CONST_MU = {"mu_pressure_exponent": 0.0, "mu_temp_coeff": 0.0}  # mu = mu_ref = 0.06
QUIET = {"vibration_amplitude": 0.0, "vibration_noise": 0.0}
LOAD = 100e3


def start(
    fmu_paths: dict[str, Path], parameters: dict | None = None, inputs: dict | None = None, name: str = "inst"
) -> Driver:
    return Driver.started(
        fmu_paths["OscillationDrive"],
        parameters,
        {"radial_load": LOAD, "t_bearing": 293.15, **(inputs or {})},
        name,
    )


def record(d: Driver, names: list[str], n: int, h: float) -> np.ndarray:
    """Outputs after each of n communication steps of h seconds."""
    rows = []
    for _ in range(n):
        d.step(h)
        rows.append(d.get(names))
    return np.array(rows)


def triangle(a: float, f: float, t: np.ndarray) -> np.ndarray:
    """Unit triangle wave starting at 0 towards +a (an independent closed form)."""
    return a * (1.0 - 4.0 * np.abs((f * t + 0.25) % 1.0 - 0.5))


# ---------------------------------------------------------------------------- kinematics


def test_sine_angle_and_velocity_follow_the_closed_form(fmu_paths: dict[str, Path]) -> None:
    a, f, h, n = 0.3, 0.5, 0.01, 250
    d = start(fmu_paths, {"amplitude": a, "frequency": f})
    angle0, omega0 = d.get(["angle", "angular_velocity"])
    assert angle0 == 0.0
    assert omega0 == pytest.approx(2 * math.pi * f * a, rel=1e-15)
    got = record(d, ["angle", "angular_velocity"], n, h)
    d.close()
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose(got[:, 0], a * np.sin(2 * np.pi * f * t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], 2 * np.pi * f * a * np.cos(2 * np.pi * f * t), rtol=0, atol=1e-12)


def test_triangle_angle_and_velocity_follow_the_closed_form(fmu_paths: dict[str, Path]) -> None:
    a, f, h, n = 0.3, 0.4, 0.01, 500
    d = start(fmu_paths, {"amplitude": a, "frequency": f, "waveform": 1})
    got = record(d, ["angle", "angular_velocity"], n, h)
    d.close()
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose(got[:, 0], triangle(a, f, t), rtol=0, atol=1e-12)
    # constant speed 4 a f between the reversals (at f t = 1/4 + k/2; corners left out)
    away = np.abs(((f * t - 0.25) * 2 + 0.5) % 1.0 - 0.5) > 1e-6
    np.testing.assert_allclose(got[away, 1], 4 * a * f * np.sign(np.cos(2 * np.pi * f * t[away])), rtol=1e-12)
    assert np.all(np.abs(got[:, 0]) <= a)


@pytest.mark.parametrize("waveform", [0, 1])
def test_sliding_distance_of_whole_cycles_is_4_beta_r_per_cycle(
    waveform: int, fmu_paths: dict[str, Path]
) -> None:
    n_cycles = 3
    d = start(fmu_paths, {"waveform": waveform})
    got = record(d, ["sliding_distance", "cycles", "angle"], round(n_cycles / F_DEFAULT / 0.1), 0.1)
    d.close()
    assert got[-1, 0] == pytest.approx(n_cycles * 4 * BETA * R, rel=1e-6)
    assert got[-1, 1] == n_cycles
    assert got[-1, 2] == pytest.approx(0.0, abs=1e-12)  # back at the start of a cycle
    assert np.all(np.diff(got[:, 0]) > 0)  # always sliding while the drive runs


@pytest.mark.parametrize("waveform", [0, 1])
def test_integrals_are_exact_even_with_reversals_inside_a_step(
    waveform: int, fmu_paths: dict[str, Path]
) -> None:
    # f h = 0.125 cycles per internal step: reversals fall inside steps; a midpoint rule would be off
    f, h, a, n_cycles = 1.25, 0.1, 0.5, 5
    d = start(
        fmu_paths, {"waveform": waveform, "frequency": f, "amplitude": a, "solver_step": h, "q_avg_window": h}
    )
    got = record(d, ["sliding_distance", "cycles"], round(n_cycles / f / h), h)
    d.close()
    assert got[-1, 0] == pytest.approx(n_cycles * 4 * a * R, rel=1e-12)
    assert got[-1, 1] == n_cycles


# ---------------------------------------------------------------------------- friction


@pytest.mark.parametrize("waveform", [0, 1])
def test_mean_friction_heat_of_whole_cycles_is_mu_f_v_mean(waveform: int, fmu_paths: dict[str, Path]) -> None:
    period = 1.0 / F_DEFAULT  # 6 s = 6000 internal steps
    d = start(fmu_paths, {**CONST_MU, "waveform": waveform, "q_avg_window": period})
    mu = d.get(["friction_coefficient"])[0]
    assert mu == 0.06
    got = record(d, ["q_friction_avg", "friction_energy"], 2 * 60, 0.1)
    d.close()
    v_mean = R * 4 * BETA * F_DEFAULT  # facts 4
    q_mean = mu * LOAD * v_mean
    assert got[-1, 0] == pytest.approx(q_mean, rel=1e-9)
    assert got[59, 0] == pytest.approx(q_mean, rel=1e-9)  # after the first cycle
    assert got[-1, 1] == pytest.approx(q_mean * 2 * period, rel=1e-9)


def test_torque_heat_speed_and_pressure_are_mu_f_r_with_the_sign_against_the_motion(
    fmu_paths: dict[str, Path],
) -> None:
    for load in (LOAD, -LOAD):  # the load's direction does not matter, its magnitude does
        d = start(fmu_paths, CONST_MU, {"radial_load": load})
        rows = record(
            d,
            ["angular_velocity", "friction_torque", "q_friction", "sliding_speed", "contact_pressure"],
            60,
            0.1,
        )
        d.close()
        omega, torque, q, v, p = rows.T
        mu = 0.06
        np.testing.assert_allclose(np.abs(torque), mu * LOAD * D_K / 2, rtol=1e-12)
        assert np.all(np.sign(torque) == -np.sign(omega))
        np.testing.assert_allclose(v, np.abs(omega) * R, rtol=1e-12)
        np.testing.assert_allclose(q, mu * LOAD * np.abs(omega) * R, rtol=1e-12)
        np.testing.assert_allclose(p, LOAD / (D_K * WIDTH), rtol=1e-12)


def mu_hand(load: float, t: float, n: float = 0.2, c: float = 0.005) -> float:
    p = abs(load) / (D_K * WIDTH)
    return min(max(0.06 * (p / 100e6) ** -n * math.exp(-c * (t - 293.15)), 0.02), 0.10)


def test_friction_coefficient_follows_the_law_and_falls_with_pressure_and_temperature(
    fmu_paths: dict[str, Path],
) -> None:
    d = start(fmu_paths)
    by_load, by_temp = [], []
    for load in (30e3, 60e3, 100e3, 200e3, 400e3):
        d.set({"radial_load": load, "t_bearing": 300.0})  # direct feedthrough: no step needed
        mu = d.get(["friction_coefficient"])[0]
        assert mu == pytest.approx(mu_hand(load, 300.0), rel=1e-12)
        by_load.append(mu)
    for t in (280.0, 300.0, 330.0, 360.0):
        d.set({"radial_load": 100e3, "t_bearing": t})
        mu = d.get(["friction_coefficient"])[0]
        assert mu == pytest.approx(mu_hand(100e3, t), rel=1e-12)
        by_temp.append(mu)
    d.close()
    assert np.all(np.diff(by_load) < 0)
    assert np.all(np.diff(by_temp) < 0)


@pytest.mark.parametrize(
    ("load", "t", "unclipped", "expected"),
    [
        (1e3, 293.15, 0.1469, 0.10),  # light load: 0.06 (1.136 MPa / 100 MPa)^-0.2 -> mu_max
        (0.0, 293.15, math.inf, 0.10),  # no load: the pressure law diverges -> mu_max
        (5e6, 450.0, 0.01221, 0.02),  # 5.68 GPa and hot: 0.06 * 0.446 * 0.456 -> mu_min
    ],
)
def test_friction_coefficient_is_clipped_to_the_liner_range(
    load: float, t: float, unclipped: float, expected: float, fmu_paths: dict[str, Path]
) -> None:
    if math.isfinite(unclipped):  # the hand calculation in the comment, before clipping
        p = load / (D_K * WIDTH)
        assert 0.06 * (p / 100e6) ** -0.2 * math.exp(-0.005 * (t - 293.15)) == pytest.approx(
            unclipped, rel=1e-3
        )
    d = start(fmu_paths, inputs={"radial_load": load, "t_bearing": t})
    mu, torque = d.get(["friction_coefficient", "friction_torque"])
    d.close()
    assert mu == expected
    assert torque == pytest.approx(-expected * load * R, rel=1e-12)  # moving up at the start


# ---------------------------------------------------------------------------- averaged heat


def test_q_friction_avg_is_the_energy_of_the_step_over_its_length(fmu_paths: dict[str, Path]) -> None:
    h = 0.5  # communication step = q_avg_window
    d = start(fmu_paths, {"q_avg_window": h})
    assert d.get(["q_friction_avg", "friction_energy"]).tolist() == [0.0, 0.0]
    e_prev = 0.0
    for k, load in enumerate(np.linspace(20e3, 250e3, 24)):
        d.set({"radial_load": float(load), "t_bearing": 293.15 + 2.0 * k})
        d.step(h)
        q_avg, energy = d.get(["q_friction_avg", "friction_energy"])
        assert q_avg == pytest.approx((energy - e_prev) / h, rel=1e-9)
        assert q_avg > 0.0
        e_prev = energy
    d.close()


def test_q_friction_avg_holds_the_last_completed_block(fmu_paths: dict[str, Path]) -> None:
    # window 1 s, communication step 0.25 s: the value changes only when a block completes
    d = start(fmu_paths, {"q_avg_window": 1.0})
    got = record(d, ["q_friction_avg", "friction_energy"], 12, 0.25)
    d.close()
    q, e = got.T
    assert np.all(q[:3] == 0.0)  # no block complete before 1 s
    assert q[3] == pytest.approx(e[3] / 1.0, rel=1e-9)  # block [0, 1] s
    assert q[7] == pytest.approx((e[7] - e[3]) / 1.0, rel=1e-9)  # block [1, 2] s
    assert q[11] == pytest.approx((e[11] - e[7]) / 1.0, rel=1e-9)  # block [2, 3] s
    assert np.all(q[4:7] == q[3])
    assert np.all(q[8:11] == q[7])
    assert len(set(q[[3, 7, 11]])) == 3  # the sine's blocks differ


# ---------------------------------------------------------------------------- stopping


def test_drive_off_holds_the_angle_and_stops_motion_and_heat(fmu_paths: dict[str, Path]) -> None:
    names = ["angle", "angular_velocity", "sliding_speed", "friction_torque", "q_friction", "q_friction_avg",
             "friction_energy", "sliding_distance", "cycles"]  # fmt: skip
    d = start(fmu_paths, {"q_avg_window": 1.0})
    record(d, names, 20, 0.1)  # run 2 s
    before = d.get(names)
    d.set({"drive_on": 0.0})
    now = dict(zip(names, d.get(names), strict=True))  # direct feedthrough: stops at once
    assert (
        now["angular_velocity"] == now["sliding_speed"] == now["friction_torque"] == now["q_friction"] == 0.0
    )
    off = record(d, names, 30, 0.1)  # 3 s off
    np.testing.assert_array_equal(off[:, 0], before[0])  # angle held
    np.testing.assert_array_equal(off[:, 6], before[6])  # no more energy
    np.testing.assert_array_equal(off[:, 7], before[7])  # nor sliding
    assert np.all(off[:, [1, 2, 3, 4]] == 0.0)
    assert off[-1, 5] == 0.0  # a whole block without heat
    d.set({"drive_on": 1.0})
    after = record(d, ["angle", "angular_velocity"], 20, 0.1)
    d.close()
    # the restart continues from the held phase: the uninterrupted swing, 3 s later
    ref = start(fmu_paths, {"q_avg_window": 1.0}, name="ref")
    uninterrupted = record(ref, ["angle", "angular_velocity"], 40, 0.1)
    ref.close()
    np.testing.assert_array_equal(after, uninterrupted[20:])


# ---------------------------------------------------------------------------- vibration


def test_ringing_after_a_reversal_follows_the_closed_form(fmu_paths: dict[str, Path]) -> None:
    f, av, fv, tau = 0.25, 0.5e-6, 40.0, 0.05
    d = start(fmu_paths, {"frequency": f, "vibration_noise": 0.0})
    got = record(d, ["vibration_z"], 200, 0.01)[:, 0]  # 2 s: one reversal, at 1 s (+amplitude)
    d.close()
    t = 0.01 * np.arange(1, 201)
    s = t - 1.0
    expected = np.where(s > 1e-9, -av * np.exp(-s / tau) * np.sin(2 * np.pi * fv * s), 0.0)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-18)
    assert np.max(np.abs(got)) > 0.3 * av


def test_vibration_is_deterministic_by_seed_and_bounded(fmu_paths: dict[str, Path]) -> None:
    n, h = 1000, 0.01
    av, sigma = 0.5e-6, 0.2e-6

    def run(seed: int, name: str) -> np.ndarray:
        d = start(fmu_paths, {"seed": seed}, name=name)
        z = record(d, ["vibration_z"], n, h)[:, 0]
        d.close()
        return z

    a, b, c = run(7, "a"), run(7, "b"), run(8, "c")
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, c)
    for z in (a, c):
        assert np.all(np.abs(z) <= av + 4 * sigma)
        assert np.std(z) > 0.5 * sigma


def test_vibration_noise_has_its_std_and_stops_with_the_drive(fmu_paths: dict[str, Path]) -> None:
    sigma = 0.2e-6
    d = start(fmu_paths, {"vibration_amplitude": 0.0, "vibration_noise": sigma, "seed": 3})
    z = record(d, ["vibration_z"], 4000, 0.001)[:, 0]
    assert abs(np.mean(z)) < 4 * sigma / math.sqrt(z.size)
    assert np.std(z) == pytest.approx(sigma, rel=0.05)
    d.set({"drive_on": 0.0})
    off = record(d, ["vibration_z"], 100, 0.001)[:, 0]
    d.close()
    assert np.all(off == 0.0)  # no ringing configured and no drive: no vibration


# ---------------------------------------------------------------------------- parameter checks


@pytest.mark.parametrize(
    ("parameters", "words"),
    [
        ({"mu_min": 0.08, "mu_max": 0.05}, "mu_max"),
        ({"q_avg_window": 0.0015}, "q_avg_window"),
    ],
)
def test_inconsistent_parameters_are_rejected_at_initialization(
    parameters: dict[str, float], words: str, fmu_paths: dict[str, Path]
) -> None:
    d = Driver(fmu_paths["OscillationDrive"])
    d.slave.setupExperiment(startTime=0.0)
    d.set(parameters)
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        d.slave.exitInitializationMode()
    assert exc.value.status == 3  # fmi2Error, the instance stays in initialization mode
    d.set({words: 0.1 if words == "mu_max" else 1.0})  # corrected, it initializes
    d.slave.exitInitializationMode()
    d.close()
