"""The names an SSP 1.0 archive is written in (namespaces, annotation types) and the one way
its elements are named in a message: ``ssd:System[tester]/ssd:Elements/ssd:Component[thermal]``.

Shared by the reader (:mod:`twin.config.ssp`) and the writer (:mod:`twin.exchange.ssp`), so an
archive the twin writes is read back under the same names.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = [
    "NS",
    "OSP_TYPE",
    "SSD_NAME",
    "TWIN_TYPE",
    "TYPES",
    "article",
    "describe",
    "path_of",
    "q",
    "seconds",
    "tag_of",
    "value_text",
]

SSD_NAME = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "ssb": "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "twin": "https://github.com/twin/ssp-annotations",
}
_PREFIX = {uri: prefix for prefix, uri in NS.items()}
#: libcosim's annotations (the fixed-step algorithm, each component's step)
OSP_TYPE = "com.opensimulationplatform"
#: the twin's own annotations (its scenario settings, delays, profiles, parameter sources)
TWIN_TYPE = "io.github.twin"
#: an FMU variable's type as an SSP connector or parameter value types it
TYPES = {
    "Real": "Real",
    "Integer": "Integer",
    "Enumeration": "Enumeration",
    "Boolean": "Boolean",
    "String": "String",
}


def q(tag: str) -> str:
    """``"ssd:System"`` in Clark notation (``{namespace}System``)."""
    prefix, local = tag.split(":")
    return f"{{{NS[prefix]}}}{local}"


def tag_of(el: Any) -> str:
    """An element's tag as the standard writes it (``ssd:Component``); another namespace's
    element by its full name."""
    m = re.fullmatch(r"\{(.*)\}(.*)", str(el.tag))
    if m is None:
        return str(el.tag)
    prefix = _PREFIX.get(m.group(1))
    return f"{prefix}:{m.group(2)}" if prefix else f"{{{m.group(1)}}}{m.group(2)}"


def describe(el: Any) -> str:
    """One element named for a message: its tag and what tells it from its siblings."""
    tag = tag_of(el)
    if tag == "ssd:Connection":
        start = ".".join(x for x in (el.get("startElement"), el.get("startConnector")) if x)
        end = ".".join(x for x in (el.get("endElement"), el.get("endConnector")) if x)
        return f"{tag}[{start} -> {end}]"
    if tag == "ssm:MappingEntry":
        return f"{tag}[{el.get('source')} -> {el.get('target')}]"
    if tag == "ssc:Annotation":
        return f"{tag}[{el.get('type')}]"
    name = el.get("name") or (
        el.get("source") if tag in ("ssd:ParameterBinding", "ssd:ParameterMapping") else None
    )
    return f"{tag}[{name}]" if name else tag


def path_of(el: Any) -> str:
    """The element's path from below its document's root: ``ssd:System[tester]/ssd:Elements/
    ssd:Component[thermal]``."""
    parts = []
    while el is not None and el.getparent() is not None:
        parts.append(describe(el))
        el = el.getparent()
    return "/".join(reversed(parts)) or describe(el)


def article(word: str) -> str:
    """``word`` with its indefinite article: "an input", "a parameter"."""
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def seconds(ns: int) -> str:
    """Integer nanoseconds as seconds, the shortest text that reads back to the same float."""
    return repr(ns / 1e9)


def value_text(kind: str, value: Any) -> str:
    """A value as an SSP parameter value's ``value`` attribute writes it."""
    if kind == "Boolean":
        return "true" if bool(value) else "false"
    if kind in ("Integer", "Enumeration"):
        return str(int(value))
    if kind == "Real":
        return repr(float(value))
    return str(value)
