"""The one reader of an FMU's ``modelDescription.xml``.

:func:`describe` reads the description of a model's source folder, an extracted FMU or an
``.fmu`` file with fmpy's reader (validated against the schema), resolved once per content
into :class:`Variable` records: unit and range come from the variable or its declared type.
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

__all__ = ["Description", "Variable", "describe"]


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


@dataclass(frozen=True)
class Description:
    """What a modelDescription.xml says that the twin uses."""

    guid: str
    model_identifier: str
    variables: Mapping[str, Variable]
    #: what variables mean to the twin, role -> variable (see :func:`_roles`)
    roles: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))


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


def _variable(sv: Any) -> Variable:
    lo, hi = _declared(sv, "min"), _declared(sv, "max")
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
    )


#: descriptions by the SHA-256 of their modelDescription.xml: a model's source file and the FMU
#: built from it hold the same bytes, so a process parses and validates each one once (fmpy
#: loads the XML schema for every file it validates: 2 ms each, a tenth of a fresh process's
#: FMU set-up)
_BY_CONTENT: dict[bytes, Description] = {}


def _description_bytes(path: Path) -> bytes:
    if path.is_dir():
        return (path / "modelDescription.xml").read_bytes()
    if path.suffix.lower() == ".xml":
        return path.read_bytes()
    with zipfile.ZipFile(path) as fmu:
        return fmu.read("modelDescription.xml")


def describe(path: str | Path) -> Description:
    """Read a ``modelDescription.xml``, an extracted FMU folder or an ``.fmu`` file (validated
    by fmpy; once per content and process)."""
    xml = _description_bytes(Path(path))
    key = hashlib.sha256(xml).digest()
    found = _BY_CONTENT.get(key)
    if found is None:
        found = _BY_CONTENT[key] = _parse(xml)
    return found


def _parse(xml: bytes) -> Description:
    """The description in ``xml``, parsed by fmpy from exactly these bytes (fmpy reads a file
    object as an FMU: they go to it as the one member of a zip in memory)."""
    from fmpy import read_model_description

    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as fmu:
        fmu.writestr("modelDescription.xml", xml)
    archive.seek(0)
    md = read_model_description(archive)
    identifier = md.coSimulation.modelIdentifier if md.coSimulation is not None else ""
    variables = {sv.name: _variable(sv) for sv in md.modelVariables}
    return Description(md.guid, identifier, MappingProxyType(variables), _roles(xml, variables))


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
