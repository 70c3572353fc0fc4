"""What a finished sweep says: quantiles of every output, and SALib's sensitivity indices.

Saltelli designs give Sobol' indices (``S1``, ``ST`` and, with ``second_order``, ``S2``,
each with its 95 % confidence half-width from SALib's bootstrap); Morris designs give the
elementary effects (``mu``, ``mu_star`` with its confidence, ``sigma``). Both need every
point of the design: with failed points, or an output that does not vary, the indices are
left out and the summary says why.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pandas as pd

from twin.sweep.spec import Spec

QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
#: the main output when the sweep file names none: the first of these that the points have
DEFAULT_MAIN = (
    "compensation.residual_rms_um.after",
    "compensation.residual_rms_um.before",
    "drift_mm.predicted",
)
_FIXED = {"point", "seed", "status", "error"}


def output_names(spec: Spec, table: pd.DataFrame) -> list[str]:
    """The figure columns of the table, in order."""
    return [c for c in table.columns if c not in _FIXED and c not in spec.names]


def main_output(spec: Spec, outputs: list[str]) -> str | None:
    """The output the plots show: the spec's ``main``, its first output, or a default."""
    if spec.main:
        return spec.main
    if spec.outputs:
        return spec.outputs[0]
    return next((c for c in DEFAULT_MAIN if c in outputs), outputs[0] if outputs else None)


def statistics(values: pd.Series) -> dict[str, Any]:
    """Count, mean, standard deviation, extremes and quantiles of the finite values."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0}
    out: dict[str, Any] = {
        "n": int(v.size),
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "min": float(v.min()),
        "max": float(v.max()),
    }
    for q, value in zip(QUANTILES, np.quantile(v, QUANTILES), strict=True):
        out[f"q{round(q * 100):02d}"] = float(value)
    return out


def _salib_problem(spec: Spec) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, list) else v for k, v in spec.problem.items()}


def _named(problem: dict[str, Any], values: Any) -> dict[str, float]:
    names = list(dict.fromkeys(problem.get("groups") or problem["names"]))
    return {n: float(x) for n, x in zip(names, np.asarray(values, dtype=float), strict=True)}


def _sobol(spec: Spec, x: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    from SALib.analyze import sobol

    problem = _salib_problem(spec)
    r = sobol.analyze(problem, y, calc_second_order=spec.second_order, seed=spec.seed)
    out = {k: _named(problem, r[k]) for k in ("S1", "S1_conf", "ST", "ST_conf")}
    if spec.second_order:
        names = list(dict.fromkeys(problem.get("groups") or problem["names"]))
        out["S2"] = {
            f"{a} x {b}": float(r["S2"][i, j])
            for i, a in enumerate(names)
            for j, b in enumerate(names)
            if j > i
        }
    return out


def _morris(spec: Spec, x: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    from SALib.analyze import morris

    problem = _salib_problem(spec)
    r = morris.analyze(problem, x, y, num_levels=spec.morris_levels, seed=spec.seed)
    return {k: _named(problem, r[k]) for k in ("mu", "mu_star", "mu_star_conf", "sigma")}


def indices(spec: Spec, table: pd.DataFrame, outputs: list[str], total: int) -> dict[str, Any]:
    """SALib's indices of each output (Saltelli and Morris designs; else empty)."""
    if spec.design not in ("saltelli", "morris"):
        return {}
    analyse = _sobol if spec.design == "saltelli" else _morris
    x = table[spec.names].to_numpy(dtype=float)
    out: dict[str, Any] = {}
    n_failed = int((table["status"] != "ok").sum()) + total - len(table)
    for name in outputs:
        y = table[name].to_numpy(dtype=float)
        if n_failed or not np.all(np.isfinite(y)):
            out[name] = {
                "skipped": f"{n_failed} points failed, gave no value or did not run: SALib needs all"
            }
        elif np.ptp(y) == 0.0:
            out[name] = {"skipped": "the output does not vary"}
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                out[name] = analyse(spec, x, y)
    return out


def rank_correlations(table: pd.DataFrame, names: list[str], output: str) -> dict[str, float]:
    """Spearman's rank correlation of each numeric input with ``output`` (ok points only)."""
    ok = table[table["status"] == "ok"]
    out = {}
    for n in names:
        x = pd.to_numeric(ok[n], errors="coerce")
        if x.notna().all() and x.nunique() > 1 and ok[output].nunique() > 1:
            out[n] = float(x.rank().corr(ok[output].rank()))
    return out


def summarise(spec: Spec, table: pd.DataFrame, total: int, timing: dict[str, Any]) -> dict[str, Any]:
    """The content of ``summary.json`` (``total``: the design's number of points)."""
    outputs = output_names(spec, table)
    main = main_output(spec, outputs)
    failed = table[table["status"] != "ok"]
    summary: dict[str, Any] = {
        "sweep": spec.name,
        "spec_file": str(spec.path),
        "base": spec.scenario.source_path,
        "design": spec.design,
        "seed": spec.seed,
        "points": total,
        "done": len(table),
        "ok": len(table) - len(failed),
        "failed": len(failed),
        "problem": dict(spec.problem),
        "main_output": main,
        "outputs": {name: statistics(table[name]) for name in outputs},
        "failures": [{"point": int(r.point), "error": r.error} for r in failed.head(20).itertuples()],
        "timing": timing,
    }
    if spec.design == "grid":
        summary["levels"] = {n: list(lv) for n, lv in zip(spec.names, spec.levels, strict=True)}
    if main is not None and main in table:
        summary["rank_correlation"] = rank_correlations(table, spec.names, main)
    found = indices(spec, table, outputs, total)
    if found:
        summary["indices"] = found
    return summary
