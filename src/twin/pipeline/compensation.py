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


def compensate(
    csv_path: Path,
    config_path: Path | None,
    out_dir: Path,
    config: tuple[EvaluationConfig, str] | None = None,
) -> dict[str, Any]:
    """The error model on a CSV of measurements (a lab's or a twin run's signals.csv).

    ``config_path`` is a TOML file with an ``[errormodel]`` table: which columns hold the eight
    temperatures (K), the probe reading (m) and, where present, load, torque, angle, vibration
    and a true wear; ``coefficients`` the tester's identified coefficients (a file written by
    ``twin identify``, or an inline table; default the committed identification); ``factors``; and optionally
    ``drift_window`` (default 5 min). Writes errormodel.csv, summary.json, error_budget.png
    into ``out_dir``; returns the summary. ``config`` (an error-model configuration and its
    name) replaces the file: :func:`run_folder_config` gives a run's own.
    """
    cfg, source = config or compensation_config(config_path)
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


def run_folder_config(run_dir: Path) -> tuple[Path, tuple[EvaluationConfig, str]]:
    """A run folder's ``signals.csv`` and the error model its run used (its scenario and
    overrides, from ``run.json``): ``twin compensate RUN_FOLDER`` needs no hand-written config."""
    from twin.config.load import load_scenario
    from twin.errormodel.config import evaluation_config
    from twin.outputs.run_folder import RUN_FILE, SIGNALS_CSV, _run_meta

    meta = _run_meta(run_dir / RUN_FILE)
    scenario = load_scenario(meta.scenario, list(meta.overrides))
    return run_dir / SIGNALS_CSV, (evaluation_config(scenario), f"{run_dir / RUN_FILE} ({meta.scenario})")


TEMPLATE_TOML = """# The error model on a lab's own record: `twin compensate lab.csv --config LAB.toml`.
# Every column is named as in the CSV's header; values in SI units (K, m, N, N.m, rad).
[errormodel]
# the paper's eight temperature measuring points -> the CSV's columns (K)
temperatures = { bearing_block = "T_bearing_block", heel_block = "T_heel_block", bearing = "T_bearing", t_plate = "T_t_plate", base = "T_base", long_pole = "T_long_pole", detecting_frame = "T_detecting_frame", room = "T_room" }
reading = "probe"                 # the wear-depth probe's reading (m)
# load = "load"                   # the load cell (N), where the tester has one
# torque = "torque"               # the friction torque sensor (N.m)
# angle = "angle"                 # the swing angle encoder (rad)
# vibration = "vibration"         # the Z vibration pickup (m)
# true_wear = "wear_offline"      # an off-line wear measurement (m), to judge the compensation
factors = ["thermal", "interference"]   # of thermal, loading, fluctuating, positioning, interference
drift_window = "5 min"            # drift ends: lines through this much of each end of the record
# coefficients = "identified.toml"  # the tester's own (`twin identify`); default: the twin's committed
"""


def write_template(folder: Path) -> list[Path]:
    """A commented ``LAB.toml`` and a small example ``lab.csv`` (1 h at 10 s, a warm-up) that
    ``twin compensate lab.csv --config LAB.toml`` runs as they are."""
    folder.mkdir(parents=True, exist_ok=True)
    toml, csv = folder / "LAB.toml", folder / "lab.csv"
    for p in (toml, csv):
        if p.exists():
            raise ConfigError("exists already: the template does not overwrite a file", source=str(p))
    toml.write_text(TEMPLATE_TOML, encoding="utf-8")
    t = np.arange(0.0, 3600.0 + 1.0, 10.0)
    rise = 2.0 * (1.0 - np.exp(-t / 1200.0))  # the room warms by about 2 K in the hour
    gains = {"bearing_block": 0.75, "heel_block": 0.65, "bearing": 0.4, "t_plate": 0.7, "base": 0.65,
             "long_pole": 1.05, "detecting_frame": 1.0, "room": 1.0}  # fmt: skip
    names = [f"T_{p}" for p in gains]
    lines = ["time," + ",".join(names) + ",probe"]
    for k, tk in enumerate(t):
        temps = [293.15 + g * rise[k] for g in gains.values()]
        probe = 4.805e-3 - 1.5e-6 * rise[k]
        lines.append(",".join(repr(float(v)) for v in [tk, *temps, probe]))
    csv.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return [toml, csv]
