"""Error sources: from measured streams to the error parameters of the tester's bodies.

The comprehensive error model needs, per body, its small-error parameters (dx .. ez of the
positioning and kinematic error characteristic matrices dT_ijp, dT_ijs). Each of the paper's
five error factors (declared in :mod:`twin.errormodel.factors`) maps measured quantities to
some of them:

- thermal dE_T: ``alpha * L * dT`` of every body from the eight temperature sensors, plus the
  probe's own zero and span drift with temperature (body 7): :func:`thermal_errors`;
- loading dE_F: the load cell times the loading chain's compliance, and the liner's creep under
  the load held, a discrete retardation spectrum over the load's history
  (:class:`LoadHistory`): :func:`loading_errors`;
- fluctuating dE_V: the spindle's runout against the angle encoder, the vibration pickup:
  :func:`fluctuating_errors`;
- positioning dE_G: the probe's tilt (cosine error) and the T-plate's rotation by the friction
  torque at the Abbe offset: :func:`positioning_errors`;
- interference dE_I: no body moves; :func:`hampel` separates the spikes from the reading.

:class:`Columns` says which column of a table holds each of those streams;
:class:`ThermalCoefficients` and :class:`MechanicalCoefficients` declare the coefficients the
factors need, each with its unit. Their values come from a coefficients file
(:mod:`twin.errormodel.coefficients`) that ``twin identify`` fits to calibration experiments,
never from the FMUs' parameters.

Only measured streams are used (the temperature sensors' readings, never the FMUs' node
temperatures), so the same code runs on a lab's CSV of real measurements.

Sign convention (Z down, the paper's): a body's ``p_dz`` moves the next body of its branch
down. Branch 1 bodies enter e_z with +1, branch 2 bodies with -1, so for branch 2 a growth
that moves the clamp's contact face down (pole, clamp) is a negative ``p_dz`` of that body.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any, Self

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
#: measuring points a tester may add to the paper's eight: a thermometer on the probe's body
#: (the probe-heating bench has one; on the tester it lets the probe's drifts read their own
#: temperature instead of the frame's bottom)
EXTRA_TEMPERATURES: dict[str, str] = {"probe_body": "sensors.t_probe_body_meas"}
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


def _declare(unit: str, meaning: str) -> Any:
    """A coefficient's field: its unit (a coefficients file must state the same) and meaning."""
    return field(metadata={"unit": unit, "meaning": meaning})


@dataclass(frozen=True)
class _Coefficients:
    """Named coefficients, each a float declared with :func:`_declare`."""

    @classmethod
    def units(cls) -> dict[str, str]:
        """The unit of every coefficient, by name, in the declared order."""
        return {f.name: f.metadata["unit"] for f in fields(cls)}

    @classmethod
    def meanings(cls) -> dict[str, str]:
        """What every coefficient is, by name."""
        return {f.name: f.metadata["meaning"] for f in fields(cls)}

    @classmethod
    def from_values(cls, values: Mapping[str, float], *, source: str = "errormodel") -> Self:
        """From a mapping holding at least every coefficient of the class (others are ignored)."""
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise ConfigError(f"missing coefficient(s): {', '.join(missing)}", source=source)
        return cls(**{f.name: float(values[f.name]) for f in fields(cls)})


@dataclass(frozen=True)
class ThermalCoefficients(_Coefficients):
    """The thermal factor's coefficients: the effective alpha * L (m/K) of each body's growth,
    per measured temperature it is driven by, and the probe's zero (m/K) and span (1/K) drift.

    They are what a thermal soak identifies (``twin identify``), never the FMUs' parameters: an
    effective coefficient lumps the material's expansion, the length that grows and how far the
    body's mean temperature follows the sensor that stands for it. The probe's two drifts come
    from the probe heated alone (``probe-heating.toml``): on the tester they multiply the frame's
    thermometer with the frame's and the probe body's growth, so no soak tells them apart.
    """

    @classmethod
    def growths(cls) -> tuple[str, ...]:
        """The alpha * L coefficients (a body's growth: never negative), in the declared order."""
        return tuple(n for n in cls.units() if n.startswith("alpha_l_"))

    # fmt: off
    alpha_l_heel_block: float = _declare("m/K", "heel block's growth lifting the spindle, per K of the heel block")
    alpha_l_bearing_block: float = _declare("m/K", "bearing block's growth lifting the spindle, per K of the bearing block")
    alpha_l_spindle: float = _declare("m/K", "spindle radius' growth under the bearing, per K of the bearing")
    alpha_l_bearing_rings: float = _declare("m/K", "bearing rings' radial growth, per K of the bearing")
    alpha_l_t_plate: float = _declare("m/K", "T-plate's growth below the outer ring, per K of the T-plate")
    alpha_l_base_inset: float = _declare("m/K", "base's growth between its top and the frame's fixing face inset in it, lowering the frame, per K of the base")
    alpha_l_detecting_frame: float = _declare("m/K", "detecting frame's growth lowering the probe, per K of the frame")
    alpha_l_probe_body: float = _declare("m/K", "probe body's growth lifting its tip, per K of the frame it is fixed on")
    probe_zero_drift: float = _declare("m/K", "probe reading's zero drift, per K of its body (in operation the frame's thermometer it is fixed on stands in)")
    probe_span_drift: float = _declare("1/K", "probe reading's span (gain) drift, per K of its body, times its reading (in operation the frame's thermometer stands in)")
    alpha_l_clamp: float = _declare("m/K", "clamp's growth down to the probe head, per K of the long pole")
    alpha_l_pole_heel: float = _declare("m/K", "long pole's growth inside the heel block, per K of the heel block")
    alpha_l_pole_base: float = _declare("m/K", "long pole's growth inside the base, per K of the base")
    alpha_l_pole_lower: float = _declare("m/K", "long pole's growth below the base, per K of the long pole")
    # fmt: on


def thermal_errors(
    rises: Mapping[str, np.ndarray], g: ThermalCoefficients, reading: np.ndarray | float = 0.0
) -> dict[str, dict[str, np.ndarray]]:
    """Body error parameters (``p_dz``) of the thermal factor from temperature rises (K).

    ``rises`` holds one array per measuring point (keys of :data:`DEFAULT_TEMPERATURES`) and,
    where a thermometer sits on the probe's body (the probe-heating calibration), ``probe_body``.
    Unmeasured parts take the nearest sensor: the spindle the bearing's, the pole inside the
    heel block and the base those bodies', the clamp the lower pole's, the probe body the
    detecting frame's (it is fixed on it); the probe's drifts take ``probe_body`` where it is
    measured, else the frame's. ``reading`` (m, the probe's reading: its position in its range)
    is what the span drift scales.

    The loop closes as drawn (``tester_topology.toml``): from the base top, branch 1 and the
    pole reach the clamp's contact face by the same Z as branch 2 through the base's inset, the
    frame and the probe's body, so coefficients of one alpha times the drawn lengths predict no
    error for a uniform rise.
    """
    r = rises
    probe = r.get("probe_body", r["detecting_frame"])
    return {
        # branch 1: heel + bearing block lift the spindle axis (up = -Z)
        "bearing_block": {
            "p_dz": -(g.alpha_l_heel_block * r["heel_block"] + g.alpha_l_bearing_block * r["bearing_block"])
        },
        "testing_spindle": {"p_dz": g.alpha_l_spindle * r["bearing"]},
        "spherical_plain_bearing": {"p_dz": g.alpha_l_bearing_rings * r["bearing"]},
        "t_plate": {"p_dz": g.alpha_l_t_plate * r["t_plate"]},
        # branch 2: the frame hangs from a face inset in the base (the base's growth over the
        # inset lowers it) and grows down
        "detecting_frame": {
            "p_dz": g.alpha_l_base_inset * r["base"] + g.alpha_l_detecting_frame * r["detecting_frame"]
        },
        # the probe's body grows up from its fixing to its tip; its zero and span drift raise
        # the reading by (k + s x) dT, as if its body had moved up
        "displacement_sensor": {
            "p_dz": -(
                g.alpha_l_probe_body * r["detecting_frame"]
                + (g.probe_zero_drift + g.probe_span_drift * np.asarray(reading)) * probe
            )
        },
        # clamp and pole grow down from the pole's top: the contact face goes down
        "contacting_clamp": {"p_dz": -g.alpha_l_clamp * r["long_pole"]},
        "long_pole": {
            "p_dz": -(
                g.alpha_l_pole_heel * r["heel_block"]
                + g.alpha_l_pole_base * r["base"]
                + g.alpha_l_pole_lower * r["long_pole"]
            )
        },
    }


# ----------------------------------------------------------------------------- the other factors


@dataclass(frozen=True)
class MechanicalCoefficients(_Coefficients):
    """What a lab identifies once on its tester: static load steps (the loading chain's
    compliance) and a static load hold (the liner's creep spectrum), gauge blocks (the probe's
    scale), a runout check and a slow oscillation under a light load (the friction torque's
    Abbe effect); see ``twin identify``.

    Each is the combination an experiment determines, not the parts it is made of: the liner's
    and the structure's compliance add, and the probe's tilt shows only as the cosine that
    scales its reading. The friction torque's effect is identified as a rotation (the T-plate
    turning, with the pole and the clamp on it, against its anti-rotation arm); the Abbe offset
    it acts at is the characteristic matrices' lever (the sensor 45 mm beside the pole in
    ``tester_topology.toml``), not a fitted number.
    """

    # fmt: off
    load_compliance: float = _declare("m/N", "T-plate's drop per N of radial load (liner and structure)")
    spindle_runout: float = _declare("m", "amplitude of the spindle's runout at the bearing")
    runout_phase: float = _declare("rad", "spindle angle of the runout's high point")
    probe_scale: float = _declare("1", "probe reading per unit motion along Z: cos of its axis' tilt")
    clamp_rotation: float = _declare("rad/(N.m)", "rotation about Y of the T-plate, long pole and clamp per N.m of friction torque (its sign: the torque sensor's positive sense)")
    creep_compliance_15min: float = _declare("m/N", "liner's creep per N of load held, retardation time 15 min")
    creep_compliance_1h: float = _declare("m/N", "liner's creep per N of load held, retardation time 1 h")
    creep_compliance_4h: float = _declare("m/N", "liner's creep per N of load held, retardation time 4 h")
    creep_compliance_16h: float = _declare("m/N", "liner's creep per N of load held, retardation time 16 h")
    # fmt: on

    def creep_compliances(self) -> np.ndarray:
        """The retardation spectrum's compliances, in the order of :data:`RETARDATION_TIMES_S`."""
        return np.array([getattr(self, name) for name in CREEP_COEFFICIENTS])


#: The liner's creep compliance as a lab models a polymer's: a discrete retardation spectrum
#: J(t) = sum_k J_k (1 - exp(-t / tau_k)) at fixed times a factor 4 apart (a generalised
#: Kelvin-Voigt body, Ferry 1980 ch. 3; the times cover a 10 h hold and a 2-day test), each J_k
#: >= 0 fitted by ``twin identify`` on a static load hold (scenarios/calibration/load-hold.toml).
#: Nothing in the times comes from the tester: they are a grid, not a fitted time constant.
RETARDATION_TIMES_S: tuple[float, ...] = (900.0, 3600.0, 14400.0, 57600.0)
#: the coefficients of :data:`RETARDATION_TIMES_S`, in that order
CREEP_COEFFICIENTS: tuple[str, ...] = (
    "creep_compliance_15min",
    "creep_compliance_1h",
    "creep_compliance_4h",
    "creep_compliance_16h",
)


class LoadHistory:
    """The load's history as the creep spectrum sees it: for each retardation time tau_k the
    load through a first-order lag, h_k' = (F - h_k) / tau_k, exact for the load held between
    samples (the DAQ's sample and hold: over each interval the load sampled at its start), and
    h_k = 0 at the record's first sample (the probe is zeroed with the load just applied:
    creep starts at the zero).

    Boltzmann superposition then gives the creep as sum_k J_k h_k(t) for any load history.
    The recursion h[n] = a_n h[n-1] + (1 - a_n) F[n-1], a_n = exp(-dt_n / tau), runs as numpy
    scans over blocks of one tau of record time each (sample n is in block floor((t_n - t_0) /
    tau)): a block's first sample takes the recursion's step from the value before it (however
    long the gap before it), the rest h[n] = A_n (h_f + sum_i (1 - a_i) F_i / A_i) with A_n the
    product of the a_i since the first, which stays above exp(-1), so the scan loses no
    precision. The blocks depend on the samples' times alone: fed in chunks (:meth:`feed`), the
    block's running product and sum carried over, it gives the same numbers bit for bit as the
    whole record at once, so the streamed error model (:mod:`~twin.errormodel.streaming`)
    equals the whole one.
    """

    def __init__(self, times_s: tuple[float, ...] = RETARDATION_TIMES_S) -> None:
        self.taus = np.asarray(times_s, dtype=float)
        self._t0: float | None = None  # the record's first time
        self._last: tuple[float, float] | None = None  # time and load of the last sample
        # per tau: the block's first value, running product and sum, the last value, its block
        self._carry = np.zeros((len(self.taus), 5))
        self._carry[:, 1] = 1.0

    def feed(self, time: np.ndarray, load: np.ndarray) -> np.ndarray:
        """h_k at each of these samples (shape (K, n)), following on from those fed before."""
        n = len(time)
        out = np.zeros((len(self.taus), n))
        if n == 0:
            return out
        first = 0
        if self._last is None:  # the record's first sample: h = 0, block 0 starts with it
            self._t0 = float(time[0])
            self._last, first = (float(time[0]), float(load[0])), 1
            if n == 1:
                return out
        assert self._t0 is not None
        t_prev, f_prev = self._last
        t = time[first:]
        dt = np.diff(np.r_[t_prev, t])
        f_held = np.r_[f_prev, load[first:-1]]
        for k, tau in enumerate(self.taus):
            a = np.exp(-dt / tau)
            block = np.floor((t - self._t0) / tau)
            out[k, first:] = self._scan(k, a, (1.0 - a) * f_held, block)
        self._last = (float(time[-1]), float(load[-1]))
        return out

    def _scan(self, k: int, a: np.ndarray, bx: np.ndarray, block: np.ndarray) -> np.ndarray:
        """One tau's values at these samples, block by block, the block's state carried."""
        h0, prod, acc, last, current = self._carry[k]
        starts = block != np.r_[current, block[:-1]]
        cuts = [*np.flatnonzero(starts), len(a)]
        if cuts[0] != 0:
            cuts.insert(0, 0)
        y = np.empty(len(a))
        for lo, hi in itertools.pairwise(cuts):
            rest = lo
            if starts[lo]:  # the block's first sample: one step of the recursion
                h0 = a[lo] * last + bx[lo]
                y[lo], prod, acc, rest = h0, 1.0, 0.0, lo + 1
            if hi > rest:
                p = np.multiply.accumulate(np.r_[prod, a[rest:hi]])[1:]
                s = np.add.accumulate(np.r_[acc, bx[rest:hi] / p])[1:]
                y[rest:hi] = p * (h0 + s)
                prod, acc = float(p[-1]), float(s[-1])
            last = float(y[hi - 1])
        self._carry[k] = (h0, prod, acc, last, block[-1])
        return y


def load_history(time: np.ndarray, load: np.ndarray) -> np.ndarray:
    """:class:`LoadHistory` of a whole record."""
    return LoadHistory().feed(np.asarray(time, dtype=float), np.asarray(load, dtype=float))


def loading_errors(
    load_change: np.ndarray, c: MechanicalCoefficients, history: np.ndarray | None = None
) -> dict[str, dict[str, np.ndarray]]:
    """Loading dE_F: the measured load change compresses liner and structure (T-plate down),
    and with the load's ``history`` (:class:`LoadHistory`) the liner creeps, sum_k J_k h_k."""
    dz = c.load_compliance * load_change
    if history is not None:
        # term by term, not a matrix product: BLAS may sum in another order for another row
        # count, and a streamed record must give the whole record's numbers bit for bit
        for j_k, h_k in zip(c.creep_compliances().tolist(), history, strict=True):
            dz = dz + j_k * h_k
    return {"spherical_plain_bearing": {"p_dz": dz}}


def fluctuating_errors(
    angle: np.ndarray | None,
    angle0: float | np.ndarray,
    vibration: np.ndarray | None,
    c: MechanicalCoefficients,
) -> dict[str, dict[str, np.ndarray]]:
    """Fluctuating dE_V: spindle runout against the encoder's angle (a kinematic error of the
    spindle) from its start ``angle0`` (records stacked: each row's record's), and the
    fixture's vibration as the vibration pickup measures it."""
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
    """Positioning dE_G: the probe's axis tilted from Z reads motion times cos(tilt), its
    ``probe_scale`` (cosine error, second order in the tilt, so it is given explicitly rather
    than left to the first-order MBS form: a translation error of the sensor, body 7), and the
    friction torque turns the T-plate, with the long pole and the contacting clamp on it, by
    ``clamp_rotation`` per N.m: a rotation error about Y of the clamp relative to the sensor
    (body 8's dT_ijp, ``p_ey``), read through the same cosine. The characteristic matrices turn
    that rotation into Z at the lever between the probe's axis and the pole's (the Abbe
    offset of the topology's drawing)."""
    cosine = -(1.0 - c.probe_scale) / c.probe_scale * reading_change
    out: dict[str, dict[str, np.ndarray]] = {"displacement_sensor": {"p_dz": -cosine}}
    if torque_change is not None:
        out["contacting_clamp"] = {"p_ey": c.clamp_rotation * torque_change * c.probe_scale}
    return out


def hampel(
    x: np.ndarray, half_window: int = 10, n_sigmas: float = 5.0, min_deviation: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """Robust spike filter (Hampel): samples further from the moving median than ``n_sigmas``
    robust deviations (1.4826 MAD), and at least ``min_deviation``, are replaced by the median.

    The floor keeps a quantized, nearly noise-free stretch (MAD = 0) from being flagged sample
    by sample. The windows are ``2 half_window + 1`` samples, the ends padded with the end
    values (scipy's ``mode="nearest"``). Returns (cleaned, is_spike).

    A sample whose window spans no more than the floor (its largest minus its smallest value)
    cannot be that far from the window's median, whatever the MAD: the medians are taken only
    around the samples whose windows span more (:func:`_quiet`), the same numbers as taking
    every one, for a fraction of the work on a slow reading (the probe's, sampled every few
    seconds: a spike or a step makes a few windows span more than a micrometre).
    """
    x = np.asarray(x)
    w = 2 * half_window + 1
    # a stream of a few windows (a Monte Carlo sample's 104 rows): every window's median costs
    # less than looking for the quiet ones first, which most such streams are not
    if x.ndim != 1 or x.dtype != np.float64 or half_window <= 0 or x.size <= _SHORT_WINDOWS * w:
        return _hampel_everywhere(x, half_window, n_sigmas, min_deviation)
    n = x.size
    # the blocks of w padded samples side by side, a block more on the right than the windows
    # reach (the last window's pair of blocks is there to take)
    padded = _edge_padded(x, half_window, -(n + 2 * half_window) % w + half_window + w)
    loud = np.flatnonzero(~_quiet(padded.reshape(-1, w), min_deviation)) * w
    if len(loud) * w * 4 > n:  # most windows span more: the medians of every window
        return _hampel_everywhere(x, half_window, n_sigmas, min_deviation)
    # the loud samples (whole blocks of them), and every sample their windows reach
    rows = (loud[:, None] + np.arange(w)).ravel()
    rows = rows[rows < n]
    reached = np.zeros(n, dtype=bool)
    reached[np.clip(loud[:, None] + np.arange(-half_window, w + half_window), 0, n - 1)] = True
    reached = np.flatnonzero(reached)
    med = x.copy()  # a quiet sample's median is never read: it stays itself (not a spike)
    med[reached] = _medians(padded, half_window, reached)
    deviation = np.abs(x - med)
    mad = _medians(_edge_padded(deviation, half_window, half_window), half_window, rows)
    spikes = np.zeros(n, dtype=bool)
    spikes[rows] = deviation[rows] > np.maximum(n_sigmas * 1.4826 * mad, min_deviation)
    return np.where(spikes, med, x), spikes


#: a stream of at most this many windows' length takes every window's median at once
#: (:func:`hampel`): at 104 rows that is 0.8 of the time of looking for the quiet windows first
#: for a loud stream and 0.9 for a quiet one; at 300 rows the quiet stream already gains
_SHORT_WINDOWS = 8


def _hampel_everywhere(
    x: np.ndarray, half_window: int, n_sigmas: float, min_deviation: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hampel` with the medians of every window."""
    med = moving_median(x, half_window)
    deviation = np.abs(x - med)
    mad = moving_median(deviation, half_window)
    threshold = np.maximum(n_sigmas * 1.4826 * mad, min_deviation)
    spikes = deviation > threshold
    return np.where(spikes, med, x), spikes


def _quiet(blocks: np.ndarray, floor: float) -> np.ndarray:
    """Per block of ``w`` samples of a padded stream (``blocks``, one per row) but the last:
    whether every window of ``w`` that starts in it surely spans no more than ``floor``.

    Then each such window's sample is no further than ``floor`` from the window's median
    (rounding is monotonic: ``|x - median|`` rounds to at most what ``max - min`` rounds to),
    so it is no spike. A window that starts in a block ends in the next one: the two blocks'
    joint span bounds its own (a NaN in them makes it loud)."""
    side = np.ascontiguousarray(blocks.T)  # the blocks side by side: reductions over rows
    top, bottom = side.max(axis=0), side.min(axis=0)
    top = np.maximum(top[:-1], top[1:])
    bottom = np.minimum(bottom[:-1], bottom[1:])
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, not quiet
        return (top - bottom) <= floor


def _edge_padded(x: np.ndarray, left: int, right: int) -> np.ndarray:
    """``np.pad(x, (left, right), mode="edge")`` of a 1-D ``x`` (without np.pad's checks)."""
    return np.concatenate((np.full(left, x[0]), x, np.full(right, x[-1])))


def _medians(padded: np.ndarray, half_window: int, rows: np.ndarray) -> np.ndarray:
    """:func:`moving_median` at the samples ``rows`` alone, of a stream ``padded`` with
    ``half_window`` end values (or more on the right): the same windows, each partitioned as
    the whole stream's are."""
    windows = padded[rows[:, None] + np.arange(2 * half_window + 1)]
    windows.partition(half_window, axis=1)
    return windows[:, half_window]


#: rows of sliding windows partitioned at a time: bounds the (rows, window) copy to ~8 MB
_MEDIAN_ROWS = 1 << 15


def moving_median(x: np.ndarray, half_window: int) -> np.ndarray:
    """The median of every window of ``2 half_window + 1`` samples centred on each sample, the
    ends padded with the end values: the same numbers as scipy's ``median_filter(x, size,
    mode="nearest")`` (a median of an odd count is one of the samples, no arithmetic), without
    importing scipy.ndimage into ``twin compensate``."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"moving_median takes one stream (a 1-D array), got {x.ndim} dimensions")
    if half_window <= 0 or x.size == 0:
        return x.copy()
    # np.pad and sliding_window_view cost most of a short stream's medians (a Monte Carlo
    # sample's 104 rows) in their checks: the same windows, made directly
    padded = _edge_padded(x, half_window, half_window)
    w, step = 2 * half_window + 1, padded.strides[0]
    out = np.empty_like(x)
    for a in range(0, x.size, _MEDIAN_ROWS):
        rows = min(_MEDIAN_ROWS, x.size - a)
        # a view of the padded stream's own buffer (as_strided's checks cost more than the
        # copy of a short stream's windows), copied before it is partitioned
        windows = np.ndarray((rows, w), padded.dtype, padded, a * step, (step, step)).copy()
        windows.partition(half_window, axis=1)  # in place: np.partition would copy them again
        out[a : a + rows] = windows[:, half_window]
    return out
