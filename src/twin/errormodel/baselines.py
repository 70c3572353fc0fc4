"""The group's own thermal compensation, as the baseline the MBS error model must beat.

Hu et al., Chinese Journal of Mechanical Engineering 2018 (DOI 10.1186/s10033-018-0288-4,
docs/reference/facts.md section 3): the probe's thermal drift is a multiple linear regression (MLR) on the
measured temperatures, and what the regression leaves is an autoregressive (AR) time series;
their bench reached a largest residual of 1 um.

:class:`MlrAr` is that model: the regression by ordinary least squares on the temperatures'
changes (one offset per record: the probe is zeroed per run), the temperatures kept chosen by
forward selection with the BIC (the group's "key temperature points"), then an AR(p) model of
what the regression leaves, by least squares, its order by the BIC. The regression is not
refitted on AR-filtered data (Cochrane-Orcutt, GLS): a soak's residual is nearly a random walk
(AR coefficients near one), and quasi-differencing by it keeps only the fast wiggles of the
temperatures, so the coefficients lose the slow drift they are for (tried: 15-25 % of the RMS
removed on the held-out replay instead of about 98 %).

Applied to a run it predicts the thermal drift from the temperatures alone. The AR part cannot
correct a prediction on line there: its one-step correction needs the last residual, which in a
wear test is hidden under the wear, and its forecast decays to zero within a few samples. So
the compensation is the regression; the AR order, coefficients and innovations' RMS are
reported with it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["MlrAr", "fit_ar", "fit_mlr_ar"]

#: the largest AR order tried
MAX_AR_ORDER = 5


@dataclass(frozen=True)
class MlrAr:
    """A fitted MLR + AR thermal model: drift = sum_k b_k (T_k - T_k(start)) per record.

    ``names`` are the temperatures kept (in the order of ``coefficients``, m/K); ``ar`` the AR
    coefficients of the residual (phi_1..phi_p); ``residual_rms`` the innovations' RMS (m).
    """

    names: tuple[str, ...]
    coefficients: tuple[float, ...]
    ar: tuple[float, ...]
    residual_rms: float

    def predict(self, temperatures: Mapping[str, np.ndarray]) -> np.ndarray:
        """The predicted thermal drift of a record from its start (m)."""
        n = len(next(iter(temperatures.values())))
        out = np.zeros(n)
        for name, b in zip(self.names, self.coefficients, strict=True):
            t = np.asarray(temperatures[name], dtype=np.float64)
            out += b * (t - t[0])
        return out

    def to_dict(self) -> dict[str, object]:
        """The model as plain numbers (for a summary)."""
        return {
            "temperatures": list(self.names),
            "coefficients_m_per_K": list(self.coefficients),
            "ar": list(self.ar),
            "residual_rms_um": self.residual_rms * 1e6,
        }


def _lagged(r: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows r[t] and columns r[t-1..t-p] for t = p..n-1."""
    cols = [r[p - k : len(r) - k] for k in range(1, p + 1)]
    return r[p:], np.column_stack(cols)


def fit_ar(residuals: Sequence[np.ndarray], max_order: int = MAX_AR_ORDER) -> tuple[float, ...]:
    """AR coefficients of the residual series (one per record, none crossing a record's
    boundary), by least squares, the order chosen by the BIC (0: white)."""
    best: tuple[float, tuple[float, ...]] | None = None
    for p in range(max_order + 1):
        if p == 0:
            rss = sum(float(np.dot(r, r)) for r in residuals)
            n = sum(len(r) for r in residuals)
            phi: tuple[float, ...] = ()
        else:
            pairs = [_lagged(r, p) for r in residuals if len(r) > p + 1]
            if not pairs:
                break
            y = np.concatenate([a for a, _ in pairs])
            x = np.vstack([b for _, b in pairs])
            sol, *_ = np.linalg.lstsq(x, y, rcond=None)
            rss = float(np.sum((y - x @ sol) ** 2))
            n = len(y)
            phi = tuple(float(v) for v in sol)
        bic = n * math.log(max(rss / max(n, 1), 1e-300)) + p * math.log(max(n, 1))
        if best is None or bic < best[0]:
            best = (bic, phi)
    return best[1] if best else ()


def _quasi_difference(a: np.ndarray, phi: Sequence[float]) -> np.ndarray:
    """a[t] - sum_k phi_k a[t-k], for t = p..n-1 (rows or columns alike)."""
    p = len(phi)
    out = a[p:].copy()
    for k, f in enumerate(phi, start=1):
        out -= f * a[p - k : len(a) - k]
    return out


@dataclass
class _Records:
    """The regression's data: per record, the target and the design (temperature changes and
    one offset column per record)."""

    targets: list[np.ndarray]
    designs: list[np.ndarray]

    def stacked(self, phi: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        y = np.concatenate([_quasi_difference(t, phi) for t in self.targets])
        x = np.vstack([_quasi_difference(d, phi) for d in self.designs])
        return y, x

    def residuals(self, beta: np.ndarray) -> list[np.ndarray]:
        return [t - d @ beta for t, d in zip(self.targets, self.designs, strict=True)]


def _records(
    drifts: Sequence[np.ndarray], temperatures: Sequence[Mapping[str, np.ndarray]], names: Sequence[str]
) -> _Records:
    n_rec = len(drifts)
    designs, targets = [], []
    for i, (y, temps) in enumerate(zip(drifts, temperatures, strict=True)):
        y = np.asarray(y, dtype=np.float64)
        cols = [np.asarray(temps[k], dtype=np.float64) - float(temps[k][0]) for k in names]
        offsets = [np.full(len(y), 1.0 if j == i else 0.0) for j in range(n_rec)]
        designs.append(np.column_stack([*cols, *offsets]) if cols or offsets else np.zeros((len(y), 0)))
        targets.append(y - y[0])
    return _Records(targets, designs)


def _ols(rec: _Records) -> tuple[float, np.ndarray]:
    """The BIC and the least-squares coefficients of the regression."""
    y, x = rec.stacked(())
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    rss = float(np.sum((y - x @ beta) ** 2))
    n = len(y)
    return n * math.log(max(rss / n, 1e-300)) + x.shape[1] * math.log(n), beta


def fit_mlr_ar(
    drifts: Sequence[np.ndarray],
    temperatures: Sequence[Mapping[str, np.ndarray]],
    *,
    candidates: Sequence[str] | None = None,
    max_order: int = MAX_AR_ORDER,
) -> MlrAr:
    """Fit the MLR + AR model to records of the probe's drift and the temperatures.

    ``drifts``: per record the probe's reading (m; its change from the first sample is
    fitted), ``temperatures``: per record the temperatures by name (K), ``candidates``: the
    temperatures the forward selection may keep (default: every one). Each record has its own
    offset (the probe is zeroed per run).
    """
    pool = list(candidates if candidates is not None else temperatures[0])
    chosen: list[str] = []
    best, beta = _ols(_records(drifts, temperatures, chosen))
    while pool:
        trials = [(*_ols(_records(drifts, temperatures, [*chosen, name])), name) for name in pool]
        bic, b, name = min(trials, key=lambda x: x[0])
        if bic >= best:
            break
        best, beta = bic, b
        chosen.append(name)
        pool.remove(name)
    residuals = _records(drifts, temperatures, chosen).residuals(beta)
    phi = fit_ar(residuals, max_order)
    innovations = np.concatenate([_quasi_difference(r, phi) for r in residuals])
    rms = float(np.sqrt(np.mean(innovations**2))) if len(innovations) else 0.0
    return MlrAr(tuple(chosen), tuple(float(v) for v in beta[: len(chosen)]), phi, rms)
