"""Credibility indexes and the interference filter against hand-made cases."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.errormodel import credibility
from twin.errormodel.credibility import discrete_frechet, ra_fluctuation
from twin.errormodel.sources import hampel


def frechet_reference(p: np.ndarray, q: np.ndarray) -> float:
    """Eiter and Mannila's recursion, cell by cell."""
    n, m = len(p), len(q)
    ca = np.zeros((n, m))
    for i, j in itertools.product(range(n), range(m)):
        d = float(np.linalg.norm(p[i] - q[j]))
        if i == 0 and j == 0:
            ca[i, j] = d
        elif i == 0:
            ca[i, j] = max(ca[i, j - 1], d)
        elif j == 0:
            ca[i, j] = max(ca[i - 1, j], d)
        else:
            ca[i, j] = max(min(ca[i - 1, j], ca[i - 1, j - 1], ca[i, j - 1]), d)
    return float(ca[-1, -1])


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 25),
    m=st.integers(1, 25),
    seed=st.integers(0, 2**31 - 1),
)
def test_frechet_equals_the_cell_by_cell_recursion(n: int, m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    p, q = rng.normal(size=(n, 2)), rng.normal(size=(m, 2))
    assert discrete_frechet(p, q) == pytest.approx(frechet_reference(p, q), rel=1e-12)


def test_frechet_of_hand_cases() -> None:
    a = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    assert discrete_frechet(a, a) == 0.0
    assert discrete_frechet(a, a + np.array([0.0, 3.0])) == pytest.approx(3.0)
    # a repeated point: the coupling may wait on it, so the distance stays 0
    assert discrete_frechet(np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.0, 0.0, 1.0, 2.0, 3.0])) == 0.0


def test_ra_of_a_sine_around_a_trend() -> None:
    t = np.arange(0.0, 36000.0, 1.0)
    z = 1e-6 * t / 3600.0 + 2.0 * np.sin(2 * np.pi * t / 60.0)
    # mean |A sin| = 2A/pi; the 30 min mean line follows the trend and averages the sine out
    assert ra_fluctuation(t, z, 1800.0) == pytest.approx(4.0 / np.pi, rel=2e-3)
    assert ra_fluctuation(t, 1e-6 * t, 1800.0) < 1e-12


def test_hampel_removes_spikes_and_keeps_the_signal() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(5000) * 0.1
    signal = 10e-6 * np.sin(2 * np.pi * t / 60.0) + rng.normal(0, 0.05e-6, t.size)
    spiky = signal.copy()
    where = rng.choice(t.size, 12, replace=False)
    spiky[where] += rng.choice([-1, 1], 12) * rng.uniform(5e-6, 50e-6, 12)
    cleaned, flags = hampel(spiky)
    assert set(np.flatnonzero(flags)) == set(where)
    assert np.max(np.abs(cleaned - signal)) < 0.5e-6
    # nothing to remove: nothing removed
    _, none = hampel(signal)
    assert not none.any()


def test_a_summary_without_the_credibility_indexes_keeps_every_other_figure() -> None:
    # a Monte Carlo's samples leave the indexes out (their Frechet recursion is half of a
    # replay's evaluation); what they do report must be the same numbers
    from twin.errormodel.evaluate import compensation_summary

    t = np.linspace(0.0, 28800.0, 2881)
    wear = 1e-5 * t / t[-1]
    raw = wear + 2e-6 * np.sin(t / 3000.0)
    comp = wear + 2e-7 * np.cos(t / 700.0)
    full = compensation_summary(t, 1800.0, raw, comp, wear)
    lean = compensation_summary(t, 1800.0, raw, comp, wear, credibility=False)
    assert "credibility" in full and "credibility" not in lean
    assert lean == {k: v for k, v in full.items() if k != "credibility"}


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 40),
    m=st.integers(1, 40),
    dims=st.integers(1, 3),
    seed=st.integers(0, 2**31 - 1),
)
def test_frechet_is_the_same_double_with_its_distances_at_once_or_per_diagonal(
    n: int, m: int, dims: int, seed: int
) -> None:
    """The distances computed for all pairs at once (short curves) or one anti-diagonal at a
    time (long ones) are the same sums of squares, and the recursion only takes minima and
    maxima of them: the two give the same double, not just a close one."""
    from twin.errormodel import credibility

    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, dims)) * 10 ** rng.uniform(-6, 6)
    q = rng.normal(size=(m, dims)) * 10 ** rng.uniform(-6, 6)
    at_once = discrete_frechet(p, q)
    cells, credibility.MATRIX_CELLS = credibility.MATRIX_CELLS, 0
    try:
        assert discrete_frechet(p, q) == at_once
    finally:
        credibility.MATRIX_CELLS = cells


@pytest.mark.parametrize("cells", [credibility.MATRIX_CELLS, 10])
def test_frechets_side_by_side_are_each_alone_to_the_bit(cells: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A run's two curves (before and after compensation) go through one recursion side by
    side: each distance is the double the cell-by-cell recursion gives it alone (minima and
    maxima of the same sums of squares), with the distances made at once or per anti-diagonal."""
    monkeypatch.setattr(credibility, "MATRIX_CELLS", cells)
    rng = np.random.default_rng(3)
    for n, m in ((1, 1), (1, 7), (9, 1), (23, 17), (40, 40)):
        q = rng.normal(size=(m, 2))
        ps = [rng.normal(size=(n, 2)), rng.normal(size=(n, 2)) * 1e-3, np.zeros((n, 2))]

        def alone(p: np.ndarray, q: np.ndarray = q) -> float:
            ca = np.full((len(p) + 1, len(q) + 1), np.inf)
            ca[0, 0] = -np.inf  # the start: the first cell is its own distance
            for i, j in itertools.product(range(len(p)), range(len(q))):
                reach = min(ca[i, j + 1], ca[i, j], ca[i + 1, j]) if i or j else ca[0, 0]
                ca[i + 1, j + 1] = max(float(np.sqrt(np.sum((p[i] - q[j]) ** 2))), reach)
            return float(ca[-1, -1])

        got = credibility.discrete_frechets(ps, q)
        assert [v.hex() for v in got] == [alone(p).hex() for p in ps]
        assert got[0] == discrete_frechet(ps[0], q)


@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 5000), scale=st.floats(-12, 3), seed=st.integers(0, 2**31 - 1))
def test_the_residuals_rms_is_np_means_to_the_bit(n: int, scale: float, seed: int) -> None:
    from twin.errormodel.evaluate import _rms

    rng = np.random.default_rng(seed)
    x = rng.normal(size=n).cumsum() * 10**scale
    x[rng.integers(0, n, max(1, n // 10))] = rng.choice([0.0, -0.0], max(1, n // 10))
    assert _rms(x).hex() == float(np.sqrt(np.mean(x**2))).hex()
    assert _rms(x[::3]).hex() == float(np.sqrt(np.mean(x[::3] ** 2))).hex()  # a strided view too
