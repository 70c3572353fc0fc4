"""A scenario's system as an SSP 1.0 archive: ``twin export-ssp SCENARIO -o tester.ssp``.

* ``SystemStructure.ssd``: one ``ssd:Component`` per FMU instance (``source`` =
  ``resources/<Model>.fmu``) with its inputs, outputs and bound parameters as connectors (Real
  connectors in their unit), the connections (a transformation as ``ssc:LinearTransformation``),
  ``ssd:Units`` with every unit a connector names (``ssc:BaseUnit`` from the FMUs'
  ``UnitDefinitions``), and a ``ssd:DefaultExperiment`` (start 0, stop = the duration);
* ``resources/<Model>.fmu``: the FMUs the twin runs (the very files of its cache);
* ``resources/<instance>.ssv``: each instance's parameter set (``ssv:ParameterSet``): its
  parameters (the seed the twin's master would give it included) and its inputs that the
  scenario holds constant, typed as the modelDescription declares them, each with its source
  and standard error (the twin's annotation);
* one SignalSource component (the twin's FMU of :data:`~twin.config.ssp.SOURCE_MODEL`) per input
  a ramp, exponential, sine or table profile drives, its parameters the profile's, stepping at
  the period of the FMU it feeds: another master runs the same inputs; the twin reads it back
  as the profile (``io.github.twin`` annotation ``twin:Profile``);
* ``resources/twin/``: the files the scenario's ``[errormodel]`` and ``[uncertainty]`` name.

Annotations carry what SSP 1.0 has no element for: libcosim's (``com.opensimulationplatform``:
the fixed-step algorithm's base step, each component's step as ``osp:StepSizeHint``) and the
twin's own (``io.github.twin``: output interval, seed, drift window, wear limit, the
``[errormodel]``, ``[uncertainty]`` and ``[reference]`` tables). A tool that knows neither reads a
plain system.

What another master could not run as the twin does (scheduled events, delayed connections, a
profile the SignalSource cannot hold) makes :func:`export_ssp` refuse, one line each, unless
``lossy``: then the archive leaves it out (a delayed connection stays, plain, with the twin's
annotation, so the twin alone reads it back delayed) and :attr:`Exported.left_out` names each.
The archive is read back by :mod:`twin.config.ssp`.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from twin.config.spec import Profile, Scenario
from twin.config.ssp import (
    NS,
    OSP_TYPE,
    PROFILE_KINDS,
    SOURCE_MODEL,
    SSD_NAME,
    TWIN_TYPE,
    TYPES,
    q,
    seconds,
    value_text,
)
from twin.errors import ConfigError, ConfigErrors
from twin.files import write_atomic
from twin.fmu.description import BASE_UNITS, BaseUnit

__all__ = ["Exported", "export_ssp"]

# the standard's prefixes, literally: libcosim's reader looks elements up as "ssv:ParameterSet"
for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)

#: each profile's parameters as the SignalSource names them
_SOURCE_PARAMS = {
    "constant": ("value",),
    "ramp": ("start", "end", "duration", "delay"),
    "exponential": ("start", "rise", "time_constant", "rise_at"),
    "sine": ("mean", "amplitude", "period", "phase"),
    "table": (),
}
#: the scenario's tables the twin's annotation carries, and the file each may name
_TABLES = {"errormodel": "coefficients", "uncertainty": "spreads", "reference": None}
#: where a table's file is looked for when the table names none (the Monte Carlo's default)
_DEFAULT_FILES = {"uncertainty": "base/priors.toml"}


@dataclass(frozen=True)
class Exported:
    """What :func:`export_ssp` wrote, and what the archive could not hold."""

    path: Path
    components: int
    connections: int
    left_out: tuple[str, ...]


@dataclass(frozen=True)
class _Source:
    """A SignalSource component carrying the profile of one input."""

    name: str
    profile: Profile
    period_ns: int
    values: Mapping[str, Any]


@dataclass
class _Content:
    """What the archive will hold, and what it cannot (key, why) for the refusal."""

    scenario: Scenario
    sources: list[_Source] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)  # member -> file
    tables: dict[str, Any] = field(default_factory=dict)
    #: (key, what, what --lossy does with it)
    cannot: list[tuple[str, str, str]] = field(default_factory=list)


# ----------------------------------------------------------------------------- what travels


def _source_values(p: Profile, period_ns: int) -> dict[str, Any]:
    """The SignalSource's parameters that make it ``p`` (stepping every ``period_ns``)."""
    values: dict[str, Any] = {"solver_step": period_ns / 1e9, "profile": PROFILE_KINDS.index(p.kind)}
    for name in _SOURCE_PARAMS[p.kind]:
        if name in p.params:
            values[name] = p.params[name]
    if p.kind == "table":
        values["table_n"] = len(p.table)
        for k, (t, v) in enumerate(p.table, 1):
            values[f"table_t_{k}"], values[f"table_v_{k}"] = t, v
    return values


def _source_problem(values: Mapping[str, Any]) -> str | None:
    """Why the SignalSource cannot hold ``values`` (a table too long, a value out of its
    declared range), or None."""
    from twin.fmu.catalog import variables

    declared = variables(SOURCE_MODEL)
    n = values.get("table_n", 2)
    if n > declared["table_n"].max:
        return f"a table of {n} points: the {SOURCE_MODEL} FMU holds at most {int(declared['table_n'].max)}"
    for name, value in values.items():
        var = declared[name]
        if not var.min <= value <= var.max:
            return (
                f"{name} = {value!r} lies outside the {SOURCE_MODEL} FMU's range [{var.min!r}, {var.max!r}]"
            )
    return None


def _profiles(c: _Content) -> None:
    names = {f.name for f in c.scenario.fmus}
    for p in c.scenario.profiles:
        if p.kind == "constant":
            continue  # a start value in the instance's parameter set
        inst, var = p.target.split(".", 1)
        period = c.scenario.fmu(inst).period_ns
        values = _source_values(p, period)
        why = _source_problem(values)
        if why is not None:
            c.cannot.append(
                (f"input.{p.target}", f"the {p.kind} profile: {why}", "leaves the input at its start value")
            )
            continue
        name = f"{inst}_{var}_profile"
        while name in names:
            name += "_"
        names.add(name)
        c.sources.append(_Source(name, p, period, values))


def _plain(value: Any) -> Any:
    """A table's value as JSON takes it (a read-only mapping as a dict)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return getattr(value, "value", value)  # an [errormodel] entry is a Parameter


def _tables(c: _Content) -> None:
    """The scenario's [errormodel], [uncertainty] and [reference] tables, and the files they
    name (or the Monte Carlo's default spreads file) copied into ``resources/twin/``."""
    sc = c.scenario
    folder = Path(sc.source_path).resolve().parent
    for name, key in _TABLES.items():
        table = _plain(getattr(sc, name))
        if not table:
            continue
        given = table.get(key) if key else None
        if key and (isinstance(given, str) or name in _DEFAULT_FILES):
            path = (folder / (given if isinstance(given, str) else _DEFAULT_FILES[name])).resolve()
            if not path.is_file():
                c.cannot.append((f"{name}.{key}", f"no such file {path}", "leaves the table out"))
                continue
            member = f"resources/twin/{path.name}"
            while member in c.files and c.files[member] != path:
                member = member.removesuffix(".toml") + "_.toml"
            c.files[member] = path
            table[key] = member
        c.tables[name] = table
    try:
        json.dumps(c.tables, allow_nan=False)
    except (TypeError, ValueError) as exc:
        c.cannot.append(("errormodel", f"a table value JSON cannot hold: {exc}", "leaves the tables out"))
        c.tables = {}


def _content(scenario: Scenario) -> _Content:
    c = _Content(scenario)
    _profiles(c)
    _tables(c)
    for e in scenario.events:
        c.cannot.append(
            (
                "event",
                f"the event at {seconds(e.at_ns)} s ({e.action} {e.target}): SSP has no scheduled events",
                "leaves it out",
            )
        )
    for conn in scenario.connections:
        if conn.delay:
            c.cannot.append(
                (
                    "delay",
                    f"the delayed connection {conn.src} -> {conn.dst}: SSP has no delay",
                    "writes it undelayed for other masters; the twin reads it back delayed",
                )
            )
    return c


# ----------------------------------------------------------------------------- the .ssd


def _values(scenario: Scenario) -> dict[str, dict[str, Any]]:
    """Each instance's parameter values (the master's seeds included) and constant inputs,
    with their source, standard error and what a value is derived from: name -> (value,
    source, std_error, derived)."""
    from twin.fmu.catalog import variables
    from twin.seeds import instance_seed

    out: dict[str, dict[str, Any]] = {}
    for i, spec in enumerate(scenario.fmus):
        values: dict[str, Any] = {k: (p.value, p.source, p.std_error, "") for k, p in spec.parameters.items()}
        if "seed" in variables(spec.model) and "seed" not in values:
            derived = (
                instance_seed(scenario.seed, i),
                "the twin's master: twin.seeds",
                None,
                "scenario.seed",
            )
            values = {"seed": derived, **values}
        out[spec.name] = values
    for p in scenario.profiles:
        if p.kind == "constant":
            inst, var = p.target.split(".", 1)
            out[inst][var] = (p.params["value"], p.source, None, "")
    return out


class _Units:
    """The units the connectors name, each with its definition from an FMU's UnitDefinitions."""

    def __init__(self) -> None:
        self.defined: dict[str, BaseUnit] = {}
        self.clashes: list[tuple[str, str, str]] = []

    def use(self, unit: str, model: str) -> bool:
        """Whether a connector can name ``unit`` (some FMU defines it)."""
        from twin.fmu.catalog import description

        definition = description(model).units.get(unit)
        if not unit or definition is None:
            return False
        known = self.defined.setdefault(unit, definition)
        if known != definition:
            self.clashes.append(
                (
                    f"fmu.{model}",
                    f"unit {unit!r}, defined differently by two FMUs",
                    "keeps the first definition",
                )
            )
        return True

    def element(self, parent: ET.Element) -> None:
        if not self.defined:
            return
        units = ET.SubElement(parent, q("ssd:Units"))
        for name, b in sorted(self.defined.items()):
            u = ET.SubElement(units, q("ssc:Unit"), name=name)
            attrs = {k: str(e) for k, e in zip(BASE_UNITS, b.exponents, strict=True) if e}
            if b.factor != 1.0:
                attrs["factor"] = repr(b.factor)
            if b.offset != 0.0:
                attrs["offset"] = repr(b.offset)
            ET.SubElement(u, q("ssc:BaseUnit"), attrs)


def _connector(
    parent: ET.Element, name: str, var: Any, units: _Units, model: str, unit: str | None = None
) -> None:
    c = ET.SubElement(parent, q("ssd:Connector"), name=name, kind=var.causality)
    t = ET.SubElement(c, q(f"ssc:{var.type}"))
    unit = unit if unit is not None else var.unit
    if var.type == "Real" and unit and units.use(unit, model):
        t.set("unit", unit)


def _annotation(parent: ET.Element, kind: str) -> ET.Element:
    annotations = parent.find(q("ssd:Annotations"))
    if annotations is None:
        annotations = ET.SubElement(parent, q("ssd:Annotations"))
    return ET.SubElement(annotations, q("ssc:Annotation"), type=kind)


def _component(parent: ET.Element, spec: Any, source: str, values: Mapping[str, Any], units: _Units) -> None:
    from twin.fmu.catalog import variables

    comp = ET.SubElement(
        parent, q("ssd:Component"), name=spec.name, source=source, type="application/x-fmu-sharedlibrary"
    )
    connectors = ET.SubElement(comp, q("ssd:Connectors"))
    for name, v in variables(spec.model).items():
        if v.causality not in ("input", "output") and name not in values:
            continue
        if v.type not in ("Real", "Integer", "Boolean"):
            continue  # an Enumeration connector needs the SSD's own enumeration; none is connected
        _connector(connectors, name, v, units, spec.model)
    bindings = ET.SubElement(comp, q("ssd:ParameterBindings"))
    ET.SubElement(bindings, q("ssd:ParameterBinding"), source=f"resources/{spec.name}.ssv")
    ET.SubElement(_annotation(comp, OSP_TYPE), q("osp:StepSizeHint"), value=seconds(spec.period_ns))


def _source_component(
    parent: ET.Element, s: _Source, target_unit: str, target_model: str, units: _Units
) -> None:
    from twin.fmu.catalog import variables

    comp = ET.SubElement(
        parent,
        q("ssd:Component"),
        name=s.name,
        source=f"resources/{SOURCE_MODEL}.fmu",
        type="application/x-fmu-sharedlibrary",
        description=f"the {s.profile.kind} profile of {s.profile.target}",
    )
    connectors = ET.SubElement(comp, q("ssd:Connectors"))
    declared = variables(SOURCE_MODEL)
    _connector(connectors, "y", declared["y"], units, target_model, unit=target_unit)
    for name in s.values:
        _connector(connectors, name, declared[name], units, SOURCE_MODEL)
    bindings = ET.SubElement(comp, q("ssd:ParameterBindings"))
    ET.SubElement(bindings, q("ssd:ParameterBinding"), source=f"resources/{s.name}.ssv")
    ET.SubElement(_annotation(comp, OSP_TYPE), q("osp:StepSizeHint"), value=seconds(s.period_ns))
    ET.SubElement(_annotation(comp, TWIN_TYPE), q("twin:Profile"), source=s.profile.source)


def _connection(parent: ET.Element, c: Any) -> ET.Element:
    (si, sv), (di, dv) = c.src.split(".", 1), c.dst.split(".", 1)
    conn = ET.SubElement(
        parent, q("ssd:Connection"), startElement=si, startConnector=sv, endElement=di, endConnector=dv
    )
    if c.affine:
        ET.SubElement(conn, q("ssc:LinearTransformation"), factor=repr(c.factor), offset=repr(c.offset))
    if c.delay:
        ET.SubElement(_annotation(conn, TWIN_TYPE), q("twin:Delay"), initial=repr(float(c.initial or 0.0)))
    return conn


def _connections(system: ET.Element, c: _Content) -> None:
    from twin.fmu.catalog import variables

    sc = c.scenario
    models = {f.name: f.model for f in sc.fmus}
    connections = ET.SubElement(system, q("ssd:Connections"))
    for conn in sc.connections:
        el = _connection(connections, conn)
        (si, sv), (di, dv) = conn.src.split(".", 1), conn.dst.split(".", 1)
        if variables(models[si])[sv].unit != variables(models[di])[dv].unit:
            # factor and offset hold the whole map: no second conversion by another master
            el.set("suppressUnitConversion", "true")
    for s in c.sources:
        inst, var = s.profile.target.split(".", 1)
        ET.SubElement(
            connections,
            q("ssd:Connection"),
            startElement=s.name,
            startConnector="y",
            endElement=inst,
            endConnector=var,
        )


def _experiment(root: ET.Element, c: _Content) -> None:
    sc = c.scenario
    experiment = ET.SubElement(
        root, q("ssd:DefaultExperiment"), startTime="0.0", stopTime=seconds(sc.duration_ns)
    )
    algorithm = ET.SubElement(_annotation(experiment, OSP_TYPE), q("osp:Algorithm"))
    ET.SubElement(algorithm, q("osp:FixedStepAlgorithm"), baseStepSize=seconds(sc.step_ns))
    twin = _annotation(experiment, TWIN_TYPE)
    settings = {
        "outputInterval": seconds(sc.output_interval_ns),
        "seed": str(sc.seed),
        "driftWindow": seconds(sc.drift_window_ns),
    }
    if sc.wear_limit_mm is not None:
        settings["wearLimitMm"] = repr(sc.wear_limit_mm)
    scenario = ET.SubElement(twin, q("twin:Scenario"), settings)
    if c.tables:  # inside: an annotation holds one element
        ET.SubElement(scenario, q("twin:Tables")).text = json.dumps(c.tables, sort_keys=True, allow_nan=False)


def _ssd(c: _Content, sources: Mapping[str, str], values: Mapping[str, Mapping[str, Any]]) -> bytes:
    from twin.fmu.catalog import variables

    sc = c.scenario
    units = _Units()
    root = ET.Element(q("ssd:SystemStructureDescription"), version="1.0", name=sc.name)
    system = ET.SubElement(root, q("ssd:System"), name=sc.name, description=sc.description)
    elements = ET.SubElement(system, q("ssd:Elements"))
    for spec in sc.fmus:
        _component(elements, spec, sources[spec.model], values[spec.name], units)
    for s in c.sources:
        inst, var = s.profile.target.split(".", 1)
        model = sc.fmu(inst).model
        _source_component(elements, s, variables(model)[var].unit, model, units)
    _connections(system, c)
    units.element(root)
    c.cannot.extend(units.clashes)
    _experiment(root, c)
    return _xml(root)


# ----------------------------------------------------------------------------- the .ssv


def _parameter_set(name: str, model: str, values: Mapping[str, tuple[Any, str, float | None, str]]) -> bytes:
    from twin.fmu.catalog import variables

    declared = variables(model)
    root = ET.Element(q("ssv:ParameterSet"), version="1.0", name=name)
    params = ET.SubElement(root, q("ssv:Parameters"))
    for pname, (value, source, std_error, derived) in values.items():
        kind = TYPES[declared[pname].type]
        kind = "Integer" if kind == "Enumeration" else kind  # its item's value, as libcosim reads it
        p = ET.SubElement(params, q("ssv:Parameter"), name=pname)
        ET.SubElement(p, q(f"ssv:{kind}"), value=value_text(kind, value))
        if source or std_error is not None or derived:
            a = ET.SubElement(ET.SubElement(p, q("ssv:Annotations")), q("ssc:Annotation"), type=TWIN_TYPE)
            attrs = {"source": source} if source else {}
            if std_error is not None:
                attrs["stdError"] = repr(float(std_error))
            if derived:
                attrs["derived"] = derived
            ET.SubElement(a, q("twin:Parameter"), attrs)
    return _xml(root)


def _xml(root: ET.Element) -> bytes:
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


# ----------------------------------------------------------------------------- the archive


def _fmu_files(scenario: Scenario, with_source: bool) -> tuple[dict[str, str], dict[str, Path]]:
    """Each model's member name, and each member's file."""
    from twin.fmu import catalog

    models = [spec.model for spec in scenario.fmus] + ([SOURCE_MODEL] if with_source else [])
    sources: dict[str, str] = {}
    files: dict[str, Path] = {}
    for model in models:
        if model in sources:
            continue
        stem = Path(model).stem if model.endswith(".fmu") else model
        name = f"resources/{stem}.fmu"
        if name in files:
            name = f"resources/{stem}-{len(files)}.fmu"
        sources[model], files[name] = name, catalog.fmu(model)
    return sources, files


def export_ssp(scenario: Scenario, out: Path, *, lossy: bool = False) -> Exported:
    """Write ``scenario``'s system as the SSP archive ``out`` (see the module); the file appears
    whole or not at all. :class:`ConfigErrors` (one line per thing, nothing written) when the
    archive cannot hold everything another master needs to run it as the twin does, unless
    ``lossy``."""
    c = _content(scenario)
    sources, files = _fmu_files(scenario, bool(c.sources))
    values = _values(scenario)
    ssd = _ssd(c, sources, values)
    if c.cannot and not lossy:
        raise ConfigErrors(
            [
                ConfigError(
                    f"the archive cannot carry {why} (--lossy {effect})", source=scenario.source_path, key=key
                )
                for key, why, effect in c.cannot
            ]
        )
    _validate_ssd(ssd)  # never write an archive other tools would refuse

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w") as zf:
            _member(zf, SSD_NAME, ssd)
            for spec in scenario.fmus:
                _member(
                    zf, f"resources/{spec.name}.ssv", _parameter_set(spec.name, spec.model, values[spec.name])
                )
            for s in c.sources:
                set_values = {k: (v, "", None, "") for k, v in s.values.items()}
                _member(zf, f"resources/{s.name}.ssv", _parameter_set(s.name, SOURCE_MODEL, set_values))
            for name, path in files.items():
                _member(zf, name, path.read_bytes(), zipfile.ZIP_STORED)  # an FMU is a zip already
            for name, path in sorted(c.files.items()):
                _member(zf, name, path.read_bytes())

    write_atomic(out, write)
    n_connections = len(scenario.connections) + len(c.sources)
    left_out = tuple(f"{key}: {why}: {effect}" for key, why, effect in c.cannot)
    return Exported(out, len(scenario.fmus) + len(c.sources), n_connections, left_out)


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
