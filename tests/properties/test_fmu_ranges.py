"""Property-based tests of every FMU's parameters and inputs against their declared ranges.

Issue 6, item 5. For every model folder in ``fmus/``:

* values inside the declared ``[min, max]`` never fail: a handful of parameters and all inputs
  drawn inside their ranges, then a few ``fmi2DoStep`` of the conformance case's step size give
  status OK and finite outputs. Parameter combinations that a model's own check refuses
  (``model_check``: trapezoid durations all zero, table times not increasing, probe range
  empty, heat shares not summing to 1, ...) are predicted here from the documented rules; such a
  rejection must be ``fmi2Error`` at ``fmi2ExitInitializationMode`` with the instance still in
  initialization mode (correcting the parameters lets it start);
* values outside the range, NaN and +-Inf for inputs and parameters make the set call fail with
  ``fmi2Error`` (fmpy's ``FMICallException``, status 3), log why, change nothing (not even the
  valid values of the same call), and leave the instance usable: a following valid set and
  ``fmi2DoStep`` succeed.

Each FMU is extracted once per module; every example instantiates it afresh.
"""

from __future__ import annotations

import contextlib
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
)
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from twin.fmu.build import model_names
from twin.fmu.slot import logging_callbacks

from ..fmus.cases import CASES

FMI2_ERROR = 3
#: where the XML declares no bound, a physical default
DEFAULT_BOUND = 1e6
#: fmi2DoStep calls per example (of the conformance case's step size)
N_STEPS = 3

COMMON = {
    "deadline": None,
    "derandomize": True,  # the same examples on every run and in CI
    "database": None,
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large],
}
VALID_EXAMPLES = 150
REFUSED_EXAMPLES = 50
INVALID_EXAMPLES = 150

MODELS = model_names()


# ----------------------------------------------------------------------------- model metadata


@dataclass(frozen=True, repr=False)
class Var:
    name: str
    vr: int
    type: str  # Real, Integer, Boolean
    causality: str
    lo: float
    hi: float
    start: Any

    def __repr__(self) -> str:
        return self.name

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:
        p.text(self.name)


@dataclass(repr=False)
class Model:
    name: str
    md: Any
    unzipdir: str
    variables: dict[str, Var] = field(default_factory=dict)

    def __repr__(self) -> str:  # hypothesis prints the fixture with a failing example
        return f"<{self.name}>"

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:
        p.text(repr(self))

    def of(self, causality: str) -> list[Var]:
        return [v for v in self.variables.values() if v.causality == causality]

    @property
    def real_outputs(self) -> list[Var]:
        return [v for v in self.of("output") if v.type == "Real"]


def _bound(value: Any, declared: Any, attr: str) -> float | None:
    if value is not None:
        return float(value)
    if declared is not None and getattr(declared, attr, None) is not None:
        return float(getattr(declared, attr))
    return None


def _start(v: Any) -> Any:
    if v.start is None:
        return None
    if v.type == "Boolean":
        return v.start in (True, "true", "1", 1)
    if v.type == "Integer":
        return int(v.start)
    return float(v.start)


def _load_model(name: str, fmu: Path, unzipdir: Path) -> Model:
    md = read_model_description(str(fmu))
    model = Model(name, md, extract(str(fmu), unzipdir=str(unzipdir)))
    for v in md.modelVariables:
        declared = getattr(v, "declaredType", None)
        lo = _bound(v.min, declared, "min")
        hi = _bound(v.max, declared, "max")
        model.variables[v.name] = Var(
            name=v.name,
            vr=v.valueReference,
            type=v.type,
            causality=v.causality,
            lo=lo if lo is not None else -DEFAULT_BOUND,
            hi=hi if hi is not None else DEFAULT_BOUND,
            start=_start(v),
        )
    return model


@pytest.fixture(scope="module")
def models(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Model]:
    """Every model extracted once for the whole module."""
    return {
        name: _load_model(name, fmu_paths[name], tmp_path_factory.mktemp(f"fmu-{name}")) for name in MODELS
    }


# ----------------------------------------------------------------------------- one FMU instance


class Instance:
    """A freshly instantiated co-simulation slave; keeps the FMU's log messages."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.log: list[str] = []
        self.time = 0.0
        #: every value a set call was accepted for (what the variables hold besides start values)
        self.known: dict[str, Any] = {}

        def log(status: int, category: str, message: str) -> None:
            self.log.append(f"[{status}] {message}")

        # the twin's shared callbacks: fmpy's logger proxy is process-global, and a second
        # registration freed with this instance would crash every later FMU that logs
        cb = logging_callbacks("prop", log)
        self.slave = FMU2Slave(
            guid=model.md.guid,
            unzipDirectory=model.unzipdir,
            modelIdentifier=model.md.coSimulation.modelIdentifier,
            instanceName="prop",
        )
        self.slave.instantiate(callbacks=cb)

    def set(self, values: dict[str, Any]) -> None:
        """Set values, one FMI call per type (all Reals in one fmi2SetReal, ...)."""
        by_type: dict[str, list[Var]] = {}
        for name in values:
            v = self.model.variables[name]
            by_type.setdefault(v.type, []).append(v)
        for typ, vs in by_type.items():
            vrs = [v.vr for v in vs]
            if typ == "Real":
                self.slave.setReal(vrs, [float(values[v.name]) for v in vs])
            elif typ == "Integer":
                self.slave.setInteger(vrs, [int(values[v.name]) for v in vs])
            else:
                self.slave.setBoolean(vrs, [values[v.name] for v in vs])
            self.known.update({v.name: values[v.name] for v in vs})

    def expected(self, names: list[str]) -> dict[str, Any]:
        """What ``get`` must return for ``names``: the last accepted value, else the start value."""
        out = {}
        for n in names:
            v = self.model.variables[n]
            value = self.known.get(n, v.start)
            out[n] = float(value) if v.type == "Real" else int(value)
        return out

    def errors_logged(self) -> list[str]:
        return [m for m in self.log if not m.startswith("[0]")]

    def get(self, names: list[str]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for typ, getter in (
            ("Real", self.slave.getReal),
            ("Integer", self.slave.getInteger),
            ("Boolean", self.slave.getBoolean),
        ):
            vs = [self.model.variables[n] for n in names if self.model.variables[n].type == typ]
            if vs:
                out.update(zip([v.name for v in vs], getter([v.vr for v in vs]), strict=True))
        return out

    def outputs(self) -> dict[str, float]:
        outs = self.model.real_outputs
        return dict(zip([v.name for v in outs], self.slave.getReal([v.vr for v in outs]), strict=True))

    def step(self, h: float) -> None:
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def close(self) -> None:
        # terminate is refused in initialization mode (an example may end there): free anyway
        with contextlib.suppress(FMICallException):
            self.slave.terminate()
        self.slave.freeInstance()


def expect_fmi_error(call: Callable[[], Any], what: str) -> None:
    """``call`` must fail with fmi2Error (not a crash, not another status, not success)."""
    try:
        call()
    except FMICallException as exc:
        assert exc.status == FMI2_ERROR, f"{what}: status {exc.status}, expected fmi2Error"
        return
    pytest.fail(f"{what}: accepted, expected fmi2Error")


def assert_finite(outputs: dict[str, float], when: str, inst: Instance) -> None:
    bad = {k: v for k, v in outputs.items() if not math.isfinite(v)}
    assert not bad, f"non-finite outputs {when}: {bad}\nlog: {inst.log}"


# ----------------------------------------------------------------------------- strategies


def value_in_range(v: Var) -> st.SearchStrategy[Any]:
    if v.type == "Boolean":
        return st.booleans()
    if v.type == "Integer":
        return st.integers(math.ceil(v.lo), math.floor(v.hi))
    return st.floats(v.lo, v.hi, allow_nan=False, allow_infinity=False)


def value_out_of_range(v: Var) -> st.SearchStrategy[Any]:
    """Values the FMU must refuse: outside [lo, hi], NaN, +-Inf; not a Boolean (0/1) for Booleans."""
    if v.type == "Boolean":
        return st.integers(-(2**31), 2**31 - 1).filter(lambda x: x not in (0, 1))
    if v.type == "Integer":
        lo, hi = math.ceil(v.lo), math.floor(v.hi)
        options = []
        if hi < 2**31 - 1:
            options.append(st.integers(hi + 1, 2**31 - 1))
        if lo > -(2**31):
            options.append(st.integers(-(2**31), lo - 1))
        return st.one_of(options)
    return st.one_of(
        st.sampled_from([math.nan, math.inf, -math.inf]),
        st.floats(min_value=v.hi, exclude_min=True, allow_infinity=False),
        st.floats(max_value=v.lo, exclude_max=True, allow_infinity=False),
    )


def solver_step_for(model: Model, case_step: float) -> st.SearchStrategy[float]:
    """An internal step the case's step is a whole multiple of (doStep refuses others)."""
    v = model.variables["solver_step"]
    ks = [k for k in range(1, 101) if v.lo <= case_step / k <= v.hi]
    return st.sampled_from(ks).map(lambda k: case_step / k)


def normalized_shares(names: list[str]) -> st.SearchStrategy[dict[str, float]]:
    """Fractions in [0, 1] that sum to 1 (ThermalNetwork's heat shares)."""

    @st.composite
    def draw(d: st.DrawFn) -> dict[str, float]:
        weights = d(st.lists(st.floats(0.0, 1.0), min_size=len(names), max_size=len(names)))
        j = d(st.integers(0, len(names) - 1))
        weights[j] = d(st.floats(0.01, 1.0))
        total = math.fsum(weights)
        return {n: w / total for n, w in zip(names, weights, strict=True)}

    return draw()


#: parameters with a dedicated strategy (the internal step must divide the case's step)
SPECIAL = {"solver_step", "q_avg_window"}
#: the fault injection input (issue 6, item 2): any value but 0 makes doStep fail on purpose
FAULT_INPUT = "fault_inject"


def physical_input(model: Model, v: Var) -> st.SearchStrategy[Any]:
    """An input value inside its range; the fault injector stays off."""
    return st.just(0.0) if v.name == FAULT_INPUT else value_in_range(v)


@st.composite
def valid_setup(d: st.DrawFn, model: Model) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(parameters, one input set per phase): a handful of parameters, every input, all in range."""
    case = CASES[model.name]
    params: dict[str, Any] = dict(case.parameters)
    plain = [v for v in model.of("parameter") if v.name not in SPECIAL]
    for v in d(st.lists(st.sampled_from(plain), unique_by=lambda v: v.name, max_size=6)):
        params[v.name] = d(value_in_range(v))
    if d(st.booleans()):
        params["solver_step"] = d(solver_step_for(model, case.step))
    if "q_avg_window" in model.variables and d(st.booleans()):
        h = params.get("solver_step", model.variables["solver_step"].start)
        w = model.variables["q_avg_window"]
        params["q_avg_window"] = d(
            st.one_of(st.integers(1, 200).map(lambda m: m * h), value_in_range(w)).filter(
                lambda x: w.lo <= x <= w.hi
            )
        )
    if model.name == "ThermalNetwork":
        for group in ("hyd_share_", "fric_share_"):
            if d(st.booleans()):
                names = [v.name for v in model.of("parameter") if v.name.startswith(group)]
                params.update(d(normalized_shares(names)))
    inputs = [
        {v.name: d(physical_input(model, v)) for v in model.of("input")} for _ in range(N_STEPS + 1)
    ]  # [0]: set in initialization mode; [k]: before step k
    return params, inputs


# ----------------------------------------------------------------------------- model rules


def _effective(model: Model, params: dict[str, Any]) -> dict[str, Any]:
    values = {v.name: v.start for v in model.of("parameter")}
    values.update(params)
    return values


# Each model's model_check as documented in its readme, on the effective parameters: True if it
# refuses them, False if it accepts them, None on the edge of a floating-point tolerance (either
# outcome is fine).


def _hydraulic_refuses(p: dict[str, Any]) -> bool | None:
    if p["profile"] == 2:
        return not (p["t_ramp_up"] + p["t_dwell_high"] + p["t_ramp_down"] + p["t_dwell_low"] > 0.0)
    if p["profile"] == 3:
        times = [p[f"table_t_{k}"] for k in range(1, p["table_n"] + 1)]
        return not all(b > a for a, b in itertools.pairwise(times))
    return False


def _oscillation_refuses(p: dict[str, Any]) -> bool | None:
    if not p["mu_min"] <= p["mu_max"]:
        return True
    h, w = p["solver_step"], p["q_avg_window"]
    n = math.floor(w / h + 0.5)
    err = abs(n * h - w)
    if n >= 1 and 0.5e-9 * w < err < 2e-9 * w:
        return None
    return n < 1.0 or err > 1e-9 * w


def _shares_off(p: dict[str, Any], group: str) -> bool | None:
    """Do the heat shares of one group miss a sum of 1 (summed as the C code does)?"""
    total = 0.0
    for name in p:  # the XML's (= the C code's node) order
        if name.startswith(group):
            total += p[name]
    off = abs(total - 1.0)
    return None if 0.5e-9 < off < 2e-9 else off > 1e-9


def _thermal_refuses(p: dict[str, Any]) -> bool | None:
    verdicts = [_shares_off(p, group) for group in ("hyd_share_", "fric_share_")]
    if True in verdicts:
        return True
    return None if None in verdicts else False


def _signal_source_refuses(p: dict[str, Any]) -> bool | None:
    """The active profile's durations positive, and no quantity its formula forms overflowing."""
    kind = p["profile"]
    if kind == 1:
        return not (p["duration"] > 0.0 and math.isfinite(p["end"] - p["start"]))
    if kind == 2:
        if not p["time_constant"] > 0.0:
            return True
        reached = -math.expm1(-p["rise_at"] / p["time_constant"])  # 0.0 when the ratio underflows
        scale = (1.0 / reached if reached else math.inf) if p["rise_at"] > 0.0 else 1.0
        return not (math.isfinite(p["rise"] * scale) and math.isfinite(p["start"] + p["rise"] * scale))
    if kind == 3:
        return not (p["period"] > 0.0 and math.isfinite(abs(p["mean"]) + abs(p["amplitude"])))
    if kind == 4:
        points = [(p[f"table_t_{k}"], p[f"table_v_{k}"]) for k in range(1, p["table_n"] + 1)]
        for (t0, v0), (t1, v1) in itertools.pairwise(points):
            if not t1 > t0 or not math.isfinite((v1 - v0) / (t1 - t0)):
                return True
    return False


MODEL_RULES: dict[str, Callable[[dict[str, Any]], bool | None]] = {
    "HydraulicLoader": _hydraulic_refuses,
    "SensorsDAQ": lambda p: not p["probe_range_min"] < p["probe_range_max"],
    "FixtureMechanics": lambda p: p["k_spring"] + p["k_head"] <= 0.0,
    "OscillationDrive": _oscillation_refuses,
    "ThermalNetwork": _thermal_refuses,
    "SignalSource": _signal_source_refuses,
}


def expected_rejection(model: Model, params: dict[str, Any]) -> bool | None:
    """Does the model's own check (documented in its readme) refuse these parameters?

    True/False; None on the edge of a floating-point tolerance (either outcome is fine).
    """
    rule = MODEL_RULES.get(model.name)
    return rule(_effective(model, params)) if rule else False


def test_every_model_has_its_rules() -> None:
    """A new model must get its model_check rules above (and a conformance case)."""
    known = {
        "HydraulicLoader",
        "SensorsDAQ",
        "FixtureMechanics",
        "OscillationDrive",
        "ThermalNetwork",
        "SignalSource",
    }
    assert set(MODELS) <= known, f"add the model_check rules of {sorted(set(MODELS) - known)}"
    assert set(MODELS) <= set(CASES)


# ----------------------------------------------------------------------------- (a) inside the ranges


@pytest.mark.parametrize("name", MODELS)
@settings(max_examples=VALID_EXAMPLES, **COMMON)
@given(data=st.data())
def test_values_in_range_step_ok_and_outputs_finite(name: str, models: dict[str, Model], data: Any) -> None:
    model = models[name]
    case = CASES[name]
    params, inputs = data.draw(valid_setup(model), label="parameters, inputs")
    inst = Instance(model)
    try:
        inst.slave.setupExperiment(startTime=0.0)
        inst.set(params)  # every value is in range: accepted in instantiated state
        inst.slave.enterInitializationMode()
        inst.set(inputs[0])
        rejected = expected_rejection(model, params)
        if rejected is False:  # initial unknowns: computed in initialization mode, finite too
            assert_finite(inst.outputs(), "in initialization mode", inst)
        try:
            inst.slave.exitInitializationMode()
            accepted = True
        except FMICallException as exc:
            assert exc.status == FMI2_ERROR, f"exitInitializationMode: status {exc.status}\n{inst.log}"
            accepted = False
        event("started" if accepted else "refused by the model check")
        if rejected is not None:
            assert accepted != rejected, (
                f"model check {'accepted' if accepted else 'refused'} {params}; "
                f"the documented rule says the opposite\nlog: {inst.log}"
            )
        if not accepted:
            assert any("invalid parameters" in m for m in inst.log), inst.log
            # still in initialization mode: the host may correct the parameters and go on
            baseline = {k: v for k, v in _effective(model, dict(case.parameters)).items() if k in params}
            inst.set(baseline)
            inst.slave.exitInitializationMode()
        assert_finite(inst.outputs(), "after initialization", inst)
        for k in range(1, N_STEPS + 1):
            inst.set(inputs[k])
            inst.step(case.step)  # raises FMICallException on any status but OK/warning
            assert_finite(inst.outputs(), f"after step {k}", inst)
        if accepted:
            assert not inst.errors_logged(), inst.log
    finally:
        inst.close()


@pytest.mark.parametrize("name", MODELS)
@settings(max_examples=REFUSED_EXAMPLES, **COMMON)
@given(data=st.data())
def test_model_check_rejection_keeps_initialization_mode(
    name: str, models: dict[str, Model], data: Any
) -> None:
    """Parameters each in range but refused together by the model: fmi2Error, instance still in
    initialization mode (doStep refused as such), outputs never handed out; a correction starts it."""
    model = models[name]
    case = CASES[name]
    bad = data.draw(refused_combination(model), label="refused parameters")
    if bad is None:
        return  # this model has no cross-parameter rule
    inst = Instance(model)
    try:
        inst.slave.setupExperiment(startTime=0.0)
        inst.set({**case.parameters, **bad})
        inst.slave.enterInitializationMode()
        inst.set(case.inputs)
        expect_fmi_error(inst.slave.exitInitializationMode, f"exitInitializationMode with {bad}")
        assert any("invalid parameters" in m for m in inst.log), inst.log
        expect_fmi_error(lambda: inst.slave.getReal([model.real_outputs[0].vr]), "getReal of an output")
        expect_fmi_error(lambda: inst.step(case.step), "doStep in initialization mode")
        assert any("not allowed in state 'initialization mode'" in m for m in inst.log), inst.log
        inst.time = 0.0
        baseline = _effective(model, dict(case.parameters))
        inst.set({k: baseline[k] for k in bad})
        inst.slave.exitInitializationMode()
        inst.step(case.step)
        assert_finite(inst.outputs(), "after the corrected start", inst)
    finally:
        inst.close()


@st.composite
def refused_combination(d: st.DrawFn, model: Model) -> dict[str, Any] | None:
    """In-range parameter values that break the model's documented cross-parameter rule."""
    r = model.variables
    if model.name == "HydraulicLoader":
        if d(st.booleans()):
            return {
                "profile": 2,
                **{n: 0.0 for n in ("t_ramp_up", "t_dwell_high", "t_ramp_down", "t_dwell_low")},
            }
        n = d(st.integers(2, 8))
        times = d(st.lists(value_in_range(r["table_t_1"]), min_size=n, max_size=n))
        k = d(st.integers(1, n - 1))
        times[k] = d(st.floats(r["table_t_1"].lo, times[k - 1]))  # not after its predecessor
        return {"profile": 3, "table_n": n, **{f"table_t_{i + 1}": t for i, t in enumerate(times)}}
    if model.name == "SensorsDAQ":
        lo = d(value_in_range(r["probe_range_min"]))
        return {"probe_range_min": lo, "probe_range_max": d(st.floats(r["probe_range_max"].lo, lo))}
    if model.name == "FixtureMechanics":
        return {"k_spring": 0.0, "k_head": 0.0}
    if model.name == "OscillationDrive":
        if d(st.booleans()):
            hi = d(st.floats(0.0, 0.99))
            return {"mu_max": hi, "mu_min": d(st.floats(hi, 1.0, exclude_min=True))}
        h = r["solver_step"].start
        m = d(st.integers(1, 1000))
        return {"q_avg_window": (m + d(st.floats(0.01, 0.99))) * h}
    if model.name == "ThermalNetwork":
        group = d(st.sampled_from(["hyd_share_", "fric_share_"]))
        names = [v.name for v in model.of("parameter") if v.name.startswith(group)]
        shares = d(
            st.lists(st.floats(0.0, 1.0), min_size=len(names), max_size=len(names)).filter(
                lambda s: abs(math.fsum(s) - 1.0) > 1e-6
            )
        )
        return dict(zip(names, shares, strict=True))
    if model.name == "SignalSource":
        if d(st.booleans()):
            kind, name = d(st.sampled_from([(1, "duration"), (2, "time_constant"), (3, "period")]))
            return {"profile": kind, name: 0.0}
        n = d(st.integers(2, 64))
        times = d(st.lists(value_in_range(r["table_t_1"]), min_size=n, max_size=n))
        k = d(st.integers(1, n - 1))
        times[k] = d(st.floats(r["table_t_1"].lo, times[k - 1]))  # not after its predecessor
        return {"profile": 4, "table_n": n, **{f"table_t_{i + 1}": t for i, t in enumerate(times)}}
    return None


# ----------------------------------------------------------------------------- (b) outside the ranges


@st.composite
def invalid_set(d: st.DrawFn, model: Model) -> tuple[str, Var, Any, dict[str, Any]]:
    """(phase, variable, bad value, valid companions set in the same call)."""
    phase = d(st.sampled_from(["instantiated", "initialization", "step complete"]))
    settable = model.of("input") + ([] if phase == "step complete" else model.of("parameter"))
    # the kind first (input/parameter x Real/Integer/Boolean), so the few Integers and Booleans
    # are drawn as often as the many Reals
    kinds = sorted({(v.causality, v.type) for v in settable})
    kind = d(st.sampled_from(kinds))
    target = d(st.sampled_from([v for v in settable if (v.causality, v.type) == kind]))
    bad = d(value_out_of_range(target), label="bad value")
    same_type = [v for v in settable if v.type == target.type and v.name not in (target.name, FAULT_INPUT)]
    if model.name == "OscillationDrive":  # a companion must not break the q_avg_window rule
        same_type = [v for v in same_type if v.name not in SPECIAL]
    companions = (
        d(st.lists(st.sampled_from(same_type), unique_by=lambda v: v.name, max_size=3)) if same_type else []
    )
    return phase, target, bad, {v.name: d(value_in_range(v)) for v in companions}


@pytest.mark.parametrize("name", MODELS)
@settings(max_examples=INVALID_EXAMPLES, **COMMON)
@given(data=st.data())
def test_values_out_of_range_give_fmi2error_and_instance_stays_usable(
    name: str, models: dict[str, Model], data: Any
) -> None:
    model = models[name]
    case = CASES[name]
    phase, target, bad, companions = data.draw(invalid_set(model), label="invalid set")
    event(f"{target.causality} {target.type} in {phase}")
    inst = Instance(model)
    try:
        inst.slave.setupExperiment(startTime=0.0)
        inst.set(case.parameters)
        if phase != "instantiated":
            inst.slave.enterInitializationMode()
            inst.set(case.inputs)
        if phase == "step complete":
            inst.slave.exitInitializationMode()
            inst.step(case.step)
        names = [target.name, *companions]
        before = inst.expected(names)
        # the whole call is refused: the bad value and its valid companions in one fmi2Set*
        n_log = len(inst.log)
        expect_fmi_error(lambda: inst.set({**companions, target.name: bad}), f"set {target.name} = {bad!r}")
        why = " ".join(inst.log[n_log:])
        assert target.name in why and any(
            s in why for s in ("outside its range", "not finite", "not a Boolean")
        ), f"the FMU must log why it refused {target.name} = {bad!r}: {inst.log[n_log:]}"
        if phase == "instantiated":  # no get before initialization mode
            inst.slave.enterInitializationMode()
        got = inst.get(names)
        assert got == before, f"a refused call changed values: {got} != {before}"
        # still usable: a valid set of the same variable is accepted, and the run goes on
        valid = data.draw(physical_input(model, target), label="valid value")
        inst.set({target.name: valid, **companions})
        if phase != "step complete":
            # valid companions may break a cross-parameter rule of the model: start from the case
            baseline = _effective(model, dict(case.parameters))
            inst.set({n: baseline[n] for n in names if n in baseline})
            inst.set(case.inputs if phase == "instantiated" else {})
            inst.slave.exitInitializationMode()
        for _ in range(2):
            inst.step(case.step)
            assert_finite(inst.outputs(), "after the refused set", inst)
    finally:
        inst.close()


# ----------------------------------------------------------------------------- regressions

RESOLUTIONS = (
    "temp_resolution",
    "probe_resolution",
    "load_resolution",
    "torque_resolution",
    "encoder_resolution",
)


@pytest.mark.parametrize("resolution", RESOLUTIONS)
def test_sensors_daq_finest_resolution_keeps_outputs_finite(
    resolution: str, models: dict[str, Model]
) -> None:
    """Found by the in-range property: quantize(x, q) = q * round(x / q) overflowed to Inf for a
    resolution in (0, ~1e-300], inside the declared [0, ...]; the outputs were Inf with status OK
    after initialization and doStep then failed."""
    model = models["SensorsDAQ"]
    case = CASES["SensorsDAQ"]
    inst = Instance(model)
    try:
        inst.slave.setupExperiment(startTime=0.0)
        inst.set({**case.parameters, resolution: 5e-324})  # the smallest positive double
        inst.slave.enterInitializationMode()
        inst.set({**case.inputs, "load_true": 1e7, "torque_true": 1e6, "angle_true": 7.0})
        assert_finite(inst.outputs(), "in initialization mode", inst)
        inst.slave.exitInitializationMode()
        assert_finite(inst.outputs(), "after initialization", inst)
        inst.step(case.step)
        assert_finite(inst.outputs(), "after a step", inst)
    finally:
        inst.close()
