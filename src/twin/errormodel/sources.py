"""Error sources: from measured streams to the error parameters of the tester's bodies.

The comprehensive error model needs, per body, its small-error parameters (dx .. ez of the
positioning and kinematic error characteristic matrices dT_ijp, dT_ijs). Each of the paper's
five error factors (declared in :mod:`twin.errormodel.factors`) maps measured quantities to
some of them:

- thermal dE_T: ``alpha * L * dT`` of every body from the eight temperature sensors, plus the
  probe's own zero drift with temperature (body 7): :func:`thermal_errors`;
- loading dE_F: the load cell times the loading chain's compliance: :func:`loading_errors`;
- fluctuating dE_V: the spindle's runout against the angle encoder, the vibration pickup:
  :func:`fluctuating_errors`;
- positioning dE_G: the probe's tilt (cosine error) and the T-plate's rotation by the friction
  torque at the Abbe offset: :func:`positioning_errors`;
- interference dE_I: no body moves; :func:`hampel` separates the spikes from the reading.

:class:`Columns` says which column of a table holds each of those streams.

Only measured streams are used (the temperature sensors' readings, never the FMUs' node
temperatures), so the same code runs on a lab's CSV of real measurements.

Sign convention (Z down, the paper's): a body's ``p_dz`` moves the next body of its branch
down. Branch 1 bodies enter e_z with +1, branch 2 bodies with -1, so for branch 2 a growth
that moves the clamp's contact face down (pole, clamp) is a negative ``p_dz`` of that body.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from twin.errors import ConfigError

#: default measured columns of the twin; a lab maps its own CSV columns instead
DEFAULT_TEMPERATURES: dict[str, str] = {
    "bearing_block": "sensors.t_bearing_block_meas",
    "heel_block": "sensors.t_heel_block_meas",
    "bearing": "sensors.t_bearing_meas",
    "t_plate": "sensors.t_t_plate_meas",
    "base": "sensors.t_base_meas",
    "long_pole": "sensors.t_long_pole_meas",
    "detecting_frame": "sensors.t_detecting_frame_meas",
    "room": "sensors.t_room_meas",
}
DEFAULT_READING = "sensors.probe_meas"
DEFAULT_LOAD = "sensors.load_meas"
DEFAULT_TORQUE = "sensors.torque_meas"
DEFAULT_ANGLE = "sensors.angle_meas"
DEFAULT_VIBRATION = "sensors.vibration_meas"
DEFAULT_TRUE_WEAR = "mechanics.wear_depth_true"


@dataclass(frozen=True)
class Columns:
    """Which column of the signal table holds each measured stream (a lab maps its own names).

    Every field is a column name (``temperatures`` one per measuring point; ``true_wear`` is
    ``None`` for measurements without a known wear). The error factors name the fields they
    read (:mod:`twin.errormodel.factors`), so a field is declared here once and a factor
    refers to it by name.
    """

    temperatures: Mapping[str, str] = field(default_factory=lambda: dict(DEFAULT_TEMPERATURES))
    reading: str = DEFAULT_READING
    load: str = DEFAULT_LOAD
    torque: str = DEFAULT_TORQUE
    angle: str = DEFAULT_ANGLE
    vibration: str = DEFAULT_VIBRATION
    true_wear: str | None = DEFAULT_TRUE_WEAR

    def names(self, field_name: str) -> tuple[str, ...]:
        """The column name(s) field ``field_name`` holds: all eight temperatures, one, or none."""
        value = getattr(self, field_name)
        if value is None:
            return ()
        if isinstance(value, Mapping):
            return tuple(value.values())
        return (value,)


#: the fields of :class:`Columns`, in their declared order
COLUMN_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(Columns))


@dataclass(frozen=True)
class ThermalGeometry:
    """Expansion coefficients (1/K), effective lengths (m) and the probe's zero drift (m/K).

    The names are those of the FixtureMechanics and SensorsDAQ parameters, whose
    modelDescription.xml says where each value comes from (handbook, estimate, or calibrated
    to the paper's FEM part results).
    """

    alpha_cast_iron: float
    alpha_steel: float
    alpha_bearing_steel: float
    h_heel_block: float
    h_bearing_block: float
    r_spindle: float
    t_bearing_rings: float
    l_t_plate: float
    l_detecting_frame: float
    l_pole_heel: float
    l_pole_base: float
    l_pole_lower: float
    l_clamp: float
    probe_zero_drift: float

    @classmethod
    def from_parameters(cls, values: Mapping[str, float], *, source: str = "errormodel") -> ThermalGeometry:
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise ConfigError(f"missing geometry value(s): {', '.join(missing)}", source=source)
        return cls(**{f.name: float(values[f.name]) for f in fields(cls)})


def thermal_errors(rises: Mapping[str, np.ndarray], g: ThermalGeometry) -> dict[str, dict[str, np.ndarray]]:
    """Body error parameters (``p_dz``) of the thermal factor from temperature rises (K).

    ``rises`` holds one array per measuring point (keys of :data:`DEFAULT_TEMPERATURES`).
    Unmeasured parts take the nearest sensor: the spindle the bearing's, the pole inside the
    heel block and the base those bodies', the clamp the lower pole's, the probe body the
    detecting frame's (it is fixed on it).
    """
    r = rises
    return {
        # branch 1: heel + bearing block lift the spindle axis (up = -Z)
        "bearing_block": {
            "p_dz": -g.alpha_cast_iron
            * (g.h_heel_block * r["heel_block"] + g.h_bearing_block * r["bearing_block"])
        },
        "testing_spindle": {"p_dz": g.alpha_steel * g.r_spindle * r["bearing"]},
        "spherical_plain_bearing": {"p_dz": g.alpha_bearing_steel * g.t_bearing_rings * r["bearing"]},
        "t_plate": {"p_dz": g.alpha_steel * g.l_t_plate * r["t_plate"]},
        # branch 2: the frame hangs from the base and grows down
        "detecting_frame": {"p_dz": g.alpha_steel * g.l_detecting_frame * r["detecting_frame"]},
        # the probe's zero drift raises the reading by k*dT, as if its body had moved up
        "displacement_sensor": {"p_dz": -g.probe_zero_drift * r["detecting_frame"]},
        # clamp and pole grow down from the pole's top: the contact face goes down
        "contacting_clamp": {"p_dz": -g.alpha_steel * g.l_clamp * r["long_pole"]},
        "long_pole": {
            "p_dz": -g.alpha_steel
            * (g.l_pole_heel * r["heel_block"] + g.l_pole_base * r["base"] + g.l_pole_lower * r["long_pole"])
        },
    }


# ----------------------------------------------------------------------------- the other factors


@dataclass(frozen=True)
class MechanicalCoefficients:
    """What a lab identifies once on its tester (static load test, runout and alignment check).

    Names as the FixtureMechanics parameters.
    """

    liner_thickness: float
    liner_modulus: float
    contact_area: float
    compliance_structure: float
    spindle_runout: float
    runout_phase: float
    sensor_tilt: float
    abbe_offset: float
    tplate_rotation_compliance: float

    @classmethod
    def from_parameters(
        cls, values: Mapping[str, float], *, source: str = "errormodel"
    ) -> MechanicalCoefficients:
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise ConfigError(f"missing coefficient(s): {', '.join(missing)}", source=source)
        return cls(**{f.name: float(values[f.name]) for f in fields(cls)})

    @property
    def load_compliance(self) -> float:
        """m/N: liner compression (thickness / (modulus * area)) plus the structure."""
        return self.liner_thickness / (self.liner_modulus * self.contact_area) + self.compliance_structure


def loading_errors(load_change: np.ndarray, c: MechanicalCoefficients) -> dict[str, dict[str, np.ndarray]]:
    """Loading dE_F: the measured load change compresses liner and structure (T-plate down)."""
    return {"spherical_plain_bearing": {"p_dz": c.load_compliance * load_change}}


def fluctuating_errors(
    angle: np.ndarray | None, angle0: float, vibration: np.ndarray | None, c: MechanicalCoefficients
) -> dict[str, dict[str, np.ndarray]]:
    """Fluctuating dE_V: spindle runout against the encoder's angle (a kinematic error of the
    spindle), and the fixture's vibration as the vibration pickup measures it."""
    out: dict[str, dict[str, np.ndarray]] = {}
    if angle is not None:
        phase = c.runout_phase
        runout = c.spindle_runout * (np.cos(angle - phase) - np.cos(angle0 - phase))
        out["testing_spindle"] = {"s_dz": runout}
    if vibration is not None:
        out["t_plate"] = {"s_dz": vibration}
    return out


def positioning_errors(
    reading_change: np.ndarray, torque_change: np.ndarray | None, c: MechanicalCoefficients
) -> dict[str, dict[str, np.ndarray]]:
    """Positioning dE_G: the probe's axis tilted from Z reads motion times cos(tilt) (cosine
    error, second order in the tilt, so it is given explicitly rather than left to the
    first-order MBS form), and the T-plate's rotation by the friction torque moves the clamp
    by the Abbe offset times the angle. Both act at the sensor (body 7, branch 2: sign -1)."""
    cosine = -(1.0 - np.cos(c.sensor_tilt)) / np.cos(c.sensor_tilt) * reading_change
    abbe = (
        0.0
        if torque_change is None
        else c.abbe_offset * c.tplate_rotation_compliance * torque_change * np.cos(c.sensor_tilt)
    )
    return {"displacement_sensor": {"p_dz": -(cosine + abbe)}}


def hampel(
    x: np.ndarray, half_window: int = 10, n_sigmas: float = 5.0, min_deviation: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """Robust spike filter (Hampel): samples further from the moving median than ``n_sigmas``
    robust deviations (1.4826 MAD), and at least ``min_deviation``, are replaced by the median.

    The floor keeps a quantized, nearly noise-free stretch (MAD = 0) from being flagged sample
    by sample. Returns (cleaned, is_spike).
    """
    from scipy.ndimage import median_filter

    size = 2 * half_window + 1
    med = median_filter(x, size=size, mode="nearest")
    mad = median_filter(np.abs(x - med), size=size, mode="nearest")
    threshold = np.maximum(n_sigmas * 1.4826 * mad, min_deviation)
    spikes = np.abs(x - med) > threshold
    return np.where(spikes, med, x), spikes
