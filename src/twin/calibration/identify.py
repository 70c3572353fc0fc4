"""``twin identify``: the error model's coefficients from calibration experiments run on the
twin, as a lab runs them on its tester.

Each experiment of :data:`twin.errormodel.identify.EXPERIMENTS` (``scenarios/calibration/``)
runs on the tester as built (``--set`` values apply to every experiment: each is the whole
tester), recording only a lab's DAQ channels (:func:`twin.pipeline.lab.lab_record`); the fits
(:func:`twin.errormodel.identify.fit_records`) make the coefficients file, with each
experiment's provenance (the hash of the scenario it ran) and the FMUs' source hashes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from twin import __version__
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import Coefficients, Prior, load_priors
from twin.errormodel.identify import CALIBRATIONS, EXPERIMENTS, Calibration, Experiment, Record, fit_records
from twin.errormodel.sources import ThermalCoefficients
from twin.fmu.build import source_hash
from twin.fmu.catalog import model_names
from twin.outputs.run_folder import scenario_fingerprint
from twin.pipeline.lab import lab_record
from twin.uncertainty.testers import instance_of

#: a growth identified below this (m/K) sits at its bound 0 (the bounded solver's zero)
AT_BOUND = 1e-12

__all__ = ["HEADER", "identify", "lab_records", "report_lines", "run_experiment"]

HEADER = """Coefficients of the error model, identified by `twin identify` from the calibration
experiments in scenarios/calibration/ (DAQ channels only; priors from priors.toml).
Made by a program: rerun `twin identify` to reproduce, do not edit by hand.
Each coefficient: value, one standard error, unit, the experiment it came from and the prior
that entered its fit; each fit: rank and condition numbers, residual and correlation."""


def run_experiment(
    experiment: Experiment, overrides: Sequence[str] = (), folder: Path | None = None
) -> Record:
    """Run one calibration experiment on the twin (its scenario in ``folder``, default the
    shipped ``calibration/``, with ``overrides``) and keep what a lab's DAQ records.

    An override of an FMU instance the experiment does not have is left out: the tester as
    built is one set of values, and the probe heated on its bench has no frame or pole."""
    path = (folder or scenarios_dir() / "calibration") / experiment.scenario
    instances = {f.name for f in load_scenario(path).fmus}
    kept = [o for o in overrides if instance_of(o.split("=", 1)[0].strip()) in (None, *instances)]
    scenario = load_scenario(path, kept)
    return lab_record(experiment, scenario, scenario_fingerprint(scenario))


def identify(
    overrides: Sequence[str] = (),
    *,
    priors: Mapping[str, Prior] | None = None,
    calibrations: Sequence[Calibration] = CALIBRATIONS,
    per_experiment: Mapping[str, Sequence[str]] | None = None,
    folder: Path | None = None,
    records: Mapping[str, Record] | None = None,
) -> Coefficients:
    """Run the calibration experiments on the twin and fit the error model's coefficients.

    ``overrides`` (``--set KEY=VALUE``) make the tester as built: they apply to every
    experiment, ``per_experiment`` adds some to one experiment only (by name). ``priors``
    default to ``scenarios/calibration/priors.toml``. In process and without files.
    ``records`` (a lab's own, :func:`lab_records`) are fitted instead of runs on the twin.
    """
    priors = load_priors() if priors is None else priors
    per_experiment = per_experiment or {}
    lab = records is not None
    needed = {e for cal in calibrations for e in cal.experiments}
    if records is None:
        records = {
            e.name: run_experiment(e, [*overrides, *per_experiment.get(e.name, ())], folder)
            for e in EXPERIMENTS
            if e.name in needed
        }
    lab_named = set(records) if lab else set()
    identified = {
        "by": "twin identify",
        "twin_version": __version__,
        "overrides": list(overrides),
        "fmu_sources": {name: source_hash(name) for name in model_names()},
        "experiments": {
            name: {
                "scenario": r.experiment.scenario,
                "sha256": r.scenario_sha256,  # a lab's record: the hash of its file
                "overrides": list(per_experiment.get(name, ())),
                "record": "lab" if name in lab_named else "twin",
            }
            for name, r in records.items()
        },
    }
    return fit_records(records, priors, identified, calibrations)


def report_lines(c: Coefficients) -> list[str]:
    """One line per fit and per coefficient, for the terminal."""
    lines = []
    for name, fit in c.fits.items():
        residuals = ", ".join(
            f"{e} {n} samples, residual {r * 1e6:.3f} um"
            for e, n, r in zip(fit.experiments, fit.samples, fit.residual_rms, strict=True)
        )
        lines.append(
            f"{name}: {residuals}; rank {fit.rank} of {len(fit.parameters)}, "
            f"{fit.informative_directions} beyond the priors, condition "
            f"{fit.condition_number_identifiable:.3g} (with priors {fit.condition_number_regularised:.3g})"
        )
    growths = ThermalCoefficients.growths()
    for name, x in c.coefficients.items():
        prior = f" (prior {x.prior.value:.4g} +- {x.prior.sigma:.2g})" if x.prior and x.prior.sigma else ""
        bound = ", at its bound 0" if name in growths and x.value < AT_BOUND else ""
        lines.append(f"  {name} = {x.value:.6g} +- {x.std_error:.2g} {x.unit} [{x.experiment}{bound}]{prior}")
    return lines


def lab_records(
    folder: Path, config: Path, calibrations: Sequence[Calibration] = CALIBRATIONS
) -> dict[str, Record]:
    """A lab's own records of the calibration experiments: ``folder`` holds one CSV per
    experiment, named as its scenario (``thermal-soak.csv`` for ``thermal-soak.toml``), its
    columns and units named by ``config`` (a LAB.toml, as ``twin compensate`` reads it). The
    experiments' designs (loads, gauge blocks, what each fit uses) are the shipped calibration
    scenarios'. Every experiment the fits need must be there: the fits depend on each other
    (:func:`~twin.errormodel.identify.fit_records`), so a set that mixed a lab's records with
    the twin's runs would fit a tester that is neither."""
    from twin.config.reader import Problems
    from twin.pipeline.compensation import lab_config
    from twin.pipeline.lab import recorded

    lab = lab_config(config)
    needed = [e for e in EXPERIMENTS if any(e.name in cal.experiments for cal in calibrations)]
    p = Problems(str(folder))
    for e in needed:
        csv = folder / (Path(e.scenario).stem + ".csv")
        if not csv.is_file():
            p.add(e.name, f"no record {csv.name} (the lab's record of calibration/{e.scenario})")
    p.check()
    calibration = scenarios_dir() / "calibration"
    return {
        e.name: recorded(
            e, load_scenario(calibration / e.scenario), folder / (Path(e.scenario).stem + ".csv"), lab
        )
        for e in needed
    }
