"""A scenario's system as an SSP 1.0 archive: ``twin export-ssp SCENARIO -o tester.ssp``.

* ``SystemStructure.ssd``: one ``ssd:Component`` per FMU instance (``source`` =
  ``resources/<Model>.fmu``) with its inputs, outputs and bound parameters as connectors, the
  connections, and a ``ssd:DefaultExperiment`` (start 0, stop = the scenario's duration);
* ``resources/<Model>.fmu``: the FMUs the twin runs (the very files of its cache);
* ``resources/<instance>.ssv``: each instance's parameter set (``ssv:ParameterSet``): its
  parameters (the seed the twin's master would give it included) and its inputs that the
  scenario holds constant, typed as the modelDescription declares them.

Annotations carry what SSP 1.0 has no element for: libcosim's (``com.opensimulationplatform``:
the fixed-step algorithm's base step, each component's step as ``osp:StepSizeHint``) and the
twin's own (``io.github.twin``: output interval, seed, drift window, and which connections are
delayed by one exchange, with their initial value). A tool that knows neither reads a plain
system. What the archive cannot hold: inputs driven by a time profile (ramp, exponential, sine,
table) and scheduled events; :func:`export_ssp` names each one it leaves out. The archive is
read back by :mod:`twin.config.ssp`.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from twin.config.spec import Scenario
from twin.config.ssp import NS, OSP_TYPE, SSD_NAME, TWIN_TYPE
from twin.config.ssp import TYPES as _TYPES
from twin.config.ssp import q as _q
from twin.config.ssp import seconds as _seconds
from twin.config.ssp import value_text as _value_text
from twin.files import write_atomic

__all__ = ["Exported", "export_ssp"]

# the standard's prefixes, literally: libcosim's reader looks elements up as "ssv:ParameterSet"
for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


@dataclass(frozen=True)
class Exported:
    """What :func:`export_ssp` wrote, and what the archive could not hold."""

    path: Path
    components: int
    connections: int
    left_out: tuple[str, ...]


def _values(scenario: Scenario) -> dict[str, dict[str, Any]]:
    """Each instance's parameter values (the master's seeds included) and constant inputs."""
    from twin.fmu.catalog import variables
    from twin.seeds import instance_seed

    out: dict[str, dict[str, Any]] = {}
    for i, spec in enumerate(scenario.fmus):
        values = {k: p.value for k, p in spec.parameters.items()}
        if "seed" in variables(spec.model) and "seed" not in values:
            values = {"seed": instance_seed(scenario.seed, i), **values}
        out[spec.name] = values
    for p in scenario.profiles:
        if p.kind == "constant":
            inst, var = p.target.split(".", 1)
            out[inst][var] = p.params["value"]
    return out


def _left_out(scenario: Scenario) -> tuple[str, ...]:
    """What an SSP archive cannot hold, one phrase each."""
    out = [f"input {p.target} ({p.kind} profile)" for p in scenario.profiles if p.kind != "constant"]
    out += [f"event at {_seconds(e.at_ns)} s ({e.action} {e.target})" for e in scenario.events]
    return tuple(out)


def _component(parent: ET.Element, spec: Any, source: str, values: Mapping[str, Any]) -> None:
    from twin.fmu.catalog import variables

    comp = ET.SubElement(
        parent, _q("ssd:Component"), name=spec.name, source=source, type="application/x-fmu-sharedlibrary"
    )
    connectors = ET.SubElement(comp, _q("ssd:Connectors"))
    for name, v in variables(spec.model).items():
        if v.causality not in ("input", "output") and name not in values:
            continue
        kind = _TYPES.get(v.type)
        if kind is None:
            continue
        c = ET.SubElement(connectors, _q("ssd:Connector"), name=name, kind=v.causality)
        t = ET.SubElement(c, _q(f"ssc:{kind}"))
        if kind == "Real" and v.unit:
            t.set("unit", v.unit)
    bindings = ET.SubElement(comp, _q("ssd:ParameterBindings"))
    ET.SubElement(bindings, _q("ssd:ParameterBinding"), source=f"resources/{spec.name}.ssv")
    annotations = ET.SubElement(comp, _q("ssd:Annotations"))
    osp = ET.SubElement(annotations, _q("ssc:Annotation"), type=OSP_TYPE)
    ET.SubElement(osp, _q("osp:StepSizeHint"), value=_seconds(spec.period_ns))


def _parameter_set(spec: Any, values: Mapping[str, Any]) -> bytes:
    from twin.fmu.catalog import variables

    declared = variables(spec.model)
    root = ET.Element(_q("ssv:ParameterSet"), version="1.0", name=spec.name)
    params = ET.SubElement(root, _q("ssv:Parameters"))
    for name, value in values.items():
        kind = _TYPES[declared[name].type]
        p = ET.SubElement(params, _q("ssv:Parameter"), name=name)
        ET.SubElement(p, _q(f"ssv:{kind}"), value=_value_text(kind, value))
    return _xml(root)


def _xml(root: ET.Element) -> bytes:
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _ssd(scenario: Scenario, sources: Mapping[str, str], values: Mapping[str, Mapping[str, Any]]) -> bytes:
    root = ET.Element(_q("ssd:SystemStructureDescription"), version="1.0", name=scenario.name)
    system = ET.SubElement(root, _q("ssd:System"), name=scenario.name, description=scenario.description)
    elements = ET.SubElement(system, _q("ssd:Elements"))
    for spec in scenario.fmus:
        _component(elements, spec, sources[spec.model], values[spec.name])
    connections = ET.SubElement(system, _q("ssd:Connections"))
    for c in scenario.connections:
        (si, sv), (di, dv) = c.src.split(".", 1), c.dst.split(".", 1)
        conn = ET.SubElement(
            connections,
            _q("ssd:Connection"),
            startElement=si,
            startConnector=sv,
            endElement=di,
            endConnector=dv,
        )
        if c.delay:
            a = ET.SubElement(
                ET.SubElement(conn, _q("ssd:Annotations")), _q("ssc:Annotation"), type=TWIN_TYPE
            )
            ET.SubElement(a, _q("twin:Delay"), initial=repr(float(c.initial or 0.0)))
    experiment = ET.SubElement(
        root, _q("ssd:DefaultExperiment"), startTime="0.0", stopTime=_seconds(scenario.duration_ns)
    )
    annotations = ET.SubElement(experiment, _q("ssd:Annotations"))
    osp = ET.SubElement(annotations, _q("ssc:Annotation"), type=OSP_TYPE)
    algorithm = ET.SubElement(osp, _q("osp:Algorithm"))
    ET.SubElement(algorithm, _q("osp:FixedStepAlgorithm"), baseStepSize=_seconds(scenario.step_ns))
    twin = ET.SubElement(annotations, _q("ssc:Annotation"), type=TWIN_TYPE)
    ET.SubElement(
        twin,
        _q("twin:Scenario"),
        outputInterval=_seconds(scenario.output_interval_ns),
        seed=str(scenario.seed),
        driftWindow=_seconds(scenario.drift_window_ns),
    )
    return _xml(root)


def export_ssp(scenario: Scenario, out: Path) -> Exported:
    """Write ``scenario``'s system as the SSP archive ``out`` (see the module); the file appears
    whole or not at all."""
    from twin.fmu import catalog

    sources: dict[str, str] = {}
    files: dict[str, Path] = {}
    for spec in scenario.fmus:
        if spec.model not in sources:
            path = catalog.fmu(spec.model)
            stem = Path(spec.model).stem if spec.model.endswith(".fmu") else spec.model
            name = f"resources/{stem}.fmu"
            if name in files.values() or name in files:
                name = f"resources/{stem}-{len(files)}.fmu"
            sources[spec.model], files[name] = name, path
    values = _values(scenario)
    ssd = _ssd(scenario, sources, values)
    _validate_ssd(ssd)  # never write an archive other tools would refuse

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w") as zf:
            _member(zf, SSD_NAME, ssd)
            for spec in scenario.fmus:
                _member(zf, f"resources/{spec.name}.ssv", _parameter_set(spec, values[spec.name]))
            for name, path in files.items():
                _member(zf, name, path.read_bytes(), zipfile.ZIP_STORED)  # an FMU is a zip already

    write_atomic(out, write)
    return Exported(out, len(scenario.fmus), len(scenario.connections), _left_out(scenario))


def _member(zf: zipfile.ZipFile, name: str, data: bytes, compression: int = zipfile.ZIP_DEFLATED) -> None:
    """One member with a fixed date: the same scenario gives the same archive, byte for byte."""
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type = compression
    info.external_attr = 0o644 << 16
    zf.writestr(info, data)


def _validate_ssd(ssd: bytes) -> None:
    """The SSP 1.0 schema's verdict on an .ssd (fmpy ships the schema; lxml checks it)."""
    from fmpy.ssp.ssd import validate_tree
    from lxml import etree

    validate_tree(etree.fromstring(ssd), "SystemStructureDescription.xsd")
