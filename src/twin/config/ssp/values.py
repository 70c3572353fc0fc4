"""SSP parameter values: parameter sets (``.ssv`` files or inline ``ssd:ParameterValues``),
parameter mappings (``.ssm`` files or inline), unit and enumeration definitions, and one value
resolved against the FMU variable it sets.

What SSP 1.0 says and the twin applies (:func:`resolve`):

- a ``ssv:Real`` with a ``unit`` is converted to the variable's unit: through the two units'
  definitions (the set's or the SSD's ``ssc:Unit``, the FMU's ``UnitDefinitions``) when both
  have one, else through the units' names (:func:`twin.units.conversion`);
- a mapping entry renames a value and may transform it: ``ssc:LinearTransformation`` (after the
  unit conversion, unless ``suppressUnitConversion``), ``ssc:IntegerMappingTransformation``,
  ``ssc:BooleanMappingTransformation``, ``ssc:EnumerationMappingTransformation`` (a value the
  map lacks is refused);
- an ``ssv:Enumeration`` is its item's value, by the enumeration its ``name`` names (the set's
  ``ssv:Enumerations``, then the SSD's) or else by the FMU variable's own type;
- a binding's ``prefix`` is put before every name of its set.

Each problem is one line naming the file and the element.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

from twin.config.ssp.names import NS, TWIN_TYPE, article, describe, path_of, q, tag_of
from twin.errors import UnitError
from twin.fmu.description import BASE_UNITS, BaseUnit
from twin.units import conversion

__all__ = ["Definitions", "Refusal", "Value", "definitions", "parameter_set", "resolve"]


class Refusal(Exception):
    """Why an element cannot be applied: one line, the file and the element path first."""

    def __init__(self, where: str, element: Any, why: str) -> None:
        super().__init__(f"{where}: {path_of(element)}: {why}")


@dataclass(frozen=True)
class Definitions:
    """Units and enumerations that names in a file resolve to (a set's own before the SSD's)."""

    units: Mapping[str, BaseUnit] = field(default_factory=lambda: MappingProxyType({}))
    enumerations: Mapping[str, Mapping[str, int]] = field(default_factory=lambda: MappingProxyType({}))

    def over(self, outer: Definitions) -> Definitions:
        """These definitions, and ``outer``'s for the names these lack."""
        return Definitions(
            MappingProxyType({**outer.units, **self.units}),
            MappingProxyType({**outer.enumerations, **self.enumerations}),
        )


def definitions(root: Any, prefix: str) -> Definitions:
    """The ``<prefix>:Units`` and ``<prefix>:Enumerations`` of a file's root (``ssd`` or ``ssv``)."""
    units = {}
    for u in root.iterfind(f"{prefix}:Units/ssc:Unit", NS):
        b = u.find("ssc:BaseUnit", NS)
        exponents = tuple(int(b.get(name, "0")) for name in BASE_UNITS)
        units[u.get("name")] = BaseUnit(exponents, float(b.get("factor", "1")), float(b.get("offset", "0")))
    enums = {}
    for e in root.iterfind(f"{prefix}:Enumerations/ssc:Enumeration", NS):
        enums[e.get("name")] = MappingProxyType(
            {i.get("name"): int(i.get("value")) for i in e.iterfind("ssc:Item", NS)}
        )
    return Definitions(MappingProxyType(units), MappingProxyType(enums))


@dataclass(frozen=True)
class Value:
    """One parameter value of a set, as read (``kind`` is its element: Real, Integer, ...)."""

    name: str
    kind: str
    text: str
    element: Any  # the ssv:Parameter, for messages
    where: str  # the file it is written in
    defs: Definitions
    unit: str | None = None
    enumeration: str | None = None
    #: the mapping entry's transformation (None: the value as it is) and its unit flag
    transformation: Any = None
    suppress_units: bool = False
    #: the twin's annotation of the parameter: (source, standard error)
    source: str = ""
    std_error: float | None = None
    #: "scenario.seed": the twin's master derived this seed from the scenario's (its export
    #: writes it for other masters); the twin derives it again, so a changed seed reaches it
    derived: str = ""


_KINDS = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")


def parameter_set(root: Any, where: str, outer: Definitions, prefix: str = "") -> list[Value]:
    """The values of one ``ssv:ParameterSet`` (already valid against the schema)."""
    defs = definitions(root, "ssv").over(outer)
    out = []
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        typed = next(c for c in p if isinstance(c.tag, str) and tag_of(c).removeprefix("ssv:") in _KINDS)
        kind = tag_of(typed).removeprefix("ssv:")
        if kind == "Binary":
            raise Refusal(where, typed, "a Binary parameter value is not supported")
        source, std_error, derived = _twin_parameter(p, where)
        out.append(
            Value(
                prefix + p.get("name"),
                kind,
                typed.get("value"),
                p,
                where,
                defs,
                unit=typed.get("unit"),
                enumeration=typed.get("name"),
                source=source,
                std_error=std_error,
                derived=derived,
            )
        )
    return out


def _twin_parameter(p: Any, where: str) -> tuple[str, float | None, str]:
    """The twin's annotation of a parameter: where its value comes from, its standard error,
    what it is derived from."""
    for a in p.iterfind("ssv:Annotations/ssc:Annotation", NS):
        if a.get("type") != TWIN_TYPE:
            continue
        for el in a:
            if not isinstance(el.tag, str):
                continue
            if tag_of(el) != "twin:Parameter":
                raise Refusal(where, el, "an annotation of the twin this version does not know")
            se = el.get("stdError")
            try:
                std_error = float(se) if se is not None else None
            except ValueError:
                raise Refusal(where, el, f"stdError {se!r} is not a number") from None
            return el.get("source", ""), std_error, el.get("derived", "")
    return "", None, ""


def apply_mapping(values: list[Value], mapping: Any, where: str) -> list[Value]:
    """The values renamed and given transformations by a ``ssm:ParameterMapping`` (a name the
    mapping does not mention keeps its name and value)."""
    entries = {}
    for e in mapping.iterfind("ssm:MappingEntry", NS):
        if e.get("source") in entries:
            raise Refusal(where, e, f"a second entry for {e.get('source')!r}")
        entries[e.get("source")] = e
    out = []
    for v in values:
        e = entries.get(v.name)
        if e is None:
            out.append(v)
            continue
        t = next((c for c in e if isinstance(c.tag, str) and tag_of(c) != "ssm:Annotations"), None)
        suppress = e.get("suppressUnitConversion", "false") in ("true", "1")
        out.append(replace(v, name=e.get("target"), transformation=t, suppress_units=suppress))
    return out


# ----------------------------------------------------------------------------- resolving


def resolve(v: Value, var: Any, fmu_units: Mapping[str, BaseUnit]) -> Any:
    """The value ``v`` sets the FMU variable ``var`` to (typed as the variable is: float, int
    or bool), its unit converted and its mapping applied; :class:`Refusal` when it cannot."""
    if v.kind == "Real":
        return _real(v, var, fmu_units)
    if v.kind == "Boolean":
        _expect(v, var, ("Boolean",))
        x = v.text.strip() in ("true", "1")
        return _mapped(v, x, "ssc:BooleanMappingTransformation", lambda s: s.strip() in ("true", "1"))
    if v.kind == "Integer":
        _expect(v, var, ("Integer", "Enumeration"))
        return _mapped(v, int(v.text), "ssc:IntegerMappingTransformation", int)
    if v.kind == "Enumeration":
        _expect(v, var, ("Integer", "Enumeration"))
        return _enumeration(v, var)
    raise Refusal(
        v.where,
        v.element,
        f"{article(v.kind)} parameter value: the twin's parameters are numbers and booleans",
    )


def _expect(v: Value, var: Any, types: tuple[str, ...]) -> None:
    if var.type not in types:
        raise Refusal(v.where, v.element, f"an ssv:{v.kind} value for {var.name!r}, a {var.type} variable")


def _mapped(v: Value, x: Any, kind: str, parse: Any) -> Any:
    """``x`` through the value's mapping transformation, which must be of ``kind``."""
    t = v.transformation
    if t is None:
        return x
    if tag_of(t) != kind:
        raise Refusal(v.where, t, f"does not apply to an ssv:{v.kind} value (it takes {kind})")
    for entry in t.iterfind("ssc:MapEntry", NS):
        if parse(entry.get("source")) == x:
            return parse(entry.get("target"))
    raise Refusal(v.where, t, f"maps no value {v.text!r} (of {v.name!r})")


def _enumeration(v: Value, var: Any) -> int:
    item = v.text
    t = v.transformation
    if t is not None and tag_of(t) == "ssc:EnumerationMappingTransformation":
        item = _mapped(v, item, "ssc:EnumerationMappingTransformation", str)
        v = replace(v, transformation=None)
    if v.enumeration is not None:
        items = v.defs.enumerations.get(v.enumeration)
        if items is None:
            raise Refusal(
                v.where, v.element, f"no enumeration {v.enumeration!r} is defined (ssc:Enumerations)"
            )
    elif var.items:
        items = var.items
    else:
        raise Refusal(
            v.where,
            v.element,
            f"an enumeration item without its enumeration's name, for {var.type} variable {var.name!r}",
        )
    if item not in items:
        raise Refusal(v.where, v.element, f"{item!r} is not an item of {v.enumeration or var.name!r}")
    return _mapped(v, items[item], "ssc:IntegerMappingTransformation", int)


def _real(v: Value, var: Any, fmu_units: Mapping[str, BaseUnit]) -> float:
    _expect(v, var, ("Real",))
    x = float(v.text)
    if not math.isfinite(x):
        raise Refusal(v.where, v.element, f"{v.text!r} is not a finite number")
    if v.unit and not v.suppress_units:
        factor, offset = unit_conversion(
            (v.unit, v.defs.units.get(v.unit)), (var.unit, fmu_units.get(var.unit)), v
        )
        x = x if (factor, offset) == (1.0, 0.0) else factor * x + offset
    t = v.transformation
    if t is None:
        return x
    if tag_of(t) != "ssc:LinearTransformation":
        raise Refusal(v.where, t, "does not apply to an ssv:Real value (it takes ssc:LinearTransformation)")
    return float(t.get("factor", "1")) * x + float(t.get("offset", "0"))


def unit_conversion(
    src: tuple[str, BaseUnit | None], dst: tuple[str, BaseUnit | None], v: Value
) -> tuple[float, float]:
    """(factor, offset) from the unit ``src`` to ``dst`` (name, definition or None), for the
    value ``v``."""
    if not dst[0]:
        raise Refusal(v.where, v.element, f"a value in {src[0]!r} for a variable without a unit")
    try:
        if src[1] is not None and dst[1] is not None:
            return src[1].conversion_to(dst[1], (src[0], dst[0]))
        return conversion(src[0], dst[0])
    except UnitError as exc:
        raise Refusal(v.where, v.element, exc.message or str(exc)) from None


def element_refusal(where: str, el: Any, why: str) -> Refusal:
    """A refusal of ``el`` (for the modules that do not build values)."""
    return Refusal(where, el, why)


def binding_name(el: Any) -> str:
    """How a binding is named in a message."""
    return describe(el)


def child(el: Any, tag: str) -> Any:
    """The first child of ``el`` with ``tag`` (``ssd:ParameterValues``), or None."""
    return el.find(tag, NS) if ":" in tag else el.find(q(tag))
