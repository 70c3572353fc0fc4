"""The SPB tester's model from its data file: bodies, geometry, sign convention, a hand calculation."""

from __future__ import annotations

import dataclasses
import re
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from twin.errormodel.tester import DATA_FILE, SOURCES, load_tester_spec, tester_model
from twin.errors import ConfigError

NAMES = (
    "base",
    "bearing_block",
    "testing_spindle",
    "spherical_plain_bearing",
    "t_plate",
    "detecting_frame",
    "displacement_sensor",
    "contacting_clamp",
    "long_pole",
)


def test_bodies_and_branches_as_in_the_paper() -> None:
    m = tester_model()
    assert tuple(b.name for b in m.topology.bodies) == NAMES
    assert m.topology.indices == tuple(range(1, 10))
    assert m.branches[0].chain == (1, 2, 3, 4, 5)
    assert m.branches[1].chain == (1, 6, 7, 8, 9)
    assert (m.branches[0].end, m.branches[1].end) == ("t_plate", "long_pole")


def test_ideal_geometry_closes_at_every_angle() -> None:
    m = tester_model()
    angles = np.random.default_rng(0).uniform(-np.pi, np.pi, 100)
    np.testing.assert_allclose(m.ideal_gap(), 0.0, atol=1e-15)
    np.testing.assert_allclose(m.ideal_gap({"angle": angles}), 0.0, atol=1e-15)
    # both ends sit above the base top (negative Z is up), the T-plate bottom 140 mm up
    np.testing.assert_allclose(m.branches[0].ideal_position(), [0.0, 0.0, -0.140], atol=1e-15)


def test_every_value_names_its_source() -> None:
    raw = tomllib.loads(resources.files("twin.errormodel").joinpath(DATA_FILE).read_text(encoding="utf-8"))
    values = [
        v for b in raw["body"] for group in ("position", "dimensions") for v in b.get(group, {}).values()
    ]
    assert values
    assert all(v["source"] in SOURCES and v.get("note") for v in values)
    spec = load_tester_spec()
    assert spec.body("long_pole").dimensions["length"].value == 0.730
    assert spec.body("long_pole").dimensions["length"].source == "paper"
    assert spec.body("long_pole").dimensions["diameter"].value == 0.010
    assert spec.body("detecting_frame").dimensions["length"].value == 0.362
    assert spec.body("detecting_frame").dimensions["width"].source == "paper"
    assert spec.motion_defaults == {"angle": 0.0}


def test_spindle_swings_and_the_outer_ring_does_not() -> None:
    spec = load_tester_spec()
    spindle, bearing = spec.body("testing_spindle").motion, spec.body("spherical_plain_bearing").motion
    assert spindle is not None and bearing is not None
    assert (spindle.type, spindle.axis, spindle.variable, spindle.scale) == ("rotation", "y", "angle", 1.0)
    assert bearing.scale == -1.0
    with pytest.raises(ConfigError, match="motion variable 'angle' is missing"):
        spindle({})


def test_thermal_experiment_hand_calculation() -> None:
    """Paper's thermal case (no load, no motion): the four thermal terms, summed by hand.

    bearing block (HT250, alpha 11e-6/K, 250 mm effective height, +6.5 K) lifts the spindle:
        p_dz(bearing_block) = -11e-6 * 0.250 * 6.5 = -17.875e-6 m
    T-plate bottom falls 0.003 mm (paper FEM):              p_dz(t_plate) = +3e-6 m
    detecting frame grows down 0.041 mm (paper FEM):        p_dz(detecting_frame) = +41e-6 m
    pole hangs from its top, clamp falls 0.040 mm relative to it (paper FEM), so the pole top
    rises relative to the clamp:                            p_dz(long_pole) = -40e-6 m
    e_z = (-17.875 + 3.0) - (41.0 - 40.0) um = -15.875 um: the reading falls.
    """
    errors = {
        "bearing_block": {"p_dz": -11e-6 * 0.250 * 6.5},
        "t_plate": {"p_dz": 3e-6},
        "detecting_frame": {"p_dz": 41e-6},
        "long_pole": {"p_dz": -40e-6},
    }
    m = tester_model()
    assert m.e_z(errors) == pytest.approx(-15.875e-6, rel=1e-12)
    assert m.e_z_full(errors) == pytest.approx(-15.875e-6, rel=1e-9)
    parts = m.e_z_by_body(errors)
    assert parts["bearing_block"] == pytest.approx(-17.875e-6)
    assert parts["detecting_frame"] == pytest.approx(-41e-6)
    assert parts["long_pole"] == pytest.approx(40e-6)
    assert parts["testing_spindle"] == 0.0

    # the same as a 480-min ramp sampled every minute: e_z ramps linearly to the same end value
    ramp = np.linspace(0.0, 1.0, 481)
    series = m.e_z({b: {k: v * ramp for k, v in p.items()} for b, p in errors.items()})
    np.testing.assert_allclose(series, -15.875e-6 * ramp, rtol=1e-12, atol=1e-20)
    assert np.all(np.diff(series) < 0)  # the reading falls throughout


def test_the_loop_closes_a_uniform_rise_with_one_alpha_predicts_no_error() -> None:
    """The error model's thermal sources with every coefficient one alpha times the drawn length
    (tester-geometry.toml, as the FMUs get them) and every measuring point warmed alike: the
    two branches grow by the same Z, so e_z stays within 1 nm. Without the base's inset and the
    probe's body the error model predicted alpha * 10 mm * dT (+1.04 um at 8.9 K, 11.7e-6/K)."""
    from twin.calibration.geometry import derive
    from twin.config.drawing import load_geometry
    from twin.config.load import scenarios_dir
    from twin.errormodel.sources import DEFAULT_TEMPERATURES, ThermalCoefficients, thermal_errors

    m = derive(load_geometry(scenarios_dir()))["FixtureMechanics"]
    alpha, rise = 11.7e-6, 8.9
    lengths = {
        "alpha_l_heel_block": "h_heel_block", "alpha_l_bearing_block": "h_bearing_block",
        "alpha_l_spindle": "r_spindle", "alpha_l_bearing_rings": "t_bearing_rings",
        "alpha_l_t_plate": "l_t_plate", "alpha_l_base_inset": "l_base_inset",
        "alpha_l_detecting_frame": "l_detecting_frame", "alpha_l_probe_body": "l_probe_body",
        "alpha_l_clamp": "l_clamp", "alpha_l_pole_heel": "l_pole_heel",
        "alpha_l_pole_base": "l_pole_base", "alpha_l_pole_lower": "l_pole_lower",
    }  # fmt: skip
    g = ThermalCoefficients.from_values(
        {
            **{k: alpha * m[v].value for k, v in lengths.items()},
            "probe_zero_drift": 0.0,
            "probe_span_drift": 0.0,
        }
    )
    rises = {point: np.array([0.0, rise]) for point in DEFAULT_TEMPERATURES}
    model = tester_model()
    e_z = model.e_z(thermal_errors(rises, g))
    assert abs(e_z[1] - e_z[0]) < 1e-9
    without = dataclasses.replace(g, alpha_l_base_inset=0.0, alpha_l_probe_body=0.0)
    assert model.e_z(thermal_errors(rises, without))[1] == pytest.approx(alpha * 0.010 * rise, rel=1e-6)


def test_the_probes_drifts_follow_its_body_where_measured_else_the_frame() -> None:
    """By hand: zero drift 0.4 um/K, span drift 2e-4/K, reading 9 mm, 10 K: the probe reads
    (0.4 + 2e-4 x 9000) um/K x 10 K = 22 um more, as if its body had moved up 22 um (p_dz < 0);
    on the bench its body's thermometer drives it, on the tester the frame's stands in."""
    from twin.errormodel.sources import DEFAULT_TEMPERATURES, ThermalCoefficients, thermal_errors

    zero = dict.fromkeys(ThermalCoefficients.units(), 0.0)
    g = ThermalCoefficients.from_values({**zero, "probe_zero_drift": 0.4e-6, "probe_span_drift": 2e-4})
    still = {point: np.zeros(2) for point in DEFAULT_TEMPERATURES}
    bench = thermal_errors({**still, "probe_body": np.array([0.0, 10.0])}, g, np.array([9e-3, 9e-3]))
    assert bench["displacement_sensor"]["p_dz"][1] == pytest.approx(-22e-6, rel=1e-12)
    tester = thermal_errors({**still, "detecting_frame": np.array([0.0, 10.0])}, g, 9e-3)
    assert tester["displacement_sensor"]["p_dz"][1] == pytest.approx(-22e-6, rel=1e-12)
    assert tester["detecting_frame"]["p_dz"][1] == 0.0  # no growth: the coefficients are zero


def test_positioning_errors_give_abbe_terms() -> None:
    coef = tester_model().e_z_coefficients()
    # sensor 45 mm beside the pole: a tilt of the sensor about Y moves the head along Z by -0.045 * ey
    # in branch 2, i.e. +0.045 in e_z; a tilt of the bearing block about X acts over its 120 mm lever
    assert coef[("displacement_sensor", "p_ey")] == pytest.approx(-0.045)
    assert coef[("bearing_block", "p_ex")] == pytest.approx(0.120)
    assert coef[("detecting_frame", "p_ex")] == 0.0  # on the pole axis: no lever


def test_the_friction_torques_rotation_reaches_e_z_at_the_drawings_abbe_lever(tmp_path: Path) -> None:
    # the positioning factor gives the clamp's rotation, not a length: the characteristic
    # matrices turn it into Z at the sensor's offset from the pole, so another drawing (the
    # probe 30 mm beside the pole instead of 45) changes the prediction in proportion
    from twin.errormodel.sources import MechanicalCoefficients, positioning_errors

    c = MechanicalCoefficients(**{**dict.fromkeys(MechanicalCoefficients.units(), 0.0), "probe_scale": 1.0,
                                  "clamp_rotation": 1e-7})  # fmt: skip
    torque = np.array([0.0, 50.0, 150.0])
    errors = positioning_errors(np.zeros(3), torque, c)
    np.testing.assert_allclose(tester_model().e_z(errors), -0.045 * 1e-7 * torque, rtol=1e-12, atol=1e-20)
    text = resources.files("twin.errormodel").joinpath("tester_topology.toml").read_text(encoding="utf-8")
    moved = text.replace("position.x = { value = 0.045,", "position.x = { value = 0.030,").replace(
        "position.x = { value = -0.045,", "position.x = { value = -0.030,"
    )
    assert moved.count("0.030,") == 2
    (tmp_path / "topology.toml").write_text(moved, encoding="utf-8")
    np.testing.assert_allclose(
        tester_model(tmp_path / "topology.toml").e_z(errors), -0.030 * 1e-7 * torque, rtol=1e-12, atol=1e-20
    )


BAD_FILE = """
[[branch]]
end = "b"
[[branch]]
end = "c"
[[body]]
index = 1
name = "a"
[[body]]
index = 2
name = "b"
lower = 1
position.z = { value = 0.1, source = "guess" }
[[body]]
index = 3
name = "c"
lower = 7
"""


def test_bad_file_reports_every_problem(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(BAD_FILE, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_tester_spec(path)
    message = str(info.value)
    assert "bad.toml: body[1].position.z: source must be one of" in message


def test_bad_topology_in_file(tmp_path: Path) -> None:
    path = tmp_path / "cycle.toml"
    path.write_text(BAD_FILE.replace('"guess"', '"estimate"'), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape("cycle.toml: body 3 ('c'): unknown lower body 7")):
        load_tester_spec(path)


def test_unreadable_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_tester_spec(tmp_path / "missing.toml")
    (tmp_path / "broken.toml").write_text("[[body]\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="TOML syntax error"):
        load_tester_spec(tmp_path / "broken.toml")
    # read by the loader's one reader of TOML files: a device is refused before it is read
    with pytest.raises(ConfigError, match="not a regular file"):
        load_tester_spec("/dev/zero")
