"""ThermalNetwork physics: against scipy's solve_ivp, the analytic steady state, energy balance.

The reference network is rebuilt here from the FMU's own parameters (names c_<node>,
g_<node>_room, g_<a>__<b>, hyd_share_<node>, fric_share_<node>), independently of the C code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from .fmi_driver import Driver

HOURS = 3600.0


class Network:
    """C dT/dt = -(L + G_room) T + G_room T_room + s_hyd Q_hyd + s_fric Q_fric."""

    def __init__(self, d: Driver, overrides: dict[str, float] | None = None) -> None:
        p = {
            v.name: float(v.start)
            for v in d.md.modelVariables
            if v.causality == "parameter" and v.type == "Real"
        }
        p.update(overrides or {})
        self.nodes = [n[2:] for n in p if n.startswith("c_")]
        idx = {n: i for i, n in enumerate(self.nodes)}
        n = len(self.nodes)
        self.c = np.array([p[f"c_{k}"] for k in self.nodes])
        self.g_room = np.array([p[f"g_{k}_room"] for k in self.nodes])
        self.s_hyd = np.array([p[f"hyd_share_{k}"] for k in self.nodes])
        self.s_fric = np.array([p[f"fric_share_{k}"] for k in self.nodes])
        lap = np.zeros((n, n))
        for name, g in p.items():
            if name.startswith("g_") and "__" in name:
                a, b = name[2:].split("__")
                i, j = idx[a], idx[b]
                lap[i, i] += g
                lap[j, j] += g
                lap[i, j] -= g
                lap[j, i] -= g
        self.k = lap + np.diag(self.g_room)

    def rhs(self, t_room: float, q_hyd: float, q_fric: float):
        source = self.g_room * t_room + self.s_hyd * q_hyd + self.s_fric * q_fric

        def f(_t: float, temp: np.ndarray) -> np.ndarray:
            return (source - self.k @ temp) / self.c

        return f

    def steady_state(self, t_room: float, q_hyd: float, q_fric: float) -> np.ndarray:
        return np.linalg.solve(self.k, self.g_room * t_room + self.s_hyd * q_hyd + self.s_fric * q_fric)


def room(t: float) -> float:
    """A room warming 8.9 K over 8 h, levelling off, with a small day ripple."""
    return 293.15 + 8.9 * (1 - np.exp(-t / (2 * HOURS))) + 0.3 * np.sin(2 * np.pi * t / (3 * HOURS))


Q_HYD, Q_FRIC = 400.0, 15.0


@pytest.mark.parametrize("step", [1.0, 60.0])
def test_matches_solve_ivp_over_8_hours(step: float, fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["ThermalNetwork"])
    net = Network(d)
    d.init(inputs={"t_room": room(0.0), "q_hydraulic": Q_HYD, "q_friction": Q_FRIC})
    outs = [f"t_{n}" for n in net.nodes]
    n_steps = round(8 * HOURS / step)
    temp = np.full(len(net.nodes), room(0.0))
    # the co-simulation holds each input over its step (zero-order hold): the reference
    # integrates the same piecewise-constant input, interval by interval for 60 s steps;
    # for 1 s steps the hold error (~4e-4 K) stays below the tolerance, so one smooth solve
    worst, checked = 0.0, 0
    if step == 1.0:
        ref = solve_ivp(
            lambda t, y: net.rhs(room(t), Q_HYD, Q_FRIC)(t, y),
            (0.0, 8 * HOURS),
            temp,
            method="Radau",
            rtol=1e-10,
            atol=1e-9,
            t_eval=np.arange(0, n_steps + 1, 600) * step,
        )
        check_at = {round(t / step): ref.y[:, i] for i, t in enumerate(ref.t)}
        for k in range(n_steps):
            d.set({"t_room": room(k * step)})
            d.slave.doStep(currentCommunicationPoint=k * step, communicationStepSize=step)
            if k + 1 in check_at:
                worst = max(worst, float(np.max(np.abs(d.get(outs) - check_at[k + 1]))))
                checked += 1
    else:
        for k in range(n_steps):
            t_room = room(k * step)
            d.set({"t_room": t_room})
            d.slave.doStep(currentCommunicationPoint=k * step, communicationStepSize=step)
            sol = solve_ivp(
                net.rhs(t_room, Q_HYD, Q_FRIC),
                (k * step, (k + 1) * step),
                temp,
                method="Radau",
                rtol=1e-11,
                atol=1e-10,
            )
            temp = sol.y[:, -1]
            worst = max(worst, float(np.max(np.abs(d.get(outs) - temp))))
            checked += 1
    d.close()
    assert checked >= 48
    assert worst < 1e-3, f"max deviation {worst:.3g} K"
    print(f"step {step} s: max deviation from solve_ivp {worst:.2e} K over {checked} checks")


def test_steady_state_equals_the_analytic_solution(fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["ThermalNetwork"])
    net = Network(d)
    d.init(inputs={"t_room": 295.0, "q_hydraulic": Q_HYD, "q_friction": Q_FRIC})
    for k in range(60 * 24):  # 60 days in hourly steps: every time constant long decayed
        d.slave.doStep(currentCommunicationPoint=k * HOURS, communicationStepSize=HOURS)
    got = d.get([f"t_{n}" for n in net.nodes])
    expected = net.steady_state(295.0, Q_HYD, Q_FRIC)
    d.close()
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-7)
    # and the heat really flows: the oil sits above the room at steady state
    assert expected[net.nodes.index("oil")] > 295.0 + 1.0


def test_energy_balance_holds(fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["ThermalNetwork"])
    net = Network(d)
    d.init(inputs={"t_room": room(0.0), "q_hydraulic": Q_HYD, "q_friction": Q_FRIC})
    outs = [f"t_{n}" for n in net.nodes]
    t0 = d.get(outs)
    for k in range(480):
        d.set({"t_room": room(k * 60.0), "q_friction": Q_FRIC * (k % 7)})
        d.slave.doStep(currentCommunicationPoint=k * 60.0, communicationStepSize=60.0)
    stored, put_in, lost = d.get(["energy_stored", "energy_in", "energy_lost"])
    t1 = d.get(outs)
    d.close()
    # stored heat computed here from the temperatures, independently of the FMU's own sum
    assert stored == pytest.approx(float(net.c @ (t1 - t0)), rel=1e-9)
    assert put_in > 0 and lost != 0
    assert stored == pytest.approx(put_in - lost, rel=1e-9, abs=1e-3)


def test_unbalanced_heat_shares_are_rejected_at_initialization(fmu_paths: dict[str, Path]) -> None:
    from fmpy.fmi1 import FMICallException

    d = Driver(fmu_paths["ThermalNetwork"])
    d.slave.setupExperiment(startTime=0.0)
    d.set({"hyd_share_oil": 0.5})
    d.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        d.slave.exitInitializationMode()
    # still in initialization mode: the host may correct the parameter and go on
    d.set({"hyd_share_base": 0.5})
    d.slave.exitInitializationMode()
    d.close()


def test_start_temperatures_are_used_when_not_starting_at_room(fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["ThermalNetwork"])
    d.init(parameters={"start_at_room": False, "t_start_bearing": 310.0}, inputs={"t_room": 290.0})
    t_bearing, t_base = d.get(["t_bearing", "t_base"])
    d.close()
    assert t_bearing == 310.0 and t_base == 293.15


def test_the_pole_heater_warms_the_lower_pole_and_counts_in_the_energy(fmu_paths: dict[str, Path]) -> None:
    # a calibration's heater tape (q_pole_heater) enters pole_lower alone: the pole warms most,
    # the frame's upper half far less, and the heat put in is the heater's, in the balance
    d = Driver(fmu_paths["ThermalNetwork"])
    net = Network(d)
    d.init(inputs={"t_room": 293.15, "q_hydraulic": 0.0, "q_friction": 0.0, "q_pole_heater": 1.0})
    outs = [f"t_{n}" for n in net.nodes]
    t0 = d.get(outs)
    for k in range(240):
        d.slave.doStep(currentCommunicationPoint=k * 60.0, communicationStepSize=60.0)
    stored, put_in, lost = d.get(["energy_stored", "energy_in", "energy_lost"])
    rise = dict(zip(net.nodes, d.get(outs) - t0, strict=True))
    d.close()
    assert put_in == pytest.approx(1.0 * 240 * 60.0, rel=1e-12)
    assert stored == pytest.approx(put_in - lost, rel=1e-9, abs=1e-3)
    assert max(rise, key=rise.get) == "pole_lower" and rise["pole_lower"] > 1.0
    assert rise["detecting_frame"] < 0.1 * rise["pole_lower"]
