"""An updated tester file: one physical tester as ``twin update`` learnt it from its lab's
records, the file ``twin run``, ``twin compensate`` and ``twin identify`` take (``--tester``).

A digital twin is the twin of one asset. The prior file (``scenarios/base/priors.toml``) says
what is not known of any tester as built; an update from one tester's records narrows that to
a posterior. The tester file keeps what the other commands need of it:

::

    [tester]
    name = "li2017-updated"
    record = "li2017.toml"                   # the record it was updated from
    record_sha256 = "..."                    # that record, its scenario file, the prior file
    scenario_sha256 = "..."                  #   and the FMU sources as they were: a changed
    prior_sha256 = "..."                     #   one makes the file stale (twin update --write
    fmu_sources = { ThermalNetwork = "..." } #   renews it)
    coefficients = "../calibration/identified-li2017-updated.toml"  # optional: the error
                                             #   model's, identified on the updated tester
    source = "twin update ..."

    [tester.diagnostics]                     # the update's own: R-hat, ESS, the discrepancy
    r_hat_max = 1.004

    [values]                                 # the updated twin's point: posterior means
    "fmu.mechanics.parameters.alpha_frame" = 1.21e-05

    [posterior]                              # evenly thinned posterior draws, one row each
    names = ["fmu.mechanics.parameters.alpha_frame", ...]
    draws = [[1.2e-05, ...], ...]

A run of the updated tester sets ``[values]``; its uncertainty's updated prediction draws its
rows from ``[posterior]`` (the inputs the update held, such as the thermal network and the
room, are drawn from the prior file as before: they stand for the update's discrepancy).
Reading it executes nothing (TOML), and every problem is reported at once, one line each.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.reader import Problems, read_toml
from twin.config.spec import Scenario
from twin.errors import ConfigError
from twin.files import write_text_atomic
from twin.uncertainty.testers import instance_of

__all__ = ["UpdatedTester", "file_sha256", "load_updated", "write_updated"]

_TOP = {"tester", "values", "posterior"}
_TESTER = {
    "name",
    "record",
    "record_sha256",
    "scenario_sha256",
    "prior_sha256",
    "fmu_sources",
    "coefficients",
    "source",
    "diagnostics",
}
_POSTERIOR = {"names", "draws", "source"}


@dataclass(frozen=True)
class UpdatedTester:
    """A checked tester file (see the module)."""

    path: Path
    name: str
    values: Mapping[str, float]
    names: tuple[str, ...] = ()
    draws: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    coefficients: Path | None = None
    stamps: Mapping[str, Any] = field(default_factory=dict)

    def draw(self, i: int) -> dict[str, float]:
        """Posterior draw ``i`` by key."""
        return {n: float(v) for n, v in zip(self.names, self.draws[i], strict=True)}

    def overrides(self, scenario: Scenario | None = None, *, coefficients: bool = True) -> list[str]:
        """The tester as ``--set KEY=VALUE`` strings: ``[values]`` (those of the instances
        ``scenario`` has, when given) and its coefficients file as the error model's (a
        scenario without an error model, ``evaluate = false``, takes none)."""
        instances = None if scenario is None else {f.name for f in scenario.fmus}
        out = [
            f"{k}={v!r}" for k, v in self.values.items() if instances is None or instance_of(k) in instances
        ]
        evaluated = (
            scenario is None
            or scenario.errormodel.get("evaluate") is None
            or bool(scenario.errormodel["evaluate"].value)
        )
        if coefficients and self.coefficients is not None and evaluated:
            out.append(f"errormodel.coefficients={json.dumps(str(self.coefficients))}")
        return out

    def check_against(self, scenario: Scenario) -> None:
        """Refuse (one line each, at once, said of this file) a key of an instance ``scenario``
        has but whose parameter it does not (a tester file of another twin), a value or a
        posterior draw outside its parameter's physical range (else every updated sample would
        fail), and a tester none of whose values ``scenario`` has (it would run the nominal
        twin as if it were the tester). Keys of instances the scenario lacks are left out when
        applied (the probe's bench has no frame)."""
        p = Problems(str(self.path))
        instances = {f.name for f in scenario.fmus}
        for where, keys in (("values", self.values), ("posterior.names", self.names)):
            for key in keys:
                if instance_of(key) in instances and scenario.nominal(key) is None:
                    p.add(f'{where}."{key}"', f"{scenario.name} has no such parameter")
        if self.values and not any(instance_of(k) in instances for k in self.values):
            p.add("values", f"none is of an FMU instance of {scenario.name} ({', '.join(sorted(instances))})")
        p.check()
        for key, value in self.values.items():
            _in_range(p, scenario, f'values."{key}"', key, value)
        for k, key in enumerate(self.names):
            column = self.draws[:, k]
            if len(column):  # its extremes: the range is an interval
                _in_range(p, scenario, f'posterior.draws (column "{key}")', key, column.min(), column.max())
        p.check()


def _in_range(p: Problems, scenario: Scenario, where: str, key: str, *values: float) -> None:
    """Whether ``scenario`` takes ``values`` of ``key`` (a key of an instance it lacks: left out)."""
    if instance_of(key) not in {f.name for f in scenario.fmus}:
        return
    for value in values:
        try:
            scenario.with_value(key, float(value))
        except ConfigError as exc:
            p.add(where, exc.message or str(exc))
            return


def file_sha256(path: Path) -> str:
    """The file's SHA-256 (hex): what a tester file stamps of its record and prior."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_updated(path: Path, source: str = "--tester", *, coefficients: bool = True) -> UpdatedTester:
    """The tester file at ``path``, checked (every problem at once, one line each);
    ``coefficients=False``: its coefficients file need not exist yet (``twin identify
    --tester`` is what writes it)."""
    if not Path(path).is_file():
        raise ConfigError(f"no such tester file {str(path)!r}", source=source)
    raw = read_toml(Path(path), str(path))
    if "values" not in raw and set(raw) - _TOP:
        # another kind of file (a record, a scenario): one line, not one per table
        others = ", ".join(f"[{k}]" for k in sorted(set(raw) - _TOP))
        raise ConfigError(
            f"not an updated tester file (it has {others}; twin update writes one: [tester], [values], [posterior])",
            source=str(path),
        )
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP, "")
    tester, values, posterior = p.table(raw, "tester"), p.table(raw, "values"), p.table(raw, "posterior")
    p.unknown_keys(tester, _TESTER, "tester.")
    p.unknown_keys(posterior, _POSTERIOR, "posterior.")
    name = tester.get("name")
    if not isinstance(name, str) or not name:
        p.add("tester.name", "expected the tester's name")
    if not values:
        p.add("values", "expected the updated values (key = number)")
    checked = {str(k): _value(p, f'values."{k}"', v) for k, v in values.items()}
    for key in checked:
        if instance_of(key) is None or len(key.split(".")) != 4:
            p.add(f'values."{key}"', "expected fmu.<instance>.parameters.<name>")
    named = None
    if "coefficients" in tester:
        spec = tester["coefficients"]
        named = (Path(path).resolve().parent / str(spec)).resolve()
        if not isinstance(spec, str) or (coefficients and not named.is_file()):
            p.add("tester.coefficients", f"no such coefficients file {spec!r}")
        elif not named.is_file():
            named = None
    names, draws = _posterior(p, posterior, checked)
    p.check()
    stamps = {
        k: tester[k]
        for k in ("record", "record_sha256", "scenario_sha256", "prior_sha256", "fmu_sources", "diagnostics")
        if k in tester
    }
    return UpdatedTester(Path(path), str(name), checked, names, draws, named, stamps)


def _value(p: Problems, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        p.add(key, f"expected a finite number, got {v!r}")
        return math.nan
    return float(v)


def _posterior(
    p: Problems, table: Mapping[str, Any], values: Mapping[str, float]
) -> tuple[tuple[str, ...], np.ndarray]:
    """``[posterior]``: its names (each one of ``[values]``) and draws (rows of finite numbers)."""
    if not table:
        return (), np.empty((0, 0))
    names = table.get("names")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        p.add("posterior.names", "expected a list of the values' keys")
        return (), np.empty((0, 0))
    for n in names:
        if n not in values:
            p.add("posterior.names", f"{n!r} is not in [values]")
    draws = table.get("draws")
    ok = (
        isinstance(draws, list) and draws and all(isinstance(r, list) and len(r) == len(names) for r in draws)
    )
    if not ok:
        p.add("posterior.draws", f"expected a list of rows of {len(names)} numbers (one per name)")
        return tuple(names), np.empty((0, len(names)))
    # numbers only: numpy would take "1e-5" and true as numbers
    numbers = all(isinstance(x, (int, float)) and not isinstance(x, bool) for r in draws for x in r)
    array = np.array(draws, dtype=float) if numbers else np.full((1, 1), np.nan)
    if not np.all(np.isfinite(array)):
        p.add("posterior.draws", "expected finite numbers (no strings, booleans, nan or inf)")
    return tuple(names), array


def write_updated(
    path: Path,
    head: Mapping[str, Any],
    values: Mapping[str, float],
    draws: tuple[Sequence[str], np.ndarray],
    comment: str = "",
) -> Path:
    """Write a tester file (``head`` is its ``[tester]`` table); returns its path. Never
    through a link (:func:`twin.files.write_text_atomic`)."""
    import tomli_w

    names, rows = draws
    data = {
        "tester": dict(head),
        "values": {k: float(v) for k, v in values.items()},
        "posterior": {"names": list(names)},
    }
    header = "".join(f"# {line}\n".replace("# \n", "#\n") for line in comment.splitlines())
    # the draws one row per line, to 7 significant digits (what a float32 keeps, more than any
    # parameter is known to): tomli_w would give each number a line of its own
    table = ",\n".join("  [" + ", ".join(f"{float(x):.7g}" for x in r) + "]" for r in rows)
    return write_text_atomic(Path(path), header + tomli_w.dumps(data) + f"draws = [\n{table},\n]\n")
