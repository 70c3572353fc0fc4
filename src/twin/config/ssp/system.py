"""An SSP 1.0 system as a scenario's data: components, their connectors and parameter
bindings, connections, the default experiment, and the annotations that say what SSP has no
element for (libcosim's and the twin's). See :mod:`twin.config.ssp` for what is applied and
what is refused.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.config.ssp.archive import Archive, validate
from twin.config.ssp.names import NS, OSP_TYPE, SSD_NAME, TWIN_TYPE, article, path_of, tag_of
from twin.config.ssp.values import (
    Refusal,
    Value,
    apply_mapping,
    definitions,
    parameter_set,
    resolve,
    unit_conversion,
)
from twin.errors import ConfigError, ConfigErrors

__all__ = ["PROFILE_KINDS", "SOURCE_MODEL", "read_system"]

#: the twin's FMU that carries an input profile in an archive, and its profiles by number
SOURCE_MODEL = "SignalSource"
PROFILE_KINDS = ("constant", "ramp", "exponential", "sine", "table")
#: each profile's parameters as the SignalSource names them (durations in seconds)
_PROFILE_PARAMS = {
    "constant": ("value",),
    "ramp": ("start", "end", "duration", "delay"),
    "exponential": ("start", "rise", "time_constant", "rise_at"),
    "sine": ("mean", "amplitude", "period", "phase"),
    "table": (),
}

#: what the reader walks: the children each element may have that it applies, or knows to
#: change nothing (geometry, graphics); every other child is refused, named
_CHILDREN = {
    "ssd:SystemStructureDescription": {
        "ssd:System",
        "ssd:Enumerations",
        "ssd:Units",
        "ssd:DefaultExperiment",
        "ssd:Annotations",
    },
    "ssd:System": {
        "ssd:Connectors",
        "ssd:ElementGeometry",
        "ssd:ParameterBindings",
        "ssd:Elements",
        "ssd:Connections",
        "ssd:SystemGeometry",
        "ssd:GraphicalElements",
        "ssd:Annotations",
    },
    "ssd:Elements": {"ssd:Component"},
    "ssd:Component": {"ssd:Connectors", "ssd:ElementGeometry", "ssd:ParameterBindings", "ssd:Annotations"},
    "ssd:Connectors": {"ssd:Connector"},
    "ssd:Connector": {
        "ssc:Real",
        "ssc:Integer",
        "ssc:Boolean",
        "ssc:String",
        "ssc:Enumeration",
        "ssd:ConnectorGeometry",
        "ssd:Annotations",
    },
    "ssd:ParameterBindings": {"ssd:ParameterBinding"},
    "ssd:ParameterBinding": {"ssd:ParameterValues", "ssd:ParameterMapping", "ssd:Annotations"},
    "ssd:Connections": {"ssd:Connection"},
    "ssd:Connection": {"ssc:LinearTransformation", "ssd:ConnectionGeometry", "ssd:Annotations"},
    "ssd:DefaultExperiment": {"ssd:Annotations"},
}
_ON_CONNECTION = "on a connection: the twin's master exchanges Real outputs only, which these do not map"
_WHY = {
    "ssd:SignalDictionaries": "signal dictionaries are not supported",
    "ssd:SignalDictionaryReference": "a signal dictionary reference is not supported",
    "ssd:System": "a nested system is not supported (its components would have to be flattened)",
    "ssc:Binary": "a Binary connector is not supported",
    "ssc:BooleanMappingTransformation": _ON_CONNECTION,
    "ssc:IntegerMappingTransformation": _ON_CONNECTION,
    "ssc:EnumerationMappingTransformation": _ON_CONNECTION,
}
_UNCONNECTED = f"unconnected in {SSD_NAME}: its start value"
#: a value that could not be resolved (its problem is reported)
_UNRESOLVED = object()


@dataclass
class _Component:
    """One component as read: its FMU, connectors (name -> declared unit), step hint, values."""

    el: Any
    name: str
    fmu: Path
    description: Any
    connectors: dict[str, str | None] = field(default_factory=dict)
    hint: str | None = None
    profile: Any = None  # the twin:Profile annotation that makes it an input's profile
    values: list[Value] = field(default_factory=list)
    #: connectors refused (their problem is reported once, not again at each connection)
    broken: set[str] = field(default_factory=set)


@dataclass(frozen=True)
class _End:
    """One end of a connection: the component, the variable, its unit (name, definition)."""

    comp: _Component
    var: Any
    unit: tuple[str, Any]

    @property
    def ref(self) -> str:
        return f"{self.comp.name}.{self.var.name}"


class _Reader:
    def __init__(self, archive: Archive) -> None:
        self.a = archive
        self.root = archive.xml(SSD_NAME)
        self.defs = definitions(self.root, "ssd")
        self.problems: list[str] = []
        self.components: dict[str, _Component] = {}
        #: components refused: connections naming them are not reported again
        self.broken: set[str] = set()

    def refuse(self, el: Any, why: str, where: str = SSD_NAME) -> None:
        self.problems.append(f"{where}: {path_of(el)}: {why}")

    def check(self) -> None:
        if self.problems:
            raise ConfigErrors([ConfigError(p, source=self.a.source) for p in dict.fromkeys(self.problems)])

    # ------------------------------------------------------------------------- structure

    def walk(self, el: Any) -> None:
        """Refuse every element the reader neither applies nor knows to change nothing."""
        allowed = _CHILDREN.get(tag_of(el), set())
        for c in el:
            if not isinstance(c.tag, str):
                continue  # a comment or a processing instruction
            tag = tag_of(c)
            if tag not in allowed:
                self.refuse(c, _WHY.get(tag, "not supported"))
            elif tag in _CHILDREN and not (tag == "ssd:System" and el is not self.root):
                self.walk(c)

    # ------------------------------------------------------------------------- annotations

    def annotation(self, el: Any, kind: str) -> Any:
        for a in el.iterfind("ssd:Annotations/ssc:Annotation", NS):
            if a.get("type") == kind:
                return a
        return None

    def known(self, annotation: Any, tags: set[str]) -> list[Any]:
        """The annotation's elements, each one of ``tags`` (others refused: an annotation of
        libcosim's or the twin's that this reader does not know might change the run)."""
        out = []
        for c in annotation if annotation is not None else ():
            if not isinstance(c.tag, str):
                continue
            if tag_of(c) in tags:
                out.append(c)
            else:
                self.refuse(
                    c, f"an annotation ({annotation.get('type')}) this version of the twin does not apply"
                )
        return out

    # ------------------------------------------------------------------------- components

    def read_components(self, system: Any) -> None:
        for el in system.iterfind("ssd:Elements/ssd:Component", NS):
            comp = self.component(el)
            if comp is not None:
                self.components[comp.name] = comp
            else:
                self.broken.add(el.get("name"))

    def component(self, el: Any) -> _Component | None:
        from twin.fmu import external

        name = el.get("name")
        kind = el.get("type", "application/x-fmu-sharedlibrary")
        if kind != "application/x-fmu-sharedlibrary":
            self.refuse(el, f"a component of type {kind!r}: the twin runs FMUs only")
            return None
        if el.get("implementation", "any") == "ModelExchange":
            self.refuse(el, "implementation 'ModelExchange': the twin runs FMUs as co-simulation")
            return None
        source = el.get("source", "")
        fmu = (self.a.folder / source).resolve()
        if (
            re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", source)
            or "#" in source
            or not fmu.is_relative_to(self.a.folder.resolve())
        ):
            self.refuse(
                el, f"source {source!r} is outside the archive (the twin runs the FMUs an archive carries)"
            )
            return None
        if not self.a.has(Path(source).as_posix()):
            self.refuse(el, f"no {source} in the archive")
            return None
        try:
            description = external.check(fmu).description
        except ConfigError as exc:
            self.refuse(el, f"{source}: {exc.message}")
            return None
        comp = _Component(el, name, fmu, description)
        self.connectors(comp)
        self.osp_hint(comp)
        twin = self.known(self.annotation(el, TWIN_TYPE), {"twin:Profile"})
        comp.profile = twin[0] if twin else None
        for b in el.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            comp.values += self.binding(b)
        return comp

    def connectors(self, comp: _Component) -> None:
        """Each connector names a variable of the FMU, of its causality and type; a unit it
        declares is the variable's own (the twin converts at connections, not at connectors)."""
        variables = comp.description.variables
        for c in comp.el.iterfind("ssd:Connectors/ssd:Connector", NS):
            name, kind = c.get("name"), c.get("kind")
            var = variables.get(name)
            typed = next((t for t in c if isinstance(t.tag, str) and tag_of(t).startswith("ssc:")), None)
            if typed is not None and tag_of(typed) == "ssc:Binary":
                comp.broken.add(name)  # refused where the reader walks the document
            elif var is None:
                comp.broken.add(name)
                self.refuse(c, f"the FMU has no variable {name!r}")
            elif kind != var.causality:
                comp.broken.add(name)
                self.refuse(c, f"kind {kind!r}, but the FMU's {name!r} is {article(var.causality)}")
            elif typed is not None and tag_of(typed) != f"ssc:{var.type}":
                comp.broken.add(name)
                self.refuse(c, f"type {tag_of(typed)}, but the FMU's {name!r} is {var.type}")
            else:
                unit = typed.get("unit") if typed is not None else None
                if unit and var.unit:
                    try:
                        same = self.conversion((unit, self.defs.units.get(unit)), self.fmu_unit(comp, var), c)
                    except Refusal as exc:
                        comp.broken.add(name)
                        self.problems.append(str(exc))
                        continue
                    if same != (1.0, 0.0):
                        comp.broken.add(name)
                        self.refuse(c, f"unit {unit!r} is not the FMU variable's unit {var.unit!r}")
                        continue
                comp.connectors[name] = unit

    def osp_hint(self, comp: _Component) -> None:
        for h in self.known(self.annotation(comp.el, OSP_TYPE), {"osp:StepSizeHint"}):
            comp.hint = h.get("value")

    def fmu_unit(self, comp: _Component, var: Any) -> tuple[str, Any]:
        return var.unit, comp.description.units.get(var.unit)

    def conversion(self, src: tuple[str, Any], dst: tuple[str, Any], el: Any) -> tuple[float, float]:
        probe = Value("", "Real", "0", el, SSD_NAME, self.defs)
        return unit_conversion(src, dst, probe)

    # ------------------------------------------------------------------------- parameter values

    def binding(self, b: Any) -> list[Value]:
        """The values one ``ssd:ParameterBinding`` gives, named and transformed by its mapping."""
        if b.get("type", "application/x-ssp-parameter-set") != "application/x-ssp-parameter-set":
            self.refuse(b, f"a parameter source of type {b.get('type')!r}: the twin reads SSP parameter sets")
            return []
        if b.get("sourceBase", "SSD") != "SSD":
            self.refuse(b, "sourceBase 'component' (a parameter set inside an FMU) is not supported")
            return []
        try:
            set_root, where = self.parameter_source(b)
            if set_root is None:
                return []
            values = parameter_set(set_root, where, self.defs, b.get("prefix", ""))
            mapping = b.find("ssd:ParameterMapping", NS)
            if mapping is not None:
                m_root, m_where = self.mapping_source(mapping)
                values = apply_mapping(values, m_root, m_where)
        except Refusal as exc:
            self.problems.append(str(exc))
            return []
        except ConfigError as exc:
            self.problems.append(exc.message or str(exc))
            return []
        return values

    def inline(self, holder: Any, tag: str, kind: str) -> tuple[Any, str]:
        """The one ``tag`` element an inline holder (ssd:ParameterValues, ssd:ParameterMapping)
        carries, validated against its schema as a document of its own."""
        from copy import deepcopy

        from lxml import etree

        items = [c for c in holder if isinstance(c.tag, str)]
        where = f"{SSD_NAME}: {path_of(holder)}"
        if len(items) != 1 or tag_of(items[0]) != tag:
            raise Refusal(SSD_NAME, holder, f"expected one {tag} inline")
        doc = etree.ElementTree(deepcopy(items[0])).getroot()
        validate(doc, kind, where, self.a.source)
        return doc, where

    def member(self, el: Any, source: str, suffix: str) -> tuple[Any, str]:
        name = Path(source).as_posix()
        if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", source) or "#" in source or not name.endswith(suffix):
            raise Refusal(SSD_NAME, el, f"source {source!r}: expected a {suffix} file of the archive")
        root = self.a.xml(name) if self.a.has(name) else None
        if root is None:
            raise Refusal(SSD_NAME, el, f"no {name} in the archive")
        validate(root, suffix.lstrip("."), name, self.a.source)
        return root, name

    def parameter_source(self, b: Any) -> tuple[Any, str]:
        inline = b.find("ssd:ParameterValues", NS)
        if b.get("source"):
            if inline is not None:
                raise Refusal(SSD_NAME, inline, "inline values beside a source: SSP allows one or the other")
            return self.member(b, b.get("source"), ".ssv")
        if inline is None:
            return None, ""
        return self.inline(inline, "ssv:ParameterSet", "ssv")

    def mapping_source(self, m: Any) -> tuple[Any, str]:
        if m.get("type", "application/x-ssp-parameter-mapping") != "application/x-ssp-parameter-mapping":
            raise Refusal(SSD_NAME, m, f"a parameter mapping of type {m.get('type')!r} is not supported")
        if m.get("sourceBase", "SSD") != "SSD":
            raise Refusal(SSD_NAME, m, "sourceBase 'component' (a mapping inside an FMU) is not supported")
        if m.get("source"):
            return self.member(m, m.get("source"), ".ssm")
        return self.inline(m, "ssm:ParameterMapping", "ssm")

    def system_values(self, system: Any) -> None:
        """Bindings of the system itself: hierarchical names (``component.variable``), applied
        after the components' own (they take precedence, as SSP says)."""
        for b in system.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            for v in self.binding(b):
                comp_name, _, var = v.name.partition(".")
                comp = self.components.get(comp_name)
                if comp is None or not var:
                    self.problems.append(
                        f"{v.where}: {path_of(v.element)}: {v.name!r} names no component's variable "
                        "(a system's parameter names are 'component.variable')"
                    )
                    continue
                comp.values.append(Value(**{**v.__dict__, "name": var}))

    def apply_values(self, comp: _Component, data: dict[str, Any], index: int) -> dict[str, Any]:
        """The component's resolved values: its parameters into ``data``'s ``[fmu]`` table, its
        inputs' start values as constant profiles; returns every value by name. ``index``: its
        place among the scenario's FMU instances (what the master derives a seed from)."""
        resolved: dict[str, Any] = {}
        derived = False
        for v in comp.values:
            value = self.resolved(comp, v)
            if value is _UNRESOLVED:
                continue
            resolved[v.name] = value
            if comp.profile is not None:
                continue  # a profile's source: read as the profile
            if v.name == "seed" and v.derived == "scenario.seed" and value == _derived_seed(data, index):
                derived = True  # the master derives it again, from the scenario's seed as run
                continue
            self.place(comp, v, value, data)
        if comp.profile is None and not derived:
            self.pin_seed(comp, data)
        return resolved

    def resolved(self, comp: _Component, v: Value) -> Any:
        var = comp.description.variables.get(v.name)
        if var is None:
            self.problems.append(
                f"{v.where}: {path_of(v.element)}: the FMU of {comp.name!r} has no variable {v.name!r}"
            )
            return _UNRESOLVED
        try:
            return resolve(v, var, comp.description.units)
        except Refusal as exc:
            self.problems.append(str(exc))
            return _UNRESOLVED

    def place(self, comp: _Component, v: Value, value: Any, data: dict[str, Any]) -> None:
        """A parameter's value into the instance's parameters, an input's as its constant profile."""
        var = comp.description.variables[v.name]
        source = {"source": v.source} if v.source else {}
        if var.causality == "parameter":
            entry: Any = value
            if v.source or v.std_error is not None:
                entry = {"value": value, **source}
                if v.std_error is not None:
                    entry["std_error"] = v.std_error
            data["fmu"][comp.name]["parameters"][v.name] = entry
        elif var.causality == "input" and var.type == "Real":
            profile = {"profile": "constant", "value": value, **source}
            data.setdefault("input", {}).setdefault(comp.name, {})[v.name] = profile
        else:
            what = "an input of type " + var.type if var.causality == "input" else article(var.causality)
            self.problems.append(
                f"{v.where}: {path_of(v.element)}: {v.name!r} is {what}: the twin sets parameters and Real inputs"
            )

    def pin_seed(self, comp: _Component, data: dict[str, Any]) -> None:
        """An FMU's ``seed`` no binding sets stays at its start value, as SSP says (libcosim does):
        the twin's master would otherwise derive one from the scenario's."""
        seed = comp.description.variables.get("seed")
        params = data["fmu"][comp.name]["parameters"]
        if seed is not None and seed.causality == "parameter" and "seed" not in params:
            params["seed"] = {
                "value": seed.start,
                "source": f"its start value: no binding of {SSD_NAME} sets it",
            }

    # ------------------------------------------------------------------------- connections

    def end(self, c: Any, element: str | None, connector: str | None) -> _End | None:
        """One end of a connection, or None (and a problem, unless its component or connector
        was refused already)."""
        comp = self.components.get(element or "")
        if comp is None:
            if element not in self.broken:
                self.refuse(c, f"no component {element!r}")
            return None
        var = comp.description.variables.get(connector or "")
        if connector in comp.broken:
            return None
        if var is None or connector not in comp.connectors:
            self.refuse(c, f"component {element!r} declares no connector {connector!r}")
            return None
        unit = comp.connectors[connector]
        return _End(comp, var, (unit, self.defs.units.get(unit)) if unit else self.fmu_unit(comp, var))

    def read_connections(self, system: Any, data: dict[str, Any]) -> None:
        for c in system.iterfind("ssd:Connections/ssd:Connection", NS):
            if c.get("startElement") is None or c.get("endElement") is None:
                self.refuse(
                    c, "a connection to the system's own connector: the twin runs the components only"
                )
                continue
            out = self.end(c, c.get("startElement"), c.get("startConnector"))
            into = self.end(c, c.get("endElement"), c.get("endConnector"))
            if out is None or into is None:
                continue
            causalities = (out.var.causality, into.var.causality)
            if causalities == ("input", "output"):
                out, into = into, out  # start and end say nothing of the direction: the kinds do
            elif causalities != ("output", "input"):
                self.refuse(
                    c,
                    f"connects {article(causalities[0])} to {article(causalities[1])}: the twin connects outputs to inputs",
                )
                continue
            if (out.var.type, into.var.type) != ("Real", "Real"):
                self.refuse(
                    c, f"{article(out.var.type)} connection: the twin's master exchanges Real outputs only"
                )
                continue
            self.connection(c, out, into, data)

    def connection(self, c: Any, out: _End, into: _End, data: dict[str, Any]) -> None:
        """One connection from the output ``out`` to the input ``into``, as ``[connections]``
        (its transformation and unit conversion folded into factor and offset) or ``[[delay]]``."""
        t = c.find("ssc:LinearTransformation", NS)
        factor = float(t.get("factor", "1")) if t is not None else 1.0
        offset = float(t.get("offset", "0")) if t is not None else 0.0
        if not (math.isfinite(factor) and math.isfinite(offset)):
            self.refuse(t, "factor and offset must be finite")
            return
        suppress = c.get("suppressUnitConversion", "false") in ("true", "1")
        folded = False
        if not suppress and out.unit[0] and into.unit[0]:
            try:
                cf, co = self.conversion(out.unit, into.unit, c)
            except Refusal as exc:
                self.problems.append(str(exc))
                return
            # SSP: the unit conversion first, then the linear transformation
            factor, offset = factor * cf, factor * co + offset
            folded = True
        twin = self.known(self.annotation(c, TWIN_TYPE), {"twin:Delay"})
        if twin:
            if (factor, offset) != (1.0, 0.0):
                self.refuse(c, "a delayed connection (twin:Delay) with a transformation or a unit conversion")
                return
            initial = twin[0].get("initial", "0")
            try:
                value = float(initial)
            except ValueError:
                self.refuse(twin[0], f"initial {initial!r} is not a number")
                return
            data.setdefault("delay", []).append({"from": out.ref, "to": into.ref, "initial": value})
            return
        target: Any = into.ref
        fmu_units_differ = out.var.unit != into.var.unit
        if (factor, offset) != (1.0, 0.0) or ((folded or suppress) and fmu_units_differ):
            target = {"to": into.ref, "factor": factor, "offset": offset}
            if (folded or suppress) and fmu_units_differ:
                target["convert_units"] = False  # the conversion is in factor and offset already
        data["connections"].setdefault(out.ref, []).append(target)

    # ------------------------------------------------------------------------- profiles

    def profiles(self, data: dict[str, Any], values: Mapping[str, Mapping[str, Any]]) -> None:
        """Each SignalSource the twin's export added for a profile becomes that profile again:
        the input it feeds gets the profile its parameters give, and the component and its one
        connection leave the system."""
        for comp in [c for c in self.components.values() if c.profile is not None]:
            if comp.description.model_name != SOURCE_MODEL:
                self.refuse(
                    comp.profile,
                    f"a twin:Profile on a {comp.description.model_name!r} FMU, not a {SOURCE_MODEL}",
                )
                continue
            prefix = f"{comp.name}."
            feeds = data["connections"].pop(f"{comp.name}.y", [])
            touching = [s for s in data["connections"] if s.startswith(prefix)]
            touching += [
                _target(d) for ds in data["connections"].values() for d in ds if _target(d).startswith(prefix)
            ]
            touching += [
                d["to"]
                for d in data.get("delay", [])
                if prefix in (d["to"][: len(prefix)], d["from"][: len(prefix)])
            ]
            if len(feeds) != 1 or not _untransformed(feeds[0]) or touching:
                self.refuse(
                    comp.profile, "a profile's source must feed one input, untransformed, and nothing else"
                )
                continue
            target = _target(feeds[0])
            receiver = self.components[target.split(".", 1)[0]]
            if comp.hint != receiver.hint:
                self.refuse(
                    comp.profile,
                    f"the source steps every {comp.hint} s, the input it feeds every {receiver.hint} s",
                )
                continue
            profile = self.profile(comp, values.get(comp.name, {}))
            if profile is not None:
                inst, var = target.split(".", 1)
                data.setdefault("input", {}).setdefault(inst, {})[var] = profile
            del data["fmu"][comp.name]

    def profile(self, comp: _Component, values: Mapping[str, Any]) -> dict[str, Any] | None:
        variables = comp.description.variables

        def get(name: str) -> Any:
            return values[name] if name in values else variables[name].start

        k = get("profile")
        if not isinstance(k, int) or not 0 <= k < len(PROFILE_KINDS):
            self.refuse(comp.profile, f"profile {k!r} is none of the SignalSource's")
            return None
        kind = PROFILE_KINDS[k]
        out: dict[str, Any] = {"profile": kind}
        for name in _PROFILE_PARAMS[kind]:
            if not (name == "rise_at" and get(name) == 0.0):  # 0: not given
                out[name] = get(name)
        if kind == "table":
            out["points"] = [[get(f"table_t_{i}"), get(f"table_v_{i}")] for i in range(1, get("table_n") + 1)]
        if comp.profile.get("source"):
            out["source"] = comp.profile.get("source")
        return out

    # ------------------------------------------------------------------------- the whole

    def unconnected(self, data: dict[str, Any]) -> None:
        """Every input nothing feeds stays at its start value (as SSP says): marked as meant."""
        fed = {_target(d) for ds in data["connections"].values() for d in ds}
        fed |= {d["to"] for d in data.get("delay", [])}
        for inst, inputs in data.get("input", {}).items():
            fed |= {f"{inst}.{v}" for v in inputs}
        for name, spec in data["fmu"].items():
            comp = self.components[name]
            marks = {
                v.name: _UNCONNECTED
                for v in comp.description.variables.values()
                if v.causality == "input" and f"{name}.{v.name}" not in fed
            }
            if marks:
                spec["unconnected"] = marks


def _target(d: Any) -> str:
    """The input a ``[connections]`` entry feeds (a name, or a table with ``to``)."""
    return d if isinstance(d, str) else str(d.get("to", ""))


def _derived_seed(data: Mapping[str, Any], index: int) -> int | None:
    """The seed the twin's master gives instance ``index`` of the scenario ``data`` describes."""
    from twin.seeds import instance_seed

    seed = data["scenario"].get("seed", 0)
    return instance_seed(seed, index) if isinstance(seed, int) and 0 <= seed < 2**31 else None


def _untransformed(d: Any) -> bool:
    """A ``[connections]`` entry passes its output's value as it is (a unit conversion that
    is the identity included)."""
    return isinstance(d, str) or (d.get("factor") == 1.0 and d.get("offset") == 0.0)


def read_system(archive: Archive) -> dict[str, Any]:
    """The archive's system as a scenario's data; :class:`ConfigErrors` naming every element
    the twin does not apply (one line each)."""
    from twin.config.ssp.settings import scenario_table, twin_tables

    r = _Reader(archive)
    r.walk(r.root)
    system = r.root.find("ssd:System", NS)
    data: dict[str, Any] = {"scenario": scenario_table(r, system), "fmu": {}, "connections": {}}
    r.read_components(system)
    r.system_values(system)
    values = {}
    instances = [c for c in r.components.values() if c.profile is None]
    for comp in r.components.values():
        data["fmu"][comp.name] = {"model": str(comp.fmu), "parameters": {}}
        if comp.hint:
            data["fmu"][comp.name]["period"] = f"{comp.hint} s"
        index = instances.index(comp) if comp in instances else -1
        values[comp.name] = r.apply_values(comp, data, index)
    r.read_connections(system, data)
    r.check()
    r.profiles(data, values)
    r.unconnected(data)
    data.update(twin_tables(r))
    r.check()
    return data
