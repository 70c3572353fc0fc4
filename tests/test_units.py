"""twin.units: FMI/Modelica unit syntax read into the one pint registry, conversions with their
offset where a temperature scale has one, and different dimensions refused."""

from __future__ import annotations

import pytest

from twin import units
from twin.errors import ConfigError, UnitError


@pytest.mark.parametrize(
    "src, dst, factor, offset",
    [
        ("K", "K", 1.0, 0.0),
        ("1", "", 1.0, 0.0),
        ("K", "degC", 1.0, -273.15),
        ("degC", "K", 1.0, 273.15),
        ("m", "mm", 1e3, 0.0),
        ("m", "um", 1e6, 0.0),
        ("N.m", "kN.m", 1e-3, 0.0),
        ("m2", "mm2", 1e6, 0.0),
        ("W/(m.K)", "W/(mm.K)", 1e-3, 0.0),
        ("1/K", "1/degC", 1.0, 0.0),  # a scale inside a compound unit is a difference
        ("m/K", "um/degC", 1e6, 0.0),
        ("Pa", "bar", 1e-5, 0.0),
        ("N", "kN", 1e-3, 0.0),
        ("rad", "deg", 57.29577951308232, 0.0),
    ],
)
def test_conversions(src: str, dst: str, factor: float, offset: float) -> None:
    f, o = units.conversion(src, dst)
    assert f == pytest.approx(factor, rel=1e-12) and o == pytest.approx(offset, abs=1e-9)
    assert units.convert(2.0, src, dst) == pytest.approx(factor * 2.0 + offset)


def test_units_written_alike_convert_exactly_without_pint() -> None:
    assert units.conversion("W/K", "W/K") == (1.0, 0.0)
    assert units.convert(-0.0, "m", "m") == -0.0


@pytest.mark.parametrize(
    "src, dst, words",
    [
        ("N", "m", "cannot be converted"),
        ("K", "W", "cannot be converted"),
        ("furlongs2x", "m", "unknown unit"),
    ],
)
def test_different_dimensions_and_unknown_units_are_refused(src: str, dst: str, words: str) -> None:
    with pytest.raises(UnitError, match=words) as info:
        units.conversion(src, dst)
    assert isinstance(info.value, ConfigError) and isinstance(info.value, ValueError)
    assert "\n" not in str(info.value)


def test_one_registry() -> None:
    assert units.registry() is units.registry()
    assert units.dimensionless("1") and units.dimensionless("rad") and not units.dimensionless("m")
