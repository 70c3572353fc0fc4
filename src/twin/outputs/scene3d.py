"""The tester in 3D for ``recording.rrd``: where the error comes from, as a user scrubs the timeline.

Boxes for the base, heel block, bearing block, spindle, T-plate, long pole, clamp, detecting
frame and sensor, sized from the geometry source (``scenarios/base/tester-geometry.toml``; their
heights and the pole's and frame's lengths placed as :func:`twin.config.drawing.positions` derives
them; where along X and Y a body stands is a schematic placement, not a drawing). Over time:

* each body is coloured by its temperature rise since the start (blue = the run's lowest, red =
  its highest; the range is written in the legend);
* each body is moved along Z by its displacement from the tester's own outputs (FixtureMechanics:
  bearing block and spindle axis, T-plate bottom, pole top, clamp, sensor), exaggerated by
  :data:`EXAGGERATION` (shown in the legend);
* the radial load is an arrow onto the T-plate, its length proportional to the load;
* the spindle turns with the swing angle of the oscillation drive.

Rerun's view is Z-up; the tester's frame is Z-down (the wear direction), so heights are negated.
At most twice :data:`MAX_FRAMES` frames are kept (every n-th recorded row, n doubling as the run grows):
the 3D view shows the trend, the time-series views every sample.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import rerun as rr

    from twin.config.drawing import Geometry

__all__ = ["EXAGGERATION", "MAX_FRAMES", "ROOT", "Body", "TesterScene", "tester_scene"]

#: the 3D view's entity root
ROOT = "/tester"
#: displacements are drawn this many times larger (1 um -> 1 mm)
EXAGGERATION = 1000.0
#: the 3D view keeps between this many and twice this many frames (for a run that long)
MAX_FRAMES = 1000
#: the load arrow's length at 200 kN (the MIL test's load), m
_ARROW_M_PER_N = 0.15 / 200e3
#: colour stops of the temperature scale: cold blue, warm yellow, hot red
_STOPS = np.array([[49, 104, 189], [250, 210, 60], [215, 40, 35]], dtype=np.float64)


@dataclass(frozen=True)
class Body:
    """One box: its name, centre (m, Z up) and half sizes at the start, and the columns of its
    temperature and Z displacement (Z down, m) if the run records them."""

    name: str
    centre: tuple[float, float, float]
    half_size: tuple[float, float, float]
    temperature: str | None
    displacement: str | None


def _boxes(g: Geometry) -> list[tuple[str, tuple[float, float, float], tuple[float, float, float]]]:
    """(name, centre, half size) of each body at the start, from the geometry source."""
    from twin.config.drawing import positions

    pos = {k: v.value for k, v in positions(g).items()}
    d = g.dim
    base_z, heel_z = d("bodies.base.z"), d("bodies.heel_block.z")
    axis_up = -pos["spindle_axis_z"]
    plate_bottom_up = -pos["t_plate_bottom_z"]
    frame_top_up, frame_len = -pos["frame_top_z"], d("bodies.detecting_frame.z")
    head_up = -pos["head_z"]
    pole_len, abbe = d("bodies.long_pole.length"), d("bodies.sensor.abbe_offset")
    block_y = -(d("bodies.bearing_block.y") / 2 + d("bodies.t_plate.y") / 2 + 0.01)  # beside the T-plate
    sensor_len, clamp_t = d("bodies.sensor.length"), d("bodies.clamp.thickness")
    frame_x = abbe + d("bodies.detecting_frame.x") / 2 + 0.01
    spindle_len = d("bodies.spindle.length")
    return [
        ("base", (0.0, 0.0, -base_z / 2), (d("bodies.base.x") / 2, d("bodies.base.y") / 2, base_z / 2)),
        (
            "heel_block",
            (0.0, block_y, heel_z / 2),
            (d("bodies.heel_block.x") / 2, d("bodies.heel_block.y") / 2, heel_z / 2),
        ),
        (
            "bearing_block",
            (0.0, block_y, heel_z + d("bodies.bearing_block.z") / 2),
            (
                d("bodies.bearing_block.x") / 2,
                d("bodies.bearing_block.y") / 2,
                d("bodies.bearing_block.z") / 2,
            ),
        ),
        (
            "spindle",
            (0.0, block_y + spindle_len / 2 - d("bodies.bearing_block.y") / 2, axis_up),
            (d("bodies.spindle.diameter") / 2, spindle_len / 2, d("bodies.spindle.diameter") / 2),
        ),
        (
            "t_plate",
            (0.0, 0.0, plate_bottom_up + d("bodies.t_plate.z") / 2),
            (d("bodies.t_plate.x") / 2, d("bodies.t_plate.y") / 2, d("bodies.t_plate.z") / 2),
        ),
        (
            "long_pole",
            (0.0, 0.0, plate_bottom_up - pole_len / 2),
            (d("bodies.long_pole.diameter") / 2, d("bodies.long_pole.diameter") / 2, pole_len / 2),
        ),
        ("clamp", (abbe / 2, 0.0, head_up + clamp_t / 2), (abbe / 2 + 0.01, 0.01, clamp_t / 2)),
        (
            "detecting_frame",
            (frame_x, 0.0, frame_top_up - frame_len / 2),
            (d("bodies.detecting_frame.x") / 2, d("bodies.detecting_frame.y") / 2, frame_len / 2),
        ),
        ("sensor", (abbe, 0.0, head_up - sensor_len / 2), (0.008, 0.008, sensor_len / 2)),
    ]


#: body -> (the role of its temperature, the role of its Z displacement (Z down)): what the
#: tester's FMUs declare those outputs as (twin.fmu.catalog.roles)
_ROLES: dict[str, tuple[str, str | None]] = {
    "base": ("temperature.base", None),
    "heel_block": ("temperature.heel_block", None),
    "bearing_block": ("temperature.bearing_block", "thermal_dz.bearing_block"),
    "spindle": ("temperature.spindle", "thermal_dz.bearing_block"),
    "t_plate": ("temperature.t_plate", "z.t_plate"),
    "long_pole": ("temperature.long_pole", "z.pole_top"),
    "clamp": ("temperature.clamp", "z.clamp"),
    "detecting_frame": ("temperature.detecting_frame", "z.sensor"),
    "sensor": ("temperature.sensor", "z.sensor"),
}
#: every role the 3D view reads: the bodies', the swing angle and the radial load
ROLES = tuple(sorted({r for pair in _ROLES.values() for r in pair if r} | {"swing_angle", "radial_load"}))


def tester_scene(columns: Mapping[str, str]) -> TesterScene | None:
    """The 3D scene of a run whose recorded columns play the roles of :data:`ROLES` (role ->
    column); None when none of the bodies' does (a system that is not the tester)."""
    from twin.config.drawing import load_geometry
    from twin.config.load import default_scenario_path

    if not any(columns.get(r) for pair in _ROLES.values() for r in pair if r):
        return None
    bodies = []
    for name, centre, half in _boxes(load_geometry(default_scenario_path().parent)):
        temp, disp = _ROLES[name]
        bodies.append(Body(name, centre, half, columns.get(temp), columns.get(disp) if disp else None))
    return TesterScene(bodies, angle=columns.get("swing_angle"), load=columns.get("radial_load"))


class TesterScene:
    """Collects the 3D view's frames from the recorded rows and sends them to a recording."""

    def __init__(self, bodies: list[Body], *, angle: str | None = None, load: str | None = None) -> None:
        self.bodies = bodies
        self.angle, self.load = angle, load
        self.columns = sorted(
            {c for b in bodies for c in (b.temperature, b.displacement) if c}
            | {c for c in (angle, load) if c}
        )
        self._stride = 1
        self._seen = 0  # rows offered so far
        self._time: list[float] = []
        self._rows: dict[str, list[float]] = {c: [] for c in self.columns}

    def collect(self, time: np.ndarray, columns: Mapping[str, np.ndarray]) -> None:
        """Keep every ``stride``-th row of a block (the columns it lacks are NaN there)."""
        n = len(time)
        first = (-self._seen) % self._stride
        picked = np.arange(first, n, self._stride)
        self._seen += n
        if not picked.size:
            return
        self._time.extend(np.asarray(time, dtype=np.float64)[picked].tolist())
        for c in self.columns:
            values = columns.get(c)
            kept = (
                np.asarray(values, dtype=np.float64)[picked]
                if values is not None
                else np.full(picked.size, np.nan)
            )
            self._rows[c].extend(kept.tolist())
        if len(self._time) > 2 * MAX_FRAMES:  # every other frame goes, the stride doubles
            self._time = self._time[::2]
            for c in self.columns:
                self._rows[c] = self._rows[c][::2]
            self._stride *= 2

    @property
    def frames(self) -> int:
        return len(self._time)

    def send(self, rec: rr.RecordingStream, timeline: str) -> None:
        """Log the static boxes and legend, then every kept frame column-wise."""
        import rerun as rr

        rec.log(ROOT, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for b in self.bodies:
            rec.log(
                f"{ROOT}/{b.name}",
                rr.Boxes3D(half_sizes=[b.half_size], labels=[b.name.replace("_", " ")], fill_mode="solid"),
                static=True,
            )
        lo, hi = self._rise_range()
        rec.log(
            f"{ROOT}/legend",
            rr.TextDocument(self._legend(lo, hi), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        if not self._time:
            return
        t = np.array(self._time)
        index = [
            rr.TimeColumn(timeline, duration=np.rint(t * 1e9).astype(np.int64).astype("timedelta64[ns]"))
        ]
        for b in self.bodies:
            self._send_body(rec, index, b, lo, hi)
        if self.load is not None:
            self._send_load(rec, index)

    def _rise(self, column: str | None) -> np.ndarray:
        if column is None:
            return np.zeros(len(self._time))
        v = np.asarray(self._rows[column])
        finite = np.flatnonzero(np.isfinite(v))
        return v - v[finite[0]] if finite.size else np.zeros_like(v)

    def _rise_range(self) -> tuple[float, float]:
        rises = [self._rise(b.temperature) for b in self.bodies if b.temperature]
        values = np.concatenate(rises) if rises and self._time else np.zeros(1)
        values = values[np.isfinite(values)]
        lo, hi = (float(values.min()), float(values.max())) if values.size else (0.0, 0.0)
        return lo, max(hi, lo + 0.1)  # a flat run still gets a scale

    def _legend(self, lo: float, hi: float) -> str:
        return (
            "## The tester\n\n"
            f"* displacements (Z) drawn **x{EXAGGERATION:g}** (1 µm shows as {EXAGGERATION * 1e-6 * 1e3:g} mm)\n"
            f"* colour: temperature rise since the start, blue {lo:+.2f} K to red {hi:+.2f} K\n"
            f"* arrow: radial load ({_ARROW_M_PER_N * 1e3 * 1e3:g} mm per kN)\n"
            "* the spindle turns with the swing angle\n\n"
            "Sizes from scenarios/base/tester-geometry.toml; X/Y placement schematic."
        )

    def _send_body(self, rec: rr.RecordingStream, index: list, b: Body, lo: float, hi: float) -> None:
        import rerun as rr

        n = len(self._time)
        dz = self._rise(b.displacement) if b.displacement else np.zeros(n)
        centres = np.tile(np.asarray(b.centre, dtype=np.float64), (n, 1))
        centres[:, 2] -= np.nan_to_num(dz) * EXAGGERATION  # Z down in the tester, up in the view
        colors = _colours(self._rise(b.temperature), lo, hi)
        kwargs = {}
        if b.name == "spindle" and self.angle is not None:
            angle = np.nan_to_num(np.asarray(self._rows[self.angle]))
            kwargs["rotation_axis_angles"] = [
                rr.RotationAxisAngle(axis=[0, 1, 0], radians=float(a)) for a in angle
            ]
        rec.send_columns(
            f"{ROOT}/{b.name}",
            indexes=index,
            columns=rr.Boxes3D.columns(centers=centres, colors=colors, **kwargs),
            strict=True,
        )

    def _send_load(self, rec: rr.RecordingStream, index: list) -> None:
        import rerun as rr

        assert self.load is not None
        force = np.nan_to_num(np.asarray(self._rows[self.load]))
        plate = next(b for b in self.bodies if b.name == "t_plate")
        top = plate.centre[2] + plate.half_size[2]
        length = np.abs(force) * _ARROW_M_PER_N
        origins = np.column_stack([np.zeros_like(length), np.zeros_like(length), top + length])
        vectors = np.column_stack([np.zeros_like(length), np.zeros_like(length), -length])
        rec.send_columns(
            f"{ROOT}/radial_load",
            indexes=index,
            columns=rr.Arrows3D.columns(
                origins=origins, vectors=vectors, labels=[f"{abs(f) / 1e3:.0f} kN" for f in force]
            ),
            strict=True,
        )


def _colours(rise: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """RGBA (uint8) of each rise on the blue-yellow-red scale from ``lo`` to ``hi``."""
    x = np.clip((np.nan_to_num(rise) - lo) / (hi - lo), 0.0, 1.0) * (len(_STOPS) - 1)
    i = np.minimum(x.astype(int), len(_STOPS) - 2)
    f = (x - i)[:, None]
    rgb = _STOPS[i] * (1 - f) + _STOPS[i + 1] * f
    return np.column_stack([np.rint(rgb), np.full(len(x), 255.0)]).astype(np.uint8)
