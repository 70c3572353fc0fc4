"""The FMUs' parameters derived from the tester as drawn (``twin geometry``).

From the geometry source (:mod:`twin.config.drawing`, ``scenarios/base/tester-geometry.toml``)
this module derives

- FixtureMechanics' lengths and expansion coefficients;
- ThermalNetwork's heat capacities (volume x density x specific heat) and conductances (exposed
  area x (convection + radiation) to the room; contact area x joint conductance, air gaps and
  axial conduction between bodies);
- OscillationDrive's bearing size;

and writes them as the parameter files ``scenarios/base/geometry-<model>.toml`` that the
scenarios include; ``tests/test_geometry.py`` checks that they are current and that every value
lies in a physical range.
"""

from __future__ import annotations

import math
from pathlib import Path

from twin.config.drawing import Derived, Geometry, load_geometry, positions
from twin.errors import ConfigError
from twin.files import write_text_atomic

__all__ = ["derive", "derived_file", "derived_file_text", "write_derived_files"]


# --- FixtureMechanics ---------------------------------------------------------------------------


#: FixtureMechanics' parts that grow (``alpha_<part>``) and the drawn body each is made of
_PARTS = {
    "heel_block": "heel_block",
    "bearing_block": "bearing_block",
    "spindle": "spindle",
    "bearing_rings": "bearing",
    "t_plate": "t_plate",
    "detecting_frame": "detecting_frame",
    "long_pole": "long_pole",
    "clamp": "clamp",
    "base": "base",
    "probe_body": "sensor",
}


def _alpha(g: Geometry, body: str) -> Derived:
    """A part's expansion coefficient: its drawn material's handbook value (each part its own
    parameter, so a tester as built draws them apart: scenarios/base/priors.toml)."""
    return Derived(g.prop(body, "alpha"), f"handbook: facts 5, {g.material(body)}")


def mechanics(g: Geometry) -> dict[str, Derived]:
    """FixtureMechanics' lengths and expansion coefficients from the drawing."""
    pos = positions(g)
    bearing = "bodies.bearing"
    ring = (g.dim(f"{bearing}.outer_diameter") - g.dim(f"{bearing}.bore")) / 2
    plate = g.dim("bodies.t_plate.centre_to_bottom") - g.dim(f"{bearing}.outer_diameter") / 2
    rod = math.pi / 4 * g.dim("bodies.long_pole.diameter") ** 2 * g.dim("bodies.long_pole.length")
    return {
        **{f"alpha_{part}": _alpha(g, body) for part, body in _PARTS.items()},
        "h_heel_block": Derived(g.dim("bodies.heel_block.z"), "drawing estimate: heel block height"),
        "h_bearing_block": Derived(
            g.dim("bodies.bearing_block.axis_height"), "drawing estimate: block foot to spindle axis"
        ),
        "r_spindle": Derived(g.dim("bodies.spindle.seat_radius"), "handbook: GE 30 ES bore / 2"),
        "l_overhang": Derived(
            g.dim("bodies.spindle.overhang"), "drawing estimate: bearing block centre to the test bearing"
        ),
        "d_bearing_block_halves": Derived(
            g.dim("bodies.bearing_block.y") / 2, "drawing estimate: half the block's length along the spindle"
        ),
        "t_bearing_rings": Derived(ring, "handbook: GE 30 ES (D - d) / 2"),
        "l_t_plate": Derived(
            plate, "drawing estimate: bearing centre to plate bottom minus the outer radius"
        ),
        "l_detecting_frame": Derived(g.dim("bodies.detecting_frame.z"), "paper: frame about 362 mm"),
        "l_pole_heel": Derived(pos["pole_heel"].value, "drawing: " + pos["pole_heel"].source),
        "l_pole_base": Derived(pos["pole_base"].value, "drawing: " + pos["pole_base"].source),
        "l_pole_lower": Derived(pos["pole_lower"].value, "drawing: " + pos["pole_lower"].source),
        "l_clamp": Derived(g.dim("bodies.clamp.thickness"), "drawing estimate: clamp fixing to contact face"),
        "l_base_inset": Derived(
            g.dim("bodies.detecting_frame.inset"), "drawing estimate: frame's fixing face below the base top"
        ),
        "l_probe_body": Derived(
            g.dim("bodies.sensor.length"), "drawing estimate: probe body plus head above the frame's bottom"
        ),
        "contact_area": Derived(
            g.dim(f"{bearing}.ball_diameter") * g.dim(f"{bearing}.liner_width"), "handbook: GE 30 ES d_k x B"
        ),
        "abbe_offset": Derived(
            g.dim("bodies.sensor.abbe_offset"), "drawing estimate: probe axis beside the pole"
        ),
        "m_pole": Derived(
            rod * g.prop("long_pole", "rho") + g.dim("bodies.clamp.mass"),
            "paper: 730 mm x 10 mm steel rod, plus the clamp (estimate)",
        ),
        # the frame's thermal bending (FixtureMechanics readme): radiation from the bearing
        # assembly onto its painted side face, conducted across its width
        "frame_view_factor": Derived(
            g.dim("bodies.detecting_frame.bearing_view_factor"),
            "drawing estimate: the bearing assembly's radiation on the frame's +X face",
        ),
        "h_radiation_frame": Derived(
            g.dim("surfaces.h_radiation_painted"), "handbook: facts 5, painted surfaces about 5 W/(m2 K)"
        ),
        "k_frame": Derived(g.prop("detecting_frame", "k"), "handbook: facts 5, steel 45"),
    }


# --- ThermalNetwork ------------------------------------------------------------------------------


def _volume(g: Geometry, body: str) -> float:
    b = g.data["bodies"][body]
    key = f"bodies.{body}"
    if b.get("shape") == "box":
        v = g.dim(f"{key}.x") * g.dim(f"{key}.y") * g.dim(f"{key}.z")
        if "bore_diameter" in b:
            v -= math.pi / 4 * g.dim(f"{key}.bore_diameter") ** 2 * g.dim(f"{key}.bore_length")
        return v
    if b.get("shape") == "rod":
        return math.pi / 4 * g.dim(f"{key}.diameter") ** 2 * g.dim(f"{key}.length")
    if b.get("shape") == "lumped":
        return g.dim(f"{key}.mass") / g.prop(body, "rho")
    raise ConfigError("shape must be box, rod or lumped", source=g.source, key=f"{key}.shape")


def mass(g: Geometry, body: str) -> float:
    """Mass of a body, kg (volume x density)."""
    return _volume(g, body) * g.prop(body, "rho")


def capacity(g: Geometry, body: str) -> float:
    """Heat capacity of a body, J/K."""
    return mass(g, body) * g.prop(body, "c")


def _pole_capacity(g: Geometry, length: float) -> float:
    area = math.pi / 4 * g.dim("bodies.long_pole.diameter") ** 2
    return area * length * g.prop("long_pole", "rho") * g.prop("long_pole", "c")


def _pole_room(g: Geometry, length: float) -> float:
    return math.pi * g.dim("bodies.long_pole.diameter") * length * g.h_room("long_pole")


def _room(g: Geometry, body: str) -> float:
    return g.dim(f"bodies.{body}.exposed_area") * g.h_room(body)


#: the network's nodes that are whole bodies of the drawing (the transmission behind the spindle
#: is its own node, behind the coupling); the bearing block's two halves, the frame, the pole, the
#: oil and the floor are derived apart
NODE_BODIES: dict[str, tuple[str, ...]] = {
    "base": ("base",),
    "heel_block": ("heel_block",),
    "spindle": ("spindle",),
    "drive_train": ("drive_train",),
    "bearing": ("bearing",),
    "t_plate": ("t_plate",),
    "clamp": ("clamp",),
    "sensor": ("sensor",),
}


def thermal_capacities(g: Geometry) -> dict[str, Derived]:
    """Heat capacities of the network's nodes from volume x density x c."""
    pos = positions(g)
    frame = capacity(g, "detecting_frame") / 2
    oil = g.dim("hydraulic_station.oil_volume") * g.dim("materials.hydraulic_oil.rho") * g.dim(
        "materials.hydraulic_oil.c"
    ) + g.dim("hydraulic_station.tank_mass") * g.dim("materials.steel_45.c")
    lower = pos["pole_lower"].value + pos["pole_below_clamp"].value
    out = {
        f"c_{node}": Derived(sum(capacity(g, b) for b in bodies), f"geometry: {' + '.join(bodies)} mass x c")
        for node, bodies in NODE_BODIES.items()
    }
    cap = _block_cap_volume(g) * g.prop("bearing_block", "rho") * g.prop("bearing_block", "c")
    block = (capacity(g, "bearing_block") - cap) / 2
    floor = g.dim("floor.area") * g.dim("floor.depth") * g.dim("floor.rho") * g.dim("floor.c")
    return out | {
        "c_bearing_block": Derived(
            block, "geometry: the bearing block's lower front half (toward the T-plate) x rho x c"
        ),
        "c_bearing_block_cap": Derived(
            cap, "geometry: the bearing block above the spindle's axis (less half the bore) x rho x c"
        ),
        "c_bearing_block_rear": Derived(
            block, "geometry: the bearing block's lower rear half (toward the drive) x rho x c"
        ),
        "c_floor": Derived(floor, "geometry: floor slab area x the depth 8 h reach x concrete rho x c"),
        "c_detecting_frame": Derived(frame, "geometry: upper half of the 362 x 50 mm frame x rho x c"),
        "c_detecting_frame_lower": Derived(frame, "geometry: lower half of the 362 x 50 mm frame x rho x c"),
        "c_pole_heel": Derived(_pole_capacity(g, pos["pole_heel"].value), "geometry: pole segment x rho x c"),
        "c_pole_base": Derived(_pole_capacity(g, pos["pole_base"].value), "geometry: pole segment x rho x c"),
        "c_pole_lower": Derived(
            _pole_capacity(g, lower), "geometry: pole below the base (to its end) x rho x c"
        ),
        "c_oil": Derived(oil, "geometry: oil volume x rho x c + tank mass x c"),
    }


def thermal_room(g: Geometry) -> dict[str, Derived]:
    """Conductances of the nodes to the room air: exposed area x (h_conv + h_rad)."""
    pos = positions(g)
    frame = _room(g, "detecting_frame") / 2
    under_plate = pos["pole_heel"].value - g.dim("bodies.heel_block.z")
    lower = pos["pole_lower"].value + pos["pole_below_clamp"].value
    out = {
        f"g_{node}_room": Derived(
            sum(_room(g, b) for b in bodies),
            f"geometry: {' + '.join(bodies)} exposed area x (h_conv + h_rad)",
        )
        for node, bodies in NODE_BODIES.items()
    }
    cap = _block_cap_area(g) * g.h_room("bearing_block")
    block = (_room(g, "bearing_block") - cap) / 2
    return out | {
        "g_bearing_block_cap_room": Derived(
            cap, "geometry: the block's top and the sides above its axis x (h_conv + h_rad)"
        ),
        "g_bearing_block_room": Derived(
            block, "geometry: half the bearing block's exposed area below its axis x (h_conv + h_rad)"
        ),
        "g_bearing_block_rear_room": Derived(
            block, "geometry: half the bearing block's exposed area below its axis x (h_conv + h_rad)"
        ),
        "g_floor_room": Derived(
            g.dim("floor.area") * g.dim("floor.h_air"), "handbook: floor area x downward free convection"
        ),
        "g_detecting_frame_room": Derived(
            frame, "geometry: half the frame's exposed area x (h_conv + h_rad)"
        ),
        "g_detecting_frame_lower_room": Derived(
            frame, "geometry: half the frame's exposed area x (h_conv + h_rad)"
        ),
        "g_pole_heel_room": Derived(
            _pole_room(g, under_plate), "geometry: the pole's free length under the T-plate"
        ),
        "g_pole_base_room": Derived(0.0, "geometry: enclosed in the base"),
        "g_pole_lower_room": Derived(
            _pole_room(g, lower), "geometry: pole surface below the base x (h_conv + h_rad)"
        ),
        "g_oil_room": Derived(
            g.dim("hydraulic_station.tank_area") * g.dim("surfaces.h_tank"),
            "handbook: tank area x 12 W/(m2 K)",
        ),
    }


def _block_cap_volume(g: Geometry) -> float:
    """The bearing block above the spindle's axis, less the upper half of the bore, m3."""
    b = "bodies.bearing_block"
    above = g.dim(f"{b}.z") - g.dim(f"{b}.axis_height")
    bore = math.pi / 8 * g.dim(f"{b}.bore_diameter") ** 2 * g.dim(f"{b}.bore_length")
    return g.dim(f"{b}.x") * g.dim(f"{b}.y") * above - bore


def _block_cap_area(g: Geometry) -> float:
    """The bearing block's top face and its four sides above the spindle's axis, m2."""
    b = "bodies.bearing_block"
    above = g.dim(f"{b}.z") - g.dim(f"{b}.axis_height")
    return g.dim(f"{b}.x") * g.dim(f"{b}.y") + 2 * (g.dim(f"{b}.x") + g.dim(f"{b}.y")) * above


def _axial(g: Geometry, body: str, area: float, length: float) -> float:
    return g.prop(body, "k") * area / length


def thermal_joints(g: Geometry) -> dict[str, Derived]:
    """Conductances between bodies: bolted contact area x h, air gaps, axial conduction."""
    pos = positions(g)
    h = g.dim("joints.h_bolted")
    gap = g.dim("joints.k_air") * math.pi * g.dim("bodies.long_pole.diameter") / g.dim("joints.pole_gap")
    rod = math.pi / 4 * g.dim("bodies.long_pole.diameter") ** 2
    frame_section = g.dim("bodies.detecting_frame.x") * g.dim("bodies.detecting_frame.y")
    frame_len = g.dim("bodies.detecting_frame.z")
    inset = g.dim("bodies.detecting_frame.inset")
    lower = pos["pole_lower"].value + pos["pole_below_clamp"].value
    seat_in = math.pi * g.dim("bodies.bearing.bore") * g.dim("bodies.bearing.liner_width")
    seat_out = math.pi * g.dim("bodies.bearing.outer_diameter") * g.dim("bodies.t_plate.bore_length")
    # the PTFE liner between the inner ring (the bearing's node) and the outer ring in the T-plate:
    # its spherical face pi d_k B through the liner's thickness, in series with the outer ring's seat
    liner = (
        g.dim("bodies.bearing.liner_k")
        * math.pi
        * g.dim("bodies.bearing.ball_diameter")
        * g.dim("bodies.bearing.liner_width")
        / g.dim("bodies.bearing.liner_thickness")
    )
    foot = h * g.dim("bodies.bearing_block.x") * g.dim("bodies.bearing_block.y") / 2
    front = g.dim("bodies.bearing_block.roller_bearing_front_share")
    across = (
        g.dim("bodies.bearing_block.x") * g.dim("bodies.bearing_block.z")
        - math.pi / 4 * g.dim("bodies.bearing_block.bore_diameter") ** 2
    )
    # the cap joins the lower halves only beside the bore: section (x - bore) y, from the cap's
    # centre to the lower halves' centres (half the block's height)
    beside = (g.dim("bodies.bearing_block.x") - g.dim("bodies.bearing_block.bore_diameter")) * g.dim(
        "bodies.bearing_block.y"
    )
    cap_path = g.dim("bodies.bearing_block.z") / 2
    hub = math.pi * g.dim("bodies.spindle.diameter") * g.dim("bodies.drive_train.hub_length")
    return {
        "g_base__heel_block": Derived(
            h * g.dim("bodies.heel_block.x") * g.dim("bodies.heel_block.y"),
            "geometry: heel block foot x h_bolted",
        ),
        "g_heel_block__bearing_block": Derived(
            foot, "geometry: the front half of the block's foot x h_bolted"
        ),
        "g_heel_block__bearing_block_rear": Derived(
            foot, "geometry: the rear half of the block's foot x h_bolted"
        ),
        "g_bearing_block__bearing_block_rear": Derived(
            _axial(g, "bearing_block", across, g.dim("bodies.bearing_block.y") / 2),
            "handbook: k A / (y/2) through the block's section (less the bore) between the halves' centres",
        ),
        "g_bearing_block__bearing_block_cap": Derived(
            _axial(g, "bearing_block", beside / 2, cap_path),
            "handbook: k A / L through the front half of the section beside the bore, cap centre to foot centre",
        ),
        "g_bearing_block_rear__bearing_block_cap": Derived(
            _axial(g, "bearing_block", beside / 2, cap_path),
            "handbook: k A / L through the rear half of the section beside the bore, cap centre to foot centre",
        ),
        "g_bearing_block__spindle": Derived(
            2.0 * front, "estimate: through the rollers of the spindle's roller bearing (in the front half)"
        ),
        "g_spindle__drive_train": Derived(
            h * hub, "geometry: the spindle's end in the coupling hub (pi d L) x h_bolted"
        ),
        "g_drive_train__floor": Derived(
            h * g.dim("bodies.drive_train.bed_area"),
            "geometry: the transmission's bed on the floor x h_bolted",
        ),
        "g_spindle__bearing": Derived(h * seat_in, "geometry: inner ring seat (pi d B) x h_bolted"),
        "g_bearing__t_plate": Derived(
            1.0 / (1.0 / liner + 1.0 / (h * seat_out)),
            "geometry: the PTFE liner (k pi d_k B / t) in series with the outer ring's seat (pi D t x h_bolted)",
        ),
        "g_base__detecting_frame": Derived(
            h * (frame_section + 2 * g.dim("bodies.detecting_frame.x") * inset),
            "geometry: frame top and its inset faces x h_bolted",
        ),
        "g_detecting_frame__detecting_frame_lower": Derived(
            _axial(g, "detecting_frame", frame_section, frame_len / 2),
            "handbook: axial k A / (L/2) of the frame",
        ),
        "g_heel_block__pole_heel": Derived(
            gap * g.dim("bodies.heel_block.z"), "geometry: air gap k_air pi d L / gap in the heel block"
        ),
        "g_base__pole_base": Derived(
            gap * pos["pole_base"].value, "geometry: air gap k_air pi d L / gap in the base"
        ),
        "g_detecting_frame_lower__pole_lower": Derived(0.05, "estimate: linear bearing guiding the pole"),
        "g_pole_heel__pole_base": Derived(
            _axial(g, "long_pole", rod, (pos["pole_heel"].value + pos["pole_base"].value) / 2),
            "handbook: axial k A / L between segment centres",
        ),
        "g_pole_base__pole_lower": Derived(
            _axial(g, "long_pole", rod, (pos["pole_base"].value + lower) / 2),
            "handbook: axial k A / L between segment centres",
        ),
        "g_pole_lower__clamp": Derived(0.2, "estimate: clamp screwed on the pole"),
        "g_clamp__sensor": Derived(0.005, "estimate: point contact of the measuring head"),
        "g_sensor__detecting_frame_lower": Derived(0.1, "estimate: probe clamped in the frame's lower end"),
        "g_t_plate__pole_heel": Derived(0.005, "estimate: point contact of the pole top"),
        "g_oil__base": Derived(
            0.0,
            "estimate: the station's heat reaches the tester through the cabinet air (the shares), not through a joint",
        ),
    }


#: the network's nodes that hang under the base, in the cabinet air the embedded station warms
UNDER_BASE = ("base", "pole_lower", "detecting_frame_lower")


def thermal_heat(g: Geometry) -> dict[str, Derived]:
    """Where the hydraulic station's lost heat goes: a share to each part under the base (the
    station is embedded in the tester, the paper says), the rest into its oil.

    The station warms the cabinet air under the base; a part takes heat from that air in
    proportion to its surface there (h A dT, one h and one dT for all). The base's underside takes
    the drawing's ``embedded_share``; the pole's lower part and the frame's lower half take that
    share scaled by their area over the base's underside."""
    pos = positions(g)
    share = g.dim("hydraulic_station.embedded_share")
    underside = g.dim("hydraulic_station.base_underside_area")
    lower = pos["pole_lower"].value + pos["pole_below_clamp"].value
    areas = {
        "base": underside,
        "pole_lower": math.pi * g.dim("bodies.long_pole.diameter") * lower,
        "detecting_frame_lower": g.dim("bodies.detecting_frame.exposed_area") / 2,
    }
    why = "drawing estimate: the embedded station's heat reaching a part under the base, by its area in the cabinet air"
    shares = {
        f"hyd_share_{node}": Derived(share * areas[node] / underside, f"{why} ({areas[node]:.3g} m2)")
        for node in UNDER_BASE
    }
    cylinder = g.dim("hydraulic_station.cylinder_share")
    shares["hyd_share_t_plate"] = Derived(
        cylinder, "drawing estimate: the loading cylinder's oil warming the T-plate"
    )
    rest = 1.0 - sum(d.value for d in shares.values())
    shares["hyd_share_oil"] = Derived(rest, "the rest of the station's heat, into its oil")
    return shares


def oscillation(g: Geometry) -> dict[str, Derived]:
    """OscillationDrive's bearing size."""
    return {
        "d_k": Derived(g.dim("bodies.bearing.ball_diameter"), "handbook: GE 30 ES d_k"),
        "liner_width": Derived(g.dim("bodies.bearing.liner_width"), "handbook: GE 30 ES B"),
    }


def derive(g: Geometry) -> dict[str, dict[str, Derived]]:
    """Every derived FMU parameter, by model."""
    return {
        "FixtureMechanics": mechanics(g),
        "ThermalNetwork": thermal_capacities(g) | thermal_room(g) | thermal_joints(g) | thermal_heat(g),
        "OscillationDrive": oscillation(g),
    }


def derived_file_text(model: str, params: dict[str, Derived]) -> str:
    """A scenario parameter file of one model's derived parameters."""
    lines = [
        f"# {model}'s parameters derived from tester-geometry.toml by `twin geometry`.",
        "# Do not edit: change the geometry file and rerun `twin geometry` (tests check this file is current).",
        "",
        "[parameters]",
    ]
    for k in sorted(params):
        d = params[k]
        # six significant digits: the drawing is not more exact, and the file stays readable
        lines.append(f'{k} = {{ value = {float(f"{d.value:.6g}")!r}, source = "derived: {d.source}" }}')
    return "\n".join(lines) + "\n"


#: the models with a derived parameter file, and that file's stem (``base/geometry-<stem>.toml``)
MODELS = {"FixtureMechanics": "mechanics", "ThermalNetwork": "thermal", "OscillationDrive": "oscillation"}


def derived_file(scenarios_dir: Path, model: str) -> Path:
    """Where a model's derived parameter file lives."""
    return scenarios_dir / "base" / f"geometry-{MODELS[model]}.toml"


def write_derived_files(scenarios_dir: Path) -> list[Path]:
    """Write every derived parameter file; returns their paths."""
    out = []
    geometry = load_geometry(scenarios_dir)
    derived = derive(geometry)
    positions(geometry)
    geometry.check_unread()  # a misspelt or unknown key: refused before any file is written
    for model, params in derived.items():
        path = derived_file(scenarios_dir, model)
        write_text_atomic(path, derived_file_text(model, params))
        out.append(path)
    return out
