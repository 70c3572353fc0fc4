"""``twin compensate``: the error model on a CSV of measurements, without a co-simulation.

The same evaluate and write stages as a run, fed from a file: a lab's record, or a twin
run's signals.csv (whose errormodel.csv it then reproduces byte for byte).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from twin.config.spec import NS_PER_S
from twin.errormodel.config import errormodel_config, input_columns, model_defaults
from twin.errormodel.evaluate import EvaluationConfig, evaluate
from twin.errors import ConfigError
from twin.outputs.csv import read_signals_csv
from twin.outputs.run_folder import RunFolder
from twin.pipeline.stages import Evaluated, budget_columns, write_outputs
from twin.signals.table import SignalTable

__all__ = ["compensate", "compensation_config"]

#: the drift's start and end values come from lines through this much of each end
DEFAULT_WINDOW_S = 300.0


def compensate(csv_path: Path, config_path: Path | None, out_dir: Path) -> dict[str, Any]:
    """The error model on a CSV of measurements (a lab's or a twin run's signals.csv).

    ``config_path`` is a TOML file with an ``[errormodel]`` table: which columns hold the eight
    temperatures (K), the probe reading (m) and, where present, load, torque, angle, vibration
    and a true wear; ``coefficients`` the tester's identified coefficients (a file written by
    ``twin identify``, or an inline table; default the committed identification); ``factors``; and optionally
    ``drift_window`` (default 5 min). Writes errormodel.csv, summary.json, error_budget.png
    into ``out_dir``; returns the summary.
    """
    cfg, source = compensation_config(config_path)
    # only the columns the error model reads: a run's wide signals.csv need not fit in memory
    table = read_signals_csv(csv_path, keep_whole_last_line=True, only=input_columns(cfg))
    table, flagged = _without_bad_rows(table, input_columns(cfg), str(csv_path))
    evaluation = evaluate(table, cfg)
    folder = RunFolder(out_dir)
    folder.make()
    summary = {
        "input": str(csv_path),
        "config": source,
        "status": "completed",
        "input_rows": {"used": len(table), "flagged": len(flagged), "flagged_times_s": flagged[:20]},
        **evaluation.summary,
    }
    columns = tuple(n for n in table.names() if n.startswith("errormodel."))
    sinks = folder.result_sinks(name=csv_path.name, plot=budget_columns(cfg))
    write_outputs(sinks, Evaluated(table, columns, evaluation.summary), lambda: summary)
    return summary


def _without_bad_rows(table: SignalTable, columns: set[str], source: str) -> tuple[SignalTable, list[float]]:
    """The table without the rows where a column the error model reads is not a finite number
    (a sensor's dropout written as nan, an inf), and the times of those rows. One bad row
    would otherwise make every result of the error model nan; the rest is computed, and the
    summary says which rows were left out (``input_rows``)."""
    used = [n for n in table.names() if n in columns]
    good = np.ones(len(table), dtype=bool)
    for name in used:
        good &= np.isfinite(table[name])
    if good.all():
        return table, []
    if good.sum() < 2:
        raise ConfigError(
            f"fewer than two rows with finite values in every column the error model reads ({', '.join(used)})",
            source=source,
        )
    flagged = [float(t) for t in table.time[~good]]
    out = SignalTable(time=np.ascontiguousarray(table.time[good]))
    for name in table.names():
        out.add(table.meta[name], np.ascontiguousarray(table[name][good]))
    return out, flagged


def compensation_config(config_path: Path | None) -> tuple[EvaluationConfig, str]:
    """The error model's configuration from ``config_path`` (the twin's defaults without
    one), and the name problems are reported under."""
    source = str(config_path) if config_path else "compensate"
    em: dict[str, Any] = {}
    if config_path is not None:
        em = _read_errormodel_table(config_path, source)
    window_s = DEFAULT_WINDOW_S
    if "drift_window" in em:
        from twin.config.load import parse_duration

        try:
            window_s = parse_duration(em.pop("drift_window")) / NS_PER_S
        except ValueError as exc:
            raise ConfigError(str(exc), source=source, key="errormodel.drift_window") from None
        if window_s <= 0:
            raise ConfigError(
                "must be positive (the drift's ends are lines through this much of the record)",
                source=source,
                key="errormodel.drift_window",
            )
    return errormodel_config(model_defaults(), em, source, window_s), source


def _read_errormodel_table(path: Path, source: str) -> dict[str, Any]:
    from twin.config.problems import read_toml

    data = read_toml(path, source)
    unknown = sorted(set(data) - {"errormodel"})
    if unknown:
        raise ConfigError(f"unknown key(s) {unknown} (expected [errormodel])", source=source)
    table = data.get("errormodel", {})
    if not isinstance(table, dict):
        raise ConfigError(
            f"expected a table [errormodel], got {type(table).__name__}", source=source, key="errormodel"
        )
    return dict(table)
