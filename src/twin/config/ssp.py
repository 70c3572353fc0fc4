"""System Structure and Parameterization (SSP 1.0) read as a scenario: ``twin run tester.ssp``.

An SSP archive (from the twin's ``twin export-ssp``, :mod:`twin.exchange.ssp`, or another FMI
tool) is read back as the system of a run: the archive is checked (members confined to it,
sizes bounded, no XML document type declarations), the ``.ssd`` is read and validated against
the SSP 1.0 schema by fmpy (:func:`fmpy.ssp.ssd.read_ssd`), the FMUs are unpacked into a folder
named by the archive's SHA-256 under the FMU cache and run as external FMUs
(:mod:`twin.fmu.external`: checked by ``fmpy validate``, hashed before loading), and the rest
becomes an ordinary scenario's data (``--set`` works as for a TOML file), which
:mod:`twin.config.load` checks as it checks a TOML file's. Annotations carry what SSP 1.0 has
no element for: libcosim's (``com.opensimulationplatform``: the base step, each component's
step) and the twin's own (``io.github.twin``: output interval, seed, drift window, delayed
connections with their initial values).
"""

from __future__ import annotations

import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree as ET

from twin.errors import ConfigError

if TYPE_CHECKING:
    pass

__all__ = ["NS", "OSP_TYPE", "SSD_NAME", "TWIN_TYPE", "read_ssp_data"]

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
    declared_inputs: dict[str, list[str]] = {}
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
        declared_inputs[name] = [k for k, v in declared.items() if v.causality == "input"]
    _connections(data, system_el, source)
    _leave_alone(data, declared_inputs)
    return data


def _leave_alone(data: dict[str, Any], declared_inputs: Mapping[str, list[str]]) -> None:
    """An input the system neither connects nor gives a value keeps its start value, as in any
    SSP tool: said so for each one (``unconnected``), which the scenario's check requires."""
    fed = {d for dsts in data["connections"].values() for d in dsts}
    fed |= {d["to"] for d in data.get("delay", [])}
    fed |= {f"{inst}.{var}" for inst, table in data.get("input", {}).items() for var in table}
    for name, inputs in declared_inputs.items():
        left = {v: f"unconnected in {SSD_NAME}: its start value" for v in inputs if f"{name}.{v}" not in fed}
        if left:
            data["fmu"][name]["unconnected"] = left


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
