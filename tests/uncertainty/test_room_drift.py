"""The rooms' slow drift (twin.uncertainty.rooms): its half-waves on the grid of its peak and
mean are worked out once, and give the same doubles as the drift evaluated there."""

from __future__ import annotations

import numpy as np
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.uncertainty import rooms


def _as_before(rng: np.random.Generator, max_amplitude: float) -> tuple[np.ndarray, float]:
    """The drift's weights and scale as smooth_drift made them before its grid's half-waves
    were kept: every half-wave evaluated again for each drift."""
    weights = rng.normal(size=3) / np.arange(1, 4)
    amplitude = float(rng.uniform(0.0, max_amplitude))
    grid = np.linspace(0.0, 1.0, 401)
    peak = float(np.max(np.abs(sum(w * np.sin((k + 1) * np.pi * grid) for k, w in enumerate(weights)))))
    return weights, amplitude / peak if peak > 0 else 0.0


@pytest.mark.parametrize("seed", range(50))
def test_the_drift_and_its_mean_are_the_same_doubles(seed: int) -> None:
    drift = rooms.smooth_drift(np.random.default_rng(seed), 1.0)
    weights, scale = _as_before(np.random.default_rng(seed), 1.0)
    assert drift.weights.tobytes() == weights.tobytes() and drift.scale == scale
    grid = np.linspace(0.0, 1.0, 401)
    assert drift.grid_mean() == float(np.mean(drift(grid)))
    # its largest excursion is the drawn amplitude (uniform in [0, 1] K here)
    assert 0.0 <= np.max(np.abs(drift(grid))) <= 1.0 + 1e-15


def test_a_shaped_room_is_its_curve_plus_its_drift() -> None:
    scenario = load_scenario(scenarios_dir() / "li2017-thermal-experiment.toml")
    target = "thermal.t_room"
    drift = rooms.smooth_drift(np.random.default_rng(3), 1.0)
    for name in rooms.ROOM_SHAPES:
        curve = rooms.shaped_curve(scenario, target, name)
        with_drift = rooms.shaped(scenario, target, name, drift, "s")
        assert with_drift == curve.profile(drift, "s")
        plain = np.array(rooms.shaped(scenario, target, name).table)
        drifted = np.array(with_drift.table)
        assert plain[:, 0].tobytes() == drifted[:, 0].tobytes()
        assert drifted[:, 1].tobytes() == (plain[:, 1] + drift(plain[:, 0] / curve.end)).tobytes()
        assert np.any(drifted[:, 1] != plain[:, 1])  # the drift moved it: the check above can fail
