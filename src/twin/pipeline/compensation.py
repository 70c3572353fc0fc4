"""``twin compensate``: the error model on a CSV of measurements, without a co-simulation.

The same evaluate and write stages as a run, fed from a file: a lab's record, or a twin
run's signals.csv (whose errormodel.csv it then reproduces byte for byte).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from twin.config.spec import NS_PER_S
from twin.errormodel.config import errormodel_config, model_defaults
from twin.errormodel.evaluate import EvaluationConfig, evaluate
from twin.errors import ConfigError
from twin.outputs.csv import read_signals_csv
from twin.outputs.run_folder import RunFolder
from twin.pipeline.stages import Evaluated, budget_columns, write_outputs

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
    table = read_signals_csv(csv_path)
    evaluation = evaluate(table, cfg)
    folder = RunFolder(out_dir)
    folder.make()
    summary = {"input": str(csv_path), "config": source, "status": "completed", **evaluation.summary}
    columns = tuple(n for n in table.names() if n.startswith("errormodel."))
    sinks = folder.result_sinks(name=csv_path.name, plot=budget_columns(cfg))
    write_outputs(sinks, Evaluated(table, columns, evaluation.summary), lambda: summary)
    return summary


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
    return errormodel_config(model_defaults(), em, source, window_s), source


def _read_errormodel_table(path: Path, source: str) -> dict[str, Any]:
    from twin.config.problems import read_toml

    data = read_toml(path, source)
    unknown = sorted(set(data) - {"errormodel"})
    if unknown:
        raise ConfigError(f"unknown key(s) {unknown} (expected [errormodel])", source=source)
    return dict(data.get("errormodel", {}))
