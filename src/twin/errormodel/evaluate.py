"""Evaluate the comprehensive error model on measured streams, end to end.

Input: a signal table with the virtual (or a lab's real) sensor readings: eight temperatures,
the displacement probe, and where present the load cell, torque sensor, angle encoder and
vibration pickup. Output, per time sample: the predicted error e_z and its five parts, one
per error factor of :data:`~twin.errormodel.factors.FACTORS` (thermal dE_T, loading dE_F,
fluctuating dE_V, positioning dE_G, interference dE_I), the thermal part body by body along
the two branches of the lower-body array, the change of the reading, and the compensated wear = reading change - predicted error;
with a true wear column (a twin run) the residual against it and the credibility indexes of
the on-line wear curve before and after compensation.

Every series is taken relative to its first sample (the probe is zeroed at the start of a
test), which keeps the compensation exact for whatever happens early in a run (running-in
wear, a load ramp). The drift numbers of the summary instead read start and end values off
least-squares lines through the first and last ``window`` seconds, evaluated at the first
and last time: that averages the sensors' noise out of a slow drift without the lag of a
plain mean. A factor whose sensor is absent from the table contributes zero.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.errormodel.credibility import discrete_frechets, ra_fluctuation
from twin.errormodel.factors import FACTORS, PARTS, Contribution, Measured, endpoints
from twin.errormodel.settings import EvaluationConfig
from twin.errormodel.sources import COLUMN_FIELDS
from twin.errormodel.tester import tester_model
from twin.signals.table import Signal, SignalTable

__all__ = [
    "END_FIGURES",
    "PARTS",
    "Evaluation",
    "compensation_summary",
    "end_figures",
    "end_reach_s",
    "endpoints",
    "evaluate",
    "evaluate_many",
    "evaluate_rows",
    "evaluation_signals",
    "summarize",
]

#: the Frechet distance is computed on at most this many points per curve (evenly decimated)
FRECHET_POINTS = 800

#: the summary's figures (by group) that read a record at its ends alone: the drifts, the
#: temperature rises and the parts' drifts (lines through its first and last drift windows)
#: and the wear (its first and last rows); the others (the parts' rms, the spikes, the
#: compensation's residuals) read every row
END_FIGURES = ("drift_mm", "temperature_rise_C", "error_parts_mm", "thermal_parts_mm", "wear_mm")


def end_reach_s(cfg: EvaluationConfig, interval_s: float) -> float | None:
    """How far from either end of a record (a row every ``interval_s``) its
    :data:`END_FIGURES` read it, s; None where they read every row.

    A row's numbers depend on that row, the first row and the load's history
    (:func:`evaluate_rows`), its cleaned reading on the rows the robust filter reaches
    (:attr:`~twin.errormodel.settings.EvaluationConfig.filter_reach`): the drift window, that
    reach beyond it, and a row more, measured from the run's start and end: a run whose length
    is not a multiple of its output interval ends up to an interval after its last row. With
    the loading factor on, the liner creeps under the load's whole history."""
    if not cfg.evaluate or cfg.factor_on("loading"):
        return None
    return cfg.window_s + (cfg.filter_reach + 1) * interval_s


def end_figures(figures: Mapping[str, float]) -> dict[str, float]:
    """The figures (dotted names, :meth:`~twin.pipeline.run_summary.RunSummary.figures`) of
    :data:`END_FIGURES`."""
    return {k: v for k, v in figures.items() if k.split(".", 1)[0] in END_FIGURES}


def evaluation_signals(*, with_true_wear: bool) -> list[Signal]:
    """Metadata of every column :func:`evaluate` adds, known before any data exists."""

    def sig(name: str, description: str, unit: str = "m") -> Signal:
        return Signal(f"errormodel.{name}", unit, "errormodel", description)

    bodies = tester_model().bodies
    out = [sig("e_z", "predicted detecting error e_z (comprehensive error model)")]
    out += [sig(f"e_{f.name}", f"{f.name} part of e_z") for f in FACTORS]
    out += [
        sig(f"{f.name}.{b}", f"{f.name} e_z contribution of body '{b}'")
        for f in FACTORS
        if f.by_body
        for b in bodies
    ]
    out += [
        sig("reading_change", "probe reading minus its start value"),
        sig("wear_compensated", "compensated wear: reading change minus predicted error"),
        sig("spike", "1 where the robust filter found an interference spike", "1"),
    ]
    if with_true_wear:
        out.append(sig("residual", "compensated wear minus true wear"))
    return out


@dataclass
class Evaluation:
    """The per-sample results (also added to the table) and the end-minus-start numbers.

    ``parts`` holds each factor's part of e_z by name (in the order of the list),
    ``by_body`` the body-by-body split of the factors declared ``by_body`` (thermal).
    """

    e_z: np.ndarray
    parts: dict[str, np.ndarray]
    by_body: dict[str, dict[str, np.ndarray]]
    reading_change: np.ndarray
    compensated: np.ndarray
    summary: dict[str, Any]


def evaluate(table: SignalTable, cfg: EvaluationConfig, *, columns: bool = True) -> Evaluation:
    """Run the error model over the table; adds ``errormodel.*`` columns to it (unless
    ``columns`` is False: a Monte Carlo sample's figures read none of them).

    Every factor of :data:`~twin.errormodel.factors.FACTORS` contributes its part (zero while
    switched off); e_z is their sum in the order of the list, the compensated wear the
    reading change minus e_z.
    """
    m = Measured.read(table, cfg, tester_model())
    contributions, rows = evaluate_rows(m)
    e_z, raw_change, compensated = rows["e_z"], rows["reading_change"], rows["wear_compensated"]
    parts = {name: c.e_z for name, c in contributions.items()}
    summary = summarize(m, contributions, e_z, rms={k: _rms(v) for k, v in parts.items()}, spikes=m.spikes)
    if "residual" in rows:
        wear = table[cfg.true_wear] - table[cfg.true_wear][0]  # as evaluate_rows took it
        summary.update(
            compensation_summary(table.time, cfg.ra_window_s, raw_change, compensated, wear, cfg.credibility)
        )
    if columns:
        meta = {s.name: s for s in evaluation_signals(with_true_wear="residual" in rows)}
        for name, values in rows.items():
            table.add(meta[f"errormodel.{name}"], values)
    by_body = {name: dict(c.by_body) for name, c in contributions.items() if c.by_body}
    return Evaluation(e_z, parts, by_body, raw_change, compensated, summary)


def evaluate_many(tables: Sequence[SignalTable], cfg: EvaluationConfig) -> list[dict[str, Any]]:
    """The summaries :func:`evaluate` makes of each of ``tables`` (with ``columns=False``), the
    same numbers bit for bit, for records of one time axis and one set of columns (a Monte
    Carlo batch's samples) at a fraction of the cost: a sample's hundred rows cost little
    more than the calls that evaluate them.

    Each record is read as :func:`evaluate` reads it (its robust filter, its load history);
    then the factors run once over the records stacked end to end (a row's numbers depend on
    its row, its record's first row and its load history: :attr:`Measured.rows_each`), and so
    does the summary, each figure an array of the records' values (their drift lines solved
    one by one, all in one call per end), taken apart into each record's summary. Records of
    other time axes or columns, or of fewer than two rows: ValueError (evaluate them one by
    one)."""
    if not tables:
        raise ValueError("no record to evaluate")
    model = tester_model()
    first = tables[0]
    n = len(first)
    names = list(first.columns)
    if n < 2:
        raise ValueError("the error model needs at least two rows")
    if any(len(t) != n or not np.array_equal(t.time, first.time) for t in tables):
        raise ValueError("the records do not share one time axis")
    if any(list(t.columns) != names for t in tables):
        raise ValueError("the records do not share one set of columns")
    ms = [Measured.read(t, cfg, model) for t in tables]

    def stacked(arrays: Sequence[np.ndarray]) -> np.ndarray:
        return np.concatenate(arrays) if len(arrays) > 1 else arrays[0]

    table = SignalTable(
        stacked([t.time for t in tables]),
        {k: stacked([t.columns[k] for t in tables]) for k in names},
        {k: first.meta[k] for k in names},
    )
    history = None if ms[0].history is None else np.concatenate([m.history for m in ms], axis=1)
    stacked_m = Measured(
        table,
        cfg,
        model,
        stacked([m.reading for m in ms]),
        stacked([m.cleaned for m in ms]),
        stacked([m.spikes for m in ms]),
        {p: stacked([m.temperatures[p] for m in ms]) for p in ms[0].temperatures},
        history,
        rows_each=n,
    )
    contributions, rows = evaluate_rows(stacked_m)
    slices = [slice(k * n, (k + 1) * n) for k in range(len(tables))]
    rms = {name: np.array([_rms(c.e_z[sl]) for sl in slices]) for name, c in contributions.items()}
    out = _unstack(
        summarize(stacked_m, contributions, rows["e_z"], rms=rms, spikes=stacked_m.spikes), len(tables)
    )
    if "residual" in rows:
        for summary, t, sl in zip(out, tables, slices, strict=True):
            wear = t[cfg.true_wear] - t[cfg.true_wear][0]  # as evaluate takes it
            summary.update(
                compensation_summary(
                    t.time,
                    cfg.ra_window_s,
                    rows["reading_change"][sl],
                    rows["wear_compensated"][sl],
                    wear,
                    cfg.credibility,
                )
            )
    return out


def _unstack(summary: dict[str, Any], records: int) -> list[dict[str, Any]]:
    """The summaries of ``records`` stacked records from their summary, whose figures are
    arrays of one value per record (a figure that is not, they share: the sensors used)."""

    def split(value: Any) -> list[Any]:
        if isinstance(value, dict):
            parts = {k: split(v) for k, v in value.items()}
            return [{k: p[i] for k, p in parts.items()} for i in range(records)]
        if isinstance(value, np.ndarray):
            return value.tolist()  # a record's own value as Python's number, as summarize gives it
        return [value] * records

    return split(summary)


def evaluate_rows(m: Measured) -> tuple[dict[str, Contribution], dict[str, np.ndarray]]:
    """Every factor's contribution and the per-sample columns (names without ``errormodel.``,
    in the order of :func:`evaluation_signals`) of the measured streams ``m``.

    Every number of a row depends on that row, the first row (each series is taken relative to
    its first sample) and the load's history (``m.history``, the liner's creep), so rows
    evaluated in chunks, each with the record's first row put in front and the history
    carried on, give the same numbers as the whole record (:mod:`~twin.errormodel.streaming`).
    """
    cfg, table = m.cfg, m.table
    contributions = {f.name: f.contribution(m) for f in FACTORS}
    parts = {name: c.e_z for name, c in contributions.items()}
    # one stacked sum, rows in the order of the list: the order of the floating-point additions
    e_z = np.sum(np.array(list(parts.values())), axis=0)
    raw_change = m.reading - m.first(m.cleaned)
    compensated = raw_change - e_z
    columns = {"e_z": e_z, **{f"e_{name}": v for name, v in parts.items()}}
    for name, c in contributions.items():
        columns.update({f"{name}.{body}": v for body, v in c.by_body.items()})
    columns.update(reading_change=raw_change, wear_compensated=compensated, spike=m.spikes.astype(float))
    if cfg.true_wear and cfg.true_wear in table:
        columns["residual"] = compensated - m.rel(table[cfg.true_wear])
    return contributions, columns


def summarize(
    m: Measured,
    contributions: dict[str, Contribution],
    e_z: np.ndarray,
    *,
    rms: Mapping[str, float | np.ndarray],
    spikes: np.ndarray | int,
) -> dict[str, Any]:
    """The end-minus-start numbers: drift, temperature rises, each part, each factor's report.

    Only the rows within the drift window of either end of ``m`` enter (the drifts are lines
    through them), so ``m`` may hold just those rows; the figures of the whole record, each
    part's ``rms`` and the ``spikes`` (their count, or the flags of every row), come separately.
    Of records stacked (``m.rows_each``), each figure is an array of the records' values (each
    part's ``rms`` given so), each the number the record's own summary holds.
    """
    parts = {name: c.e_z for name, c in contributions.items()}
    # every drift's lines solved in one go (the same numbers as one by one)
    predicted, probe, *drifts = m.drifts([e_z, m.reading, *m.temperatures.values(), *parts.values()])
    rises = dict(zip(m.temperatures, drifts[: len(m.temperatures)], strict=True))
    part_drifts = dict(zip(parts, drifts[len(m.temperatures) :], strict=True))
    summary: dict[str, Any] = {
        "drift_mm": {"predicted": predicted * 1e3, "probe": probe * 1e3},
        "temperature_rise_C": rises,
        "error_parts_mm": {**{k: v * 1e3 for k, v in part_drifts.items()}, "total": predicted * 1e3},
        "error_parts_rms_um": {k: rms[k] * 1e6 for k in parts},
    }
    for f in FACTORS:
        if f.report is not None:
            summary.update(f.report(contributions[f.name], m))
    summary["interference_spikes"] = (
        int(np.sum(spikes)) if m.rows_each is None else np.sum(np.reshape(spikes, (-1, m.rows_each)), axis=1)
    )
    summary["sensors_used"] = _sensors_used(m)
    return summary


def _sensors_used(m: Measured) -> dict[str, bool]:
    """Per optional sensor (in the order of the config's fields): present and read by a factor
    that is switched on."""
    on = {s for f in FACTORS if f.is_on(m.cfg) for s in f.sensors}
    declared = {s for f in FACTORS for s in f.sensors}
    return {s: s in on and m.sensor(s) is not None for s in COLUMN_FIELDS if s in declared}


def compensation_summary(
    t: np.ndarray,
    ra_window_s: float,
    raw_change: np.ndarray,
    compensated: np.ndarray,
    wear: np.ndarray,
    credibility: bool = True,
) -> dict[str, Any]:
    """The true and compensated wear, the residuals and (``credibility``) the credibility
    indexes of the on-line wear curve, before (raw reading change) and after compensation
    (minus e_z), over the whole record (time ``t``)."""
    before, after = raw_change - wear, compensated - wear
    out: dict[str, Any] = {
        "wear_mm": {"true": float(wear[-1]) * 1e3, "compensated": float(compensated[-1]) * 1e3},
        "compensation": {
            "residual_rms_um": {"before": _rms(before) * 1e6, "after": _rms(after) * 1e6},
            "residual_max_um": {"before": _absmax(before) * 1e6, "after": _absmax(after) * 1e6},
        },
    }
    if credibility:
        frechet_before, frechet_after = _frechet_um(t, [raw_change, compensated], wear)
        out["credibility"] = {
            "frechet_um": {"before": frechet_before, "after": frechet_after},
            "ra_um": {
                "before": ra_fluctuation(t, raw_change, ra_window_s) * 1e6,
                "after": ra_fluctuation(t, compensated, ra_window_s) * 1e6,
            },
        }
    return out


def _rms(x: np.ndarray) -> float:
    """``sqrt(mean(x**2))`` of a float64 ``x``: np.mean's own steps (its sum, a division by
    the count), without its checks, which took longer than the arithmetic of a sample's row."""
    return float(np.sqrt(np.add.reduce(x**2, axis=None) / x.size))


def _absmax(x: np.ndarray) -> float:
    return float(np.max(np.abs(x)))


def _frechet_um(t: np.ndarray, onlines: list[np.ndarray], true: np.ndarray) -> list[float]:
    """Frechet distance between each on-line curve and the true one (t in hours, z in um),
    decimated evenly; the curves' recursions run side by side."""
    step = max(1, int(np.ceil(len(t) / FRECHET_POINTS)))
    idx = np.arange(0, len(t), step)
    if idx[-1] != len(t) - 1:  # and the last row (np.unique of the two would load numpy.ma)
        idx = np.append(idx, len(t) - 1)
    th = t[idx] / 3600.0
    ps = [np.column_stack([th, online[idx] * 1e6]) for online in onlines]
    q = np.column_stack([th, true[idx] * 1e6])
    return discrete_frechets(ps, q)
