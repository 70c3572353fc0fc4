"""A sweep's figures: axes in words with units (an FMU variable's for a design key, the unit
in a figure's name for an output), whole-number counts, the main driver in the scatter even
when its effect is two-sided, and nothing written through a planted symlink."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.sweep.analysis import pawn_indices, rank_correlations
from twin.sweep.plots import MAX_PANELS, draw_all, figure_label, histogram_figure, key_label, labels, ranking
from twin.sweep.spec import Spec

SINE = scenarios_dir() / "sine-load.toml"


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SINE)


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("fmu.sensors.parameters.probe_zero_drift", "sensors probe_zero_drift (m/K)"),
        ("fmu.hydraulic.parameters.load_amplitude", "hydraulic load_amplitude (N)"),
        ("input.thermal.t_room.amplitude", "t_room amplitude (K)"),
        ("input.thermal.t_room.period", "t_room period (s)"),
        ("scenario.seed", "scenario.seed"),
    ],
)
def test_a_design_key_reads_with_its_fmu_variables_unit(scenario: object, key: str, expected: str) -> None:
    assert key_label(key, scenario) == expected  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("compensation.residual_rms_um.after", "compensation residual rms after (µm)"),
        ("drift_mm.probe", "drift probe (mm)"),
        ("temperature_rise_C.detecting_frame", "temperature rise detecting frame (°C)"),
    ],
)
def test_an_output_reads_with_the_unit_its_name_carries(name: str, expected: str) -> None:
    assert figure_label(name) == expected


def test_counts_on_a_histogram_are_whole_numbers() -> None:
    fig = histogram_figure(pd.Series([1.0, 1.1, 1.2, 2.0, 2.5]), "drift probe (mm)")
    ax = fig.axes[0]
    ticks = [t for t in ax.get_yticks() if ax.get_ylim()[0] <= t <= ax.get_ylim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)
    assert ax.get_xlabel() == "drift probe (mm)" and ax.get_ylabel() == "points"


def test_the_scatter_shows_the_main_driver_of_a_two_sided_effect(scenario: object, tmp_path: Path) -> None:
    """Twenty inputs, the output a parabola of the fifth: by the rank correlation it would be
    anywhere (its correlation is about zero, like the inputs without effect); by PAWN it is
    first, so its panel is drawn."""
    rng = np.random.default_rng(4)
    names = [f"fmu.thermal.parameters.g_{k}" for k in range(20)]
    x = rng.random((300, 20))
    table = pd.DataFrame(x, columns=names)
    table["point"] = range(300)
    table["status"] = "ok"
    table["y_um"] = (x[:, 4] - 0.5) ** 2 + 0.02 * x[:, 0] + 0.01 * rng.random(300)
    spec = Spec(path=Path("s.toml"), name="s", scenario=scenario, design="lhs", samples=300, seed=1,
                problem={"num_vars": 20, "names": names})  # fmt: skip
    ranks = rank_correlations(table, names, "y_um")
    assert abs(ranks[names[4]]) < 0.15  # Spearman sees next to nothing of it
    summary = {"main_output": "y_um", "rank_correlation": ranks, "pawn": pawn_indices(spec, table, "y_um")}
    kind, _, order = ranking("lhs", summary, names)
    assert kind == "pawn" and order[0] == names[4] and names[4] in order[:MAX_PANELS]
    axis = labels(names, ["y_um"], scenario)  # type: ignore[arg-type]
    assert axis["y_um"] == "y (µm)"
    (tmp_path / "scatter.png").symlink_to(tmp_path / "outside.png")
    drawn = draw_all(tmp_path, "lhs", table, names, summary, axis)
    assert {p.name for p in drawn} == {"scatter.png", "sensitivity.png", "histogram.png"}
    assert not (tmp_path / "scatter.png").is_symlink() and not (tmp_path / "outside.png").exists()
