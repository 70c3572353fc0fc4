"""The share of a Monte Carlo figure's variance each input group explains, from the samples
alone (a given-data method: no special design, the prior's own draws).

Method: SALib's RBD-FAST (:func:`SALib.analyze.rbd_fast.analyze`, Plischke 2010, with the bias
correction of Tissot & Prieur 2012 that SALib applies) gives each drawn input's first-order
index from any sample of independent inputs (:func:`first_order`: SALib's point estimate,
computed as SALib computes it); a group's share is the sum of its inputs' indices.
Summing is right for independent inputs of a nearly additive figure, which the replay's drift
is (each body adds alpha x length x rise, each a small spread around the drawing), and it keeps
the groups the prior file names without a group-aware design. What the first-order indices do
not explain is ``rest``: the sensors' noise (a seed, no number to sort the samples by),
interactions and the estimate's own error (each index is known to a few hundredths at 200
samples and runs a little low on normal inputs, so a group of many small inputs is uncertain by
about a tenth; the sum of the indices is reported beside the shares).
``M`` = 4 harmonics: the drift is monotone in each input, and fewer harmonics keep the
estimate's noise down at a few hundred samples.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "HARMONICS",
    "MIN_SAMPLES",
    "NOISE",
    "REST",
    "ROOM",
    "THERMAL_NETWORK",
    "first_order",
    "variance_shares",
]

#: the input groups the prior file does not name in a [spread] entry
ROOM = "room curve"
NOISE = "noise"
THERMAL_NETWORK = "thermal network"
#: what the first-order indices leave: noise, interactions and the estimate's error
REST = "rest (noise, interactions)"
#: RBD-FAST's harmonics
HARMONICS = 4
#: fewer samples than this give no shares: with about 85 drawn inputs, at 64 samples the summed
#: indices were mostly their estimator's noise (groups at -17 % and +41 %); at 200 they sum to
#: about 1
MIN_SAMPLES = 200


def variance_shares(
    rows: Sequence[Mapping[str, Any]], figure: str, groups: Mapping[str, str]
) -> dict[str, Any]:
    """The shares of ``figure``'s variance over ``rows`` (samples with their drawn inputs by
    key) per input group of ``groups`` (key -> group): the summed first-order indices, the
    rest, and how they were estimated. Inputs that did not vary are left out."""
    y = np.array([float(r[figure]) for r in rows], dtype=float)
    names = [n for n in groups if all(n in r for r in rows)]
    x = np.array([[float(r[n]) for n in names] for r in rows], dtype=float).reshape(len(rows), len(names))
    varied = [i for i in range(len(names)) if np.ptp(x[:, i]) > 0] if len(rows) else []
    out: dict[str, Any] = {
        "method": f"SALib rbd_fast first-order indices (given data, M = {HARMONICS}), summed per input group",
        "samples": len(rows),
    }
    if len(rows) < MIN_SAMPLES or not varied or not np.ptp(y) > 0:
        out["groups"] = {}
        out["why_none"] = f"needs at least {MIN_SAMPLES} samples that ran and a figure that varies"
        return out
    names = [names[i] for i in varied]
    s1 = [first_order(x[:, i], y) for i in varied]
    by_group: dict[str, float] = {}
    for name, s in zip(names, s1, strict=True):
        g = groups[name]
        by_group[g] = by_group.get(g, 0.0) + float(s)
    explained = float(sum(by_group.values()))
    out["first_order_sum"] = explained
    out["groups"] = {**by_group, REST: 1.0 - explained}
    out["by_input"] = {n: float(s) for n, s in zip(names, s1, strict=True)}
    return out


def first_order(x: np.ndarray, y: np.ndarray, harmonics: int = HARMONICS) -> float:
    """RBD-FAST's first-order index of the input ``x`` on the figure ``y``, bias-corrected: the
    number SALib's ``rbd_fast.analyze(...)["S1"]`` gives, to the last bit.

    SALib's module imports pandas, scipy.signal and all of scipy.stats (about half a second and
    a hundred MB, most of what a default run's shares cost) for an estimate that is a sort and
    one FFT; its bootstrap of the index's interval (``S1_conf``) is not reported. So its three
    steps are taken here with the arithmetic SALib and scipy use, the same numbers (tested
    against SALib): ``permute_outputs`` (the figure in the input's order, up the even ranks
    and down the odd), ``compute_first_order`` (scipy.signal's periodogram: the mean taken out,
    scaled by the boxcar window's ``1 / sqrt(n)``, scipy.fft's real FFT, squared magnitudes
    doubled but for the first and an even length's last; the first ``harmonics`` over all but
    the first) and ``unskew_S1`` (Tissot & Prieur's correction). The real FFT is numpy's: the
    same pocketfft as scipy.fft's, the same bits (tested), without scipy's import (a fifth of
    a CPU second of a default run)."""
    rfft = np.fft.rfft

    order = np.argsort(x)
    permuted = y[np.concatenate([order[::2], order[1::2][::-1]])]
    n = permuted.size
    window = np.ones(n) * (1 / np.sqrt(sum(np.ones(n) ** 2) / 1.0))
    spectrum = rfft((permuted - np.mean(permuted, -1, keepdims=True)) * window, n=n, axis=-1)
    power = spectrum.real**2 + spectrum.imag**2
    power[1 : -1 if n % 2 == 0 else None] *= 2
    s1 = np.sum(power[1 : harmonics + 1]) / np.sum(power[1:])
    lamb = (2 * harmonics) / n
    return float(s1 - lamb / (1 - lamb) * (1 - s1))
