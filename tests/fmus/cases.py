"""One conformance case per FMU: the inputs to drive it with and its step sizes.

Every model in fmus/ must have an entry (tests/fmus/test_conformance.py checks), so a new
model cannot skip the conformance tests.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Case:
    inputs: dict[str, float]
    step: float
    stop: float
    parameters: dict[str, float] = field(default_factory=dict)


CASES: dict[str, Case] = {
    "ThermalNetwork": Case(
        inputs={"t_room": 301.0, "q_hydraulic": 350.0, "q_friction": 25.0},
        step=60.0,
        stop=4 * 3600.0,
        parameters={"t_start_bearing": 295.0},
    ),
    "HydraulicLoader": Case(
        # a fast trapezoid (2.5 s period) with a small bias, default servo and pump ripple
        inputs={"load_offset": 5e3, "station_on": 1.0},
        step=0.01,
        stop=5.0,
        parameters={
            "profile": 2,
            "load_low": 20e3,
            "load_high": 200e3,
            "t_ramp_up": 0.5,
            "t_dwell_high": 1.0,
            "t_ramp_down": 0.5,
            "t_dwell_low": 0.5,
        },
    ),
    "SensorsDAQ": Case(
        # the paper's thermal experiment, part way through: the eight points a few K above a
        # 20 degC start, the probe at its 4.805 mm start reading; plus a 120 kN load, a friction
        # torque, a swing angle and a fixture vibration, and frequent long interference spikes
        # (0.2 s > the 0.1 s communication step, so every spike shows in the outputs)
        inputs={
            "t_bearing_block": 297.5,
            "t_heel_block": 297.0,
            "t_bearing": 295.2,
            "t_t_plate": 297.4,
            "t_base": 297.1,
            "t_long_pole": 299.3,
            "t_detecting_frame": 298.9,
            "t_room": 298.9,
            "t_probe_body": 298.0,
            "probe_true": 4.805e-3,
            "load_true": 120e3,
            "torque_true": 85.0,
            "angle_true": 0.3,
            "vibration_true": 0.4e-6,
        },
        step=0.1,
        stop=30.0,
        parameters={"temp_tau": 20.0, "spike_rate": 1.0, "spike_duration": 0.2},
    ),
    "OscillationDrive": Case(
        # the MIL-spec swing (+-25 deg, 10 cycles/min) under a 100 kN radial load on a warm
        # bearing; 5 s spans the first two reversals (1.5 s, 4.5 s) and their ringing
        inputs={"radial_load": 100e3, "t_bearing": 300.0, "drive_on": 1.0},
        step=0.01,
        stop=5.0,
        parameters={"q_avg_window": 0.05},
    ),
    "FixtureMechanics": Case(
        # the paper's measured rises on a 293.15 K start (inputs are held; the model is algebraic)
        inputs={
            "t_heel_block": 298.95,
            "t_bearing_block": 299.65,
            "t_spindle": 296.35,
            "t_bearing": 296.35,
            "t_t_plate": 299.45,
            "t_detecting_frame": 302.05,
            "t_pole_heel": 298.95,
            "t_pole_base": 299.15,
            "t_pole_lower": 302.75,
            "t_clamp": 302.75,
            "radial_load": 100e3,
            "angle": 0.3,
            "sliding_speed": 5.8e-3,
            "contact_pressure": 110e6,
            "friction_torque": 90.0,
            "vibration_z": 0.2e-6,
            "wear_offset": 2e-6,
        },
        step=1.0,
        stop=120.0,
        parameters={
            "reference_at_start": False,
            "spindle_runout": 3e-6,
            "sensor_tilt": 0.01,
            "abbe_offset": 0.02,
            "tplate_rotation_compliance": 1e-7,
        },
    ),
    "SignalSource": Case(
        # a day-night room (the day-night scenario's sine) sped up to a 20 s period, so that 60
        # one-second steps pass through three cycles; no inputs drive it but its fault_inject
        inputs={"fault_inject": 0.0},
        step=1.0,
        stop=60.0,
        parameters={
            "profile": 3,
            "mean": 293.15,
            "amplitude": 3.0,
            "period": 20.0,
            "phase": -1.5707963267948966,
        },
    ),
}
