"""What a lab's DAQ records of a run: its channels and nothing else.

A lab does not know its tester's expansion coefficients, lengths or compliances; it records the
eight temperatures, the probe, the load cell, the torque sensor, the angle encoder and the
vibration pickup (:func:`twin.errormodel.identify.lab_channels`). A calibration experiment run on
the twin (``twin identify``, each tester of ``twin heldout``) keeps exactly those, so no fit
can see a true or internal value of the twin.
"""

from __future__ import annotations

from twin.config.spec import Scenario
from twin.errormodel.identify import Experiment, Record, known_displacement, lab_channels
from twin.errors import ConfigError, RunError
from twin.pipeline.prepare import prepare_scenario
from twin.pipeline.stages import simulate

__all__ = ["lab_record"]


def lab_record(experiment: Experiment, scenario: Scenario, digest: str = "") -> Record:
    """Run ``experiment``'s ``scenario`` on the twin and keep what a lab's DAQ records, with the
    known displacement at each sample and the samples its fit uses; ``digest`` names what ran."""
    prepared = prepare_scenario(scenario)
    channels = lab_channels(experiment=experiment)
    missing = sorted(channels - prepared.plan.column_names())
    if missing:
        raise ConfigError(f"the experiment records no {', '.join(missing)}", source="twin identify")
    simulation = simulate(prepared, keep=channels)
    result = simulation.result
    if result.status != "completed":
        raise RunError(f"calibration experiment {experiment.name!r} {result.status}: {result.error}")
    table = simulation.table
    known, used = known_displacement(scenario, experiment, table.time)
    return Record(experiment, table, known, used, digest)
