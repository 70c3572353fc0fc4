"""What a finished sweep says: quantiles of every output, and SALib's sensitivity indices.

Saltelli designs give Sobol' indices (``S1``, ``ST`` and, with ``second_order``, ``S2``,
each with its 95 % confidence half-width from SALib's bootstrap); Morris designs give the
elementary effects (``mu``, ``mu_star`` with its confidence, ``sigma``). Both rest on whole
blocks of the design (a Saltelli base sample, a Morris trajectory): a failed point takes its
block out, and the indices name the failed points and how many blocks they rest on; only an
output left with fewer than two whole blocks, or that does not vary, is skipped, saying why.

Sampled designs (random, Monte Carlo, Latin hypercube, Sobol' sequence) give SALib's PAWN
index, a given-data method, from the points as they are: it ranks an input whose effect is
two-sided (the output rising at both ends of its range), which a rank correlation misses; a
dummy input's PAWN is its noise floor. (SALib's delta, the other given-data method, costs
about 6 s for 256 points of 20 inputs and grows with the square of the points; PAWN takes
milliseconds.) The rank correlations stay beside it for the direction of a monotonic effect.
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


def _block(spec: Spec) -> int:
    """Points per base sample: SALib's Saltelli block (k + 2, or 2k + 2 with second-order
    indices) or a Morris trajectory (k + 1), k the groups or the keys."""
    problem = spec.problem
    k = len(set(problem["groups"])) if problem.get("groups") else int(problem["num_vars"])
    if spec.design == "saltelli":
        return 2 * k + 2 if spec.second_order else k + 2
    return k + 1


def named_points(points: list[int], limit: int = 10) -> str:
    """``3, 17, 22`` (``and N more`` past ``limit``)."""
    shown = ", ".join(str(p) for p in points[:limit])
    return shown + (f" and {len(points) - limit} more" if len(points) > limit else "")


def _complete_blocks(
    spec: Spec, table: pd.DataFrame, name: str, total: int
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The design's rows and ``name``'s values of every whole block (a Saltelli base sample,
    a Morris trajectory) whose points all gave a finite value, and the points that did not.

    SALib's estimators need each block whole but not every block: a block with a failed
    point is left out and the indices rest on the others (their confidence widens)."""
    points = table["point"].to_numpy(dtype=int) if "point" in table else np.arange(len(table))
    x = np.full((total, len(spec.names)), np.nan)
    y = np.full(total, np.nan)
    ok = (table["status"] == "ok").to_numpy()
    x[points] = table[spec.names].to_numpy(dtype=float)
    y[points[ok]] = table[name].to_numpy(dtype=float)[ok]
    bad = [int(i) for i in np.flatnonzero(~np.isfinite(y))]
    size = _block(spec)
    whole = np.isfinite(y).reshape(-1, size).all(axis=1)
    keep = np.repeat(whole, size)
    return x[keep], y[keep], bad


def indices(spec: Spec, table: pd.DataFrame, outputs: list[str], total: int) -> dict[str, Any]:
    """SALib's indices of each output (Saltelli and Morris designs; else empty).

    Points that failed (or did not run) take their whole block out of the estimate; the
    result names them (``failed_points``, ``blocks_used``), and only an output left with no
    whole block, or that does not vary, is skipped, saying why."""
    if spec.design not in ("saltelli", "morris"):
        return {}
    analyse = _sobol if spec.design == "saltelli" else _morris
    out: dict[str, Any] = {}
    n_blocks = total // _block(spec)
    for name in outputs:
        x, y, bad = _complete_blocks(spec, table, name, total)
        used = len(y) // _block(spec)
        if used < 2:
            out[name] = {
                "skipped": f"points {named_points(bad)} failed or gave no value: "
                f"{used} of {n_blocks} whole blocks left, SALib needs 2",
                "failed_points": bad,
            }
        elif np.ptp(y) == 0.0:
            out[name] = {"skipped": "the output does not vary"}
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                out[name] = analyse(spec, x, y)
            if bad:
                out[name] |= {"failed_points": bad, "blocks_used": f"{used} of {n_blocks}"}
    return out


#: the input PAWN compares each input with: uniform noise, unrelated to the output
DUMMY = "(dummy: no effect)"


def pawn_indices(spec: Spec, table: pd.DataFrame, output: str) -> dict[str, Any]:
    """SALib's PAWN index of each numeric input for ``output``, from the sampled points as
    they are (a given-data method: any design): the median, over ten slices of the input's
    range, of the Kolmogorov-Smirnov distance between the output's distribution in the slice
    and overall. It sees an effect that raises the output at both ends of an input's range,
    which a rank correlation misses. A dummy input (seeded noise) is analysed beside them:
    an index not above the dummy's is not told apart from no effect at this sample size.
    Empty with fewer than 20 finite points."""
    from SALib.analyze import pawn

    ok = table[(table["status"] == "ok") & np.isfinite(table[output].to_numpy(dtype=float))]
    names = [
        n for n in spec.names if pd.to_numeric(ok[n], errors="coerce").notna().all() and ok[n].nunique() > 1
    ]
    if len(ok) < 20 or not names or ok[output].nunique() < 2:
        return {}
    rng = np.random.default_rng(spec.seed)
    x = np.column_stack([ok[names].to_numpy(dtype=float), rng.random(len(ok))])
    y = ok[output].to_numpy(dtype=float)
    labels = [*names, DUMMY]
    problem = {"num_vars": len(labels), "names": labels, "bounds": [[0.0, 1.0]] * len(labels)}
    slices = max(3, min(10, len(ok) // 20))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = pawn.analyze(problem, x, y, S=slices, seed=spec.seed)
    found = {n: float(v) for n, v in zip(labels, r["median"], strict=True)}
    return {"pawn": {n: found[n] for n in names}, "pawn_dummy": found[DUMMY], "slices": slices}


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
        "failed_points": [int(p) for p in failed["point"]],
        "failures": [{"point": int(r.point), "error": r.error} for r in failed.head(20).itertuples()],
        "timing": timing,
    }
    if spec.design == "grid":
        summary["levels"] = {n: list(lv) for n, lv in zip(spec.names, spec.levels, strict=True)}
    if main is not None and main in table:
        summary["rank_correlation"] = rank_correlations(table, spec.names, main)
        if spec.design not in ("saltelli", "morris", "grid"):
            summary["pawn"] = pawn_indices(spec, table, main)
    found = indices(spec, table, outputs, total)
    if found:
        summary["indices"] = found
    return summary
