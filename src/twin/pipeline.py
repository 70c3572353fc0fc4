"""One run from scenario to files: co-simulate, evaluate the error model, write the outputs.

A run folder holds ``signals.csv``, ``summary.json``, ``recording.rrd`` and
``error_budget.png``. A run that fails part way still writes everything recorded so far and
a summary with ``"status": "failed"`` and the reason.
"""

from __future__ import annotations

import json
import os
import pickle
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from twin import __version__
from twin.config.spec import NS_PER_S, Scenario
from twin.cosim.master import Loop, Master, RunResult
from twin.errormodel.config import errormodel_config, evaluation_config, input_columns, model_defaults
from twin.errormodel.evaluate import PARTS, EvaluationConfig, evaluate
from twin.errors import ConfigError, RunError
from twin.outputs import write_signals_csv, write_summary
from twin.outputs.summary import write_json_atomic
from twin.paper import DRIFT_M, TEMPERATURE_RISE_K
from twin.signals.recorder import RunFolderRecorder
from twin.signals.table import SignalTable

RUN_FILE = "run.json"
CHECKPOINT_FILE = "checkpoint.pkl"


def run(
    scenario: Scenario,
    out_dir: Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    process_start: float | None = None,
    loop: Loop = "fast",
    overrides: Sequence[str] = (),
    stop: Callable[[], str | None] | None = None,
    checkpoint_every_ns: int | None = None,
    resume: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run and write the run folder; returns the summary. Raises only before the run starts,
    or :class:`RunError` after writing everything recorded up to a failure.

    ``stop`` is polled between batches (a signal name ends the run as "interrupted", with
    every row recorded so far on disk). With ``checkpoint_every_ns`` the whole twin is saved
    to ``checkpoint.pkl`` at that interval; ``resume`` continues from such a checkpoint.
    """
    from twin.errormodel.evaluate import evaluation_signals

    process_start = process_start or time.perf_counter()
    cfg = evaluation_config(scenario)  # checked before anything runs
    out_dir.mkdir(parents=True, exist_ok=True)
    if resume is None:
        (out_dir / CHECKPOINT_FILE).unlink(missing_ok=True)
        write_json_atomic(
            out_dir / RUN_FILE,
            json.dumps(
                {
                    "scenario": str(Path(scenario.source_path).resolve()),
                    "overrides": list(overrides),
                    "loop": loop,
                    "checkpoint_every_ns": checkpoint_every_ns,
                },
                indent=2,
            ),
        )
    em_signals = evaluation_signals(with_true_wear=bool(cfg.true_wear))
    budget = ["errormodel.e_z", *[f"errormodel.e_{p}" for p in PARTS], "errormodel.reading_change"]
    kept = input_columns(cfg)
    recorder = RunFolderRecorder(
        out_dir,
        keep=kept.__contains__,
        recording_name=scenario.name,
        extra_signals=em_signals,
        budget_columns=budget,
        resume=resume["recorder"] if resume else None,
    )

    def save_checkpoint(snapshot: dict[str, Any]) -> None:
        data = {"master": snapshot, "recorder": recorder.checkpoint(), "scenario": scenario.name}
        tmp = out_dir / (CHECKPOINT_FILE + ".tmp")
        with open(tmp, "wb") as f:
            pickle.dump(data, f, protocol=5)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, out_dir / CHECKPOINT_FILE)  # atomic: a kill never leaves half a checkpoint

    try:
        master = Master(
            scenario,
            progress=progress,
            loop=loop,
            recorder=recorder,
            stop=stop,
            checkpoint_every_ns=checkpoint_every_ns,
            on_checkpoint=save_checkpoint if checkpoint_every_ns else None,
            resume=resume["master"] if resume else None,
        )
        result: RunResult = master.run()
        table = recorder.table()
        summary: dict[str, Any] = {
            "scenario": scenario.name,
            "scenario_file": scenario.source_path,
            "status": result.status,
            "seed": scenario.seed,
        }
        if result.error is not None:
            summary["error"] = str(result.error)
        if result.status == "interrupted":
            summary["error"] = f"interrupted by {result.info.get('interrupted_by')}"
        summary["sim_end_s"] = result.end_ns / NS_PER_S
        evaluated = None
        if len(table) >= 2:
            try:
                evaluated = evaluate(table, cfg)
            except ConfigError as exc:
                summary["errormodel_error"] = str(exc)
        if evaluated is not None:
            summary.update(evaluated.summary)
            summary["drift_mm"]["paper_measured"] = DRIFT_M * 1e3
            summary["temperature_rise_C_paper"] = dict(TEMPERATURE_RISE_K)
            names = [s.name for s in em_signals if s.name in table]
            recorder.append_extra(table, names)
            em_table = SignalTable(table.time)
            for n in names:
                em_table.add(table.meta[n], table[n])
            write_signals_csv(em_table, out_dir / "errormodel.csv")
            _plot(table, out_dir, f"{scenario.name}: predicted error and its parts", cfg)
    finally:
        recorder.finish()
    # the co-simulation loop alone: the time spent writing the files is reported apart
    cosim_s = result.cosim_s - recorder.write_s
    summary["timing"] = {
        "cosim_s": cosim_s,
        "write_s": recorder.write_s,
        "total_s": time.perf_counter() - process_start,
        "macro_steps": result.macro_steps,
        "fmu_steps": result.fmu_steps,
        "realtime_factor": (result.end_ns / NS_PER_S) / cosim_s if cosim_s > 0 else None,
    }
    summary["wall_s"] = summary["timing"]["total_s"]
    summary["versions"] = {"twin": __version__, "python": platform.python_version()}
    write_summary(out_dir / "summary.json", summary)
    if result.error is not None:
        raise RunError(f"{result.error} (everything recorded up to it is in {out_dir})")
    return summary


def resume_run(
    run_dir: Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    stop: Callable[[], str | None] | None = None,
    process_start: float | None = None,
) -> dict[str, Any]:
    """Continue a killed or interrupted run from its last checkpoint."""
    from twin.config.load import load_scenario

    meta_path, ckpt_path = run_dir / RUN_FILE, run_dir / CHECKPOINT_FILE
    if not meta_path.is_file():
        raise ConfigError(f"no {RUN_FILE}: not a run folder", source=str(run_dir))
    if not ckpt_path.is_file():
        raise ConfigError(
            f"no {CHECKPOINT_FILE}: the run saved no checkpoint (use --checkpoint-every)", source=str(run_dir)
        )
    meta = json.loads(meta_path.read_text())
    scenario = load_scenario(meta["scenario"], meta.get("overrides", []))
    with open(ckpt_path, "rb") as f:
        checkpoint = pickle.load(f)
    if checkpoint.get("scenario") != scenario.name:
        raise ConfigError("the checkpoint belongs to another scenario", source=str(ckpt_path))
    return run(
        scenario,
        run_dir,
        progress=progress,
        process_start=process_start,
        loop=meta.get("loop", "fast"),
        overrides=meta.get("overrides", []),
        stop=stop,
        checkpoint_every_ns=meta.get("checkpoint_every_ns"),
        resume=checkpoint,
    )


def compensate(csv_path: Path, config_path: Path | None, out_dir: Path) -> dict[str, Any]:
    """The error model on a CSV of measurements (a lab's or a twin run's signals.csv).

    ``config_path`` is a TOML file with an ``[errormodel]`` table: which columns hold the eight
    temperatures (K), the probe reading (m) and, where present, load, torque, angle, vibration
    and a true wear; ``geometry`` the tester's coefficients (names as the FixtureMechanics and
    SensorsDAQ parameters; defaults are those FMUs' values); ``factors``; and optionally
    ``drift_window`` (default 5 min). Writes errormodel.csv, summary.json, error_budget.png.
    """
    import tomllib

    from twin.config.load import parse_duration
    from twin.outputs import read_signals_csv

    em: dict[str, Any] = {}
    window_s = 300.0
    source = str(config_path) if config_path else "compensate"
    if config_path is not None:
        try:
            data = tomllib.loads(config_path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError("file not found", source=source) from None
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(f"cannot read: {exc}", source=source) from None
        unknown = sorted(set(data) - {"errormodel"})
        if unknown:
            raise ConfigError(f"unknown key(s) {unknown} (expected [errormodel])", source=source)
        em = dict(data.get("errormodel", {}))
        if "drift_window" in em:
            try:
                window_s = parse_duration(em.pop("drift_window")) / NS_PER_S
            except ValueError as exc:
                raise ConfigError(str(exc), source=source, key="errormodel.drift_window") from None
    cfg = errormodel_config(model_defaults(), em, source, window_s)
    table = read_signals_csv(csv_path)
    evaluated = evaluate(table, cfg)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = [n for n in table.names() if n.startswith("errormodel.")]
    em_table = SignalTable(table.time)
    for n in names:
        em_table.add(table.meta[n], table[n])
    write_signals_csv(em_table, out_dir / "errormodel.csv")
    summary = {"input": str(csv_path), "config": source, "status": "completed", **evaluated.summary}
    write_summary(out_dir / "summary.json", summary)
    _plot(table, out_dir, f"{csv_path.name}: predicted error and its parts", cfg)
    return summary


def _plot(table: SignalTable, out_dir: Path, title: str, cfg: EvaluationConfig) -> None:
    from twin.outputs import error_budget_png

    error_budget_png(
        table,
        out_dir / "error_budget.png",
        reading=cfg.reading,
        predicted="errormodel.e_z",
        parts={p: f"errormodel.e_{p}" for p in PARTS},
        temperatures=[c for c in cfg.temperatures.values() if c in table],
        title=title,
    )


def summary_line(summary: Mapping[str, Any]) -> str:
    """A short human line for the terminal."""
    d = summary.get("drift_mm", {})
    if "predicted" in d:
        return (
            f"{summary['scenario']}: {summary['status']}; drift predicted {d['predicted']:+.4f} mm, "
            f"probe {d['probe']:+.4f} mm (paper {d.get('paper_measured', float('nan')):+.3f} mm)"
        )
    return f"{summary['scenario']}: {summary['status']}"
