"""Load a scenario file (TOML) into a checked, frozen :class:`~twin.config.spec.Scenario`.

Every problem in a file is collected and reported at once, one line each naming the file
and the dotted key (like FMPy's validators), as :class:`~twin.errors.ConfigErrors`. Each
table is checked by its own module: ``[scenario]`` by :mod:`~twin.config.scenario_table`,
``[fmu.*]`` by :mod:`~twin.config.fmus`, ``[connections]`` and ``[[delay]]`` by
:mod:`~twin.config.connections`, ``[input.*]`` by :mod:`~twin.config.inputs`, ``[[event]]``
by :mod:`~twin.config.events`; what a model declares comes from :mod:`twin.fmu.catalog`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from importlib.resources import files
from pathlib import Path
from types import MappingProxyType
from typing import Any

from twin.config.connections import check_inputs_fed, load_connections
from twin.config.durations import MAX_DURATION_NS, format_duration, parse_duration
from twin.config.events import FAULTS, load_events
from twin.config.experiment import Experiment
from twin.config.fmus import load_fmus
from twin.config.inputs import load_profiles
from twin.config.overrides import apply_overrides
from twin.config.reader import Problems, did_you_mean, read_toml, table
from twin.config.scenario_table import load_scenario_table
from twin.config.spec import FMUSpec, Parameter, Scenario
from twin.errors import ConfigError, ConfigErrors
from twin.fmu.catalog import shipped_folder

__all__ = [
    "FAULTS",
    "MAX_DURATION_NS",
    "apply_overrides",
    "check_not_installed_copy",
    "default_scenario_path",
    "find_scenario",
    "format_duration",
    "load_scenario",
    "load_scenario_data",
    "parse_duration",
    "read_scenario_data",
    "scenarios_dir",
    "shipped_scenarios",
]

#: the tables of a scenario file; "errormodel", "uncertainty" and "reference" are passed on as
#: written, and checked where they are used (twin.pipeline.prepare)
_TOP_KEYS = {
    "scenario",
    "fmu",
    "connections",
    "delay",
    "input",
    "event",
    "errormodel",
    "uncertainty",
    "reference",
}


def _check_periods(p: Problems, fmus: Sequence[FMUSpec], duration: int | None, start: int = 0) -> None:
    for f in fmus:
        if duration and duration > 0 and f.period_ns > 0 and duration % f.period_ns:
            p.add(f"fmu.{f.name}.period", f"{format_duration(f.period_ns)} does not divide scenario.duration")
        elif start > 0 and f.period_ns > 0 and start % f.period_ns:
            # the instance steps on its period's grid from 0: it would not step at the start
            p.add(f"fmu.{f.name}.period", f"{format_duration(f.period_ns)} does not divide scenario.start")


def load_scenario_data(data: dict[str, Any], source: str, base_dir: Path) -> Scenario:
    """Check an already-parsed scenario; raises :class:`ConfigErrors` listing every problem."""
    p = Problems(source)
    p.unknown_keys(data, _TOP_KEYS, "")
    sc = load_scenario_table(p, data, source)
    fmus = load_fmus(p, data, base_dir, sc.step_ns)
    on_grid = bool(sc.step_ns) and sc.start_ns % (sc.step_ns or 1) == 0  # else said of scenario.start
    _check_periods(p, fmus, sc.duration_ns, sc.start_ns if on_grid else 0)
    by_name = {f.name: f for f in fmus}
    connections = load_connections(p, data, by_name)
    profiles = load_profiles(p, data, by_name, connections)
    events = load_events(p, data, by_name, sc.duration_ns, connections, sc.start_ns)
    check_inputs_fed(p, data, fmus)
    errormodel = table(p, data, "errormodel")
    uncertainty, reference = table(p, data, "uncertainty"), table(p, data, "reference")

    if p.items:
        raise ConfigErrors(p.items)
    assert sc.step_ns is not None and sc.duration_ns is not None and sc.output_interval_ns is not None
    return Scenario(
        name=sc.name,
        description=sc.description,
        source_path=source,
        duration_ns=sc.duration_ns,
        step_ns=sc.step_ns,
        output_interval_ns=sc.output_interval_ns,
        seed=sc.seed,
        fmus=tuple(fmus),
        connections=tuple(connections),
        profiles=tuple(profiles),
        events=tuple(events),
        drift_window_ns=sc.drift_window_ns,
        wear_limit_mm=sc.wear_limit_mm,
        errormodel=MappingProxyType({k: Parameter(v) for k, v in errormodel.items()}),
        uncertainty=MappingProxyType(uncertainty),
        reference=MappingProxyType(reference),
        start_ns=sc.start_ns,
    )


def _merge(base: dict[str, Any], over: Mapping[str, Any], source: str, path: str = "") -> dict[str, Any]:
    """``over`` (a file) on top of ``base`` (what it extends), by the one merge rule of
    ``extends`` (docs/scenario-files.md):

    - tables merge key by key, whatever their keys (a parameter table holding a parameter
      named ``profile`` is a table like any other);
    - a parameter given as ``{ value, source }`` is one value: it replaces the base's whole,
      so a value never keeps the source of the value it replaced;
    - an input's profile (``[input.<fmu>.<variable>]``) that names another kind of profile
      replaces the base's whole: a sine does not inherit a constant's ``value``; the same kind
      merges key by key (a sine's amplitude alone changed);
    - arrays of tables (``[[delay]]``, ``[[event]]``) extend the base's; an entry with
      ``remove = true`` instead removes the base's entries that have every other value it
      gives (none matched: an error);
    - anything else (a value, an array of values such as ``parameter_files``) is replaced.

    A connection is removed by giving its output no input: ``"thermal.t_sensor" = []``.
    """
    out = dict(base)
    for k, v in over.items():
        key = f"{path}{k}"
        old = out.get(k)
        if isinstance(v, dict) and isinstance(old, dict) and not _replaces_whole(key, old, v):
            out[k] = _merge(old, v, source, key + ".")
        elif _array_of_tables(v) and (old is None or old == [] or _array_of_tables(old)):
            out[k] = _extend(old or [], v, source, key)
        else:
            out[k] = v
    return out


def _replaces_whole(key: str, old: Mapping[str, Any], new: Mapping[str, Any]) -> bool:
    """Whether ``new`` replaces ``old`` whole: a parameter's ``{ value, source }`` (the source
    goes with its value) or an input's profile of another kind (key ``input.a.b``)."""
    parts = key.split(".")
    if len(parts) == 4 and parts[0] == "fmu" and parts[2] == "parameters":
        return True
    return (
        len(parts) == 3
        and parts[0] == "input"
        and new.get("profile", old.get("profile")) != old.get("profile")
    )


def _array_of_tables(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(e, dict) for e in v)


def _extend(
    base: list[dict[str, Any]], over: list[dict[str, Any]], source: str, key: str
) -> list[dict[str, Any]]:
    """The base's entries, less those an entry with ``remove = true`` names, then the file's."""
    out = list(base)
    for i, entry in enumerate(over):
        if entry.get("remove") is not True:
            out.append(entry)
            continue
        named = {k: v for k, v in entry.items() if k != "remove"}
        kept = [e for e in out if not (named and all(e.get(k) == v for k, v in named.items()))]
        if len(kept) == len(out):
            raise ConfigError(
                f"removes nothing: no {key} of the file it extends has {_shown(named)}",
                source=source,
                key=f"{key}[{i}]",
            )
        out = kept
    return out


def _shown(named: Mapping[str, Any]) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in named.items()) or "(no key given)"


#: the longest ``extends`` chain (the shipped scenarios use 2 files)
MAX_EXTENDS = 16


def read_scenario_data(path: Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A scenario file's data with its ``extends`` chain resolved.

    ``extends = "base/tester-system.toml"`` (relative to the file) takes that file as the
    starting point; the file's own tables merge over it key by key. A base's
    ``parameter_files`` stay relative to the base. An SSP archive (``.ssp``) is read as
    :func:`twin.config.ssp.read_ssp_data` reads it.
    """
    if path.suffix == ".ssp":  # a system from another FMI tool: its FMUs run as external ones
        from twin.config.ssp import read_ssp_data

        return read_ssp_data(path)
    if path.suffix == ".fmu":  # one FMU alone, as fmpy simulates it
        from twin.config.single_fmu import read_fmu_data

        return read_fmu_data(path)
    data = read_toml(path, str(path))
    parent = data.pop("extends", None)
    if parent is None:
        return data
    if not isinstance(parent, str):
        raise ConfigError(f"expected a file name, got {parent!r}", source=str(path), key="extends")
    base_path = (path.resolve().parent / parent).resolve()
    if base_path in _seen or base_path == path.resolve():
        raise ConfigError(f"circular extends through {base_path.name}", source=str(path), key="extends")
    if len(_seen) >= MAX_EXTENDS:
        raise ConfigError(
            f"an extends chain longer than {MAX_EXTENDS} files", source=str(path), key="extends"
        )
    try:
        base = read_scenario_data(base_path, (*_seen, path.resolve()))
    except ConfigError as exc:
        if exc.source != str(base_path) or exc.key is not None:
            raise
        # the base itself cannot be read: say so where it is named
        raise ConfigError(f"{parent}: {exc.message}", source=str(path), key="extends") from None
    _anchor(base, base_path.parent)
    return _merge(base, data, str(path))


def _anchor(base: dict[str, Any], folder: Path) -> None:
    """A base's files (its parameter files, its coefficients file, its Monte Carlo's spreads)
    are named relative to the base's own folder: made absolute before a file extends it."""

    def absolute(name: Any) -> Any:
        return str((folder / name).resolve()) if isinstance(name, str) else name

    for spec in base.get("fmu", {}).values():
        if isinstance(spec, dict) and isinstance(spec.get("parameter_files"), list):
            spec["parameter_files"] = [absolute(f) for f in spec["parameter_files"]]
    for name, key in (("errormodel", "coefficients"), ("uncertainty", "spreads")):
        if isinstance(base.get(name), dict) and isinstance(base[name].get(key), str):
            base[name][key] = absolute(base[name][key])


def load_scenario(
    path: str | Path, overrides: Sequence[str] = (), experiment: Experiment | None = None
) -> Scenario:
    """Read (resolving ``extends``), override (``--set``, then the ``experiment``'s times: the
    command line's ``--start-time``, ``--stop-time``, ...) and check a scenario file (TOML, an
    SSP archive: :mod:`twin.config.ssp`, or one FMU: :mod:`twin.config.single_fmu`); the
    experiment's input file then drives the inputs it names."""
    path = Path(path)
    if path.suffix == ".ssp":
        from twin.config.ssp import discard_unpacked

        try:
            return _load_scenario(path, overrides, experiment)
        except ConfigError:
            discard_unpacked(path)  # a refused archive leaves no unpacked copy in the cache
            raise
    return _load_scenario(path, overrides, experiment)


def _load_scenario(path: Path, overrides: Sequence[str], experiment: Experiment | None) -> Scenario:
    data = read_scenario_data(path)
    apply_overrides(data, overrides, f"{path}: --set")
    if experiment is not None:
        experiment.set_times(data)
    if path.suffix == ".ssp":  # what an archive may leave to the command line (its step)
        from twin.config.ssp import finish_ssp_data

        finish_ssp_data(data, str(path))
    scenario = load_scenario_data(data, str(path), path.resolve().parent)
    return experiment.drive(scenario) if experiment is not None else scenario


def find_scenario(name: str | Path | None) -> Path:
    """The scenario a command names: a file (TOML, SSP or one FMU), or the name of a shipped scenario
    (``sine-load`` for ``scenarios/sine-load.toml``); none: the paper's experiment."""
    if name is None:
        return default_scenario_path()
    path = Path(name)
    if path.exists() or path.suffix in (".toml", ".ssp", ".fmu") or len(path.parts) > 1:
        return path  # a file (a missing one is reported by the loader, naming it)
    shipped = {p.stem: p for p in sorted(scenarios_dir().glob("*.toml"))}
    if str(name) in shipped:
        return shipped[str(name)]
    raise ConfigError(
        f"no scenario file or shipped scenario named {str(name)!r}{did_you_mean(str(name), shipped)} "
        "(`twin list` shows them)",
        source="scenario",
    )


def shipped_scenarios() -> list[tuple[str, Path, list[tuple[str, str]]]]:
    """The shipped scenarios and calibration experiments that describe themselves: (title,
    folder, [(name, description), ...]) of each group (``twin list``)."""
    folder = scenarios_dir()
    groups = [("scenarios", folder, ""), ("calibration experiments", folder / "calibration", "calibration/")]
    out = []
    for title, where, prefix in groups:
        rows = []
        for p in sorted(where.glob("*.toml")):
            desc = read_toml(p, str(p)).get("scenario", {})
            if isinstance(desc, dict) and "description" in desc:
                rows.append((prefix + (p.name if prefix else p.stem), str(desc["description"])))
        out.append((title, where, rows))
    return out


def default_scenario_path() -> Path:
    """The paper's thermal experiment: ``scenarios/li2017-thermal-experiment.toml``."""
    return scenarios_dir() / "li2017-thermal-experiment.toml"


def scenarios_dir() -> Path:
    """The shipped scenarios: package data of ``twin.config``, or ``scenarios/`` of the checkout."""
    candidates = shipped_folder("twin.config", "scenarios", "scenarios")
    return next((c for c in candidates if c.is_dir()), candidates[-1])


def installed_scenarios() -> Path | None:
    """The installed copy of the scenarios (package data of a plain ``pip install .``), or
    None when the twin runs from a checkout (an editable install reads the repository's)."""
    copy = files("twin.config") / "scenarios"
    return copy if isinstance(copy, Path) and copy.is_dir() else None


def check_not_installed_copy(target: Path, option: str, installed: Path | None = None) -> None:
    """Refuse to write ``target`` (a file, or a folder written into) when the write would land
    in the installed copy of the scenarios.

    A plain install runs its own copy of ``scenarios/``: a file written there is not the
    repository's, the next ``pip install .`` puts the old one back, and a command that then
    writes the clone (``twin identify --out scenarios/...``) would split a tester from its
    coefficients. A file is written by replacing it in its folder (:mod:`twin.files`), so a
    file that is a link lands where the link is, not where it points. ``installed`` defaults
    to :func:`installed_scenarios`.
    """
    copy = installed if installed is not None else installed_scenarios()
    if copy is None:
        return
    lands = target.resolve() if target.is_dir() else target.parent.resolve() / target.name
    if lands.is_relative_to(copy.resolve()):
        raise ConfigError(
            f"{target} is in the installed copy of the scenarios, not the repository's (the next "
            "`pip install .` would put it back): install with `pip install -e .` to write the "
            "repository's scenarios/",
            source=option,
        )
