"""The MLR + AR baseline on synthetic records whose answer is known."""

from __future__ import annotations

import numpy as np

from twin.errormodel.baselines import fit_ar, fit_mlr_ar


def _ar_noise(rng: np.random.Generator, n: int, phi: float, sigma: float) -> np.ndarray:
    e = rng.normal(0.0, sigma, n)
    out = np.zeros(n)
    for t in range(1, n):
        out[t] = phi * out[t - 1] + e[t]
    return out


def _temperatures(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Three smooth, distinct temperature histories and a fourth that plays no part."""
    t = np.linspace(0.0, 1.0, n)
    return {
        "frame": 293.15 + 5.0 * np.sin(2.0 * np.pi * t) + 0.3 * rng.normal(size=n).cumsum() / np.sqrt(n),
        "pole": 293.15 + 8.0 * t**2,
        "block": 293.15 + 3.0 * (1.0 - np.exp(-4.0 * t)),
        "base": 293.15 + 2.0 * np.cos(3.0 * np.pi * t),
    }


def test_ar_coefficient_of_a_known_series_is_found() -> None:
    rng = np.random.default_rng(1)
    x = _ar_noise(rng, 20000, 0.7, 1.0)
    phi = fit_ar([x])
    assert len(phi) >= 1
    assert abs(phi[0] - 0.7) < 0.03
    assert all(abs(p) < 0.05 for p in phi[1:])


def test_white_noise_has_no_ar_part() -> None:
    rng = np.random.default_rng(2)
    assert fit_ar([rng.normal(size=5000)]) == ()


def test_mlr_ar_recovers_known_coefficients_and_predicts_a_new_record() -> None:
    rng = np.random.default_rng(3)
    truth = {"frame": -4.0e-6, "pole": 3.5e-6, "block": 1.2e-6}
    records, temps = [], []
    for n in (3000, 2000):
        tt = _temperatures(rng, n)
        drift = sum(b * (tt[k] - tt[k][0]) for k, b in truth.items())
        records.append(7e-6 + drift + _ar_noise(rng, n, 0.8, 0.05e-6))  # an offset: the probe's zero
        temps.append(tt)
    model = fit_mlr_ar(records, temps)
    assert set(model.names) == set(truth)  # the unused 'base' is not selected
    for name, b in zip(model.names, model.coefficients, strict=True):
        assert abs(b - truth[name]) < 0.03e-6, name
    assert model.ar and abs(model.ar[0] - 0.8) < 0.05
    fresh = _temperatures(np.random.default_rng(4), 1500)
    expected = sum(b * (fresh[k] - fresh[k][0]) for k, b in truth.items())
    assert np.max(np.abs(model.predict(fresh) - expected)) < 0.2e-6
