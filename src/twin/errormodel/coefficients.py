"""The coefficients file: what ``twin identify`` found, and all the error model knows of a tester.

The error model reads its coefficients from such a file only (or from the same table inline in
a lab's ``[errormodel]``), never from the FMUs' parameters. A file (TOML)::

    [identified]                           # provenance: who fitted what on which twin
    by = "twin identify"
    twin_version = "0.1.0"
    overrides = []                         # --set values of the tester as built
    [identified.experiments.thermal_soak]
    scenario = "thermal-soak.toml"
    sha256 = "..."                         # of the experiment's resolved scenario data

    [coefficients.alpha_l_detecting_frame]  # one table per coefficient, every one required
    value = 4.6e-06
    std_error = 2.1e-08                    # one standard error
    unit = "m/K"                           # must be the unit the error model declares
    experiment = "thermal_soak"            # which fit it comes from
    prior = { value = 4.2e-06, sigma = 6.4e-07, source = "..." }   # where a prior entered

    [fit.thermal_soak]                     # one table per fit (optional in a lab's own file)
    parameters = ["alpha_l_heel_block", ...]
    samples = 2880
    residual_rms = 1.4e-07                 # m
    noise_inflation = 3.1                  # the residuals' serial correlation, see identify
    rank = 7                               # of the data's Jacobian (columns scaled to norm 1)
    informative_directions = 5             # directions the data know better than the priors
    condition_number = 1.0e+08             # of the data's Jacobian, all parameters
    condition_number_identifiable = 266.0  # over its rank only
    condition_number_regularised = 35.0    # with the priors
    singular_values = [...]
    correlation = [[1.0, ...], ...]        # of the estimates, in the order of parameters

A bad file is bad input: one :class:`~twin.errors.ConfigError` per problem, one line naming
the file and the key (a missing coefficient, a value that is not a finite number or is beyond
any tester of this kind (:data:`PLAUSIBLE`), a unit that is not the declared one).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.reader import Problems, number_problem
from twin.errormodel.sources import MechanicalCoefficients, ThermalCoefficients
from twin.files import write_text_atomic

__all__ = [
    "DEFAULT_FILE",
    "PRIORS_FILE",
    "Coefficient",
    "Coefficients",
    "Fit",
    "Prior",
    "coefficient_units",
    "default_path",
    "load_coefficients",
    "load_priors",
    "parse_coefficients",
    "priors_path",
    "read_toml_file",
]

#: the committed coefficients of the nominal twin, relative to the scenarios folder
DEFAULT_FILE = "calibration/identified.toml"
#: the drawing's and handbook's priors and start values, relative to the scenarios folder
PRIORS_FILE = "calibration/priors.toml"


def coefficient_units() -> dict[str, str]:
    """Every coefficient the error model needs, with its unit, in the declared order."""
    return {**ThermalCoefficients.units(), **MechanicalCoefficients.units()}


def default_path() -> Path:
    """The committed default coefficients file (``twin identify`` on the nominal twin)."""
    from twin.config.load import scenarios_dir

    return scenarios_dir() / DEFAULT_FILE


def priors_path() -> Path:
    """The committed priors file."""
    from twin.config.load import scenarios_dir

    return scenarios_dir() / PRIORS_FILE


@dataclass(frozen=True)
class Prior:
    """What is known of a coefficient before any experiment: the drawing's length times the
    handbook's expansion, an estimate. ``sigma`` is ``None`` for a start value only (a flat
    prior: the fit is not pulled towards it)."""

    value: float
    sigma: float | None
    unit: str
    source: str = ""


@dataclass(frozen=True)
class Coefficient:
    """One coefficient: value, one standard error, unit, the fit it came from, and the prior
    that entered that fit (if any)."""

    value: float
    std_error: float
    unit: str
    experiment: str
    prior: Prior | None = None


@dataclass(frozen=True)
class Fit:
    """How one fit went (see :mod:`twin.errormodel.identify` for the numbers): its parameters,
    its experiments and, per experiment, the samples used, the residual's rms (m) and the
    noise inflation for the residuals' serial correlation."""

    parameters: tuple[str, ...]
    experiments: tuple[str, ...]
    samples: tuple[int, ...]
    residual_rms: tuple[float, ...]
    noise_inflation: tuple[float, ...]
    rank: int
    informative_directions: int
    condition_number: float
    condition_number_identifiable: float
    condition_number_regularised: float
    singular_values: tuple[float, ...]
    correlation: tuple[tuple[float, ...], ...]


@dataclass(frozen=True)
class Coefficients:
    """A tester's coefficients, the fits behind them and where they come from.

    Plain mappings (treat them as read-only), so the object pickles: a sweep's workers send
    it back.
    """

    coefficients: Mapping[str, Coefficient]
    fits: Mapping[str, Fit] = field(default_factory=dict)
    identified: Mapping[str, Any] = field(default_factory=dict)

    def values(self) -> dict[str, float]:
        """Every coefficient's value by name."""
        return {name: c.value for name, c in self.coefficients.items()}

    def thermal(self) -> ThermalCoefficients:
        """The thermal factor's coefficients."""
        return ThermalCoefficients.from_values(self.values())

    def mechanics(self) -> MechanicalCoefficients:
        """The loading, fluctuating and positioning factors' coefficients."""
        return MechanicalCoefficients.from_values(self.values())

    def with_values(self, **values: float) -> Coefficients:
        """A copy with some values replaced (their standard errors and origin kept)."""
        unknown = sorted(set(values) - set(self.coefficients))
        if unknown:
            raise KeyError(f"unknown coefficient(s) {unknown}")
        new = {k: replace(c, value=float(values.get(k, c.value))) for k, c in self.coefficients.items()}
        return replace(self, coefficients=new)

    def covariance(self, names: Sequence[str]) -> np.ndarray:
        """Covariance of the named coefficients: standard errors, and the correlation of any two
        that came from the same fit (those of different fits are independent)."""
        se = np.array([self.coefficients[n].std_error for n in names])
        corr = np.eye(len(names))
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                fit = self.fits.get(self.coefficients[a].experiment)
                if i != j and fit is not None and a in fit.parameters and b in fit.parameters:
                    corr[i, j] = fit.correlation[fit.parameters.index(a)][fit.parameters.index(b)]
        return corr * np.outer(se, se)

    def to_toml(self, header: str = "") -> str:
        """The file's text (``header`` becomes comment lines at its top)."""
        lines = [f"# {h}".rstrip() for h in header.splitlines()]
        lines += _section("identified", self.identified)
        meanings = {**ThermalCoefficients.meanings(), **MechanicalCoefficients.meanings()}
        for name, c in self.coefficients.items():
            table = _coefficient_table(c, meanings.get(name, ""))
            lines += _section(f"coefficients.{name}", table, inline={"prior"})
        for name, fit in self.fits.items():
            lines += _section(f"fit.{name}", _fit_table(fit))
        return "\n".join(lines).lstrip("\n") + "\n"

    def write(self, path: str | Path, header: str = "") -> Path:
        """Write the file (the folder must exist); returns its path."""
        path = Path(path)
        return write_text_atomic(path, self.to_toml(header))  # never through a planted link


def _coefficient_table(c: Coefficient, meaning: str) -> dict[str, Any]:
    out: dict[str, Any] = {k: getattr(c, k) for k in ("value", "std_error", "unit", "experiment")}
    if c.prior is not None:
        prior = {"value": c.prior.value, "sigma": c.prior.sigma, "source": c.prior.source}
        out["prior"] = {k: v for k, v in prior.items() if v is not None}
    if meaning:
        out["meaning"] = meaning
    return out


def _fit_table(fit: Fit) -> dict[str, Any]:
    out = {f.name: getattr(fit, f.name) for f in fields(Fit)}
    # four decimals say all a correlation has to say, and keep the matrix readable
    out["correlation"] = [[round(x, 4) for x in row] for row in fit.correlation]
    return out


# ----------------------------------------------------------------------------- TOML out


def _toml_value(v: Any) -> str:
    """One value as TOML: strings, booleans, numbers, arrays and inline tables."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return ("-inf" if v < 0 else "inf") if math.isinf(v) else "nan" if math.isnan(v) else repr(v)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, Sequence):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, np.generic):
        return _toml_value(v.item())
    raise TypeError(f"no TOML for {type(v).__name__}")


def _section(
    path: str, table: Mapping[str, Any], inline: frozenset[str] | set[str] = frozenset()
) -> list[str]:
    """``[path]`` with the table's values, then its sub-tables as ``[path.key]`` (those named in
    ``inline`` stay inline tables); no header for a table that holds only sub-tables."""
    nested = {k: v for k, v in table.items() if isinstance(v, Mapping) and k not in inline}
    lines = [f"{k} = {_toml_value(v)}" for k, v in table.items() if k not in nested]
    lines = ["", f"[{path}]", *lines] if lines or not nested else []
    for k, v in nested.items():
        lines += _section(f"{path}.{k}", v, inline)
    return lines


# ----------------------------------------------------------------------------- TOML in


def read_toml_file(path: str | Path) -> dict[str, Any]:
    """A TOML file's data; a missing or malformed file is a one-line :class:`ConfigError`."""
    from twin.config.reader import read_toml  # the loader's one reader of TOML files

    return read_toml(Path(path), str(path))


def load_coefficients(path: str | Path) -> Coefficients:
    """Read and check a coefficients file.

    The parsed file is kept while the file is unchanged (same inode, size and modification
    time): a sweep's client builds a scenario per point, and parsing the same file each time
    was the largest part of that work. :class:`Coefficients` is frozen, so sharing it is safe.
    """
    try:
        st = Path(path).stat()
    except OSError:
        return parse_coefficients(read_toml_file(path), str(path))  # reports the missing file
    return _load_unchanged(str(Path(path).resolve()), str(path), st.st_ino, st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=16)
def _load_unchanged(resolved: str, shown: str, inode: int, size: int, mtime_ns: int) -> Coefficients:
    del inode, size, mtime_ns  # the cache's key: a changed file is read again
    return parse_coefficients(read_toml_file(resolved), shown)


def _table(p: Problems, raw: Any, key: str, allowed: set[str]) -> Mapping[str, Any] | None:
    """``raw`` when it is a table with only ``allowed`` keys (unknown ones are problems)."""
    if not isinstance(raw, Mapping):
        p.add(key, "expected a table")
        return None
    p.unknown_keys(raw, allowed, f"{key}." if key else "")
    return raw


def _text(p: Problems, raw: Mapping[str, Any], k: str, key: str, default: str | None = None) -> str | None:
    v = raw.get(k, default)
    if not isinstance(v, str):
        p.add(f"{key}.{k}", "missing" if v is None else "must be a string")
        return None
    return v


def _prior(p: Problems, raw: Any, unit: str, key: str) -> Prior | None:
    """A prior: its value within :data:`PRIOR_MAX`, its sigma (where it is a prior, not only a
    start value) between :data:`PRIOR_SIGMA_MIN` and :data:`PRIOR_MAX`, its unit the declared one."""
    raw = _table(p, raw, key, {"value", "sigma", "source", "unit"})
    if raw is None:
        return None
    if "unit" in raw and raw["unit"] != unit:
        p.add(f"{key}.unit", f"unit must be {unit!r}, got {raw['unit']!r}")
        return None
    n = len(p.items)
    value = p.number(raw, "value", f"{key}.", lo=-PRIOR_MAX, hi=PRIOR_MAX)
    sigma = None
    if "sigma" in raw:
        why = number_problem(raw["sigma"], PRIOR_SIGMA_MIN, PRIOR_MAX)
        if why is not None:
            p.add(
                f"{key}.sigma",
                f"must be a finite number > 0, from {PRIOR_SIGMA_MIN:g} to {PRIOR_MAX:g} {unit} "
                f"(leave it out for a start value only), got {raw['sigma']!r}",
            )
        else:
            sigma = float(raw["sigma"])
    text = _text(p, raw, "source", key, "")
    if len(p.items) > n or value is None or text is None:
        return None
    return Prior(value, sigma, unit, text)


#: the largest magnitude a coefficient (and its standard error) may have, by unit: far past any
#: tester of this kind (an estimate, not a measurement), so that a typo (1e308, a unit slip of
#: 10^6) is refused with its key instead of overflowing the error model into Inf and a plot
#: that cannot be drawn. 1 mm per kelvin (the tester's longest path, the heel block's, is about
#: 2e-6 m/K); 1 um per newton (0.2 m at the tester's 200 kN; the structure's is about 1e-10);
#: 1 cm of runout; a phase of 1000 rad; a probe scale of 10; 1 rad per N m of clamp torque.
PLAUSIBLE = {"m/K": 1e-3, "m/N": 1e-6, "m": 1e-2, "rad": 1e3, "1": 10.0, "rad/(N.m)": 1.0}


def _plausible(p: Problems, raw: Mapping[str, Any], k: str, unit: str, key: str) -> float | None:
    """``raw[k]``: a finite number (not negative for a standard error) no larger than any
    tester of this kind has (:data:`PLAUSIBLE`)."""
    value = p.number(raw, k, f"{key}.", lo=0.0 if k == "std_error" else -math.inf)
    if value is None:
        return None
    bound = PLAUSIBLE.get(unit, math.inf)
    if abs(value) > bound:
        p.add(
            f"{key}.{k}",
            f"{value!r} {unit} is beyond any tester of this kind (|value| <= {bound:g} {unit})".replace(
                " 1 ", " "
            ),
        )
        return None
    return value


def _coefficient(p: Problems, raw: Any, unit: str, key: str) -> Coefficient | None:
    raw = _table(p, raw, key, {"value", "std_error", "unit", "experiment", "prior", "meaning"})
    if raw is None:
        return None
    if raw.get("unit") != unit:
        got = "no unit" if "unit" not in raw else repr(raw["unit"])
        p.add(f"{key}.unit", f"unit must be {unit!r}, got {got}")
        return None
    value = _plausible(p, raw, "value", unit, key)
    std_error = _plausible(p, raw, "std_error", unit, key)
    prior = _prior(p, raw["prior"], unit, f"{key}.prior") if "prior" in raw else None
    experiment = _text(p, raw, "experiment", key)
    if value is None or std_error is None or experiment is None or ("prior" in raw and prior is None):
        return None
    return Coefficient(value, std_error, unit, experiment, prior)


def _is_number(v: Any) -> bool:
    """An int or float that is not NaN (infinite condition numbers are allowed)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and not math.isnan(v)


#: how each field of a fit table is checked and converted
_FIT_FIELDS: dict[str, tuple[Callable[[Any], bool], Callable[[Any], Any], str]] = {
    "strings": (
        lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
        tuple,
        "a list of names",
    ),
    "ints": (
        lambda v: isinstance(v, list) and all(isinstance(x, int) for x in v),
        tuple,
        "a list of integers",
    ),
    "numbers": (
        lambda v: isinstance(v, list) and all(_is_number(x) for x in v),
        lambda v: tuple(float(x) for x in v),
        "a list of numbers",
    ),
    "int": (lambda v: isinstance(v, int) and not isinstance(v, bool), int, "an integer"),
    "number": (_is_number, float, "a number"),
    "matrix": (
        lambda v: (
            isinstance(v, list) and all(isinstance(r, list) and all(_is_number(x) for x in r) for r in v)
        ),
        lambda v: tuple(tuple(float(x) for x in r) for r in v),
        "a list of rows of numbers",
    ),
}
_FIT_KINDS = {
    "parameters": "strings",
    "experiments": "strings",
    "samples": "ints",
    "residual_rms": "numbers",
    "noise_inflation": "numbers",
    "rank": "int",
    "informative_directions": "int",
    "condition_number": "number",
    "condition_number_identifiable": "number",
    "condition_number_regularised": "number",
    "singular_values": "numbers",
    "correlation": "matrix",
}


def _fit(p: Problems, raw: Any, key: str) -> Fit | None:
    raw = _table(p, raw, key, set(_FIT_KINDS))
    if raw is None:
        return None
    values = {}
    for k, kind in _FIT_KINDS.items():
        check, convert, what = _FIT_FIELDS[kind]
        if k not in raw or not check(raw[k]):
            p.add(f"{key}.{k}", f"must be {what}")
            return None
        values[k] = convert(raw[k])
    n = len(values["parameters"])
    if n == 0 or any(len(row) != n for row in values["correlation"]) or len(values["correlation"]) != n:
        p.add(f"{key}.correlation", f"must be {n} x {n}, one row per parameter")
        return None
    return Fit(**values)


def parse_coefficients(data: Mapping[str, Any], source: str) -> Coefficients:
    """Check a coefficients file's data (or a lab's inline table with ``coefficients`` only).

    Every coefficient the error model declares must be there, with a finite value, a finite
    non-negative standard error, the declared unit and the experiment it came from; every
    problem is reported at once, one line each.
    """
    p = Problems(source)
    _table(p, data, "", {"identified", "coefficients", "fit"})
    units = coefficient_units()
    raw = _table(p, data.get("coefficients"), "coefficients", set(units)) or {}
    missing = [name for name in units if name not in raw]
    if missing and raw and not set(raw) - set(units):  # a misspelt name is the first thing to say
        p.add(
            "coefficients",
            f"missing coefficient(s): {', '.join(missing)} (`twin identify` writes every one the "
            "error model declares; a file from an older twin lacks the newer ones)",
        )
    coefficients = {
        name: _coefficient(p, raw[name], unit, f"coefficients.{name}")
        for name, unit in units.items()
        if name in raw
    }
    fit_tables = p.table(data, "fit")
    fits = {name: _fit(p, f, f"fit.{name}") for name, f in fit_tables.items()}
    identified = p.table(data, "identified")
    p.check()
    return Coefficients(
        {k: v for k, v in coefficients.items() if v is not None},
        {k: v for k, v in fits.items() if v is not None},
        dict(identified),
    )


#: the largest magnitude of a prior's value and sigma, in the coefficient's SI unit. Every
#: coefficient is a bench tester's displacement per kelvin, newton or newton-metre, a runout
#: (m), an angle (rad) or the probe's scale (1): real ones lie between 1e-12 and 2 pi. Far
#: beyond, the fit (steps of sigma, residuals divided by noise of about 1e-12 m) overflows:
#: a value of 1e308 gives residuals that are not finite, a sigma of 1e308 steps that are not
PRIOR_MAX = 1e6
#: the smallest sigma of a prior (SI unit): 1e-18 of the smallest coefficient, far below any
#: knowledge; much smaller sigmas square to zero in the fit's normal matrix (1e-300 gives a
#: correlation of NaN), and 0 divides by zero
PRIOR_SIGMA_MIN = 1e-30


def load_priors(path: str | Path | None = None) -> dict[str, Prior]:
    """The priors file (default: the committed one): a ``[priors.<name>]`` table for every
    coefficient, with ``value``, its ``unit`` and ``source``, and ``sigma`` where it is a prior
    (without, the value only starts the fit).

    Every problem of the file is reported, one line each (:class:`ConfigErrors`): a missing
    prior, a wrong unit, a value that is not a finite number within :data:`PRIOR_MAX`, a sigma
    that is not a finite number between :data:`PRIOR_SIGMA_MIN` and :data:`PRIOR_MAX`."""
    path = priors_path() if path is None else Path(path)
    source = str(path)
    data = read_toml_file(path)
    p = Problems(source)
    _table(p, data, "", {"priors"})
    units = coefficient_units()
    raw = _table(p, data.get("priors"), "priors", set(units)) or {}
    missing = [name for name in units if name not in raw]
    if missing:
        p.add("priors", f"missing prior(s): {', '.join(missing)}")
    priors = {}
    for name, unit in units.items():
        if name not in raw:
            continue
        key = f"priors.{name}"
        if not isinstance(raw[name], Mapping) or raw[name].get("unit") != unit:
            p.add(f"{key}.unit", f"unit must be {unit!r}")
            continue
        prior = _prior(p, raw[name], unit, key)
        if prior is not None:
            priors[name] = prior
    p.check()
    return priors
