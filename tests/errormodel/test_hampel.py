"""The robust spike filter's medians taken only where a window spans more than the floor: the
same doubles and flags as the medians of every window."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.errormodel import sources
from twin.errormodel.sources import hampel

#: the filter as it was: the median and the MAD of every window (what it falls back on)
everywhere = sources._hampel_everywhere


def probe_like(rng: np.random.Generator, n: int, spikes: int = 3) -> np.ndarray:
    """A slow drift read in 0.1 um steps with a little noise and a few spikes: the probe's
    reading as the twin's sensors give it."""
    drift = 23e-6 * np.arange(n) / 2880 + rng.normal(0.0, 0.05e-6, n)  # 8 h every 10 s
    x = np.round(drift / 1e-7) * 1e-7
    where = rng.integers(0, n, spikes)
    x[where] += rng.choice([-1.0, 1.0], spikes) * rng.uniform(0.5e-6, 30e-6, spikes)
    return x


def of_kind(kind: str, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``x`` as a stream of ``kind``: noise, with two NaNs, with infinities and a -0.0, signed
    zeros, steps, or rounded to ties; any other kind (the probe's) is ``x`` itself."""
    n = x.size
    if kind == "noise":
        return rng.normal(0.0, 1e-6, n)
    if kind == "nan":
        x[rng.integers(0, n, 2)] = np.nan
    elif kind == "inf":
        x[rng.integers(0, n, 3)] = rng.choice([np.inf, -np.inf, -0.0], 3)
    elif kind == "signed zeros":
        return rng.choice([0.0, -0.0, 1e-7, -1e-7], n)
    elif kind == "steps":
        return np.repeat(rng.normal(0.0, 3e-6, n // 200 + 1), 200)[:n]
    elif kind == "ties":
        return np.round(x / 1e-6) * 1e-6
    return x


def same(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    return a[0].dtype == b[0].dtype and a[0].tobytes() == b[0].tobytes() and np.array_equal(a[1], b[1])


def test_the_probes_reading_takes_the_short_way_to_the_same_doubles() -> None:
    rng = np.random.default_rng(11)
    x = probe_like(rng, 2881)
    padded = np.pad(x, (10, -(x.size + 20) % 21 + 31), mode="edge")
    quiet = sources._quiet(padded.reshape(-1, 21), 1e-6)
    assert quiet.mean() > 0.8  # the shortcut is taken: most windows span less than the floor
    got = hampel(x, 10, 5.0, 1e-6)
    assert same(got, everywhere(x, 10, 5.0, 1e-6))
    assert 1 <= got[1].sum() <= 3


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(1, 3000),
    half_window=st.integers(0, 12),
    floor=st.sampled_from([1e-6, 2e-7, 5e-6, 0.0, float("nan")]),
    kind=st.sampled_from(["probe", "noise", "nan", "inf", "signed zeros", "steps"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_the_same_doubles_and_flags_as_every_windows_median(
    n: int, half_window: int, floor: float, kind: str, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    x = of_kind(kind, probe_like(rng, n, spikes=max(1, n // 500)), rng)
    with np.errstate(invalid="ignore"):  # inf - inf in both
        assert same(hampel(x, half_window, 5.0, floor), everywhere(x, half_window, 5.0, floor))


@pytest.mark.parametrize("x", [np.arange(50), np.arange(50.0, dtype=np.float32), np.ones(5)])
def test_other_streams_take_every_windows_median(x: np.ndarray) -> None:
    with np.errstate(invalid="ignore"):
        assert same(hampel(x, 3, 5.0, 1e-6), everywhere(x, 3, 5.0, 1e-6))


def _median_filter(x: np.ndarray, half_window: int) -> np.ndarray:
    """The moving median as numpy's own helpers make it (what moving_median made before its
    windows were made directly): np.pad's end values, sliding_window_view, np.partition."""
    windows = np.lib.stride_tricks.sliding_window_view(
        np.pad(x, half_window, mode="edge"), 2 * half_window + 1
    )
    return np.partition(windows, half_window, axis=1)[:, half_window]


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(1, 400),
    half_window=st.integers(1, 12),
    kind=st.sampled_from(["noise", "nan", "inf", "signed zeros", "ties"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_moving_median_is_numpy_s_median_of_every_window(
    n: int, half_window: int, kind: str, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    x = of_kind(kind, rng.normal(0.0, 1e-6, n), rng)
    assert sources.moving_median(x, half_window).tobytes() == _median_filter(x, half_window).tobytes()


def test_moving_median_in_chunks_is_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    # a long record's windows are partitioned a chunk of rows at a time
    x = np.random.default_rng(5).normal(size=1000)
    monkeypatch.setattr(sources, "_MEDIAN_ROWS", 64)
    assert sources.moving_median(x, 7).tobytes() == _median_filter(x, 7).tobytes()


@pytest.mark.parametrize(
    "x",
    [
        np.arange(40.0)[::-2],  # strided, reversed
        np.arange(30, dtype=np.float32) % 7,
        np.arange(25) % 5,  # integers
        np.arange(20.0).astype(">f8"),  # big-endian
        [1.0, float("nan"), -0.0, 3.0],
    ],
)
def test_moving_median_takes_any_1d_stream_as_float64(x: object) -> None:
    as_float = np.asarray(x, dtype=np.float64)
    assert sources.moving_median(x, 3).tobytes() == _median_filter(as_float, 3).tobytes()  # type: ignore[arg-type]


def test_moving_median_refuses_what_is_not_one_stream() -> None:
    with pytest.raises(ValueError, match="1-D"):
        sources.moving_median(np.zeros((3, 4)), 2)
