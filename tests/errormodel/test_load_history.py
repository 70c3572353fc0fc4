"""The load's history for the liner's creep (errormodel.sources.LoadHistory): the exact lag
recursion, the same bits whatever the chunks, any sampling (irregular, gaps of days)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin.errormodel.sources import RETARDATION_TIMES_S, LoadHistory, load_history


def recursion(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """h[n] = a_n h[n-1] + (1 - a_n) F[n-1], sample by sample in Python (the definition)."""
    out = np.zeros((len(RETARDATION_TIMES_S), len(t)))
    for k, tau in enumerate(RETARDATION_TIMES_S):
        h = 0.0
        for n in range(1, len(t)):
            a = math.exp(-(t[n] - t[n - 1]) / tau)
            h = a * h + (1 - a) * f[n - 1]
            out[k, n] = h
    return out


def records() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(3)
    regular = np.arange(20_000) * 0.5 + 12.0
    irregular = np.cumsum(rng.uniform(0.1, 900.0, 3_000))  # jittery, up to a retardation time
    gaps = np.r_[np.arange(0.0, 3_000.0, 10.0), 7 * 86_400.0 + np.arange(0.0, 3_000.0, 10.0)]
    first_short = np.r_[0.0, 1.0 + 600.0 * np.arange(2_000)]  # 1 s, then 10 min apart
    out = {}
    for name, t in (
        ("regular", regular),
        ("irregular", irregular),
        ("week gap", gaps),
        ("first short", first_short),
    ):
        f = 2e5 * (np.sin(t / 5_000.0) > 0) + 500.0 * rng.standard_normal(len(t))
        out[name] = (t, f)
    return out


RECORDS = records()


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_the_history_is_the_lag_recursion(name: str) -> None:
    t, f = RECORDS[name]
    got = load_history(t, f)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, recursion(t, f), rtol=0, atol=1e-10 * 2e5)


@pytest.mark.parametrize("name", sorted(RECORDS))
@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_chunks_give_the_whole_records_bits(name: str, chunk: int) -> None:
    t, f = (x[:3_000] for x in RECORDS[name])
    n = len(t)
    whole = load_history(t, f)
    history = LoadHistory()
    parts = [history.feed(t[a : a + chunk], f[a : a + chunk]) for a in range(0, n, chunk)]
    assert np.concatenate(parts, axis=1).tobytes() == whole.tobytes()


def test_a_held_load_gives_the_exact_step_response() -> None:
    t = np.arange(0.0, 36_000.0, 10.0)
    h = load_history(t, np.full(len(t), 2e5))
    assert np.all(h[:, 0] == 0.0)  # creep starts at the zero
    want = 2e5 * -np.expm1(-t[-1] / np.array(RETARDATION_TIMES_S))
    np.testing.assert_allclose(h[:, -1], want, rtol=1e-12)
