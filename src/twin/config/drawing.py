"""The tester as drawn: one geometry and materials source for the FMUs and the error model.

``scenarios/base/tester-geometry.toml`` holds every body's dimensions and material with its
source (paper, handbook, drawing estimate). :class:`Geometry` reads it (every entry a
``{ value, source }`` table); :func:`positions` places the detecting system (spindle axis,
T-plate bottom, frame, sensor, clamp, the long pole's segments), which the error model's
characteristic matrices use (``errormodel/tester_topology.toml`` must agree: a test checks it)
and the recording's 3D view draws. The FMUs' parameters derived from it are made by
:mod:`twin.calibration.geometry` (``twin geometry``). Nothing here reads the paper's FEM
results or its measured drift: lengths come from the drawing, so the FEM comparison stays a
comparison.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.config.reader import number_problem, read_toml
from twin.errors import ConfigError

__all__ = ["GEOMETRY_FILE", "Derived", "Geometry", "load_geometry", "positions"]

#: the geometry source, relative to the scenarios folder
GEOMETRY_FILE = Path("base") / "tester-geometry.toml"
#: the geometry file's keys a derivation need not read: a body's shape (box, rod, lumped: read
#: for the bodies whose volume is derived from it, and by the 3D view), the frame's FEM nodes
#: and each material's conductivity, which document the drawing; every other key must be read
#: by a derivation, so that a misspelt one is refused, not silently ignored
NOT_DERIVED = ("bodies.*.shape", "bodies.detecting_frame.nodes", "materials.*.k")


@dataclass(frozen=True)
class Derived:
    """A derived number with the arithmetic that made it (the ``source`` of a parameter)."""

    value: float
    source: str


class Geometry:
    """Read access to the geometry file: ``g.dim("bodies.t_plate.x")`` returns the number."""

    def __init__(self, data: dict[str, Any], source: str) -> None:
        self.data = data
        self.source = source
        #: every key read so far (:meth:`unread`: the file's keys nothing reads)
        self.read: set[str] = set()

    def unread(self) -> list[str]:
        """The keys of the file nothing has read (after :func:`positions` and every
        derivation: a misspelt or unknown key, which would otherwise be ignored silently).
        A ``{ value, source }`` entry is one key; a table's own scalars (material, finish,
        a note) are keys of their own."""
        out: list[str] = []
        stack: list[tuple[str, Any]] = [(k, v) for k, v in self.data.items()]
        while stack:
            key, node = stack.pop()
            if isinstance(node, dict) and "value" not in node:
                stack.extend((f"{key}.{k}", v) for k, v in node.items())
            elif key not in self.read and not any(fnmatch.fnmatchcase(key, k) for k in NOT_DERIVED):
                out.append(key)
        return sorted(out)

    def check_unread(self) -> None:
        """Refuse the keys nothing read (:meth:`unread`), each with a close match: one line each."""
        from twin.errors import ConfigErrors, did_you_mean

        problems = [
            ConfigError(f"unknown key{did_you_mean(key, sorted(self.read))}", source=self.source, key=key)
            for key in self.unread()
        ]
        if problems:
            raise problems[0] if len(problems) == 1 else ConfigErrors(problems)

    def entry(self, dotted: str) -> dict[str, Any]:
        self.read.add(dotted)
        node: Any = self.data
        for part in dotted.split("."):
            if not isinstance(node, dict) or part not in node:
                raise ConfigError("missing", source=self.source, key=dotted)
            node = node[part]
        if not isinstance(node, dict) or "value" not in node or "source" not in node:
            raise ConfigError("must be a table { value = ..., source = ... }", source=self.source, key=dotted)
        v = node["value"]
        why = number_problem(v, lo=0.0)
        if why is not None:
            raise ConfigError(why, source=self.source, key=dotted)
        return node

    def dim(self, dotted: str) -> float:
        return float(self.entry(dotted)["value"])

    def material(self, body: str) -> str:
        self.read.add(f"bodies.{body}.material")
        name = self.data.get("bodies", {}).get(body, {}).get("material")
        if name not in self.data.get("materials", {}):
            raise ConfigError(f"unknown material {name!r}", source=self.source, key=f"bodies.{body}.material")
        return str(name)

    def prop(self, body: str, what: str) -> float:
        """A material property (rho, c, alpha, k) of a body's material."""
        return self.dim(f"materials.{self.material(body)}.{what}")

    def h_room(self, body: str) -> float:
        """Convection + radiation coefficient of a body's exposed surface, W/(m2 K)."""
        self.read.add(f"bodies.{body}.finish")
        finish = self.data["bodies"][body].get("finish")
        if finish not in ("painted", "bare"):
            raise ConfigError(
                "finish must be 'painted' or 'bare'", source=self.source, key=f"bodies.{body}.finish"
            )
        return self.dim("surfaces.h_convection") + self.dim(f"surfaces.h_radiation_{finish}")


def load_geometry(scenarios_dir: Path) -> Geometry:
    """The geometry file of a scenarios folder."""
    path = scenarios_dir / GEOMETRY_FILE
    return Geometry(read_toml(path, str(path)), str(path))


# --- positions (base frame, Z down, origin on the base top at the pole's axis) ----------------


def positions(g: Geometry) -> dict[str, Derived]:
    """Z positions of the detecting system's points and the pole's segment lengths, m."""
    heel = g.dim("bodies.heel_block.z")
    axis = -(heel + g.dim("bodies.bearing_block.axis_height"))
    plate_bottom = axis + g.dim("bodies.t_plate.centre_to_bottom")
    frame_top = g.dim("bodies.detecting_frame.inset")
    frame_len = g.dim("bodies.detecting_frame.z")
    head = frame_top + frame_len - g.dim("bodies.sensor.length")
    clamp_fixing = head - g.dim("bodies.clamp.thickness")
    base_bottom = g.dim("bodies.base.z")
    pole_len = g.dim("bodies.long_pole.length")
    if clamp_fixing - plate_bottom > pole_len:
        raise ConfigError("the pole does not reach the clamp", source=g.source, key="bodies.long_pole.length")
    return {
        "spindle_axis_z": Derived(axis, "-(heel block z + bearing block axis_height)"),
        "t_plate_bottom_z": Derived(plate_bottom, "spindle axis + T-plate centre_to_bottom"),
        "frame_top_z": Derived(frame_top, "detecting frame inset"),
        "head_z": Derived(head, "frame inset + frame length - sensor length"),
        "pole_heel": Derived(
            -plate_bottom, "T-plate bottom to the base top (heel block and the free length under the plate)"
        ),
        "pole_base": Derived(base_bottom, "base thickness"),
        "pole_lower": Derived(clamp_fixing - base_bottom, "base bottom to the clamp's fixing on the pole"),
        "pole_below_clamp": Derived(
            pole_len - (clamp_fixing - plate_bottom), "rest of the 730 mm pole below the clamp"
        ),
        "pole_top_to_head": Derived(
            head - plate_bottom, "pole top (T-plate bottom) to the head's contact face"
        ),
    }
