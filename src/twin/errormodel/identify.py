"""The error model's coefficients fitted to calibration records, as a lab finds them.

A lab does not know its tester's expansion coefficients, lengths, compliances or runout; it
measures what they do. The calibration experiments of ``scenarios/calibration/``
(:data:`EXPERIMENTS`: a thermal soak with the drive off, gauge blocks under the pole, static
load steps, a runout check, a slow oscillation at light load, a static load hold for the
liner's creep, the long pole heated alone) are recorded with only the channels a lab's DAQ
records (:func:`lab_channels`: the ``sensors.*`` readings the error model reads, never a true
or internal FMU value; :mod:`twin.pipeline.lab` records them on the twin,
:mod:`twin.calibration.identify` runs them), and this module fits the error model's own form
to those records (:func:`fit_records`), one calibration after the other, each fit using what
the ones before found.

The fit of an experiment (:func:`fit_experiment`): the model is the sum of the error model's
factors (:data:`~twin.errormodel.factors.FACTORS`, interference aside: the target is the
reading the robust filter cleaned), evaluated by the factors' own functions on the record with
trial coefficients, so whatever form the factors have is the form fitted. The target is the
cleaned reading's change minus any known displacement (the gauge blocks); a constant offset and,
in the short experiments, a linear drift are nuisance terms projected out. The parameters are
found by ``scipy.optimize.least_squares``; where a coefficient has a prior (the drawing's
length times the handbook's alpha, ``scenarios/calibration/priors.toml``) it enters as a
pseudo-observation (value - prior) / sigma: a regularised, Bayesian least-squares fit, so a
direction the data cannot see (two temperatures that rise together, two coefficients of one
sensor) stays at the prior instead of running off, and the file says so.

Uncertainties: the data's noise is estimated from the residuals, inflated by
sqrt((1 + rho) / (1 - rho)) for their lag-1 correlation rho (a residual that is model misfit
rather than white noise carries less information than its sample count), per record but not
below the level of all the fit's records together (one DAQ made them all), and the standard
errors and correlations come from the inverse of J^T J of the whitened problem (data and
priors). Each fit reports the rank and condition number of the data's Jacobian (columns scaled
to norm 1: the collinearity of what was measured), the number of directions the data determine
better than the priors, and the condition number with the priors.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from twin.config.spec import Scenario
from twin.errormodel.coefficients import Coefficient, Coefficients, Fit, Prior, coefficient_units
from twin.errormodel.factors import FACTORS, Measured
from twin.errormodel.settings import EvaluationConfig
from twin.errormodel.sources import CREEP_COEFFICIENTS, Columns, MechanicalCoefficients, ThermalCoefficients
from twin.errormodel.tester import tester_model
from twin.errors import ConfigError, RunError
from twin.signals.table import SignalTable

__all__ = [
    "CALIBRATIONS",
    "EXPERIMENTS",
    "Calibration",
    "Experiment",
    "Record",
    "fit_calibration",
    "fit_records",
    "lab_channels",
]

#: relative rank tolerance: a direction of the scaled Jacobian below it is not seen at all
RANK_RTOL = 1e-7
#: a flat prior's sigma in units of the parameter's scale (for the count of informative directions)
FLAT = 1e6
#: passes over the fits (:func:`fit_records`): the second sees every coefficient identified
PASSES = 2
#: a record's model is taken as affine in a fit's parameters (:meth:`_Block.linearise`) when
#: its affine form predicts two further trial points to within this fraction of the largest
#: prediction or change: rounding leaves some 1e-14, a phase or a scale that divides 1e-1 and more
AFFINE_RTOL = 1e-9


@dataclass(frozen=True)
class Experiment:
    """One calibration experiment: its scenario (in ``scenarios/calibration/``) and which of
    its samples a fit uses.

    ``nuisance``: ``offset`` (always sensible: the probe is zeroed by hand), ``drift`` (a
    line in time: slow thermal drift and wear in a short experiment) and ``position`` (an offset
    of its own for each value of the known displacement: the probe's linearity error at each
    position it is set to). ``known_displacement``
    names the input (``instance.variable``) whose profile moves the T-plate by a known amount
    (the gauge blocks). ``use_when`` = (input, value) keeps only the samples while that input's
    profile is at that value (the drive stopped: a warm-up whose wear nobody measures is left
    out). ``settle_s``: samples within that time after a change of either input are left out.
    ``temperatures``: thermometers this experiment adds to the eight (measuring point: column,
    the lab's record keeps them too); ``factors``: the error factors that act in it (None: all;
    the probe alone on a bench has no tester around it to load, turn or tilt).
    """

    name: str
    scenario: str
    nuisance: tuple[str, ...] = ("offset",)
    known_displacement: str | None = None
    use_when: tuple[str, float] | None = None
    settle_s: float = 0.0
    temperatures: Mapping[str, str] = field(default_factory=dict)
    factors: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Calibration:
    """One fit: the coefficients ``fit`` from the records of ``experiments`` together.

    ``starts`` gives further start values of a parameter (a phase), ``lower`` lower bounds.
    """

    name: str
    experiments: tuple[str, ...]
    fit: tuple[str, ...]
    starts: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    lower: Mapping[str, float] = field(default_factory=dict)


# fmt: off
#: the calibration experiments a lab runs on its tester (scenarios/calibration/)
EXPERIMENTS: tuple[Experiment, ...] = (
    Experiment("thermal_soak", "thermal-soak.toml"),
    Experiment("hot_cooldown", "hot-cooldown.toml", nuisance=("offset", "drift"),
               use_when=("oscillation.drive_on", 0.0), settle_s=60.0),
    Experiment("gauge_blocks", "gauge-blocks.toml", nuisance=("offset", "drift"),
               known_displacement="mechanics.wear_offset", settle_s=1.0),
    Experiment("load_steps", "load-steps.toml", nuisance=("offset", "drift")),
    Experiment("runout_check", "runout-check.toml", nuisance=("offset", "drift")),
    Experiment("light_oscillation", "light-oscillation.toml", nuisance=("offset", "drift")),
    Experiment("load_hold", "load-hold.toml"),
    Experiment("pole_heating", "pole-heating.toml"),
    Experiment("probe_heating", "probe-heating.toml", nuisance=("position",),
               known_displacement="sensors.probe_true", settle_s=60.0,
               temperatures={"probe_body": "sensors.t_probe_body_meas"}, factors=("thermal",)),
)

#: the probe's own coefficients: on the tester they multiply the frame's thermometer with the
#: frame's and the probe body's growth, so they come from the probe heated alone, first
PROBE_DRIFTS: tuple[str, ...] = ("probe_zero_drift", "probe_span_drift")

#: the fits, in order: the probe's drifts on the bench first, then the thermal one (with them
#: held), so the short mechanical experiments take their small thermal drift from it
CALIBRATIONS: tuple[Calibration, ...] = (
    Calibration("probe_drift", ("probe_heating",), fit=PROBE_DRIFTS),
    # the pole heated alone tells its growth apart from the frame's (the soak warms both); a
    # body's growth is never negative: the fit is bounded at 0
    Calibration("thermal", ("thermal_soak", "hot_cooldown", "pole_heating"),
                fit=tuple(n for n in ThermalCoefficients.units() if n not in PROBE_DRIFTS),
                lower=dict.fromkeys(ThermalCoefficients.growths(), 0.0)),
    Calibration("probe_scale", ("gauge_blocks",), fit=("probe_scale",)),
    # the loading chain: the steps give the elastic compliance, the hold the liner's creep
    # spectrum (each >= 0); fitted together, as the hold's first minutes see both. No drift term
    # in the hold: a line in time would take the creep's place
    Calibration("load_compliance", ("load_steps", "load_hold"), fit=("load_compliance", *CREEP_COEFFICIENTS),
                lower=dict.fromkeys(CREEP_COEFFICIENTS, 0.0)),
    Calibration("runout", ("runout_check",), fit=("spindle_runout", "runout_phase"),
                starts={"runout_phase": (math.pi / 2, math.pi, -math.pi / 2)}, lower={"spindle_runout": 0.0}),
    Calibration("abbe", ("light_oscillation",), fit=("clamp_rotation",)),
)
# fmt: on


#: the Columns fields a lab's DAQ records (the true wear is not one of them)
LAB_FIELDS: tuple[str, ...] = ("temperatures", "reading", "load", "torque", "angle", "vibration")


def lab_channels(columns: Columns | None = None, experiment: Experiment | None = None) -> frozenset[str]:
    """The columns a lab records: the eight temperatures, probe, load cell, torque sensor,
    angle encoder and vibration pickup (the twin's ``sensors.*`` readings by default), and the
    thermometers ``experiment`` adds."""
    columns = columns or Columns()
    extra = experiment.temperatures.values() if experiment is not None else ()
    return frozenset([*(name for f in LAB_FIELDS for name in columns.names(f)), *extra])


@dataclass(frozen=True)
class Record:
    """One experiment's DAQ record: the lab's channels, the known displacement at each sample
    (zero without gauge blocks) and the samples the fit uses."""

    experiment: Experiment
    table: SignalTable
    known: np.ndarray
    used: np.ndarray
    scenario_sha256: str = ""


def known_displacement(
    scenario: Scenario, experiment: Experiment, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The known displacement at the times ``t`` (what the lab set: the profile of the input
    the experiment names, zero without one) and the samples a fit uses (see
    :class:`Experiment`: ``use_when`` and ``settle_s``)."""
    used = np.ones(len(t), dtype=bool)
    known = np.zeros(len(t))
    if experiment.known_displacement is not None:
        f = _profile(scenario, experiment.known_displacement)
        known = f(t)
        used &= _settled(f, t, experiment.settle_s)
    if experiment.use_when is not None:
        target, value = experiment.use_when
        f = _profile(scenario, target)
        used &= (f(t) == value) & _settled(f, t, experiment.settle_s)
    return known, used


def _profile(scenario: Scenario, target: str) -> Callable[[np.ndarray], np.ndarray]:
    """The time function of the profile driving ``target`` (``instance.variable``)."""
    from twin.config.profiles import profile_function

    for p in scenario.profiles:
        if p.target == target:
            return profile_function(p)
    raise ConfigError(f"no profile drives {target}", source=scenario.source_path, key="input")


def _settled(f: Callable[[np.ndarray], np.ndarray], t: np.ndarray, settle_s: float) -> np.ndarray:
    """The samples at which ``f`` has not changed over the ``settle_s`` before them."""
    now = f(t)
    return np.all([f(np.maximum(t - d, t[0])) == now for d in np.linspace(0.0, settle_s, 11)], axis=0)


# ----------------------------------------------------------------------------- one fit


def _config(values: Mapping[str, float], experiment: Experiment | None = None) -> EvaluationConfig:
    """The error model with ``values``, the twin's default columns, no true wear; the factors
    and the added thermometers of ``experiment`` (default: every factor, the eight)."""
    if experiment is None:
        return EvaluationConfig(**_coefficient_fields(values), true_wear=None)
    temperatures = {**Columns().temperatures, **experiment.temperatures}
    return EvaluationConfig(
        **_coefficient_fields(values), true_wear=None, temperatures=temperatures, factors=experiment.factors
    )


def _coefficient_fields(values: Mapping[str, float]) -> dict[str, Any]:
    return {
        "thermal": ThermalCoefficients.from_values(values, source="twin identify"),
        "mechanics": MechanicalCoefficients.from_values(values, source="twin identify"),
    }


def _lag1(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of the residuals, in [0, 0.99]."""
    if len(r) < 3 or not np.any(r):
        return 0.0
    rho = float(np.dot(r[1:], r[:-1]) / np.dot(r, r))
    return min(max(rho, 0.0), 0.99)


@dataclass
class _Block:
    """One record's rows of a fit: the target, its nuisance columns (orthonormal), the model's
    prediction part by part (each factor's, at the used samples) as a function of the fitted
    parameters, and the noise level."""

    target: np.ndarray
    basis: np.ndarray
    #: the parts of the prediction at p: every factor's, or those named, in the factors' order
    parts: Callable[[np.ndarray, Sequence[str] | None], list[np.ndarray]]
    sigma: float = 1.0
    rms: float = 0.0
    inflation: float = 1.0
    #: the residual's affine part once :meth:`linearise` found it: the point p0, the residual
    #: there and its slope (nuisance projected out) of every part but the ``moving`` ones
    affine: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    #: the parts that are not affine in the parameters: evaluated at every p
    moving: tuple[str, ...] = ()

    def project(self, r: np.ndarray) -> np.ndarray:
        """``r`` with the nuisance columns projected out."""
        return r - self.basis @ (self.basis.T @ r)

    def predict(self, p: np.ndarray) -> np.ndarray:
        """The model's prediction at ``p`` (its parts summed in the factors' order)."""
        return np.sum(self.parts(p, None), axis=0)

    @property
    def is_affine(self) -> bool:
        """Every part affine: the residual is r0 - slope (p - p0)."""
        return self.affine is not None and not self.moving

    def residual(self, p: np.ndarray) -> np.ndarray:
        """Target minus model, the nuisance projected out (not whitened)."""
        if self.affine is None:
            return self.project(self.target - self.predict(p))
        p0, r0, slope = self.affine
        r = r0 - slope @ (p - p0)
        if self.moving:
            r = r - self.project(np.sum(self.parts(p, self.moving), axis=0))
        return r

    def linearise(self, p0: np.ndarray, steps: np.ndarray) -> bool:
        """Keep each part's affine form where it has one: most coefficients multiply a recorded
        signal (a body's growth its temperature rise, a compliance the load, a drift the
        frame's thermometer, the clamp's rotation the torque), and most parts of a fit do not
        depend on its parameters at all (the thermal one in the runout's fit).

        A part's form: its prediction at ``p0`` and its change over one step of each parameter
        (``steps``), checked against the part at two further points, each parameter moved by a
        quarter to three quarters of a step either way (never to zero: a step may be the value
        itself). A part that misses (the runout's phase, the probe's scale: a cosine,
        a division) is ``moving``: evaluated at every trial point, and the fit takes finite
        differences. Every part affine, the fit evaluates the model n + 3 times instead of once
        per residual and n times per Jacobian, and its Jacobian is exact; else each residual
        evaluates the moving parts only. True when the block is affine. A model that cannot be
        evaluated at a point of the check (an ArithmeticError) is kept whole, as without it.
        """
        try:
            return self._linearise(p0, steps)
        except ArithmeticError:
            self.affine, self.moving = None, ()
            return False

    def _linearise(self, p0: np.ndarray, steps: np.ndarray) -> bool:
        n = len(p0)
        f0 = self.parts(p0, None)
        names = [f.name for f in _FITTED]
        ups = [self.parts(p0 + s * e, None) for s, e in zip(steps, np.eye(n), strict=True)]
        slopes = [
            np.column_stack([(up[k] - f0[k]) / s for up, s in zip(ups, steps, strict=True)])
            for k in range(len(f0))
        ]
        affine = [True] * len(f0)
        signs = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
        for z in (0.5 * signs, -signs * (0.25 + 0.5 * np.arange(n) / max(n - 1, 1))):
            at = self.parts(p0 + steps * z, None)
            for k, (f, base, slope) in enumerate(zip(at, f0, slopes, strict=True)):
                change = slope @ (steps * z)
                size = max(float(np.max(np.abs(base))), float(np.max(np.abs(change))), 1e-300)
                affine[k] &= float(np.max(np.abs(f - base - change))) <= AFFINE_RTOL * size
        kept = [k for k in range(len(f0)) if affine[k]]
        fixed = np.sum([f0[k] for k in kept], axis=0) if kept else np.zeros_like(self.target)
        slope = np.sum([slopes[k] for k in kept], axis=0) if kept else np.zeros((len(self.target), n))
        self.affine = (p0.copy(), self.project(self.target - fixed), self.project(slope))
        self.moving = tuple(names[k] for k in range(len(f0)) if not affine[k])
        return self.is_affine

    def measure(self, p: np.ndarray) -> tuple[np.ndarray, int]:
        """The residuals at ``p`` and their degrees of freedom before the fit's parameters
        (the nuisance columns taken); keeps this record's own RMS and lag-1 inflation for the
        report."""
        r = self.residual(p)
        dof = max(len(r) - self.basis.shape[1], 1)
        rho = _lag1(r)
        self.rms = max(float(np.sqrt(np.dot(r, r) / dof)), 1e-15)
        self.inflation = math.sqrt((1 + rho) / (1 - rho))
        return r, dof


def noise_levels(blocks: Sequence[_Block], p: np.ndarray, n_params: int) -> bool:
    """Each record's noise level: its residuals' spread, inflated by sqrt((1 + rho) / (1 - rho))
    for their lag-1 correlation rho, but never below the fit's common level (the same of all its
    records pooled). True when no level moved by 1 % or more.

    One DAQ made every record, so none is less noisy than the common level; a record the model
    fits worse than that carries misfit, and counts less. Without the floor a record that fits
    well sets its own small level and outweighs the others, which then fit worse and count less
    still: on some testers as built that feedback ended with the soak and the pole heating
    discounted 14-fold and the thermal fit resting on the cool-down alone (issue 12).
    """
    rr = lag = 0.0
    dof = 0
    for b in blocks:
        r, d = b.measure(p)
        rr += float(np.dot(r, r))
        lag += float(np.dot(r[1:], r[:-1]))
        dof += d
    rho = min(max(lag / rr, 0.0), 0.99) if rr > 0 else 0.0
    common = max(math.sqrt(rr / max(dof - n_params, 1)), 1e-15) * math.sqrt((1 + rho) / (1 - rho))
    levels = [max(common, b.rms * b.inflation) for b in blocks]
    settled = all(abs(level / b.sigma - 1.0) < 0.01 for level, b in zip(levels, blocks, strict=True))
    for level, b in zip(levels, blocks, strict=True):
        b.sigma = level
    return settled


@dataclass
class _Problem:
    """One fit's least-squares problem in scaled parameters z = (p - start) / scale."""

    names: tuple[str, ...]
    start: np.ndarray
    scale: np.ndarray
    prior_sigma: np.ndarray  # inf where the prior is flat
    blocks: list[_Block]

    def params(self, z: np.ndarray) -> np.ndarray:
        return self.start + self.scale * z

    def data(self, z: np.ndarray) -> np.ndarray:
        """The whitened data residuals of every block, stacked."""
        p = self.params(z)
        return np.concatenate([b.residual(p) / b.sigma for b in self.blocks])

    def residual(self, z: np.ndarray) -> np.ndarray:
        prior = self.scale * z / self.prior_sigma  # zero rows for flat priors
        return np.concatenate([self.data(z), prior])

    @property
    def affine(self) -> bool:
        """Every block's model is affine in the parameters (:meth:`_Block.linearise`)."""
        return all(b.is_affine for b in self.blocks)

    def jacobian(self, z: np.ndarray, h: float = 1e-3) -> np.ndarray:
        """The whitened data residuals' derivatives in z: the affine form's slope where every
        block has one, else central differences."""
        if self.affine:
            return np.vstack([-b.affine[2] * self.scale / b.sigma for b in self.blocks])  # type: ignore[index]
        step = h * np.eye(len(z))
        return np.column_stack([(self.data(z + d) - self.data(z - d)) / (2 * h) for d in step])

    def compressed(self) -> tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]:
        """An affine problem's residual in n + 1 + n rows with the same sum of squares at every
        z, and its (constant) Jacobian.

        The whitened data residuals are d(z) = b + A z. With A = QR, ||b + A z||^2 =
        ||Q^T b + R z||^2 + ||b - Q Q^T b||^2: the n rows Q^T b + R z, one constant row for the
        part of b no parameter reaches, then the priors' rows. The solver sees the same cost,
        gradient and J^T J as with every sample's row (thousands), at the cost of n rows.
        """
        n = len(self.names)
        a = self.jacobian(np.zeros(n))
        b = self.data(np.zeros(n))
        q, r = np.linalg.qr(a)
        c = q.T @ b
        rest = np.array([float(np.linalg.norm(b - q @ c))])
        prior = self.scale / self.prior_sigma  # zero for flat priors
        jac = np.vstack([r, np.zeros((1, n)), np.diag(prior)])

        def residual(z: np.ndarray) -> np.ndarray:
            return np.concatenate([c + r @ z, rest, prior * z])

        return residual, jac

    def bounds(self, lower: Mapping[str, float]) -> np.ndarray:
        """The scaled lower bounds (-inf where none)."""
        lo = [
            (lower[n] - s) / c if n in lower else -np.inf
            for n, s, c in zip(self.names, self.start, self.scale, strict=True)
        ]
        return np.array(lo)


#: the factors a fit's model sums: all but the interference, which the robust filter took out
_FITTED = tuple(f for f in FACTORS if f.name != "interference")


def _block(record: Record, values: Mapping[str, float], names: Sequence[str]) -> _Block:
    """The rows of one record: its cleaned reading's change minus the known displacement,
    against the error model's factors (interference aside) with trial coefficients."""
    cfg = _config(values, record.experiment)
    measured = Measured.read(record.table, cfg, tester_model())
    used = record.used
    target = (measured.cleaned - measured.cleaned[0] - (record.known - record.known[0]))[used]
    t = record.table.time[used]
    basis, _ = np.linalg.qr(np.column_stack(_nuisance(record.experiment.nuisance, t, record.known[used])))

    def parts(p: np.ndarray, which: Sequence[str] | None) -> list[np.ndarray]:
        trial = {**values, **dict(zip(names, p.tolist(), strict=True))}
        m = replace(measured, cfg=replace(cfg, **_coefficient_fields(trial)))
        return [f.contribution(m).e_z[used] for f in _FITTED if which is None or f.name in which]

    # a first guess of the noise: the robust spread of the first differences
    diffs = np.diff(target)
    sigma = 1.4826 * float(np.median(np.abs(diffs - np.median(diffs)))) / math.sqrt(2)
    return _Block(target, basis, parts, max(sigma, 1e-12))


def _nuisance(kinds: Sequence[str], t: np.ndarray, known: np.ndarray) -> list[np.ndarray]:
    """The nuisance columns of a record's used samples: a constant, a line in time, one
    indicator per known position (see :class:`Experiment`)."""
    out = []
    for kind in kinds:
        if kind == "offset":
            out.append(np.ones(len(t)))
        elif kind == "drift":
            out.append((t - t[0]) / max(t[-1] - t[0], 1.0))
        else:  # position
            out += [(known == k).astype(float) for k in np.unique(known)]
    return out


def _scale(prior: Prior) -> float:
    """The size of a parameter's steps: its prior's sigma, else its start value's size, else
    one (an angle in rad)."""
    if prior.sigma is not None:
        return prior.sigma
    return 1.0 if prior.unit == "rad" or prior.value == 0 else abs(prior.value)


def _problem(
    cal: Calibration,
    records: Sequence[Record],
    values: Mapping[str, float],
    priors: Mapping[str, Prior],
    linearise: bool = True,
) -> _Problem:
    """The fit's problem; ``linearise``: each block's affine form where it has one
    (:meth:`_Block.linearise`; False: the model at every trial point, as a check of it)."""
    names = cal.fit
    start = np.array([priors[n].value for n in names])
    sigma = np.array([math.inf if priors[n].sigma is None else priors[n].sigma for n in names])
    scale = np.array([_scale(priors[n]) for n in names])
    blocks = [_block(r, values, names) for r in records]
    if linearise:
        for b in blocks:
            b.linearise(start, scale)
    return _Problem(names, start, scale, sigma, blocks)


def _starts(cal: Calibration, prob: _Problem) -> list[np.ndarray]:
    """The scaled start vectors: the priors' values, and one more per extra start value."""
    out = [np.zeros(len(prob.names))]
    for name, extra in cal.starts.items():
        i = prob.names.index(name)
        for v in extra:
            z = np.zeros(len(prob.names))
            z[i] = (v - prob.start[i]) / prob.scale[i]
            out.append(z)
    return out


def _solve(prob: _Problem, z0s: Sequence[np.ndarray], lo: np.ndarray) -> np.ndarray:
    """The best of the least-squares solutions from the start vectors ``z0s``."""
    from scipy.optimize import least_squares

    if prob.affine:
        residual, jac = prob.compressed()
        solutions = [
            least_squares(residual, np.maximum(z0, lo), jac=lambda _: jac, bounds=(lo, np.inf), method="trf")
            for z0 in z0s
        ]
    else:
        solutions = [
            least_squares(prob.residual, np.maximum(z0, lo), bounds=(lo, np.inf), method="trf") for z0 in z0s
        ]
    return min(solutions, key=lambda sol: sol.cost).x


def fit_calibration(
    cal: Calibration,
    records: Sequence[Record],
    values: Mapping[str, float],
    priors: Mapping[str, Prior],
    *,
    linearise: bool = True,
) -> tuple[dict[str, Coefficient], Fit]:
    """Fit the coefficients of ``cal`` to its experiments' ``records``, the others at ``values``.

    The noise levels are found with the fit: from each record's first differences at first,
    then from the residuals (serial-correlation inflated, each record's own but not below the
    records' common level: :func:`noise_levels`), refitting until they settle. ``linearise``
    False evaluates the model at every trial point even where it is affine (the check of
    :meth:`_Block.linearise`: both find the same optimum).
    """
    prob = _problem(cal, records, values, priors, linearise)
    lo = prob.bounds(cal.lower)
    z = _solve(prob, _starts(cal, prob), lo)
    for _ in range(8):
        if noise_levels(prob.blocks, prob.params(z), len(z)):
            break
        z = _solve(prob, [z], lo)
    return _report(cal, [r.experiment.name for r in records], prob, z, priors)


def _report(
    cal: Calibration, experiments: Sequence[str], prob: _Problem, z: np.ndarray, priors: Mapping[str, Prior]
) -> tuple[dict[str, Coefficient], Fit]:
    """Values, standard errors, correlation and the diagnostics of the fit at ``z``."""
    jd = prob.jacobian(z)  # whitened data rows
    jp = np.diag(prob.scale / prob.prior_sigma)  # prior rows (zero for flat priors)
    info = jd.T @ jd + jp.T @ jp
    if np.linalg.matrix_rank(info) < len(z):
        raise RunError(f"the experiments {list(experiments)} do not determine all of {list(prob.names)}")
    cov = np.linalg.inv(info) * np.outer(prob.scale, prob.scale)
    se = np.sqrt(np.diag(cov))
    units = coefficient_units()
    out = {
        n: Coefficient(
            float(v), float(s), units[n], cal.name, priors[n] if priors[n].sigma is not None else None
        )
        for n, v, s in zip(prob.names, _canonical(prob.names, prob.params(z)), se, strict=True)
    }
    return out, Fit(
        parameters=prob.names,
        experiments=tuple(experiments),
        samples=tuple(len(b.target) for b in prob.blocks),
        residual_rms=tuple(b.rms for b in prob.blocks),
        noise_inflation=tuple(b.inflation for b in prob.blocks),
        correlation=tuple(tuple(float(x) for x in row) for row in cov / np.outer(se, se)),
        **_diagnostics(jd, jp, prob),
    )


def _canonical(names: Sequence[str], p: np.ndarray) -> list[float]:
    """Angles (unit rad) wrapped to [-pi, pi]."""
    units = coefficient_units()
    return [
        math.remainder(v, 2 * math.pi) if units[n] == "rad" else float(v)
        for n, v in zip(names, p, strict=True)
    ]


def _diagnostics(jd: np.ndarray, jp: np.ndarray, prob: _Problem) -> dict[str, Any]:
    """Rank and condition numbers of the data's Jacobian and of the regularised problem."""
    norms = np.linalg.norm(jd, axis=0)
    s = np.linalg.svd(jd / np.where(norms > 0, norms, 1.0), compute_uv=False)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s[0] > 0 else 0
    # the data's singular values in units of the prior sigmas (a flat prior: very wide)
    width = np.where(np.isfinite(prob.prior_sigma), prob.prior_sigma, FLAT * prob.scale) / prob.scale
    informative = int(np.sum(np.linalg.svd(jd * width, compute_uv=False) >= 1.0))
    s_all = np.linalg.svd(np.vstack([jd, jp]), compute_uv=False)
    return {
        "rank": rank,
        "informative_directions": informative,
        "condition_number": float(s[0] / s[-1]) if s[-1] > 0 else math.inf,
        "condition_number_identifiable": float(s[0] / s[rank - 1]) if rank else math.inf,
        "condition_number_regularised": float(s_all[0] / s_all[-1]) if s_all[-1] > 0 else math.inf,
        "singular_values": tuple(float(x) for x in s),
    }


# ----------------------------------------------------------------------------- all of them


def fit_records(
    records: Mapping[str, Record],
    priors: Mapping[str, Prior],
    identified: Mapping[str, Any] | None = None,
    calibrations: Sequence[Calibration] = CALIBRATIONS,
    *,
    linearise: bool = True,
) -> Coefficients:
    """Fit the calibrations in order, each with what the others found, to the records (by
    experiment name) of their experiments: :data:`PASSES` times over, as the fits depend on
    each other through the experiments (the cool-down of the thermal fit runs under load, so
    the liner creeps in it; the load hold warms a little, so it drifts), the first pass with
    the priors' values for what is not fitted yet, the next with the pass before's.

    A coefficient no calibration fits keeps its prior, with the prior's sigma as its standard
    error (its experiment says "prior"); one without a prior sigma is an error. ``linearise``:
    see :func:`fit_calibration`.
    """
    values = {n: p.value for n, p in priors.items()}
    found: dict[str, Coefficient] = {}
    fits: dict[str, Fit] = {}
    for _ in range(PASSES):
        for cal in calibrations:
            coefficients, fits[cal.name] = fit_calibration(
                cal, [records[e] for e in cal.experiments], values, priors, linearise=linearise
            )
            found.update(coefficients)
            values.update({n: c.value for n, c in coefficients.items()})
    for name in coefficient_units():
        prior = priors[name]
        if name not in found and prior.sigma is None:
            raise ConfigError(
                f"no calibration fits {name} and its prior has no sigma", source="twin identify"
            )
        found.setdefault(name, Coefficient(prior.value, prior.sigma or 0.0, prior.unit, "prior", prior))
    ordered = {n: found[n] for n in coefficient_units()}
    return Coefficients(ordered, fits, dict(identified or {}))
