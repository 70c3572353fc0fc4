"""Calibration records in ``twin update``'s likelihood: the probe heated alone on its bench.

A lab's probe-heating record (the design of ``scenarios/calibration/probe-heating.toml``, the
record a CSV named by its LAB.toml as ``twin identify --records`` reads it) identifies the
probe's zero drift (m/K) and span drift (1/K) with their standard errors, by ``twin identify``'s
own fit (:data:`twin.errormodel.identify.CALIBRATIONS`' ``probe_drift``), its priors on the two
made flat: the update's prior on them is the prior file's, and counting the calibration
priors too would count one belief twice.

The link (the update's likelihood terms): the probe on the bench is the tester's probe with its
conditioner, and what it drifts per kelvin of its own body there it drifts on the tester, so

    identified ~ N(fmu.sensors.parameters.probe_*_drift, standard error)

with the FMU parameters in the same units as the identified coefficients (m/K and 1/K: the
SensorsDAQ's ``probe_zero_drift`` and ``probe_span_drift``; the error model declares the same,
twin.errormodel.sources). What the link leaves out: a probe whose drift changes between the
bench and the tester (remounted, aged), and the fit's own form (the span drift read as a gain
on the indicated position): the standard error is the fit's, nothing is added for either.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = [
    "EXPERIMENT",
    "LINKS",
    "Bench",
    "identified_links",
    "lab_bench_records",
    "links_summary",
    "read_benches",
]

#: the one calibration record the update takes: twin identify's probe heated alone
EXPERIMENT = "probe_heating"
#: the identified coefficient -> the prior file's key it measures (the same units: m/K, 1/K)
LINKS = {
    "probe_zero_drift": "fmu.sensors.parameters.probe_zero_drift",
    "probe_span_drift": "fmu.sensors.parameters.probe_span_drift",
}
_KEYS = {"experiment", "record", "lab", "source"}


@dataclass(frozen=True)
class Bench:
    """A ``[[calibration]]`` table of a record file: the lab's CSV and its LAB.toml."""

    experiment: str
    record: Path
    lab: Path
    source: str


def read_benches(p: Any, raw: Any, folder: Path) -> tuple[Bench, ...]:
    """The record file's ``[[calibration]]`` tables (``p``: its :class:`~twin.config.reader.Problems`;
    paths relative to ``folder``), each problem one line."""
    if raw is None:
        return ()
    if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
        p.add("calibration", "expected [[calibration]] tables (experiment, record, lab, source)")
        return ()
    out = []
    for k, table in enumerate(raw):
        where = f"calibration[{k}]."
        p.unknown_keys(table, _KEYS, where)
        if table.get("experiment") != EXPERIMENT:
            p.add(
                f"{where}experiment",
                f"expected {EXPERIMENT!r} (the probe heated alone: the one bench record the update links to its parameters)",
            )
        files = {}
        for key in ("record", "lab"):
            value = table.get(key)
            files[key] = (folder / value).resolve() if isinstance(value, str) else None
            if files[key] is None or not files[key].is_file():
                p.add(f"{where}{key}", f"no such file {value!r}")
        if not isinstance(table.get("source"), str):
            p.add(f"{where}source", "expected a string: who took the record, on which probe")
        if all(files.values()):
            out.append(Bench(EXPERIMENT, files["record"], files["lab"], str(table.get("source", ""))))
    if len(raw) > 1:
        p.add("calibration", f"expected one {EXPERIMENT} record, got {len(raw)}")
    return tuple(out)


def identified_links(records: Sequence[Any]) -> dict[str, tuple[float, float]]:
    """The likelihood terms of bench ``records`` (twin.errormodel.identify.Record of the probe
    heated alone, a lab's or the twin's): prior file key -> (identified value, standard error)."""
    from twin.errormodel.coefficients import load_priors
    from twin.errormodel.identify import CALIBRATIONS, fit_calibration

    if not records:
        return {}
    priors = load_priors()
    flat = {n: dataclasses.replace(priors[n], sigma=None) for n in LINKS}
    calibration = next(c for c in CALIBRATIONS if c.experiments == (EXPERIMENT,))
    # the probe's fit alone: on the bench nothing else of the tester acts (no frame, no pole)
    priors = {**priors, **flat}
    fitted, _ = fit_calibration(
        calibration, list(records[:1]), {n: q.value for n, q in priors.items()}, priors
    )
    out = {}
    for name, key in LINKS.items():
        c = fitted[name]
        out[key] = (float(c.value), float(c.std_error))
    return out


def lab_bench_records(benches: Sequence[Bench]) -> list[Any]:
    """The benches' CSVs read as ``twin identify --records`` reads them (the experiment's
    design from the shipped calibration scenario)."""
    from twin.config.load import load_scenario, scenarios_dir
    from twin.errormodel.identify import EXPERIMENTS
    from twin.pipeline.compensation import lab_config
    from twin.pipeline.lab import recorded

    experiment = next(e for e in EXPERIMENTS if e.name == EXPERIMENT)
    design = load_scenario(scenarios_dir() / "calibration" / experiment.scenario)
    return [recorded(experiment, design, b.record, lab_config(b.lab)) for b in benches]


def links_summary(links: Mapping[str, tuple[float, float]], benches: Sequence[Bench]) -> dict[str, Any]:
    """summary.json's record of the calibration terms."""
    return {
        "records": [str(b.record) for b in benches],
        "terms": {k: {"identified": v, "standard_error": s} for k, (v, s) in links.items()},
        "link": "identified ~ N(the FMU parameter, the fit's standard error): the bench's probe is the tester's (m/K, 1/K)",
    }
