"""One geometry source: the derived parameter files are current, every value is physical, and the
error model's topology and priors agree with the drawing."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest

from twin.calibration.geometry import capacity, derive, derived_file, derived_file_text, mass
from twin.config.drawing import load_geometry, positions
from twin.config.load import scenarios_dir
from twin.errormodel.tester import load_tester_spec

SCENARIOS = scenarios_dir()
G = load_geometry(SCENARIOS)


@pytest.mark.parametrize("model", ["FixtureMechanics", "ThermalNetwork", "OscillationDrive"])
def test_the_derived_files_are_current(model: str) -> None:
    # a geometry change without `twin geometry` would leave the FMUs on the old drawing
    text = derived_file_text(model, derive(G)[model])
    assert derived_file(SCENARIOS, model).read_text(encoding="utf-8") == text


def test_masses_come_from_volume_and_density() -> None:
    # the base: 1.0 x 0.6 x 0.1 m of cast iron at 7500 kg/m3
    assert mass(G, "base") == pytest.approx(450.0)
    assert capacity(G, "base") == pytest.approx(450.0 * 490.0)
    # the frame: 362 x 50 x 20 mm of steel, 2.84 kg; its two lumps share it
    c = derive(G)["ThermalNetwork"]
    assert c["c_detecting_frame"].value + c["c_detecting_frame_lower"].value == pytest.approx(
        0.362 * 0.05 * 0.02 * 7850 * 470
    )


BODY_AREA = {  # node -> (exposed area m2) as the drawing gives it, for the h range check
    "g_base_room": G.dim("bodies.base.exposed_area"),
    "g_heel_block_room": G.dim("bodies.heel_block.exposed_area"),
    "g_bearing_block_room": G.dim("bodies.bearing_block.exposed_area"),
    "g_t_plate_room": G.dim("bodies.t_plate.exposed_area"),
    "g_detecting_frame_room": G.dim("bodies.detecting_frame.exposed_area") / 2,
    "g_clamp_room": G.dim("bodies.clamp.exposed_area"),
    "g_sensor_room": G.dim("bodies.sensor.exposed_area"),
}


@pytest.mark.parametrize("name", sorted(BODY_AREA))
def test_room_conductances_have_a_handbook_h(name: str) -> None:
    # facts 5: natural convection 2-25 W/(m2 K), plus up to about 5 of radiation
    h = derive(G)["ThermalNetwork"][name].value / BODY_AREA[name]
    assert 2.0 <= h <= 30.0


def test_every_derived_value_is_physical() -> None:
    for model, params in derive(G).items():
        for k, d in params.items():
            assert math.isfinite(d.value) and d.value >= 0, (model, k)
            assert d.source, (model, k)
    th = derive(G)["ThermalNetwork"]
    for k, d in th.items():
        if k.startswith("c_"):
            assert 10.0 <= d.value <= 1e6, k  # 20 g of steel .. 2 t of iron
    # time constants from geometry: the 10 mm pole about half an hour in air (facts 5: ~26 min at h = 6)
    tau_pole = th["c_pole_lower"].value / th["g_pole_lower_room"].value
    assert 15 * 60 <= tau_pole <= 45 * 60
    # the frame (2.8 kg, 0.045 m2) an hour or so, not the minute of an implausible lump
    tau_frame = th["c_detecting_frame"].value / th["g_detecting_frame_room"].value
    assert 30 * 60 <= tau_frame <= 5 * 3600


def test_lengths_are_the_drawings() -> None:
    m = derive(G)["FixtureMechanics"]
    assert m["l_detecting_frame"].value == pytest.approx(0.362)  # paper
    pole = m["l_pole_heel"].value + m["l_pole_base"].value + m["l_pole_lower"].value
    assert pole < 0.730  # the pole's top-to-clamp part lies within its 730 mm (paper)
    assert pole + m["l_clamp"].value == pytest.approx(positions(G)["pole_top_to_head"].value)


def test_the_error_models_topology_agrees_with_the_drawing() -> None:
    spec = load_tester_spec()
    pos = positions(G)
    assert spec.body("bearing_block").position["z"].value == pytest.approx(pos["spindle_axis_z"].value)
    assert spec.body("t_plate").position["z"].value == pytest.approx(G.dim("bodies.t_plate.centre_to_bottom"))
    assert spec.body("detecting_frame").position["z"].value == pytest.approx(pos["frame_top_z"].value)
    sensor_z = spec.body("displacement_sensor").position["z"].value
    assert pos["frame_top_z"].value + sensor_z == pytest.approx(pos["head_z"].value)
    assert -spec.body("long_pole").position["z"].value == pytest.approx(pos["pole_top_to_head"].value)
    assert spec.body("displacement_sensor").position["x"].value == pytest.approx(
        G.dim("bodies.sensor.abbe_offset")
    )
    assert spec.body("spherical_plain_bearing").dimensions["outer_diameter"].value == pytest.approx(
        G.dim("bodies.bearing.outer_diameter")
    )


def test_the_thermal_priors_are_alpha_times_the_drawn_length() -> None:
    priors = tomllib.loads((SCENARIOS / "calibration" / "priors.toml").read_text(encoding="utf-8"))["priors"]
    m = derive(G)["FixtureMechanics"]
    a = {k.removeprefix("alpha_"): v.value for k, v in m.items() if k.startswith("alpha_")}
    # each growth is its part's alpha times its drawn length: l_<body> unless named here
    length = {"heel_block": "h_heel_block", "bearing_block": "h_bearing_block", "spindle": "r_spindle",
              "bearing_rings": "t_bearing_rings"}  # fmt: skip
    part = {
        "base_inset": "base",
        "pole_heel": "long_pole",
        "pole_base": "long_pole",
        "pole_lower": "long_pole",
    }
    growths = [k.removeprefix("alpha_l_") for k in priors if k.startswith("alpha_l_")]
    assert len(growths) == 12  # every body between the heel block's foot and the probe's tip
    for body in growths:
        expected = a[part.get(body, body)] * m[length.get(body, f"l_{body}")].value
        assert priors[f"alpha_l_{body}"]["value"] == pytest.approx(expected, rel=1e-3), body


def test_twin_geometry_writes_the_files(tmp_path: Path) -> None:
    import shutil

    from twin.cli import main

    (tmp_path / "base").mkdir()
    shutil.copy(SCENARIOS / "base" / "tester-geometry.toml", tmp_path / "base")
    assert main(["geometry", "--scenarios", str(tmp_path)]) == 0
    for model in ("FixtureMechanics", "ThermalNetwork", "OscillationDrive"):
        assert derived_file(tmp_path, model).read_text() == derived_file(SCENARIOS, model).read_text()
