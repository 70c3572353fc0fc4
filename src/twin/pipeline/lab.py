"""What a lab's DAQ records of a run: its channels and nothing else.

A lab does not know its tester's expansion coefficients, lengths or compliances; it records the
eight temperatures, the probe, the load cell, the torque sensor, the angle encoder and the
vibration pickup (:func:`twin.errormodel.identify.lab_channels`). A calibration experiment run on
the twin (``twin identify``, each tester of ``twin heldout``) keeps exactly those, so no fit
can see a true or internal value of the twin; a lab's own record of the same experiment
(:func:`recorded`, ``twin identify --records DIR``) is read into the same form.
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

from twin.config.spec import Scenario
from twin.errormodel.identify import LAB_FIELDS, Experiment, Record, known_displacement, lab_channels
from twin.errormodel.sources import Columns
from twin.errors import ConfigError, RunError
from twin.fmu.pool import SlotPool
from twin.pipeline.compensation import LabConfig
from twin.pipeline.prepare import prepare_scenario
from twin.pipeline.stages import simulate
from twin.signals.csv import CsvReader, Flag
from twin.signals.table import Block, Signal, SignalTable

__all__ = ["lab_record", "recorded"]


def lab_record(
    experiment: Experiment, scenario: Scenario, digest: str = "", pool: SlotPool | None = None
) -> Record:
    """Run ``experiment``'s ``scenario`` on the twin and keep what a lab's DAQ records, with the
    known displacement at each sample and the samples its fit uses; ``digest`` names what ran,
    ``pool`` reuses FMU instances (:mod:`twin.fmu.pool`)."""
    prepared = prepare_scenario(scenario)
    channels = lab_channels(experiment=experiment)
    missing = sorted(channels - prepared.plan.column_names())
    if missing:
        raise ConfigError(f"the experiment records no {', '.join(missing)}", source="twin identify")
    simulation = simulate(prepared, keep=channels, pool=pool)
    result = simulation.result
    if result.status != "completed":
        raise RunError(f"calibration experiment {experiment.name!r} {result.status}: {result.error}")
    table = simulation.table
    known, used = known_displacement(scenario, experiment, table.time)
    return Record(experiment, table, known, used, digest)


def recorded(experiment: Experiment, scenario: Scenario, csv: Path, lab: LabConfig) -> Record:
    """A lab's own record of ``experiment`` (``csv``, its columns and units as ``lab``, a
    LAB.toml, names them), in the twin's channel names and SI, with the known displacement and
    the samples its fit uses from the experiment's design (``scenario``: the lab ran the design
    the twin's calibration scenario describes, its times counted from the record's start).

    Rows the error model cannot use are left out as ``twin compensate`` leaves them (their
    count on stderr); a column the experiment's fits read missing is refused naming its key.
    """
    cfg, twin_names = lab.cfg, Columns()
    # the paper's eight thermometers, and those the experiment adds (the probe's bench: one on
    # the probe's body), mapped by measuring point to the twin's channels
    points = [*twin_names.temperatures, *experiment.temperatures]
    lacking = [pt for pt in experiment.temperatures if pt not in cfg.temperatures]
    if lacking:
        raise ConfigError(
            f"the record of {experiment.name} needs a thermometer on {', '.join(lacking)}: name its column "
            f"in [errormodel] temperatures ({', '.join(f'{pt} = ...' for pt in lacking)})",
            source=lab.source,
            key=f"errormodel.temperatures.{lacking[0]}",
        )
    twin_points = {**twin_names.temperatures, **experiment.temperatures}
    rename = {cfg.temperatures[pt]: twin_points[pt] for pt in points}
    rename |= {
        lab_col: twin_col
        for fld in LAB_FIELDS
        if fld != "temperatures"
        for lab_col, twin_col in zip(cfg.names(fld), twin_names.names(fld), strict=True)
    }
    required = {cfg.reading: "reading", **{cfg.temperatures[pt]: f"temperatures.{pt}" for pt in points}}
    flags: list[Flag] = []
    reader = CsvReader(
        csv,
        (required, lab.source),
        set(rename),
        on_flag=flags.append,
        time_column=lab.units.time,
    )
    try:
        blocks = [lab.units.to_si(b, reader.source) for b in reader.blocks()]
    finally:
        reader.close()
    if sum(len(b) for b in blocks) < 2:
        raise ConfigError(f"fewer than two usable rows ({reader.read_rows} read)", source=str(csv))
    if flags:
        print(
            f"twin: {csv}: {len(flags)} row(s) left out (first: line {flags[0].line}: {flags[0].reason})",
            file=sys.stderr,
        )
    data = Block.join(blocks)
    time = data.time - data.time[0]  # the design's clock starts with the record
    table = SignalTable(time=time)
    for lab_col, values in data.columns.items():
        table.add(Signal(rename[lab_col], "", "measured"), values)
    known, used = known_displacement(scenario, experiment, time)
    return Record(experiment, table, known, used, hashlib.sha256(csv.read_bytes()).hexdigest())
