"""The paper's five error factors, each declared once, in one list.

Li et al. (2017) name five factors of the wear-depth detecting error: thermal dE_T, loading
dE_F, fluctuating dE_V, positioning dE_G and (detecting) interference dE_I. Each becomes one
:class:`Factor` in :data:`FACTORS`: its name, the paper's symbol, a label for plots, the
sensor columns it reads (fields of :class:`~twin.errormodel.sources.Columns`, which
``EvaluationConfig`` extends) and its function, from the :class:`Measured` streams to its
per-sample :class:`Contribution` to e_z. :func:`~twin.errormodel.evaluate.evaluate`, the
summary it builds, the CSV columns (``evaluation_signals``) and ``input_columns`` iterate the
list, and a plot finds each part's column and label here, so a new factor is one more entry
(with its error parameters in :mod:`~twin.errormodel.sources`, and a new field of ``Columns``
if it reads a new instrument): nothing else to remember. A declaration with a part missing
fails when this module is imported, with a :class:`FactorError` that says what.

A factor's function maps measured streams to the small-error parameters of the tester's
bodies (the error characteristic matrices dT_ijp and dT_ijs) and through the characteristic
matrices of both branches to e_z (:meth:`Measured.e_z`); interference is the exception, the
spikes a robust filter takes out of the reading. The parts add up to e_z in the order of the
list; the order is part of the numbers (a floating-point sum), so keep it.
"""

from __future__ import annotations

import functools
import keyword
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin.errormodel.model import ErrorModel, Errors
from twin.errormodel.settings import EvaluationConfig
from twin.errormodel.sources import (
    COLUMN_FIELDS,
    MechanicalCoefficients,
    fluctuating_errors,
    hampel,
    load_history,
    loading_errors,
    positioning_errors,
    thermal_errors,
)
from twin.errors import ConfigError, TwinError
from twin.signals.table import SignalTable

__all__ = [
    "FACTORS",
    "FEM_GROUPS",
    "PARTS",
    "Contribution",
    "Factor",
    "FactorError",
    "Measured",
    "end_lines",
    "endpoints",
    "factor",
    "factor_list",
]

#: how the tester's bodies group into the paper's four FEM part results (docs/reference/facts.md 2)
FEM_GROUPS: dict[str, tuple[str, ...]] = {
    "bearing_block": ("bearing_block",),
    "t_plate": ("testing_spindle", "spherical_plain_bearing", "t_plate"),
    "detecting_frame": ("detecting_frame",),
    "long_pole": ("contacting_clamp", "long_pole"),
    "displacement_sensor": ("displacement_sensor",),
}


class FactorError(TwinError, TypeError):
    """A factor declared with a part missing or wrong (a programming error, not bad input).

    Raised when the list is built, that is when this module is imported, or when a factor's
    function returns something its declaration does not promise.
    """


def endpoints(t: np.ndarray, y: np.ndarray, window_s: float) -> tuple[float, float]:
    """Start and end value of ``y`` from lines through the first and last ``window_s``.

    A least-squares line evaluated at the first (last) time averages the sensors' noise out
    of a slow drift without the lag of a plain mean.
    """
    return EndLines(t, window_s).values(y)


class EndLines:
    """The lines of :func:`endpoints` for one time axis ``t``, for any number of streams:
    which rows each line goes through, and its design matrix, are worked out once."""

    def __init__(self, t: np.ndarray, window_s: float) -> None:
        self.start = _LineAt(t, t <= t[0] + window_s, float(t[0]))
        self.end = _LineAt(t, t >= t[-1] - window_s, float(t[-1]))

    def values(self, y: np.ndarray) -> tuple[float, float]:
        """Start and end value of ``y`` (one value per time)."""
        return self.start.value(y), self.end.value(y)

    def drifts(self, ys: Sequence[np.ndarray]) -> list[float]:
        """End minus start value of each of ``ys``: the numbers of :meth:`values` (each line
        solved on its own, as polyfit solves it), every stream's in one call per end."""
        starts, ends = self.start.values(ys), self.end.values(ys)
        return [end - start for start, end in zip(starts, ends, strict=True)]

    def stacked_drifts(self, ys: Sequence[np.ndarray], records: int) -> list[np.ndarray]:
        """:meth:`drifts` of the ``records`` stacked end to end in each of ``ys`` (each of this
        time axis' length): per stream, an array of its records' drifts. Every record's lines
        are solved on their own, so each is the number :meth:`drifts` gives that record alone
        (the same subtraction, element by element), all of them in one call per end."""
        each = [record for y in ys for record in np.reshape(y, (records, -1))]
        drifts = np.subtract(self.end.values(each), self.start.values(each))
        return list(drifts.reshape(len(ys), records))


#: the last time axis and window :func:`end_lines` was asked for, and their lines
_LAST_LINES: tuple[np.ndarray, float, EndLines] | None = None


def end_lines(t: np.ndarray, window_s: float) -> EndLines:
    """:class:`EndLines` of the time axis ``t``: those of the last call again when ``t`` holds
    the same times and the window is the same (a Monte Carlo's samples share one time axis:
    their lines are made once, not once per sample; they depend on the times alone)."""
    global _LAST_LINES
    last = _LAST_LINES  # one read: another thread may replace it meanwhile
    if last is not None and last[1] == window_s and last[0].dtype == t.dtype and np.array_equal(last[0], t):
        return last[2]
    lines = EndLines(t, window_s)
    _LAST_LINES = (np.array(t), window_s, lines)  # a copy: the caller's array may change
    return lines


def _raise_not_converged(err: object, flag: object) -> None:
    raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")


#: numpy's least-squares kernel, which loops over a stack of systems calling LAPACK's gelsd on
#: each as np.linalg.lstsq calls it on one (np.linalg.lstsq takes no stack); None where this
#: numpy has no such kernel (1.x names it otherwise): then one lstsq call per stream
_STACKED_LSTSQ: Any = getattr(getattr(np.linalg, "_umath_linalg", None), "lstsq", None)


#: the values a line keeps of the streams it solved (:meth:`_LineAt.values`): a Monte Carlo
#: batch's 20 samples solve about 500 a line; more are forgotten all at once (a few MB)
_SOLVED_KEPT = 4096


class _LineAt:
    """The least-squares line through the rows ``mask`` of ``(t, y)``, evaluated at ``at``:
    ``np.polyfit(t[mask] - at, y[mask], 1)``'s intercept, made as polyfit makes it (the same
    scaled Vandermonde matrix, rcond and solver: the same doubles), with the matrix made once."""

    def __init__(self, t: np.ndarray, mask: np.ndarray, at: float) -> None:
        self.mask = mask
        self.count = int(mask.sum())
        if self.count < 2:
            return
        self.rows = np.flatnonzero(mask)
        #: the same rows as a slice where they follow one another (an end's window: the
        #: streams' rows are then taken as a view, no index array walked)
        first = int(self.rows[0])
        self._take: slice | np.ndarray = (
            slice(first, first + self.count) if int(self.rows[-1]) - first + 1 == self.count else self.rows
        )
        #: the values of the streams solved, by their rows' bytes (:meth:`values`)
        self._solved: dict[bytes, float] = {}
        self._deficient = False  # the matrix's rank (the same for every stream) is below 2
        x = np.asarray(t[mask] - at) + 0.0
        self.rcond = len(x) * np.finfo(x.dtype).eps
        lhs = np.vander(x, 2)
        self.scale = np.sqrt((lhs * lhs).sum(axis=0))
        lhs /= self.scale
        self.lhs = lhs

    def value(self, y: np.ndarray) -> float:
        if self.count < 2:
            return float(y[self.mask][0]) if self.count else float("nan")
        c, _resids, rank, _s = np.linalg.lstsq(self.lhs, np.asarray(y[self.mask]) + 0.0, self.rcond)
        if rank != 2:
            warnings.warn("Polyfit may be poorly conditioned", np.exceptions.RankWarning, stacklevel=3)
        return float(c[1] / self.scale[1])

    def values(self, ys: Sequence[np.ndarray]) -> list[float]:
        """:meth:`value` of each of ``ys``: the systems solved one by one in numpy's stacked
        kernel (one gelsd call each, with the operands lstsq gives it), not as one system of
        many right-hand sides, whose blocked products round otherwise.

        A stream whose rows are the very bytes of one solved before takes its value: each
        system is solved on its own, so its value depends on its rows alone. A Monte Carlo's
        samples share their time axis and so their lines (:func:`end_lines`); an updated
        sample's temperatures and the thermal parts of most bodies are its prior sample's (the
        posterior sets the mechanics' and the probe's parameters), and a factor switched off
        is zeros in every sample: 45 % of the default run's systems are found, not solved.
        At most :data:`_SOLVED_KEPT` values are kept."""
        if self.count < 2 or _STACKED_LSTSQ is None or not ys:
            return [self.value(y) for y in ys]
        # the streams as one array, then their rows (the same numbers in the same places as
        # each stream's rows stacked); + 0.0 as value() adds it: a -0.0 becomes +0.0 before
        # the solver sees it (the solver's doubles: a float32 stream's rows as the kernel casts them)
        b = (_side_by_side(ys)[:, self._take][:, :, None] + 0.0).astype(np.float64, copy=False)
        keys = [system.tobytes() for system in b]
        solved = self._solved
        found = {key: value for key in keys if (value := solved.get(key)) is not None}
        todo: dict[bytes, int] = {}  # each stream not solved before, once: its first place
        for j, key in enumerate(keys):
            if key not in found and key not in todo:
                todo[key] = j
        if todo:
            rows = list(todo.values())
            with np.errstate(
                call=_raise_not_converged, invalid="call", over="ignore", divide="ignore", under="ignore"
            ):
                c, _resids, rank, _s = _STACKED_LSTSQ(
                    self.lhs, b if len(rows) == len(keys) else b[rows], self.rcond, signature="ddd->ddid"
                )
            self._deficient = bool((rank != 2).any())
            if len(solved) + len(rows) > _SOLVED_KEPT:
                solved.clear()
            for key, value in zip(todo, (c[:, 1, 0] / self.scale[1]).tolist(), strict=True):
                found[key] = solved[key] = value
        if self._deficient:
            warnings.warn("Polyfit may be poorly conditioned", np.exceptions.RankWarning, stacklevel=3)
        return [found[key] for key in keys]


def _side_by_side(ys: Sequence[np.ndarray]) -> np.ndarray:
    """The 1-D streams ``ys`` (of one length) as the rows of one array, their dtypes promoted as
    ``np.stack`` promotes them (``np.array`` of the list, without ``np.stack``'s per-array
    checks: most of a short stream's cost); ``np.stack`` where they are not all 1-D arrays of
    one length."""
    arrays = [np.asarray(y) for y in ys]
    n = arrays[0].shape
    if len(n) == 1 and all(a.shape == n for a in arrays):
        return np.array(arrays)
    return np.stack(arrays)


@dataclass(frozen=True)
class Contribution:
    """What one factor adds: its per-sample part of e_z (m) and, for a factor declared
    ``by_body``, the same split over the tester's bodies (one array per body)."""

    e_z: np.ndarray
    by_body: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class Measured:
    """The measured streams of one evaluation, as the factors read them.

    ``reading`` is the displacement probe's reading, ``cleaned`` the same after the robust
    (Hampel) filter and ``spikes`` where that filter found interference; ``temperatures`` the
    eight measuring points' readings; ``history`` the load cell's history as the liner's creep
    sees it (:class:`~twin.errormodel.sources.LoadHistory`, shape (K, n)), ``None`` without a
    load cell. Built by :meth:`read`, which raises :class:`~twin.errors.ConfigError` for a
    missing reading or temperature column.
    """

    table: SignalTable
    cfg: EvaluationConfig
    model: ErrorModel
    reading: np.ndarray
    cleaned: np.ndarray
    spikes: np.ndarray
    temperatures: dict[str, np.ndarray]
    history: np.ndarray | None = None
    #: the rows of each record where records of one time axis are stacked end to end (a Monte
    #: Carlo batch's samples: :func:`~twin.errormodel.evaluate.evaluate_many`); None: one record
    rows_each: int | None = None

    @classmethod
    def read(
        cls,
        table: SignalTable,
        cfg: EvaluationConfig,
        model: ErrorModel,
        filtered: tuple[np.ndarray, np.ndarray] | None = None,
        history: np.ndarray | None = None,
    ) -> Measured:
        """The streams of ``table``: the reading (filtered first: the positioning factor and the
        reading change start from the cleaned reading), the eight temperatures and the load's
        history.

        ``filtered`` is the robust filter's (cleaned, spikes) of these rows when the filter ran
        on a longer stretch (a streamed record, whose windows reach over chunk ends), ``history``
        the load's history of these rows when it ran over the record before them."""
        if len(table.time) < 2:
            raise ConfigError("the error model needs at least two samples", source="errormodel")
        reading = _column(table, cfg.reading, "probe reading")
        if filtered is None:
            filtered = hampel(reading, cfg.spike_half_window, cfg.spike_sigmas, cfg.spike_min)
        cleaned, spikes = filtered
        temperatures = {
            point: _column(table, col, f"temperature at '{point}'") for point, col in cfg.temperatures.items()
        }
        if history is None and cfg.factor_on("loading"):
            load = table.columns.get(cfg.load)
            history = None if load is None else load_history(table.time, load)
        return cls(table, cfg, model, reading, cleaned, spikes, temperatures, history)

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.table.time)

    def sensor(self, name: str) -> np.ndarray | None:
        """The stream of the column that field ``name`` names, or ``None`` where the table has
        no such column (an instrument the tester lacks)."""
        column = getattr(self.cfg, name)
        return self.table.columns.get(column)

    def drifts(self, ys: Sequence[np.ndarray]) -> list[Any]:
        """End minus start value of each of ``ys`` over the run (see :func:`endpoints`), their
        lines solved together; with records stacked, per stream an array of its records'
        drifts, each the number its record alone gives (:meth:`EndLines.stacked_drifts`)."""
        if self.rows_each is not None:
            return self._ends.stacked_drifts(ys, self.n // self.rows_each)
        return self._ends.drifts(ys)

    @functools.cached_property
    def _ends(self) -> EndLines:
        """The lines of :meth:`drifts` (of a record's time axis), worked out once for every stream
        it is asked for."""
        t = self.table.time if self.rows_each is None else self.table.time[: self.rows_each]
        return end_lines(t, self.cfg.window_s)

    def first(self, y: np.ndarray) -> Any:
        """The first value of ``y``; with records stacked, each row's record's first value."""
        if self.rows_each is None:
            return y[0]
        return np.repeat(y[:: self.rows_each], self.rows_each)

    def rel(self, y: np.ndarray) -> np.ndarray:
        """The change of a stream since its first sample (the probe is zeroed at the start); with
        records stacked, since its record's first sample: the same subtraction, row by row."""
        return y - self.first(y)

    def change(self, name: str) -> np.ndarray | None:
        """:meth:`sensor` relative to its first sample."""
        values = self.sensor(name)
        return None if values is None else self.rel(values)

    @property
    def coefficients(self) -> MechanicalCoefficients:
        """The mechanical coefficients a lab identifies once (only ``identified`` factors ask)."""
        if self.cfg.mechanics is None:
            raise FactorError("a factor not declared 'identified' asked for the mechanical coefficients")
        return self.cfg.mechanics

    def e_z(self, errors: Errors) -> np.ndarray:
        """First-order e_z of the small-error parameters ``errors``, one value per sample."""
        if not errors:
            return np.zeros(self.n)
        return np.asarray(self.model.e_z(errors), dtype=float) * np.ones(self.n)

    def zero(self, by_body: bool = False) -> Contribution:
        """A factor's contribution while it is switched off or its cause is not measured."""
        bodies = {b: np.zeros(self.n) for b in self.model.bodies} if by_body else {}
        return Contribution(np.zeros(self.n), bodies)


def _column(table: SignalTable, name: str, what: str) -> np.ndarray:
    if name not in table:
        raise ConfigError(f"no column '{name}' for the {what}", source="errormodel")
    return table[name]


#: a factor's function: the measured streams -> its contribution to e_z
Function = Callable[[Measured], Contribution]
#: what a factor adds to the summary, from its contribution (also the zero one of a factor
#: switched off, so the summary has the same keys whichever factors run)
Report = Callable[[Contribution, Measured], Mapping[str, Any]]


@dataclass(frozen=True, kw_only=True)
class Factor:
    """One error factor of the paper, declared once; checked when constructed.

    ``name`` names its column ``errormodel.e_<name>``, its key in the summary and in the
    ``[errormodel] factors`` list; ``symbol`` is the paper's (``dE_T``); ``label`` the legend
    of the plots. ``columns`` are the :class:`~twin.errormodel.sources.Columns` fields it
    needs (the table must have them), ``sensors`` those it reads where present (an absent
    instrument leaves its input out, and the summary's ``sensors_used`` says so). ``function``
    computes the contribution. ``identified``: it needs the mechanical coefficients a lab
    identifies once on its tester and contributes zero without them. ``by_body``: it also
    records its contribution body by body (columns ``errormodel.<name>.<body>``). ``report``
    adds figures of its own to the summary (of records stacked, each figure an array of the
    records' values: their drifts are, :meth:`Measured.drifts`).
    """

    name: str
    symbol: str
    label: str
    function: Function
    columns: tuple[str, ...] = ()
    sensors: tuple[str, ...] = ()
    identified: bool = False
    by_body: bool = False
    report: Report | None = None

    def __post_init__(self) -> None:
        problems = [p for check in _CHECKS if (p := check(self))]
        if problems:
            raise FactorError(f"factor {self.name!r}: " + "; ".join(problems))

    @property
    def column(self) -> str:
        """The column of its part of e_z."""
        return f"errormodel.e_{self.name}"

    def is_on(self, cfg: EvaluationConfig) -> bool:
        """Whether ``cfg`` switches it on (its ``factors``): then its sensors count as used."""
        return cfg.factor_on(self.name)

    def contribution(self, m: Measured) -> Contribution:
        """Its contribution on ``m``, zero while switched off; checked against the declaration.

        Raises :class:`~twin.errors.ConfigError` for a needed column the table lacks.
        """
        if not self.is_on(m.cfg) or (self.identified and m.cfg.mechanics is None):
            return m.zero(self.by_body)
        for name in self.columns:
            for column in m.cfg.names(name):
                _column(m.table, column, f"{self.name} factor ({name})")
        c = self.function(m)
        if np.shape(c.e_z) != (m.n,):
            raise FactorError(f"factor {self.name!r} returned e_z of shape {np.shape(c.e_z)}, not ({m.n},)")
        if set(c.by_body) != (set(m.model.bodies) if self.by_body else set()):
            raise FactorError(
                f"factor {self.name!r} returned values by body for {sorted(c.by_body)}, "
                f"declared by_body={self.by_body} (bodies {list(m.model.bodies)})"
            )
        return c


def _check_name(f: Factor) -> str | None:
    ok = isinstance(f.name, str) and f.name.isidentifier() and f.name.islower()
    return None if ok and not keyword.iskeyword(f.name) else "name must be a lower_snake identifier"


def _check_texts(f: Factor) -> str | None:
    if not all(isinstance(t, str) and t.strip() for t in (f.symbol, f.label)):
        return "symbol and label must be non-empty strings"
    return None


def _check_columns(f: Factor) -> str | None:
    if not isinstance(f.columns, tuple) or not isinstance(f.sensors, tuple):
        return "columns and sensors must be tuples of EvaluationConfig fields"
    declared = (*f.columns, *f.sensors)
    if not declared:
        return "declares no columns (give 'columns' and/or 'sensors': the EvaluationConfig fields it reads)"
    unknown = [c for c in declared if c not in COLUMN_FIELDS]
    if unknown:
        return f"{unknown} are not column fields of EvaluationConfig (those are {list(COLUMN_FIELDS)})"
    if len(set(declared)) != len(declared):
        return "a column is declared twice"
    return None


def _check_callables(f: Factor) -> str | None:
    if not callable(f.function):
        return "has no function (measured streams -> contribution)"
    if f.report is not None and not callable(f.report):
        return "report must be callable or None"
    return None


_CHECKS: tuple[Callable[[Factor], str | None], ...] = (
    _check_name,
    _check_texts,
    _check_columns,
    _check_callables,
)


def factor_list(*factors: Factor) -> tuple[Factor, ...]:
    """The factors as one tuple, refusing anything but factors and a name or symbol used twice."""
    for f in factors:
        if not isinstance(f, Factor):
            raise FactorError(f"not a Factor: {f!r}")
    for what in ("name", "symbol"):
        values = [getattr(f, what) for f in factors]
        twice = sorted({v for v in values if values.count(v) > 1})
        if twice:
            raise FactorError(f"factor {what}(s) {twice} declared twice")
    return tuple(factors)


def factor(name: str) -> Factor:
    """The declared factor called ``name``."""
    for f in FACTORS:
        if f.name == name:
            return f
    raise KeyError(name)


# ----------------------------------------------------------------------------- the five factors


def _thermal(m: Measured) -> Contribution:
    """Thermal dE_T: alpha L dT of every body from the temperature rises, plus the probe's
    zero drift and its span drift on the cleaned reading (its position in its range), through
    the positioning error matrices dT_ijp (``p_dz``)."""
    rises = {point: m.rel(y) for point, y in m.temperatures.items()}
    by_body = m.model.e_z_by_body(thermal_errors(rises, m.cfg.thermal, m.cleaned))
    return Contribution(np.sum(np.array(list(by_body.values())), axis=0), by_body)


def _thermal_report(c: Contribution, m: Measured) -> dict[str, Any]:
    """The thermal drift of the paper's FEM parts (mm), to set beside its Table 6 and text."""
    names = [b for bodies in FEM_GROUPS.values() for b in bodies]
    drift = dict(zip(names, m.drifts([c.by_body[b] for b in names]), strict=True))
    return {"thermal_parts_mm": {g: sum(drift[b] for b in bodies) * 1e3 for g, bodies in FEM_GROUPS.items()}}


def _loading(m: Measured) -> Contribution:
    """Loading dE_F: the load cell's change compresses the liner and the structure, and the
    liner creeps under the load's history."""
    load = m.change("load")
    if load is None:
        return m.zero()
    return Contribution(m.e_z(loading_errors(load, m.coefficients, m.history)))


def _fluctuating(m: Measured) -> Contribution:
    """Fluctuating dE_V: the spindle's runout against the encoder's angle and the fixture's
    vibration, through the kinematic error matrices dT_ijs (``s_dz``)."""
    angle = m.sensor("angle")
    angle0 = m.first(np.asarray(angle, dtype=float)) if angle is not None else 0.0
    errors = fluctuating_errors(angle, angle0, m.change("vibration"), m.coefficients)
    return Contribution(m.rel(m.e_z(errors)))


def _positioning(m: Measured) -> Contribution:
    """Positioning dE_G: the probe's tilt from Z (cosine error of the cleaned reading change)
    and the T-plate's rotation by the friction torque, a rotation error of the clamp that the
    characteristic matrices read at the Abbe lever."""
    errors = positioning_errors(m.rel(m.cleaned), m.change("torque"), m.coefficients)
    return Contribution(m.rel(m.e_z(errors)))


def _interference(m: Measured) -> Contribution:
    """Detecting interference dE_I: the spikes the robust filter took out of the reading."""
    return Contribution(m.reading - m.cleaned)


# A table, formatted by hand: the five factors side by side, in the paper's order.
# fmt: off
#: the paper's five factors; e_z is their sum, in this order
FACTORS: tuple[Factor, ...] = factor_list(
    Factor(name="thermal", symbol="dE_T", label="thermal ΔE_T", function=_thermal,
           columns=("temperatures",), by_body=True, report=_thermal_report),
    Factor(name="loading", symbol="dE_F", label="loading ΔE_F", function=_loading,
           sensors=("load",), identified=True),
    Factor(name="fluctuating", symbol="dE_V", label="fluctuating ΔE_V", function=_fluctuating,
           sensors=("angle", "vibration"), identified=True),
    Factor(name="positioning", symbol="dE_G", label="positioning ΔE_G", function=_positioning,
           columns=("reading",), sensors=("torque",), identified=True),
    Factor(name="interference", symbol="dE_I", label="interference ΔE_I", function=_interference,
           columns=("reading",)),
)
# fmt: on

#: the factors' names in order (the parts of e_z)
PARTS: tuple[str, ...] = tuple(f.name for f in FACTORS)
