"""FixtureMechanics physics against hand calculations."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from twin.paper import FEM_PARTS_M

from .fmi_driver import Driver

T0 = 293.15
TEMPS = (
    "t_heel_block", "t_bearing_block", "t_spindle", "t_bearing", "t_t_plate",
    "t_detecting_frame", "t_pole_heel", "t_pole_base", "t_pole_lower", "t_clamp", "t_detecting_frame_lower",
    "t_base", "t_sensor", "t_bearing_block_rear",
)  # fmt: skip
M_POLE = 0.650072  # kg, the default: 730 mm x 10 mm steel rod + 0.2 kg clamp (tester-geometry.toml)
# the paper's measured rises, applied where its FEM applied them (facts.md 2)
PAPER_RISES = {
    "t_heel_block": 5.8, "t_bearing_block": 6.5, "t_bearing_block_rear": 6.5, "t_spindle": 3.2, "t_bearing": 3.2, "t_t_plate": 6.3,
    "t_detecting_frame": 8.9, "t_detecting_frame_lower": 8.9, "t_pole_heel": 5.8, "t_pole_base": 6.0, "t_pole_lower": 9.6, "t_clamp": 9.6,
}  # fmt: skip


@pytest.fixture
def mech(fmu_paths: dict[str, Path]) -> Driver:
    d = Driver(fmu_paths["FixtureMechanics"])
    d.init(inputs=dict.fromkeys(TEMPS, T0))
    yield d
    d.close()


def test_reproduces_the_papers_fem_parts_at_the_measured_rises(mech: Driver) -> None:
    mech.set({k: T0 + v for k, v in PAPER_RISES.items()})
    bb, sp, br, tp, fr, pole, cl = mech.get(
        [
            "dz_bearing_block",
            "dz_spindle",
            "dz_bearing",
            "dz_t_plate",
            "dz_detecting_frame",
            "dz_long_pole",
            "dz_clamp",
        ]
    )
    # compared, not fitted: the drawing's lengths (tester-geometry.toml) give each part within
    # 25 % of the paper's FEM result at the paper's rises (the lumped model cannot follow the FEM's
    # temperature field inside each body)
    assert bb == pytest.approx(FEM_PARTS_M["bearing_block"], rel=0.25)
    assert sp + br + tp == pytest.approx(FEM_PARTS_M["t_plate"], rel=0.25)
    assert fr == pytest.approx(FEM_PARTS_M["detecting_frame"], rel=0.25)
    assert pole + cl == pytest.approx(FEM_PARTS_M["long_pole"], rel=0.25)
    probe, bending = mech.get(["probe_true", "dz_frame_bending"])
    # the frame bends too (its rise is above the bearing's here: it radiates towards it), by 0.01 um
    assert abs(bending) < 2e-8
    assert probe - 4.805e-3 == pytest.approx(bb + sp + br + tp + pole + cl - fr - bending, abs=1e-12)


#: the parts that grow, each with its own expansion coefficient (alpha_<part>)
PARTS = ("heel_block", "bearing_block", "spindle", "bearing_rings", "t_plate", "detecting_frame",
         "long_pole", "clamp", "base", "probe_body")  # fmt: skip


def test_the_loop_closes_a_uniform_rise_with_one_alpha_leaves_the_reading(fmu_paths: dict[str, Path]) -> None:
    """Both branches, from the base top to the probe's contact, add up to the same Z as drawn
    (-0.140 + 0.512 = 0.050 + 0.362 - 0.040 = 0.372 m): with every body of one material warmed
    alike, the reading moves by alpha dT times nothing but its own zero offset. Without the base's
    inset and the probe's body the 10 mm left over moved it by about +1 um at 8.9 K."""
    alpha, rise = 11.7e-6, 8.9
    d = Driver(fmu_paths["FixtureMechanics"])
    try:
        d.init(
            parameters={f"alpha_{part}": alpha for part in PARTS},
            inputs=dict.fromkeys(TEMPS, T0),
        )
        before = d.get(["probe_true"])[0]
        d.set({k: T0 + rise for k in TEMPS})
        after, inset, probe_body, tilt = d.get(
            ["probe_true", "dz_base_inset", "dz_probe_body", "dz_bearing_block_tilt"]
        )
    finally:
        d.close()
    assert abs(after - before) < 1e-9
    assert tilt == 0.0  # the block's two halves alike: no gradient, no tilt
    # and the two new segments are what close it: each alone is microns
    assert inset == pytest.approx(alpha * 0.050 * rise, rel=1e-12)
    assert probe_body == pytest.approx(-alpha * 0.040 * rise, rel=1e-12)


def test_each_part_grows_with_its_own_alpha_and_rise_factor(fmu_paths: dict[str, Path]) -> None:
    """The pole's and the frame's coefficients are parameters of their own (a tester as built
    draws them apart), and a part's rise factor scales its growth alone."""
    rise = 8.9
    d = Driver(fmu_paths["FixtureMechanics"])
    try:
        d.init(
            parameters={"alpha_long_pole": 12.5e-6, "rise_factor_detecting_frame": 1.1},
            inputs=dict.fromkeys(TEMPS, T0),
        )
        d.set({k: T0 + rise for k in TEMPS})
        pole, frame, clamp = d.get(["dz_long_pole", "dz_detecting_frame", "dz_clamp"])
    finally:
        d.close()
    assert pole == pytest.approx(12.5e-6 * (0.14 + 0.1 + 0.262) * rise, rel=1e-12)
    assert frame == pytest.approx(11.7e-6 * 1.1 * 0.362 * rise, rel=1e-12)
    assert clamp == pytest.approx(11.7e-6 * 0.010 * rise, rel=1e-12)  # the clamp's steel: untouched


def test_hand_calculation_of_the_frames_thermal_bending(mech: Driver) -> None:
    # the bearing 50 K above the frame (the MIL test's rise): flux h_r F dT = 5 x 0.1 x 50 W/m2,
    # curvature alpha q / k, the lower end turns by kappa L, the head at e = 45 mm goes down
    mech.set({"t_bearing": T0 + 50.0})
    tilt, bending, sensor, frame = mech.get(
        ["frame_tilt", "dz_frame_bending", "z_sensor", "dz_detecting_frame"]
    )
    expected = 11.7e-6 * (5.0 * 0.1 * 50.0) / 51.0 * 0.362
    assert tilt == pytest.approx(expected, rel=1e-12)
    assert bending == pytest.approx(0.045 * expected, rel=1e-12)  # 0.09 um: about the probe's resolution
    assert sensor == pytest.approx(frame + bending, abs=1e-15)
    # the frame warmed alike on both faces does not bend
    mech.set({"t_detecting_frame": T0 + 50.0, "t_detecting_frame_lower": T0 + 50.0})
    assert mech.get(["frame_tilt"])[0] == pytest.approx(0.0, abs=1e-18)


def test_hand_calculation_of_the_frame_and_block(mech: Driver) -> None:
    # the frame's upper lump +1 K, its lower lump +3 K: each half of the 362 mm grows with its own
    mech.set(
        {
            "t_detecting_frame": T0 + 1.0,
            "t_detecting_frame_lower": T0 + 3.0,
            "t_bearing_block": T0 + 2.0,
            "t_bearing_block_rear": T0 + 2.0,
        }
    )
    fr, bb = mech.get(["dz_detecting_frame", "dz_bearing_block"])
    assert fr == pytest.approx(11.7e-6 * 0.362 * (1.0 + 3.0) / 2, rel=1e-12)
    assert bb == pytest.approx(-11e-6 * 0.1 * 2.0, rel=1e-12)


def test_hand_calculation_of_the_bearing_blocks_tilt(mech: Driver) -> None:
    """The block's front half (toward the T-plate) 1 K above its rear half: the front grows
    alpha h dT taller over the halves' 60 mm, the block and spindle turn about X by
    A = -11e-6 x 0.1 x 1 / 0.06 = -18.3 urad, and the test bearing 115 mm out on the spindle
    (100 mm above the block's foot) goes up by about L A = 2.1 um; the pole follows it to the
    reading. The halves' mean (+0.5 K) lifts the axis as before."""
    before = mech.get(["probe_true"])[0]
    mech.set({"t_bearing_block": T0 + 1.0})
    grad, a, dz, bb, z_t, probe = mech.get(
        [
            "bearing_block_gradient",
            "bearing_block_tilt",
            "dz_bearing_block_tilt",
            "dz_bearing_block",
            "z_t_plate",
            "probe_true",
        ]
    )
    alpha, h, d, overhang = 11e-6, 0.1, 0.06, 0.115
    angle = -alpha * h * 1.0 / d
    assert grad == pytest.approx(1.0, rel=1e-9)
    assert a == pytest.approx(angle, rel=1e-9)
    # the test bearing at (y, z) = (L, -h) from the foot, through Rot_x(A): z' = L sin A - h cos A
    assert dz == pytest.approx(overhang * math.sin(angle) + h * (1.0 - math.cos(angle)), rel=1e-9)
    assert dz == pytest.approx(-2.108e-6, rel=1e-3)
    assert bb == pytest.approx(-alpha * h * 0.5, rel=1e-12)
    assert z_t == pytest.approx(bb + dz, abs=1e-15)
    assert probe - before == pytest.approx(bb + dz, abs=1e-12)
    # the rear warmer instead turns it the other way
    mech.set({"t_bearing_block": T0, "t_bearing_block_rear": T0 + 1.0})
    assert mech.get(["dz_bearing_block_tilt"])[0] == pytest.approx(
        overhang * math.sin(-angle) + h * (1.0 - math.cos(angle)), rel=1e-9
    )


def test_wear_moves_the_probe_one_to_one(mech: Driver) -> None:
    (p0,) = mech.get(["probe_true"])
    mech.set({"wear_offset": 50e-6})
    p1, z_t, force = mech.get(["probe_true", "z_t_plate", "contact_force"])
    assert p1 - p0 == pytest.approx(50e-6, abs=1e-15)
    assert z_t == pytest.approx(50e-6, abs=1e-15)
    # the pole is pushed down: spring and head compress, the contact force grows
    assert force == pytest.approx(20.0 + 0.9 - M_POLE * 9.80665 + (2000.0 + 60.0) * 50e-6, rel=1e-12)


def test_lift_off_is_reported_not_hidden(fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths["FixtureMechanics"])
    # a weak spring: the pole cannot follow a T-plate that rises by 1 mm
    d.init(parameters={"f_spring0": 5.6, "k_spring": 100.0}, inputs=dict.fromkeys(TEMPS, T0))
    d.set({"wear_offset": -1e-3})
    gap, lift, force, top = d.get(["pole_gap", "lift_off", "contact_force", "z_pole_top"])
    d.close()
    f_free = 5.6 + 0.9 - M_POLE * 9.80665
    assert force == 0.0 and lift == 1.0
    assert top == pytest.approx(-f_free / 160.0, rel=1e-12)  # where spring + head balance gravity
    assert gap == pytest.approx(top + 1e-3, rel=1e-12)


def test_load_compliance_and_runout(fmu_paths: dict[str, Path]) -> None:
    import math

    d = Driver(fmu_paths["FixtureMechanics"])
    d.init(parameters={"spindle_runout": 3e-6, "runout_phase": 0.5}, inputs=dict.fromkeys(TEMPS, T0))
    d.set({"radial_load": 200e3, "angle": 0.4})
    load, run = d.get(["dz_loading", "dz_runout"])
    d.close()
    # liner: 0.4 mm x p / 3.1 GPa with p = F / 8.8 cm2; structure 0.5e-10 m/N
    assert load == pytest.approx(0.4e-3 * (200e3 / 8.8e-4) / 3.1e9 + 0.5e-10 * 200e3, rel=1e-12)
    assert run == pytest.approx(3e-6 * (math.cos(0.4 - 0.5) - math.cos(0.5)), rel=1e-12)


def test_archard_wear_with_running_in_matches_the_closed_form(fmu_paths: dict[str, Path]) -> None:
    import math

    d = Driver(fmu_paths["FixtureMechanics"])
    d.init(inputs=dict.fromkeys(TEMPS, T0))
    v, p = 5.8e-3, 250e6
    d.set({"sliding_speed": v, "contact_pressure": p})
    for k in range(3600):
        d.slave.doStep(currentCommunicationPoint=float(k), communicationStepSize=1.0)
    (wear,) = d.get(["wear_depth_true"])
    d.close()
    s, k_ss, f, s0 = v * 3600.0, 4e-16, 4.0, 50.0
    expected = k_ss * p * (s + f * s0 * (1.0 - math.exp(-s / s0)))
    assert wear == pytest.approx(expected, rel=1e-9)
    # and the wear moves the T-plate: it is in the true probe displacement
    assert 1e-6 < wear < 1e-4


def test_positioning_cosine_and_abbe_terms(fmu_paths: dict[str, Path]) -> None:
    import math

    d = Driver(fmu_paths["FixtureMechanics"])
    tilt, offset, c_rot = 0.02, 0.03, 2e-7
    d.init(
        parameters={"sensor_tilt": tilt, "abbe_offset": offset, "tplate_rotation_compliance": c_rot},
        inputs=dict.fromkeys(TEMPS, T0),
    )
    d.set({"wear_offset": 100e-6, "friction_torque": 50.0})
    pos, probe, rot = d.get(["dz_positioning", "probe_true", "tplate_rotation"])
    d.close()
    assert rot == pytest.approx(c_rot * 50.0, rel=1e-12)
    relative = 100e-6
    measured = (relative + offset * rot) * math.cos(tilt)
    assert pos == pytest.approx(measured - relative, rel=1e-9)
    assert probe == pytest.approx(4.805e-3 + measured, rel=1e-12)
