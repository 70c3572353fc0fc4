"""System Structure and Parameterization (SSP 1.0) read as a scenario: ``twin run tester.ssp``.

An SSP archive (from the twin's ``twin export-ssp``, :mod:`twin.exchange.ssp`, or another FMI
tool) is read back as the system of a run. The archive is checked (members confined to it,
sizes bounded, no XML document type, every ``.ssd``, ``.ssv`` and ``.ssm`` valid against the
SSP 1.0 schema: :mod:`~twin.config.ssp.archive`), its FMUs are unpacked into a folder named by
the archive's SHA-256 under the FMU cache and run as external FMUs (:mod:`twin.fmu.external`),
and the rest becomes an ordinary scenario's data (``--set`` works as for a TOML file), which
:mod:`twin.config.load` checks as it checks a TOML file's.

Applied (:mod:`~twin.config.ssp.system`, :mod:`~twin.config.ssp.values`):

- components (FMUs of the archive, co-simulation), their connectors (each must name a variable
  of the FMU, of its causality and type, in its unit);
- connections from a Real output to a Real input, with ``ssc:LinearTransformation`` and the
  conversion between the two ends' units (SSP: the conversion first, then the transformation;
  none with ``suppressUnitConversion``) folded into the connection's factor and offset;
- parameter bindings: ``.ssv`` files and inline ``ssd:ParameterValues``, with a ``prefix``, a
  parameter mapping (``.ssm`` or inline) and its transformations, on components and on the
  system (``component.variable`` names, taking precedence); Real values in their unit converted
  to the variable's, Integer, Boolean and Enumeration values; a value of an input is its start
  value, held (the twin drives it as a constant);
- an input nothing connects stays at its start value: marked as meant (``unconnected``);
- the default experiment: stop time as the duration, a start time of 0 only;
- libcosim's annotations (``com.opensimulationplatform``): the fixed step, each component's
  step; without them the step is missing and the check asks for ``--step-size``;
- the twin's annotations (``io.github.twin``): output interval, seed, drift window, wear limit,
  the ``[errormodel]``, ``[uncertainty]`` and ``[reference]`` tables with their files, delayed
  connections, parameter sources and standard errors, and the profiles its export carries as
  SignalSource components (read back as the profiles they came from).

Refused, each with one line naming the file and the element (exit 2): signal dictionaries,
nested systems, components that are not FMUs or run as model exchange, sources outside the
archive, connections to the system's own connectors, connections that are not output to input
or not Real (the master exchanges Real outputs only), mapping transformations on connections,
Binary and String values, annotations of libcosim or the twin this version does not know,
parameter values for variables an FMU lacks, and anything else the SSP 1.0 schema allows that
the reader does not apply. Graphical elements (geometry) and other tools' annotations change
nothing and are passed over.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from twin.config.ssp.archive import Archive, discard_unpacked
from twin.config.ssp.names import NS, OSP_TYPE, SSD_NAME, TWIN_TYPE, TYPES, q, seconds, value_text
from twin.config.ssp.system import PROFILE_KINDS, SOURCE_MODEL, read_system
from twin.errors import ConfigError, ConfigErrors

__all__ = [
    "NS",
    "OSP_TYPE",
    "PROFILE_KINDS",
    "SOURCE_MODEL",
    "SSD_NAME",
    "TWIN_TYPE",
    "TYPES",
    "discard_unpacked",
    "finish_ssp_data",
    "q",
    "read_ssp_data",
    "seconds",
    "value_text",
]


def read_ssp_data(path: Path) -> dict[str, Any]:
    """An SSP archive as a scenario's data (the tables of a scenario file), its FMUs unpacked.

    :class:`ConfigError` lines (the archive, the file in it, the element, what is wrong) for an
    archive the twin cannot run as it is written. A step or duration it does not give is left
    out: :func:`finish_ssp_data` names it once the command line had its say.
    """
    archive = Archive.open(path)
    try:
        return read_system(archive)
    except BaseException:
        discard_unpacked(path)
        raise


def finish_ssp_data(data: dict[str, Any], source: str) -> None:
    """An archive's data after ``--set`` (and ``--step-size``): the step and the duration must
    be given by now, and a component without its own step steps at the scenario's."""
    scenario = data.get("scenario")
    if not isinstance(scenario, dict):
        return  # the [scenario] check names it
    missing = []
    if "step" not in scenario:
        missing.append(
            ConfigError(
                "missing: the SSP gives no step; give --step-size or --set scenario.step=...",
                source=source,
                key="scenario.step",
            )
        )
    if "duration" not in scenario:
        missing.append(
            ConfigError(
                "missing: the SSP gives no stop time; give --stop-time or --set scenario.duration=...",
                source=source,
                key="scenario.duration",
            )
        )
    if missing:
        raise ConfigErrors(missing)
    scenario.setdefault("output_interval", scenario["step"])
    for spec in data.get("fmu", {}).values():
        if isinstance(spec, dict):
            spec.setdefault("period", scenario["step"])
