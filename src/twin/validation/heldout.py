"""``twin heldout``: the error model judged on testers it was not identified on... by a lab's rules.

For each of N testers as built (:mod:`twin.uncertainty.testers`, drawn from the one prior file
scenarios/base/priors.toml), on a Dask worker:

1. every calibration experiment of ``twin identify`` (``scenarios/calibration/``) runs on that
   tester, and :func:`twin.errormodel.identify.fit_records` fits the error model's
   coefficients from the DAQ channels alone (in memory, no file);
2. the group's MLR + AR thermal compensation (:mod:`twin.errormodel.baselines`) is fitted on
   the same thermal calibration records;
3. operating scenarios the identification never saw run on the same tester (each with a slow
   random drift on its room, facts 6), and both models compensate them.

One row per tester and scenario: the RMS error before and after, the % of the RMS removed and
the largest residual, for the MBS model and the baseline, the tester's drawn values and its
identified coefficients. The held-out file (``scenarios/validation/heldout.toml``) names the
prior file, the scenarios and the goals; it names no FMU parameter.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.load import load_scenario
from twin.config.reader import Problems
from twin.config.spec import Scenario
from twin.cosim.controls import RunControls
from twin.errormodel.baselines import MlrAr, fit_mlr_ar
from twin.errormodel.coefficients import Prior
from twin.errormodel.identify import Experiment, Record
from twin.errors import ConfigError, RunError
from twin.fmu.pool import SlotPool
from twin.pipeline.cluster import StudyOptions
from twin.seeds import Key, generator, scenario_seed
from twin.uncertainty import rooms
from twin.uncertainty.testers import Testers, apply, load_room, load_testers

__all__ = ["HeldOut", "load_heldout", "run_heldout", "run_tester", "summarise"]

#: the identify calibration whose experiments the baseline is fitted on (the thermal ones)
THERMAL_CALIBRATION = "thermal"
_TOP = {"heldout", "scenario", "goals"}
_HELDOUT_KEYS = {"spreads", "testers", "seed", "room", "room_drift_K", "calibration"}
_SCENARIO_KEYS = {"name", "file", "set", "thermal_only"}
GOAL_KEYS = (
    "median_removed_pct",
    "p10_removed_pct",
    "thermal_only_max_um",
    "probe_drift_r",
    "probe_drift_bias_um_per_K",
    "negative_alpha_l",
)
#: the drawn FMU parameter beside the identified coefficient it stands for (the probe's drifts
#: are the probe's own: the probe-heating calibration measures them on the bench)
PROBE_PAIRS = {
    "probe_zero_drift": "fmu.sensors.parameters.probe_zero_drift",
    "probe_span_drift": "fmu.sensors.parameters.probe_span_drift",
}
#: an identified growth below this (m/K) sits at its bound 0
AT_BOUND = 1e-12
MODELS = ("mbs", "mlr_ar")


@dataclass(frozen=True)
class HeldOutScenario:
    """An operating scenario of the validation: its file, overrides, and whether only
    thermal errors act in it (no load, no motion)."""

    name: str
    path: Path
    overrides: tuple[str, ...] = ()
    thermal_only: bool = False


@dataclass(frozen=True)
class HeldOut:
    """A checked held-out file."""

    path: Path
    spreads: Path
    testers: int
    seed: int
    room: str
    room_drift_K: float
    calibration: Path
    scenarios: tuple[HeldOutScenario, ...]
    goals: Mapping[str, float] = field(default_factory=dict)


def _loads(p: Problems, key: str, path: Path, sets: Sequence[str]) -> Scenario | None:
    """The problems of a scenario file the held-out file names, loaded with its overrides as
    every tester's run will be: found before any tester runs, not by every tester's worker.
    The scenario, or None when it has problems."""
    from twin.pipeline.prepare import prepare_scenario

    try:
        scenario = load_scenario(path, list(sets))
        prepare_scenario(scenario)
        return scenario
    except ConfigError as exc:
        problems = getattr(exc, "problems", [exc])
        first = problems[0]
        where = ": ".join(x for x in (path.name, first.key) if x)
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        p.add(key, f"{where}: {first.message or first}{more}")
        return None


def _check_room(p: Problems, room: Any, loaded: Sequence[tuple[str, Scenario]]) -> str:
    """``heldout.room``: ``input.<instance>.<variable>``, a profile of every held-out scenario
    (its drift is added to that profile): checked before any tester runs."""
    if not isinstance(room, str) or not room.startswith("input.") or room.count(".") != 2:
        p.add("heldout.room", f"expected 'input.<instance>.<variable>' (a profile's key), got {room!r}")
        return str(room)
    target = room.split(".", 1)[1]
    for name, scenario in loaded:
        if not any(pr.target == target for pr in scenario.profiles):
            known = ", ".join(f"input.{pr.target}" for pr in scenario.profiles) or "none"
            p.add("heldout.room", f"no profile drives {target} in scenario {name!r} (its profiles: {known})")
            break
    return room


def _scenarios(
    p: Problems, folder: Path, raw: Any, loaded: list[tuple[str, Scenario]]
) -> list[HeldOutScenario]:
    if not isinstance(raw, list) or not raw:
        p.add("scenario", "expected at least one [[scenario]]")
        return []
    out = []
    for i, s in enumerate(raw):
        where = f"scenario[{i}]"
        if not isinstance(s, dict) or not isinstance(s.get("file"), str):
            p.add(where, "expected a table with file = '...'")
            continue
        p.unknown_keys(s, _SCENARIO_KEYS, f"{where}.")
        path = (folder / s["file"]).resolve()
        sets = p.strings(s, "set", f"{where}.")
        name = s.get("name", path.stem)
        if not path.is_file():
            p.add(f"{where}.file", f"no such file {s['file']!r}")
        elif (scenario := _loads(p, f"{where}.file", path, sets)) is not None:
            loaded.append((str(name), scenario))
        thermal = p.boolean(s, "thermal_only", f"{where}.", default=False)
        out.append(HeldOutScenario(str(name), path, sets, thermal))
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        p.add("scenario", "two scenarios share a name")
    return out


def load_heldout(path: str | Path, *, testers: int | None = None) -> HeldOut:
    """Read and check a held-out file; every problem at once (:class:`ConfigErrors`)."""
    from twin.config.reader import read_toml
    from twin.errormodel.identify import EXPERIMENTS  # the experiments every tester runs

    path = Path(path)
    folder = path.resolve().parent
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP, "")
    h = p.table(raw, "heldout")
    p.unknown_keys(h, _HELDOUT_KEYS, "heldout.")
    spreads = (folder / str(h.get("spreads", "../base/priors.toml"))).resolve()
    if not spreads.is_file():
        p.add("heldout.spreads", f"no such file {spreads.name!r}")
    calibration = (folder / str(h.get("calibration", "../calibration"))).resolve()
    missing = sorted({e.scenario for e in EXPERIMENTS if not (calibration / e.scenario).is_file()})
    if missing:
        p.add("heldout.calibration", f"{calibration} lacks the calibration experiments {', '.join(missing)}")
    goals_raw = p.table(raw, "goals")
    p.unknown_keys(goals_raw, set(GOAL_KEYS), "goals.")
    goals = {k: p.number(goals_raw, k, "goals.", lo=0.0) for k in GOAL_KEYS if k in goals_raw}
    count = {"testers": testers} if testers is not None else h
    loaded: list[tuple[str, Scenario]] = []
    scenarios = tuple(_scenarios(p, folder, raw.get("scenario"), loaded))
    # the room's slow drift: the prior file's, unless this file overrides it
    prior_drift = load_room(spreads).drift_K if spreads.is_file() and "room_drift_K" not in h else 1.0
    room_drift = p.number({"room_drift_K": prior_drift} | h, "room_drift_K", "heldout.", lo=0.0) or 0.0
    room = h.get("room", "input.thermal.t_room")
    if room_drift > 0:  # the room's key is used only to drift it
        room = _check_room(p, room, loaded)
    cfg = HeldOut(
        path=path,
        spreads=spreads,
        testers=p.integer(count, "testers", "heldout.", default=50, lo=1, hi=10**6),
        seed=p.integer(h, "seed", "heldout.", default=0, lo=0, hi=2**63 - 1),
        room=str(room),
        room_drift_K=room_drift,
        calibration=calibration,
        scenarios=scenarios,
        goals={k: v for k, v in goals.items() if v is not None},
    )
    p.check()
    return cfg


# ----------------------------------------------------------------------------- one tester


@dataclass(frozen=True)
class TesterJob:
    """Everything a worker needs for one tester, built and checked on the client."""

    index: int
    values: Mapping[str, float]
    calibration: tuple[tuple[Experiment, Scenario], ...]
    heldout: tuple[tuple[HeldOutScenario, Scenario], ...]
    priors: Mapping[str, Prior]


def _lab_config(values: Mapping[str, float]) -> Any:
    """The error model's configuration with ``values``, the twin's default columns, no true
    wear (a lab's record has none)."""
    from twin.errormodel.config import errormodel_config

    return replace(errormodel_config(values, {}, "twin heldout", 300.0), true_wear=None)


def fit_baseline(records: Mapping[str, Record], values: Mapping[str, float]) -> MlrAr:
    """The MLR + AR model on the thermal calibration's records: the cleaned reading (the same
    robust spike filter as the MBS model) against the eight temperatures, fitted samples only."""
    from twin.errormodel.factors import Measured
    from twin.errormodel.identify import CALIBRATIONS
    from twin.errormodel.tester import tester_model

    cal = next(c for c in CALIBRATIONS if c.name == THERMAL_CALIBRATION)
    cfg = _lab_config(values)
    drifts, temps = [], []
    for name in cal.experiments:
        r = records[name]
        m = Measured.read(r.table, cfg, tester_model())
        drifts.append(m.cleaned[r.used])
        temps.append({k: v[r.used] for k, v in m.temperatures.items()})
    return fit_mlr_ar(drifts, temps)


def _figures(before: np.ndarray, after: np.ndarray) -> dict[str, float]:
    rms_b, rms_a = float(np.sqrt(np.mean(before**2))), float(np.sqrt(np.mean(after**2)))
    return {
        "rms_after_um": rms_a * 1e6,
        "removed_pct": 100.0 * (1.0 - rms_a / rms_b) if rms_b > 0 else math.nan,
        "max_residual_um": float(np.max(np.abs(after))) * 1e6,
    }


def evaluate_heldout(
    scenario: Scenario, values: Mapping[str, float], baseline: MlrAr, pool: SlotPool | None = None
) -> dict[str, float]:
    """Run a held-out scenario (its FMU instances from ``pool`` where given), compensate it with
    the identified ``values`` (MBS) and with the baseline; the figures of both against the
    twin's true wear.

    The error model's rows only (:func:`~twin.errormodel.evaluate.evaluate_rows`, the numbers
    a run's evaluation writes): a run's summary (drifts, credibility metrics) is not a figure
    of this table."""
    from twin.errormodel.evaluate import evaluate_rows
    from twin.errormodel.factors import Measured
    from twin.errormodel.sources import MechanicalCoefficients, ThermalCoefficients
    from twin.errormodel.tester import tester_model
    from twin.pipeline import prepare_scenario, simulate

    prepared = prepare_scenario(scenario)
    cfg = replace(
        prepared.evaluation,
        thermal=ThermalCoefficients.from_values(values, source="twin heldout: identified"),
        mechanics=MechanicalCoefficients.from_values(values, source="twin heldout: identified"),
    )
    sim = simulate(prepared, pool=pool)
    if sim.result.status != "completed":
        raise RunError(f"{scenario.name} {sim.result.status}: {sim.result.error}")
    t = sim.table
    if not cfg.evaluate or not cfg.true_wear or cfg.true_wear not in t or len(t) < 2:
        raise RunError(f"{scenario.name}: the error model did not run (no tester, no true wear or no rows)")
    try:
        contributions, columns = evaluate_rows(Measured.read(t, cfg, tester_model()))
    except ConfigError as exc:
        raise RunError(f"{scenario.name}: the error model did not run ({exc})") from None
    wear = t[cfg.true_wear] - t[cfg.true_wear][0]
    raw = columns["reading_change"]
    before = raw - wear
    temps = {point: t[col] for point, col in cfg.temperatures.items()}
    thermal_b = baseline.predict(temps)
    out = {"rms_before_um": float(np.sqrt(np.mean(before**2))) * 1e6}
    out["max_before_um"] = float(np.max(np.abs(before))) * 1e6
    out.update({f"mbs.{k}": v for k, v in _figures(before, columns["residual"]).items()})
    after_b = raw - contributions["interference"].e_z - thermal_b - wear
    out.update({f"mlr_ar.{k}": v for k, v in _figures(before, after_b).items()})
    return out


def run_tester(job: TesterJob) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """Identify one tester, fit the baseline, judge both on the held-out scenarios.

    Returns one row of figures per held-out scenario and the timings. Its thirteen runs, and
    the next tester's on this worker, reuse the FMU instances of the ones before (the process's
    :func:`~twin.fmu.pool.sweep_pool`: reset instances, the same signals bit for bit).
    """
    from twin.errormodel.identify import fit_records
    from twin.fmu.pool import sweep_pool
    from twin.pipeline.lab import lab_record

    start = time.perf_counter()
    pool = sweep_pool()
    records = {e.name: lab_record(e, s, pool=pool) for e, s in job.calibration}
    coefficients = fit_records(records, job.priors)
    identified = coefficients.values()
    identify_s = time.perf_counter() - start
    baseline = fit_baseline(records, identified)
    ident = {f"identified.{k}": v for k, v in identified.items()}
    rows = []
    for _, scenario in job.heldout:
        figures = evaluate_heldout(scenario, identified, baseline, pool)
        figures["mlr_ar.temperatures_kept"] = float(len(baseline.names))
        figures["mlr_ar.ar_order"] = float(len(baseline.ar))
        rows.append({**figures, **ident})
    return rows, {"identify_s": identify_s, "total_s": time.perf_counter() - start}


def tester_task(payload: dict[str, Any]) -> dict[str, Any]:
    """What a worker runs for one tester: never raises, a failure is a failed record."""
    import os

    from twin.pipeline.cluster import one_line
    from twin.pipeline.shipping import check_worker

    record: dict[str, Any] = {"index": payload["index"], "status": "ok", "error": "", "rows": []}
    try:
        check_worker()
        record["rows"], record["timing"] = run_tester(payload["scenario"])
    except Exception as exc:
        record.update(status="failed", error=one_line(exc))
    record["pid"] = os.getpid()
    return record


# ----------------------------------------------------------------------------- the client


@dataclass(frozen=True)
class Bases:
    """The scenarios every tester's job starts from, each file read and checked once per
    study: the calibration experiments (in :data:`~twin.errormodel.identify.EXPERIMENTS`'
    order) and the held-out scenarios with their overrides (in the file's order). A tester's
    values, seeds and room drift make new scenarios from them (a scenario is immutable)."""

    calibration: tuple[Scenario, ...]
    heldout: tuple[Scenario, ...]


def load_bases(cfg: HeldOut) -> Bases:
    """The files of ``cfg``'s calibration experiments and held-out scenarios, loaded."""
    from twin.errormodel.identify import EXPERIMENTS

    return Bases(
        tuple(load_scenario(cfg.calibration / e.scenario) for e in EXPERIMENTS),
        tuple(load_scenario(ho.path, list(ho.overrides)) for ho in cfg.scenarios),
    )


def _heldout_scenario(cfg: HeldOut, base: Scenario, values: Mapping[str, float], i: int, j: int) -> Scenario:
    """Held-out scenario ``j`` of tester ``i``: its file and overrides (``base``), the tester's
    values, a seed of its own and the room's slow drift."""
    scenario = apply(base, values)
    scenario = scenario.with_seed(scenario_seed(cfg.seed, Key.RUN, i, j))
    if cfg.room_drift_K > 0:
        drift = rooms.smooth_drift(generator(cfg.seed, Key.ROOM, i, j), cfg.room_drift_K)
        target = cfg.room.split(".", 1)[1]
        scenario = scenario.with_input(rooms.drifted(scenario, target, drift))
    return scenario


def make_job(
    cfg: HeldOut, testers: Testers, priors: Mapping[str, Prior], i: int, bases: Bases | None = None
) -> TesterJob:
    """Tester ``i``'s job: its drawn values applied to every calibration experiment and
    every held-out scenario (scenarios built and checked here, on the client, from ``bases``:
    default, the files read now)."""
    from twin.errormodel.identify import EXPERIMENTS

    bases = bases or load_bases(cfg)
    values = testers.draw(i)
    calibration = []
    for k, (e, base) in enumerate(zip(EXPERIMENTS, bases.calibration, strict=True)):
        scenario = apply(base, values)
        calibration.append((e, scenario.with_seed(scenario_seed(cfg.seed, Key.RUN, i, 1000 + k))))
    heldout = tuple(
        (ho, _heldout_scenario(cfg, base, values, i, j))
        for j, (ho, base) in enumerate(zip(cfg.scenarios, bases.heldout, strict=True))
    )
    return TesterJob(i, values, tuple(calibration), heldout, priors)


def rows_of(cfg: HeldOut, values: Mapping[str, float], record: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The table rows of one tester's record (failed: one row per scenario with its error)."""
    i = record["index"]
    out = []
    for j, ho in enumerate(cfg.scenarios):
        row = {"point": i * len(cfg.scenarios) + j, "seed": cfg.seed, "tester": i, "scenario": ho.name}
        row.update(thermal_only=ho.thermal_only, **values, status=record["status"], error=record["error"])
        if record["status"] == "ok":
            row.update(record["rows"][j])
        out.append(row)
    return out


def run_heldout(
    cfg: HeldOut,
    out: Path,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
    options: StudyOptions = StudyOptions(),  # noqa: B008
) -> dict[str, Any]:
    """Run every tester on Dask (``options``: where, whether only the testers the folder's
    table lacks, with the same files and settings) into ``out`` (``results.parquet``,
    ``results.csv``, ``summary.json``); returns the summary. ``controls.echo`` is told each
    tester as it finishes."""
    from twin.errormodel.coefficients import load_priors
    from twin.outputs.summary import write_summary
    from twin.pipeline.cluster import bounded_logs, execute, failed, one_line, open_client
    from twin.pipeline.results import ResultStore
    from twin.pipeline.shipping import BinariesPlugin, collect

    testers = Testers(tuple(load_testers(cfg.spreads)), cfg.seed)
    priors = load_priors()
    meta = {
        "heldout": str(cfg.path),
        "testers": cfg.testers,
        "seed": cfg.seed,
        "fingerprint": fingerprint(cfg),
        "inputs": inputs(cfg),
    }
    store = ResultStore(
        out,
        ["tester", "scenario", "thermal_only", *testers.names],
        meta,
        resume=options.resume,
        size=cfg.testers * len(cfg.scenarios),
    )
    todo = [i for i in range(cfg.testers) if not _complete(store, cfg, i)]
    timings: list[dict[str, float]] = []

    bases = load_bases(cfg)

    def payload(i: int) -> dict[str, Any]:
        try:
            return {"index": i, "scenario": make_job(cfg, testers, priors, i, bases)}
        except ConfigError as exc:
            return failed(i, one_line(exc)) | {"rows": []}

    start = time.perf_counter()
    with bounded_logs(), open_client(options.scheduler, options.workers) as client:
        threads = max(1, sum(client.nthreads().values()))
        controls.echo(
            f"heldout: {cfg.testers} testers x {len(cfg.scenarios)} scenarios on {threads} workers; results in {out}"
        )
        client.register_plugin(BinariesPlugin(collect()))
        store.start()
        begin = time.perf_counter()
        for record in execute(client, todo, payload, tester_task, controls.stop):
            for row in rows_of(cfg, testers.draw(record["index"]), record):
                store.add(row)
            timings.append(record.get("timing", {}))
            store.flush()
            controls.echo(f"tester {record['index']}: {record['status']} {record['error']}".rstrip())
            if controls.stopped():
                break
        elapsed = time.perf_counter() - begin
        if caught := controls.stopped():
            # before the cluster closes: its close takes seconds the command may not get
            store.flush(force=True)
            stopped = interrupted(cfg, caught)
            write_summary(out / "summary.json", stopped)
            return stopped
    store.flush(force=True)
    table = store.table()
    summary = {"status": "completed", **summarise(cfg, table)}
    summary["timing"] = _timing(timings, elapsed, time.perf_counter() - start, threads)
    write_summary(out / "summary.json", summary)
    return summary


def interrupted(cfg: HeldOut, name: str) -> dict[str, Any]:
    """The summary of a held-out validation a signal stopped (its table holds the testers that
    finished; ``--resume`` runs the rest)."""
    return {
        "heldout": str(cfg.path),
        "status": "interrupted",
        "error": f"interrupted by {name}",
        "testers": cfg.testers,
    }


def fingerprint(cfg: HeldOut) -> str:
    """A hash of what decides the results: the held-out and spreads files, every scenario
    file, the number of testers and the seed (a resumed run must be the same one)."""
    import hashlib

    h = hashlib.sha256(f"{cfg.testers} {cfg.seed}".encode())
    for path in (cfg.path, cfg.spreads, *(s.path for s in cfg.scenarios)):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def inputs(cfg: HeldOut) -> dict[str, str]:
    """What decides the rows, by name (:mod:`twin.pipeline.provenance`): the number of
    testers and the seed, the held-out and spreads files, every scenario and every file it
    reads, the code that runs a tester; a resume with any of them changed is refused naming it."""
    from twin.pipeline.provenance import code_digests, digest, file_digests, scenario_files

    files = [cfg.path.resolve(), cfg.spreads.resolve()]
    for s in cfg.scenarios:
        files += [f for f in scenario_files(s.path) if f not in files]
    return {"testers": digest(cfg.testers), "seed": digest(cfg.seed)} | file_digests(files) | code_digests()


def _complete(store: Any, cfg: HeldOut, i: int) -> bool:
    """Tester ``i`` has an ok row for every scenario in the table already."""
    n = len(cfg.scenarios)
    return all(store.status(i * n + j) == "ok" for j in range(n))


def _timing(
    timings: Sequence[Mapping[str, float]], elapsed: float, wall: float, threads: int
) -> dict[str, Any]:
    ident = [t["identify_s"] for t in timings if "identify_s" in t]
    total = [t["total_s"] for t in timings if "total_s" in t]
    return {
        "wall_s": wall,
        "testers_s": elapsed,
        "workers": threads,
        "identify_s_mean": float(np.mean(ident)) if ident else None,
        "tester_s_mean": float(np.mean(total)) if total else None,
    }


# ----------------------------------------------------------------------------- the summary


def _stats(frame: Any, model: str) -> dict[str, Any]:
    if f"{model}.removed_pct" not in frame.columns:  # no tester gave a row (every one failed)
        return {"rows": 0}
    removed = frame[f"{model}.removed_pct"].to_numpy(dtype=float)
    largest = frame[f"{model}.max_residual_um"].to_numpy(dtype=float)
    if len(removed) == 0:
        return {"rows": 0}
    return {
        "rows": len(removed),
        "removed_pct_median": float(np.median(removed)),
        "removed_pct_p10": float(np.percentile(removed, 10)),
        "largest_residual_um": float(np.max(largest)),
        "rms_after_um_median": float(np.median(frame[f"{model}.rms_after_um"].to_numpy(dtype=float))),
    }


def identification(ok: Any) -> dict[str, Any]:
    """How well the testers' identification found what was drawn, one row per tester: the
    correlation and mean difference (identified - drawn) of each probe drift, and the
    identified alpha * L that are negative or at their bound 0 (count per coefficient)."""
    per_tester = ok.drop_duplicates("tester")
    out: dict[str, Any] = {"testers": len(per_tester)}
    for name, drawn_key in PROBE_PAIRS.items():
        column = f"identified.{name}"
        if column not in per_tester.columns or drawn_key not in per_tester.columns or len(per_tester) < 2:
            continue
        found = per_tester[column].to_numpy(dtype=float)
        drawn = per_tester[drawn_key].to_numpy(dtype=float)
        scale = 1e6 if name == "probe_zero_drift" else 1.0  # um/K; the span drift in 1/K
        spread = np.std(found) > 0 and np.std(drawn) > 0
        out[name] = {
            "r": float(np.corrcoef(found, drawn)[0, 1]) if spread else math.nan,
            "bias": float(np.mean(found - drawn)) * scale,
            "unit": "um/K" if scale != 1.0 else "1/K",
        }
    growths = [c for c in per_tester.columns if c.startswith("identified.alpha_l_")]
    values = per_tester[growths].to_numpy(dtype=float) if growths else np.zeros((0, 0))
    out["negative_alpha_l"] = int(np.sum(values < 0))
    out["alpha_l_at_bound"] = {
        c.removeprefix("identified."): int(n)
        for c, n in zip(growths, np.sum(np.abs(values) < AT_BOUND, axis=0).tolist(), strict=True)
        if n
    }
    return out


def _identification_goals(cfg: HeldOut, ident: Mapping[str, Any]) -> dict[str, Any]:
    """The identification's goals: one model-free entry each (``identified``)."""
    zero = ident.get("probe_zero_drift", {})
    figures = {
        "probe_drift_r": (zero.get("r"), True),
        "probe_drift_bias_um_per_K": (None if "bias" not in zero else abs(zero["bias"]), False),
        "negative_alpha_l": (ident.get("negative_alpha_l"), False),
    }
    out: dict[str, Any] = {}
    for goal, target in cfg.goals.items():
        if goal not in figures:
            continue
        value, at_least = figures[goal]
        ok = value is not None and not math.isnan(value)
        met = None if not ok else (value >= target if at_least else value <= target)
        out[goal] = {
            "goal": target,
            "at_least" if at_least else "at_most": target,
            "identified": {"value": value if ok else None, "met": met},
        }
    return out


def _goals(cfg: HeldOut, models: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    figures = {
        "median_removed_pct": ("removed_pct_median", "all", True),
        "p10_removed_pct": ("removed_pct_p10", "all", True),
        "thermal_only_max_um": ("largest_residual_um", "thermal_only", False),
    }
    for goal, target in cfg.goals.items():
        if goal not in figures:
            continue
        stat, group, at_least = figures[goal]
        entry: dict[str, Any] = {"goal": target, "at_least" if at_least else "at_most": target}
        for model in MODELS:
            value = models[model].get(group, {}).get(stat)
            met = None if value is None else (value >= target if at_least else value <= target)
            entry[model] = {"value": value, "met": met}
        out[goal] = entry
    return out


def summarise(cfg: HeldOut, table: Any) -> dict[str, Any]:
    """Median and 10th percentile of the % of RMS removed, the largest residual (all rows,
    thermal-only rows, per scenario) for both models, and the goals."""
    ok = table[table["status"] == "ok"]
    models: dict[str, Any] = {}
    for model in MODELS:
        models[model] = {
            "all": _stats(ok, model),
            "thermal_only": _stats(ok[ok["thermal_only"].astype(bool)], model),
            "by_scenario": {s.name: _stats(ok[ok["scenario"] == s.name], model) for s in cfg.scenarios},
        }
    testers_failed = sorted({int(t) for t in table.loc[table["status"] != "ok", "tester"]})
    ident = identification(ok)
    return {
        "heldout_file": str(cfg.path),
        "spreads_file": str(cfg.spreads),
        "testers": cfg.testers,
        "testers_failed": testers_failed,
        "seed": cfg.seed,
        "scenarios": [
            {"name": s.name, "thermal_only": s.thermal_only, "set": list(s.overrides)} for s in cfg.scenarios
        ],
        "models": models,
        "identification": ident,
        "goals": {**_goals(cfg, models), **_identification_goals(cfg, ident)},
    }


def report_lines(summary: dict[str, Any]) -> list[str]:
    """The figures and goals, one line each."""
    lines = []
    ident = summary.get("identification", {})
    for name in PROBE_PAIRS:
        if name in ident:
            f = ident[name]
            lines.append(
                f"{name}: identified vs drawn over {ident['testers']} testers r {f['r']:.3f}, "
                f"bias {f['bias']:.3g} {f['unit']}"
            )
    if "negative_alpha_l" in ident:
        bound = ", ".join(f"{k} {v}" for k, v in ident["alpha_l_at_bound"].items()) or "none"
        lines.append(
            f"identified alpha*L negative: {ident['negative_alpha_l']}; at their bound 0 (testers): {bound}"
        )
    for model, m in summary["models"].items():
        a, th = m["all"], m["thermal_only"]
        if not a.get("rows"):
            lines.append(f"{model}: no row")
            continue
        thermal = f"{th['largest_residual_um']:.2f} um" if th.get("rows") else "no thermal-only row"
        lines.append(
            f"{model}: % of RMS removed median {a['removed_pct_median']:.1f}, 10th percentile "
            f"{a['removed_pct_p10']:.1f}; largest residual {a['largest_residual_um']:.2f} um; "
            f"thermal-only largest {thermal}"
        )
    for goal, g in summary["goals"].items():
        parts = ", ".join(
            f"{m} {v['value']:.2f} ({'met' if v['met'] else 'not met'})"
            for m, v in g.items()
            if isinstance(v, dict) and v.get("value") is not None
        )
        lines.append(f"goal {goal} {g['goal']}: {parts}")
    return lines
