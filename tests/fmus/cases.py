"""One conformance case per FMU: the inputs to drive it with and its step sizes.

Every model in fmus/ must have an entry (tests/fmus/test_conformance.py checks), so a new
model cannot skip the conformance tests.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Case:
    inputs: dict[str, float]
    step: float
    stop: float
    parameters: dict[str, float] = field(default_factory=dict)


CASES: dict[str, Case] = {
    "ThermalNetwork": Case(
        inputs={"t_room": 301.0, "q_hydraulic": 350.0, "q_friction": 25.0},
        step=60.0,
        stop=4 * 3600.0,
        parameters={"t_start_bearing": 295.0},
    ),
}
