"""The SPB tester's error model, built from the data file ``tester_topology.toml``.

Nine bodies, two branches (Li et al. 2017, Fig. 4): branch 1 base(1) -> bearing_block(2) ->
testing_spindle(3) -> spherical_plain_bearing(4) -> t_plate(5); branch 2 base(1) -> detecting_frame(6)
-> displacement_sensor(7) -> contacting_clamp(8) -> long_pole(9). Geometry, motions and their sources
are data; this module only reads and checks them.

Sign convention. Z is the wear direction, positive DOWN. The displacement-sensor reading increases
when the clamp moves down (+Z) relative to the sensor, so the reading error is
``e_z = dz(branch-1 end) - dz(branch-2 end)`` (positive: the reading increases). Example, the paper's
thermal experiment: the bearing block lifts the spindle (p_dz of bearing_block < 0) and the detecting
frame grows downward (p_dz of detecting_frame > 0), so ``e_z < 0`` and the reading falls. The long pole
hangs from its top (pressed against the T-plate), so its expansion lowers the clamp relative to the pole
top: that is ``p_dz < 0`` of long_pole (pole top relative to clamp), which partly cancels the frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.config.reader import number_problem
from twin.errormodel.model import ErrorModel, Joint
from twin.errormodel.topology import Body, Topology
from twin.errormodel.transforms import rotation_x, rotation_y, rotation_z, translation
from twin.errors import ConfigError, ConfigErrors

__all__ = [
    "DATA_FILE",
    "BodySpec",
    "BranchSpec",
    "MotionSpec",
    "TesterSpec",
    "Value",
    "load_tester_spec",
    "tester_model",
]

#: Name of the packaged data file (next to this module).
DATA_FILE = "tester_topology.toml"
#: Allowed provenance labels of a value (as in the project's reference facts).
SOURCES = frozenset({"paper", "handbook", "estimate", "derived", "calibrated"})

_ROTATIONS = {"x": rotation_x, "y": rotation_y, "z": rotation_z}


@dataclass(frozen=True)
class Value:
    """A number with its provenance (``paper``, ``handbook``, ``estimate``, ``derived``, ``calibrated``)."""

    value: float
    source: str
    note: str = ""


@dataclass(frozen=True)
class MotionSpec:
    """An ideal kinematic matrix: rotation or translation along ``axis`` by ``scale * motion[variable]``.

    Callable on a mapping of motion variables, as :class:`twin.errormodel.model.Joint` expects.
    """

    type: str
    axis: str
    variable: str
    scale: float = 1.0

    def __call__(self, motion: Mapping[str, NDArray[np.float64]]) -> NDArray[np.float64]:
        if self.variable not in motion:
            raise ConfigError(f"motion variable '{self.variable}' is missing (given: {sorted(motion)})")
        q = self.scale * np.asarray(motion[self.variable], dtype=np.float64)
        if self.type == "rotation":
            return _ROTATIONS[self.axis](q)
        xyz = {a: (q if a == self.axis else 0.0) for a in "xyz"}
        return translation(xyz["x"], xyz["y"], xyz["z"])


@dataclass(frozen=True)
class BodySpec:
    """One body of the data file: topology entry, ideal position, motion, dimensions."""

    body: Body
    position: dict[str, Value] = field(default_factory=dict)
    motion: MotionSpec | None = None
    dimensions: dict[str, Value] = field(default_factory=dict)
    note: str = ""

    def joint(self) -> Joint:
        """The body's ideal characteristic matrices ``T_ijp`` (translation) and ``T_ijs``."""
        p = {a: self.position[a].value if a in self.position else 0.0 for a in "xyz"}
        return Joint(positioning=translation(p["x"], p["y"], p["z"]), kinematic=self.motion)


@dataclass(frozen=True)
class BranchSpec:
    """A branch end: its name, end body and the point ``p_n`` in the end body's frame."""

    name: str
    end: str
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    note: str = ""


@dataclass(frozen=True)
class TesterSpec:
    """The parsed data file."""

    name: str
    reference: str
    bodies: tuple[BodySpec, ...]
    branches: tuple[BranchSpec, BranchSpec]
    motion_defaults: dict[str, float]
    source: str = DATA_FILE

    def topology(self) -> Topology:
        """The validated topology of the bodies."""
        return Topology((b.body for b in self.bodies), source=self.source)

    def body(self, name: str) -> BodySpec:
        """The spec of body ``name``."""
        for b in self.bodies:
            if b.body.name == name:
                return b
        raise ConfigError(f"unknown body {name!r}", source=self.source)

    def model(self) -> ErrorModel:
        """The ready :class:`ErrorModel` (branch 1 = first ``[[branch]]`` of the file)."""
        topology = self.topology()
        joints = {b.body.index: b.joint() for b in self.bodies if b.body.lower is not None}
        b1, b2 = self.branches
        return ErrorModel(
            topology, joints, (b1.end, b2.end), (b1.point, b2.point), motion_defaults=self.motion_defaults
        )


def _value(raw: Any, key: str, problems: list[ConfigError], source: str) -> Value | None:
    if not isinstance(raw, dict) or "value" not in raw or "source" not in raw:
        problems.append(ConfigError("must be a table { value = ..., source = ... }", source=source, key=key))
        return None
    v, src = raw["value"], raw["source"]
    why = number_problem(v)
    if why is not None:
        problems.append(ConfigError(f"value: {why}", source=source, key=key))
        return None
    if src not in SOURCES:
        problems.append(
            ConfigError(f"source must be one of {sorted(SOURCES)}, got {src!r}", source=source, key=key)
        )
        return None
    return Value(float(v), src, str(raw.get("note", "")))


def _body(raw: Any, i: int, problems: list[ConfigError], source: str) -> BodySpec | None:
    key = f"body[{i}]"
    if (
        not isinstance(raw, dict)
        or not isinstance(raw.get("index"), int)
        or not isinstance(raw.get("name"), str)
    ):
        problems.append(ConfigError("needs an integer 'index' and a string 'name'", source=source, key=key))
        return None
    lower = raw.get("lower")
    if lower is not None and (isinstance(lower, bool) or not isinstance(lower, int)):
        problems.append(ConfigError(f"'lower' must be a body index, got {lower!r}", source=source, key=key))
        return None
    unknown = set(raw) - {"index", "name", "lower", "note", "position", "motion", "dimensions"}
    if unknown:
        problems.append(ConfigError(f"unknown keys {sorted(unknown)}", source=source, key=key))
    position: dict[str, Value] = {}
    for axis, v in raw.get("position", {}).items():
        if axis not in "xyz" or len(axis) != 1:
            problems.append(
                ConfigError(f"position axis must be x, y or z, got {axis!r}", source=source, key=key)
            )
        elif (val := _value(v, f"{key}.position.{axis}", problems, source)) is not None:
            position[axis] = val
    dimensions = {
        name: val
        for name, v in raw.get("dimensions", {}).items()
        if (val := _value(v, f"{key}.dimensions.{name}", problems, source)) is not None
    }
    motion = None
    if "motion" in raw:
        m = raw["motion"]
        ok = (
            isinstance(m, dict)
            and m.get("type") in ("rotation", "translation")
            and m.get("axis") in ("x", "y", "z")
            and isinstance(m.get("variable"), str)
            and isinstance(m.get("scale", 1.0), int | float)
        )
        if not ok:
            problems.append(
                ConfigError(
                    "motion must be { type = rotation|translation, axis = x|y|z, variable = NAME, scale = S }",
                    source=source,
                    key=f"{key}.motion",
                )
            )
        else:
            motion = MotionSpec(m["type"], m["axis"], m["variable"], float(m.get("scale", 1.0)))
    return BodySpec(
        Body(raw["index"], raw["name"], lower), position, motion, dimensions, str(raw.get("note", ""))
    )


def _parse(data: dict[str, Any], source: str) -> TesterSpec:
    problems: list[ConfigError] = []
    model = data.get("model", {})
    bodies = [
        b for i, raw in enumerate(data.get("body", [])) if (b := _body(raw, i, problems, source)) is not None
    ]
    branches = []
    raw_branches = data.get("branch", [])
    if len(raw_branches) != 2:
        problems.append(
            ConfigError(f"exactly two [[branch]] tables needed, got {len(raw_branches)}", source=source)
        )
    for i, raw in enumerate(raw_branches):
        point = raw.get("point", [0.0, 0.0, 0.0])
        if not isinstance(raw.get("end"), str) or not (
            isinstance(point, list) and len(point) == 3 and all(isinstance(c, int | float) for c in point)
        ):
            problems.append(
                ConfigError(
                    "needs 'end' (a body name) and 'point' = [x, y, z]", source=source, key=f"branch[{i}]"
                )
            )
            continue
        branches.append(
            BranchSpec(
                str(raw.get("name", f"branch {i + 1}")),
                raw["end"],
                (float(point[0]), float(point[1]), float(point[2])),
                str(raw.get("note", "")),
            )
        )
    defaults = model.get("motion_defaults", {})
    if not isinstance(defaults, dict) or not all(isinstance(v, int | float) for v in defaults.values()):
        problems.append(
            ConfigError(
                "must map motion variable names to numbers", source=source, key="model.motion_defaults"
            )
        )
        defaults = {}
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)
    spec = TesterSpec(
        name=str(model.get("name", "")),
        reference=str(model.get("reference", "")),
        bodies=tuple(bodies),
        branches=(branches[0], branches[1]),
        motion_defaults={k: float(v) for k, v in defaults.items()},
        source=source,
    )
    spec.model()  # validates the topology, the branch ends and the matrices now, not at first use
    return spec


@cache
def _packaged_spec() -> TesterSpec:
    from twin.config.reader import parse_toml

    text = resources.files("twin.errormodel").joinpath(DATA_FILE).read_text(encoding="utf-8")
    return _parse(parse_toml(text, DATA_FILE), DATA_FILE)


def load_tester_spec(path: str | Path | None = None) -> TesterSpec:
    """Read and check a tester topology file; ``None`` reads the packaged ``tester_topology.toml``.

    Problems raise :class:`twin.errors.ConfigError` (several at once as ``ConfigErrors``).
    """
    if path is None:
        return _packaged_spec()
    from twin.config.reader import read_toml  # the one reader of a user's TOML files

    path = Path(path)
    return _parse(read_toml(path, str(path)), str(path))


def tester_model(path: str | Path | None = None) -> ErrorModel:
    """The tester's ready :class:`ErrorModel` (bodies named as in the data file, motion ``angle``);
    the packaged tester's is made once per process and shared (a model is not changed by use)."""
    if path is None:
        return _packaged_model()
    return load_tester_spec(path).model()


@cache
def _packaged_model() -> ErrorModel:
    return _packaged_spec().model()


# pytest collects module-level callables named test*; "tester_model" imported into a test module would
# be run as a test. Tell pytest it is not one.
tester_model.__test__ = False  # type: ignore[attr-defined]
