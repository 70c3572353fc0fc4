"""System Structure and Parameterization (SSP 1.0): the tester system exchanged with other FMI tools.

``twin export-ssp SCENARIO -o tester.ssp`` writes an SSP archive of a scenario's system:

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
table) and scheduled events; :func:`export_ssp` names each one it leaves out.

``twin run tester.ssp`` reads such an archive back as the system of a run: the archive is
checked (members confined to it, sizes bounded, no XML document type declarations), the
``.ssd`` is read and validated against the SSP 1.0 schema by fmpy (:func:`fmpy.ssp.ssd.read_ssd`),
the FMUs are unpacked into a folder named by the archive's SHA-256 under the FMU cache and run
as external FMUs (:mod:`twin.fmu.external`: checked by ``fmpy validate``, hashed before
loading), and the rest becomes an ordinary scenario (``--set`` works as for a TOML file).
"""

from __future__ import annotations

import os
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree as ET

from twin.errors import ConfigError
from twin.files import write_atomic

if TYPE_CHECKING:
    from twin.config.spec import Scenario

__all__ = ["SSD_NAME", "Exported", "export_ssp", "read_ssp_data"]

SSD_NAME = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "twin": "https://github.com/twin/ssp-annotations",
}
OSP_TYPE = "com.opensimulationplatform"
TWIN_TYPE = "io.github.twin"
#: most members and bytes an archive may unpack to (a zip bomb is refused, not unpacked)
MAX_MEMBERS = 256
MAX_UNPACKED = 2 << 30
#: the largest XML file read from an archive
MAX_XML = 16 << 20
_TYPES = {
    "Real": "Real",
    "Integer": "Integer",
    "Enumeration": "Integer",
    "Boolean": "Boolean",
    "String": "String",
}

for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


def _q(tag: str) -> str:
    prefix, local = tag.split(":")
    return f"{{{NS[prefix]}}}{local}"


def _seconds(ns: int) -> str:
    """Integer nanoseconds as seconds, the shortest text that reads back to the same float."""
    return repr(ns / 1e9)


def _value_text(kind: str, value: Any) -> str:
    if kind == "Boolean":
        return "true" if bool(value) else "false"
    if kind == "Integer":
        return str(int(value))
    if kind == "Real":
        return repr(float(value))
    return str(value)


# ----------------------------------------------------------------------------- export


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


# ----------------------------------------------------------------------------- import


def _safe_members(zf: zipfile.ZipFile, source: str) -> list[zipfile.ZipInfo]:
    """The archive's members, refused when one would land outside it or it unpacks too big."""
    members = zf.infolist()
    if len(members) > MAX_MEMBERS:
        raise ConfigError(f"{len(members)} members: more than {MAX_MEMBERS}", source=source)
    if sum(m.file_size for m in members) > MAX_UNPACKED:
        raise ConfigError(f"unpacks to more than {MAX_UNPACKED >> 30} GB", source=source)
    for m in members:
        parts = Path(m.filename).parts
        if m.filename.startswith(("/", "\\")) or ".." in parts or ":" in m.filename or "\\" in m.filename:
            raise ConfigError(f"member {m.filename!r} would land outside the archive's folder", source=source)
    return members


def _xml_bytes(zf: zipfile.ZipFile, name: str, source: str) -> bytes:
    try:
        info = zf.getinfo(name)
    except KeyError:
        raise ConfigError(f"no {name} in the archive", source=source) from None
    if info.file_size > MAX_XML:
        raise ConfigError(f"{name}: larger than {MAX_XML >> 20} MB", source=source)
    data = zf.read(info)
    # no document type: an entity could expand without bound or read a file of this machine
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise ConfigError(f"{name}: XML with a document type declaration is not read", source=source)
    return data


def _unpack(path: Path, zf: zipfile.ZipFile, members: list[zipfile.ZipInfo]) -> Path:
    """The archive's files under the FMU cache, in a folder named by its SHA-256 (so a run of
    the same archive, a resume included, names the same FMU files)."""
    from twin.fmu.toolchain import file_sha256, private_cache_dir

    folder = private_cache_dir() / "ssp" / file_sha256(path)[:32]
    done = folder / ".complete"
    if done.is_file():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    for m in members:
        if m.is_dir():
            continue
        target = folder / m.filename
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
        with zf.open(m) as src, open(tmp, "wb") as dst:
            while block := src.read(1 << 20):
                dst.write(block)
        os.replace(tmp, target)
    done.write_text("ok\n")
    return folder


def read_ssp_data(path: Path) -> dict[str, Any]:
    """An SSP archive as a scenario's data (the tables of a scenario file), its FMUs unpacked.

    One :class:`ConfigError` line (the archive, what is wrong) for an archive the twin cannot run.
    """
    source = str(path)
    try:
        zf = zipfile.ZipFile(path)
    except (OSError, zipfile.BadZipFile) as exc:
        raise ConfigError(f"not an SSP archive: {exc}", source=source) from None
    with zf:
        members = _safe_members(zf, source)
        ssd = _xml_bytes(zf, SSD_NAME, source)
        ssv = {m.filename: _xml_bytes(zf, m.filename, source) for m in members if m.filename.endswith(".ssv")}
        folder = _unpack(path, zf, members)
    system = _read_ssd(path, ssd)
    return _scenario_data(system, ET.fromstring(ssd), ssv, folder, source)


def _read_ssd(path: Path, ssd: bytes) -> Any:
    """fmpy's reading of the .ssd, validated against the SSP 1.0 schema."""
    from fmpy.ssp.ssd import read_ssd

    try:
        return read_ssd(str(path), validate=True)
    except Exception as exc:  # lxml's and fmpy's errors for a document that breaks the schema
        first = " ".join(str(exc).split())[:300]
        raise ConfigError(f"{SSD_NAME}: not valid SSP 1.0: {first}", source=str(path)) from None


def _annotation(element: ET.Element | None, kind: str) -> ET.Element | None:
    if element is None:
        return None
    for a in element.iterfind("ssd:Annotations/ssc:Annotation", NS):
        if a.get("type") == kind:
            return a
    return None


def _scenario_table(root: ET.Element, name: str, description: str, source: str) -> dict[str, Any]:
    experiment = root.find("ssd:DefaultExperiment", NS)
    if experiment is None or experiment.get("stopTime") is None:
        raise ConfigError(f"{SSD_NAME}: no DefaultExperiment stopTime (the run's duration)", source=source)
    start = experiment.get("startTime")
    # the schema makes it an xs:double (INF and NaN included); a twin's run starts at 0 s, so
    # another start would silently shift every profile and event: refused, not ignored
    if start is not None and float(start) != 0.0:
        raise ConfigError(
            f"{SSD_NAME}: DefaultExperiment startTime {start!r}: a start time other than 0 is not "
            "supported (a twin's run starts at 0 s)",
            source=source,
        )
    algorithm = _annotation(experiment, OSP_TYPE)
    fixed = algorithm.find("osp:Algorithm/osp:FixedStepAlgorithm", NS) if algorithm is not None else None
    if fixed is None or fixed.get("baseStepSize") is None:
        raise ConfigError(
            f"{SSD_NAME}: no fixed step (an osp:FixedStepAlgorithm baseStepSize annotation)", source=source
        )
    table: dict[str, Any] = {
        "name": name,
        "description": description,
        "duration": f"{experiment.get('stopTime')} s",
        "step": f"{fixed.get('baseStepSize')} s",
    }
    twin = _annotation(experiment, TWIN_TYPE)
    settings = twin.find("twin:Scenario", NS) if twin is not None else None
    if settings is not None:
        if settings.get("outputInterval"):
            table["output_interval"] = f"{settings.get('outputInterval')} s"
        if settings.get("driftWindow"):
            table["drift_window"] = f"{settings.get('driftWindow')} s"
        seed = settings.get("seed")
        if seed is not None:
            # an integer as a scenario file's seed is, checked where that one is (scenario.seed:
            # an integer in [0, 2^31)); anything else ("abc", "1.5", "²") is passed on as text
            # for that check to refuse. [0-9], not str.isdigit(): that takes "²", int() does not
            is_int = re.fullmatch(r"\s*[+-]?[0-9]{1,30}\s*", seed)
            table["seed"] = int(seed) if is_int else seed
    else:
        table["output_interval"] = table["step"]
    return table


def _parameter_values(component: Any, ssv: Mapping[str, bytes], source: str) -> dict[str, Any]:
    values: dict[str, Any] = {}
    for binding in component.parameterBindings:
        if binding.source is None:
            continue
        data = ssv.get(binding.source)
        if data is None:
            raise ConfigError(
                f"component {component.name}: no {binding.source} in the archive", source=source
            )
        for p in ET.fromstring(data).iterfind("ssv:Parameters/ssv:Parameter", NS):
            for kind in ("Real", "Integer", "Boolean", "String"):
                v = p.find(f"ssv:{kind}", NS)
                if v is not None:
                    text = v.get("value", "")
                    values[p.get("name", "")] = _typed(kind, text, component.name, source)
    return values


def _typed(kind: str, text: str, component: str, source: str) -> Any:
    try:
        if kind == "Real":
            return float(text)
        if kind == "Integer":
            return int(text)
    except ValueError:
        raise ConfigError(f"component {component}: {text!r} is not a {kind}", source=source) from None
    return text in ("true", "1") if kind == "Boolean" else text


def _scenario_data(
    system: Any, root: ET.Element, ssv: Mapping[str, bytes], folder: Path, source: str
) -> dict[str, Any]:
    from twin.fmu import external

    system_el = root.find("ssd:System", NS)
    data: dict[str, Any] = {
        "scenario": _scenario_table(root, root.get("name") or "ssp", system.system.description or "", source),
        "fmu": {},
        "connections": {},
    }
    components = {e.name: e for e in system.system.elements if e.source}
    hints = {}
    for el in system_el.iterfind("ssd:Elements/ssd:Component", NS) if system_el is not None else ():
        hint = _annotation(el, OSP_TYPE)
        value = hint.find("osp:StepSizeHint", NS) if hint is not None else None
        hints[el.get("name")] = value.get("value") if value is not None else None
    for name, comp in components.items():
        fmu_path = (folder / comp.source).resolve()
        if not fmu_path.is_relative_to(folder.resolve()):
            raise ConfigError(
                f"component {name}: source {comp.source!r} is outside the archive", source=source
            )
        model = str(fmu_path)
        declared = external.check(fmu_path).description.variables if fmu_path.is_file() else {}
        values = _parameter_values(comp, ssv, source)
        params = {k: v for k, v in values.items() if k not in declared or declared[k].causality != "input"}
        inputs = {k: v for k, v in values.items() if k in declared and declared[k].causality == "input"}
        period = f"{hints[name]} s" if hints.get(name) else data["scenario"]["step"]
        data["fmu"][name] = {"model": model, "period": period, "parameters": params}
        for var, value in inputs.items():
            data.setdefault("input", {}).setdefault(name, {})[var] = {"profile": "constant", "value": value}
    _connections(data, system_el, source)
    return data


def _connections(data: dict[str, Any], system_el: ET.Element | None, source: str) -> None:
    """The plain connections as ``[connections]``, the delayed ones as ``[[delay]]``."""
    for c in system_el.iterfind("ssd:Connections/ssd:Connection", NS) if system_el is not None else ():
        src = f"{c.get('startElement')}.{c.get('startConnector')}"
        dst = f"{c.get('endElement')}.{c.get('endConnector')}"
        delay = _annotation(c, TWIN_TYPE)
        d = delay.find("twin:Delay", NS) if delay is not None else None
        if d is not None:
            data.setdefault("delay", []).append(
                {"from": src, "to": dst, "initial": _typed("Real", d.get("initial", "0"), src, source)}
            )
            continue
        targets = data["connections"].setdefault(src, [])
        targets.append(dst)
