"""The one reader of an FMU's ``modelDescription.xml``.

:func:`describe` reads the description of a model's source folder, an extracted FMU or an
``.fmu`` file with fmpy's reader (validated against the schema), resolved once per content
into :class:`Variable` records: unit, range and nominal value come from the variable or its
declared type. It also reads the ``<ModelStructure>``: which inputs each output depends on at a
communication point (direct feedthrough) and in initialization mode, with FMI 2.0's defaults
(:func:`_dependencies`), which the master's loop analysis needs (:mod:`twin.config.loops`).
"""

from __future__ import annotations

import hashlib
import io
import math
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from twin.errors import ConfigError, UnitError

__all__ = [
    "BASE_UNITS",
    "MAX_DESCRIPTION_BYTES",
    "BaseUnit",
    "Description",
    "Variable",
    "describe",
    "describe_xml",
    "fmpy_description",
    "validate_xml",
]

#: the base units of FMI's and SSP's unit definitions, in their order
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@dataclass(frozen=True)
class BaseUnit:
    """A unit as FMI 2.0 (``<BaseUnit>``) and SSP 1.0 (``ssc:BaseUnit``) define it: the
    exponents of :data:`BASE_UNITS`, and ``value_in_base = factor * value + offset``. Two such
    definitions convert into each other exactly as those standards say, whatever the units are
    called (:meth:`conversion_to`); units known by name only go through :mod:`twin.units`."""

    exponents: tuple[int, ...] = (0,) * len(BASE_UNITS)
    factor: float = 1.0
    offset: float = 0.0

    def dimension(self) -> str:
        """The exponents as text (``kg.m.s-2``), for messages."""
        parts = [f"{b}{e if e != 1 else ''}" for b, e in zip(BASE_UNITS, self.exponents, strict=True) if e]
        return ".".join(parts) or "no dimension"

    def conversion_to(self, dst: BaseUnit, names: tuple[str, str] = ("", "")) -> tuple[float, float]:
        """``(factor, offset)`` carrying a value from this unit to ``dst`` (``value_in_dst =
        factor * value + offset``), through their common base unit; exactly ``(1.0, 0.0)`` for
        equal definitions. :class:`~twin.errors.UnitError` (naming ``names``) when their
        exponents differ."""
        if self.exponents != dst.exponents:
            a, b = names
            raise UnitError(
                f"'{a}' ({self.dimension()}) cannot be converted to '{b}' ({dst.dimension()})"
                if a or b
                else f"{self.dimension()} cannot be converted to {dst.dimension()}"
            )
        if (self.factor, self.offset) == (dst.factor, dst.offset):
            return 1.0, 0.0
        # base = fs v + os = fd w + od  ->  w = (fs / fd) v + (os - od) / fd
        return self.factor / dst.factor, (self.offset - dst.offset) / dst.factor


@dataclass(frozen=True)
class Variable:
    """One scalar variable of a modelDescription, with unit and range resolved.

    ``min``/``max`` are the declared bounds (or those of the declared type), ``-inf``/``inf``
    when there are none; ``unit`` is ``""`` when none is declared; ``start`` is typed by
    ``type`` (``float``, ``int``, ``bool`` or ``str``) and ``None`` when absent.
    """

    name: str
    value_reference: int
    type: str
    causality: str
    variability: str
    unit: str
    min: float
    max: float
    start: float | int | bool | str | None
    description: str
    #: an Enumeration's items by name (its declared type's), empty for other types
    items: Mapping[str, int] = field(default_factory=lambda: MappingProxyType({}))
    #: the magnitude the variable is scaled by (FMI 2.0: 1 when none is declared); an algebraic
    #: loop's convergence is judged relative to it for values near zero
    nominal: float = 1.0


@dataclass(frozen=True)
class Description:
    """What a modelDescription.xml says that the twin uses."""

    guid: str
    model_identifier: str
    variables: Mapping[str, Variable]
    #: what variables mean to the twin, role -> variable (see :func:`_roles`)
    roles: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    model_name: str = ""
    fmi_version: str = ""
    #: the model's own description text
    text: str = ""
    #: the FMI interfaces it offers: "co-simulation", "model exchange"
    kinds: tuple[str, ...] = ()
    #: its UnitDefinitions that give a BaseUnit, by name (what an SSP's units are converted to)
    units: Mapping[str, BaseUnit] = field(default_factory=lambda: MappingProxyType({}))
    #: output -> the inputs it depends on at a communication point (direct feedthrough)
    feedthrough: Mapping[str, tuple[str, ...]] = field(default_factory=lambda: MappingProxyType({}))
    #: output -> the inputs its value in initialization mode depends on
    initial_dependencies: Mapping[str, tuple[str, ...]] = field(default_factory=lambda: MappingProxyType({}))


def _declared(sv: Any, attribute: str) -> Any:
    """An attribute of an fmpy variable, else of its declared type (None if neither gives one)."""
    value = getattr(sv, attribute, None)
    if value in (None, "") and sv.declaredType is not None:
        value = getattr(sv.declaredType, attribute, None)
    return value


def _start(kind: str, text: str | None) -> float | int | bool | str | None:
    if text is None:
        return None
    if kind == "Boolean":
        return text in ("true", "1")
    return {"Real": float, "Integer": int, "Enumeration": int}.get(kind, str)(text)


def _items(sv: Any) -> Mapping[str, int]:
    items = getattr(sv.declaredType, "items", None) if sv.type == "Enumeration" else None
    return MappingProxyType({str(i.name): int(i.value) for i in items or ()})


def _units(md: Any) -> Mapping[str, BaseUnit]:
    out = {}
    for u in md.unitDefinitions or ():
        b = u.baseUnit
        if u.name and b is not None:
            exponents = tuple(int(getattr(b, name) or 0) for name in BASE_UNITS)
            out[str(u.name)] = BaseUnit(exponents, float(b.factor or 1.0), float(b.offset or 0.0))
    return MappingProxyType(out)


def _variable(sv: Any) -> Variable:
    lo, hi = _declared(sv, "min"), _declared(sv, "max")
    nominal = _declared(sv, "nominal") if sv.type == "Real" else None
    return Variable(
        name=sv.name,
        value_reference=int(sv.valueReference),
        type=sv.type,
        causality=sv.causality,
        variability=sv.variability,
        unit=str(_declared(sv, "unit") or ""),
        min=float(lo) if lo is not None else -math.inf,
        max=float(hi) if hi is not None else math.inf,
        start=_start(sv.type, sv.start),
        description=sv.description or "",
        items=_items(sv),
        nominal=abs(float(nominal)) if nominal not in (None, "") and float(nominal) != 0 else 1.0,
    )


#: descriptions by the SHA-256 of their modelDescription.xml: a model's source file and the FMU
#: built from it hold the same bytes, so a process parses and validates each one once (fmpy
#: loads the XML schema again for every file it validates)
_BY_CONTENT: dict[bytes, Description] = {}


#: the largest modelDescription.xml read: a model of 100 000 variables writes about 30 MB
MAX_DESCRIPTION_BYTES = 64 << 20


def _description_bytes(path: Path) -> bytes:
    """The bytes of the description at ``path``: a folder's ``modelDescription.xml``, an XML
    file, or an FMU's member (its zip read within :mod:`twin.fmu.safezip`'s bounds)."""
    from twin.fmu.safezip import MAX_ARCHIVE_BYTES, open_regular, open_zip, read_member

    if path.is_dir():
        path = path / "modelDescription.xml"
    source = str(path)
    if path.suffix.lower() == ".xml":
        with open_regular(path, source, "a modelDescription.xml", MAX_DESCRIPTION_BYTES) as f:
            return f.read()
    with (
        open_regular(path, source, "expected an FMU", MAX_ARCHIVE_BYTES) as f,
        open_zip(f, source, "not an FMU") as fmu,
    ):
        try:
            info = fmu.getinfo("modelDescription.xml")
        except KeyError:
            raise ConfigError("no modelDescription.xml in the archive", source=source) from None
        return read_member(fmu, info, source, MAX_DESCRIPTION_BYTES)


def describe(path: str | Path) -> Description:
    """Read a ``modelDescription.xml``, an extracted FMU folder or an ``.fmu`` file (validated
    by fmpy; once per content and process). A file that is none of these, or whose description
    fmpy refuses, is one :class:`~twin.errors.ConfigError` line naming it."""
    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise ConfigError("file not found", source=str(path))
    return describe_xml(_description_bytes(path), str(path))


def describe_xml(raw: bytes, source: str) -> Description:
    """The description in the bytes ``raw`` of a modelDescription.xml, read as
    :func:`twin.fmu.safezip.safe_xml` allows (UTF-8 or UTF-16, no document type) and validated
    by fmpy; ``source`` names where it came from in a problem's line."""
    from twin.fmu.safezip import safe_xml

    xml, _ = safe_xml(raw, "modelDescription.xml", source)
    key = hashlib.sha256(xml).digest()
    found = _BY_CONTENT.get(key)
    if found is None:
        try:
            found = _parse(xml)
        except (AttributeError, TypeError, KeyError, IndexError):
            # fmpy reads the document's attributes before it validates: one it lacks ends in
            # "'NoneType' object has no attribute ...", which says nothing of the file
            raise ConfigError(
                "not a readable FMI model description: modelDescription.xml lacks an element or "
                'attribute FMI requires (its root must be <fmiModelDescription fmiVersion="2.0" ...>)',
                source=source,
            ) from None
        except Exception as exc:  # fmpy raises several kinds for a document that is not FMI's
            raise ConfigError(
                f"not a readable FMI model description: {_first_problem(exc)}", source=source
            ) from None
        _BY_CONTENT[key] = found
    return found


def fmpy_description(xml: bytes) -> Any:
    """fmpy's ModelDescription of these checked bytes (:func:`describe_xml` has read them)."""
    from fmpy import read_model_description

    return read_model_description(_in_memory(xml))


def validate_xml(xml: bytes) -> list[str]:
    """fmpy's validation (``fmpy validate``) of these checked bytes: the problems it finds."""
    from fmpy.validation import validate_fmu

    return validate_fmu(_in_memory(xml))  # type: ignore[arg-type]  # fmpy takes a file object too


def _in_memory(xml: bytes) -> io.BytesIO:
    """``xml`` as the one member of a zip in memory: fmpy reads a file object as an FMU."""
    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as fmu:
        fmu.writestr("modelDescription.xml", xml)
    archive.seek(0)
    return archive


def _first_problem(exc: Exception) -> str:
    """The first problem fmpy names (its validation lists them one per line), on one line."""
    lines = [ln.strip().lstrip("- ").strip() for ln in str(exc).splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith("Failed to validate")]
    more = f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""
    return (" ".join(lines[0].split()) + more) if lines else type(exc).__name__


def _parse(xml: bytes) -> Description:
    """The description in ``xml``, parsed by fmpy from exactly these bytes (fmpy reads a file
    object as an FMU: they go to it as the one member of a zip in memory)."""
    md = fmpy_description(xml)
    identifier = md.coSimulation.modelIdentifier if md.coSimulation is not None else ""
    variables = {sv.name: _variable(sv) for sv in md.modelVariables}
    kinds = tuple(
        k for k, i in (("co-simulation", md.coSimulation), ("model exchange", md.modelExchange)) if i
    )
    feedthrough, initial = _dependencies(md)
    return Description(
        md.guid,
        identifier,
        MappingProxyType(variables),
        _roles(xml, variables),
        md.modelName or "",
        md.fmiVersion or "",
        md.description or "",
        kinds,
        _units(md),
        feedthrough,
        initial,
    )


def _dependencies(md: Any) -> tuple[Mapping[str, tuple[str, ...]], Mapping[str, tuple[str, ...]]]:
    """Which inputs each output depends on: at a communication point (``ModelStructure/Outputs``)
    and in initialization mode (``ModelStructure/InitialUnknowns``), by FMI 2.0's rules:

    - an ``Unknown`` without ``dependencies`` depends on every known, so on every input;
      ``dependencies=""`` on none (only on states: no direct feedthrough);
    - an output that ``Outputs`` does not list (which FMI forbids) is taken to depend on every
      input, the safe side;
    - an output that ``InitialUnknowns`` does not list has ``initial="exact"``: its start value,
      known before anything is set, depends on no input.

    Only inputs are kept (a dependency on a state or a parameter is no edge between FMUs)."""
    inputs = tuple(v.name for v in md.modelVariables if v.causality == "input")
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]

    def listed(unknowns: Any) -> dict[str, tuple[str, ...]]:
        out = {}
        for u in unknowns:
            deps = u.dependencies
            names = inputs if deps is None else tuple(v.name for v in deps if v.causality == "input")
            out[u.variable.name] = names
        return out

    at_steps, at_init = listed(md.outputs), listed(md.initialUnknowns)
    feedthrough = {name: at_steps.get(name, inputs) for name in outputs}
    initial = {name: at_init.get(name, ()) for name in outputs}
    return MappingProxyType(feedthrough), MappingProxyType(initial)


#: the tool name of the twin's own annotations in a modelDescription.xml
TOOL = "io.github.twin"


def _roles(xml: bytes, variables: Mapping[str, Variable]) -> Mapping[str, str]:
    """The roles a model's variables play for the twin, from its vendor annotation::

        <VendorAnnotations><Tool name="io.github.twin"><Roles>
          <Role name="swing_cycles" variable="cycles"/>
        </Roles></Tool></VendorAnnotations>

    so that no package names a model to find, say, the swing-cycle counter. Read after fmpy
    has validated the document (FMI lets a tool's annotation be one element: ``Roles``); a
    role naming no variable of the model is left out."""
    from xml.etree import ElementTree as ET

    root = ET.fromstring(xml)
    out = {}
    for tool in root.iterfind("VendorAnnotations/Tool"):
        if tool.get("name") != TOOL:
            continue
        for role in tool.iterfind("Roles/Role"):
            name, variable = role.get("name"), role.get("variable")
            if name and variable in variables:
                out[name] = variable
    return MappingProxyType(out)
