"""Units: the one pint registry of the twin, and the conversions between the units that FMUs,
SSP files and labs write.

FMI and SSP units are written in Modelica's syntax (``N.m``, ``m2``, ``W/(m.K)``, ``1``);
:func:`parse` reads that syntax (pint's own as well: ``N*m``, ``m**2``, ``degC``, ``mm``) into
a pint unit of the one registry. :func:`conversion` gives the factor and offset that carry a
value from one unit to another (``dst = factor * src + offset``: an offset only between
temperature scales), or refuses units of different dimensions with a :class:`UnitError`.

A unit may also come with its definition, as FMI's ``UnitDefinitions`` and SSP's ``ssc:Units``
write it: :class:`twin.fmu.description.BaseUnit` converts between two definitions exactly as
those standards define them, whatever the units are called.

pint is imported the first time a unit is parsed: a run whose connections all agree in unit
never loads it.
"""

from __future__ import annotations

import functools
import re
from typing import Any

from twin.errors import UnitError

__all__ = [
    "UnitError",
    "conversion",
    "convert",
    "dimensionless",
    "parse",
    "registry",
    "same_unit",
]

#: a unit name followed by its exponent, Modelica style: ``m2``, ``s-1``
_EXPONENT = re.compile(r"(?<=[A-Za-z])(-?\d+)(?![\d.])")
#: temperature scales with an offset: a value converts with it only when the unit is one alone
_OFFSET_UNITS = frozenset({"degC", "degF", "celsius", "fahrenheit"})


@functools.cache
def registry() -> Any:
    """The twin's one pint UnitRegistry (offset units such as degC allowed in conversions)."""
    import pint

    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


def _pint_syntax(text: str) -> str:
    """Modelica's unit syntax in pint's: ``.`` between factors is ``*``, a trailing integer an
    exponent (``m2`` -> ``m**2``); ``1`` alone is dimensionless."""
    text = text.strip()
    if text in ("", "1"):
        return "dimensionless"
    text = re.sub(r"(?<=[A-Za-z)\d])\.(?=[A-Za-z(])", "*", text)
    text = _EXPONENT.sub(r"**\1", text)
    if text not in _OFFSET_UNITS:
        # inside a compound unit (1/degC, W/(m.degC)) a temperature scale is a difference
        text = re.sub(r"\b(deg[CF])\b", r"delta_\1", text)
    return text


@functools.cache
def parse(text: str) -> Any:
    """The pint unit ``text`` names (Modelica or pint syntax); :class:`UnitError` if none."""
    ureg = registry()
    try:
        quantity = ureg.parse_expression(_pint_syntax(text))
    except Exception as exc:  # pint raises several kinds (UndefinedUnitError, a syntax error)
        raise UnitError(f"unknown unit {text!r} ({type(exc).__name__})") from None
    units = getattr(quantity, "units", None)
    magnitude = getattr(quantity, "magnitude", quantity)
    if units is None or magnitude != 1:
        raise UnitError(f"{text!r} is not a unit (a number times a unit: {quantity})")
    return units


def same_unit(a: str, b: str) -> bool:
    """Whether ``a`` and ``b`` are written alike (no conversion needed, pint not loaded)."""
    return a.strip() == b.strip() or {a.strip(), b.strip()} <= {"", "1"}


def dimensionless(text: str) -> bool:
    """Whether ``text`` is a unit without dimension (``1``, ``rad`` is not: pint keeps it)."""
    return same_unit(text, "1") or parse(text).dimensionless


def conversion(src: str, dst: str) -> tuple[float, float]:
    """``(factor, offset)`` with ``value_in_dst = factor * value_in_src + offset``; exactly
    ``(1.0, 0.0)`` for units written alike. :class:`UnitError` for different dimensions."""
    if same_unit(src, dst):
        return 1.0, 0.0
    a, b = parse(src), parse(dst)
    ureg = registry()
    if a.dimensionality != b.dimensionality:
        raise UnitError(f"'{src}' ({_dimension(a)}) cannot be converted to '{dst}' ({_dimension(b)})")
    zero = ureg.Quantity(0.0, a).to(b).magnitude
    one = ureg.Quantity(1.0, a).to(b).magnitude
    return float(one - zero), float(zero)


def convert(value: float, src: str, dst: str) -> float:
    """``value`` in ``src`` expressed in ``dst``."""
    factor, offset = conversion(src, dst)
    return value if (factor, offset) == (1.0, 0.0) else factor * value + offset


def _dimension(unit: Any) -> str:
    text = str(unit.dimensionality)
    return "no dimension" if text == "dimensionless" else text
