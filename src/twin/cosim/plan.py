"""The static plan of a run: which instance steps when, what feeds each input, what is recorded.

Built once from the :class:`~twin.config.spec.Scenario` by :func:`make_plan`, without loading
any FMU: it reads each model's ``modelDescription.xml`` (value references, outputs, start
values, units) and resolves every "instance.variable" name to indices, so the loops, the
events and the checkpoint work on indices only. This is the master's counterpart of
libcosim's ``system_structure``: the checked, resolved description of the system.

Each input of an instance is of one :class:`InputKind`: fed by a connection (the visible
output of another instance at the same exchange), by a delayed connection (that output one
exchange late, its declared initial value first), or driven by a function of time (a
profile, or its start value until a set/ramp event changes it). Driven inputs are numbered
across the whole plan: they are the columns of the driven matrix the master evaluates for a
batch of ticks at once.

The plan also holds what the FMUs' ``<ModelStructure>`` says of the connections
(:mod:`twin.config.loops`): the algebraic loops the master iterates at each communication
point (:attr:`Plan.loops`), and the order in which initialization sets inputs and reads
outputs, variable by variable (:attr:`Plan.init_stages`).
"""

from __future__ import annotations

import dataclasses
import marshal
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, TypeVar

from twin.config.loops import Cycle, check_loops, initialization_stages
from twin.config.spec import NS_PER_S, Connection, Event, FMUSpec, ParameterValue, Scenario
from twin.errors import ConfigError
from twin.fmu.catalog import roles as model_roles
from twin.fmu.catalog import variables as model_variables
from twin.seeds import instance_seed
from twin.signals.table import Signal as SignalMeta

#: ticks per batch at most: bounds the driven matrix and the row buffer (memory flat in run length)
BATCH_TICKS = 32_768

#: how often a run reports its progress: at every hundredth of its ticks
PROGRESS_MARKS = 100

#: how a driven column is driven: ("constant", v), ("profile", index in scenario.profiles) or
#: ("ramp", v0, v1, t0_s, duration_s); data, not a function, so that a checkpoint can keep it
DrivenSpec = tuple[Any, ...]


class InputKind(IntEnum):
    """What feeds an input (the values are shared with ``native/stepper.c``)."""

    CONNECTION = 0
    DELAYED = 1
    DRIVEN = 2


class ColumnKind(IntEnum):
    """What a recorded column shows (the values are shared with ``native/stepper.c``)."""

    OUTPUT = 0  # the visible value of an output (its bias included)
    INPUT = 1  # the value last set on a driven input


@dataclass(frozen=True)
class PlannedInput:
    """One input of an instance.

    ``src`` is the source instance (connection, delayed) or the driven column (driven); ``idx``
    the output index in the source instance; ``initial`` the value the input holds before the
    first exchange (a delayed connection's initial value, a driven input's start value). A
    connection gives ``factor * output + offset`` (:class:`~twin.config.spec.Connection`).
    """

    name: str
    vr: int
    kind: InputKind
    src: int
    idx: int
    initial: float
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class PlannedInstance:
    """One FMU instance: its model, its period, its Real outputs and the inputs it is given."""

    index: int
    name: str
    model: str
    period_ns: int
    period_ticks: int
    outputs: tuple[str, ...]
    out_vrs: tuple[int, ...]
    inputs: tuple[PlannedInput, ...]
    #: set after fmi2SetupExperiment, in this order (a generated noise seed first)
    parameters: tuple[tuple[str, ParameterValue], ...]

    @property
    def in_names(self) -> list[str]:
        return [i.name for i in self.inputs]


@dataclass(frozen=True)
class PlannedEvent:
    """A scenario event resolved to indices.

    ``index`` is the output index (bias) or the input index (set, ramp) in ``instance``;
    ``column`` the driven column a set or ramp changes (-1 for a bias).
    """

    at_ns: int
    action: str
    instance: int
    index: int
    column: int
    value: float
    duration_ns: int


#: a variable resolved to indices: (instance, index in its inputs or in its outputs)
VarIndex = tuple[int, int]


@dataclass(frozen=True)
class PlannedLoop:
    """An algebraic loop (a cycle through direct feedthrough, :class:`twin.config.loops.Cycle`)
    resolved to indices: the inputs and outputs on it, and its name for a message."""

    name: str
    inputs: tuple[VarIndex, ...]
    outputs: tuple[VarIndex, ...]

    @property
    def instances(self) -> tuple[int, ...]:
        return tuple(sorted({i for i, _ in self.inputs + self.outputs}))


@dataclass(frozen=True)
class PlannedStage:
    """One stage of initialization (:class:`twin.config.loops.InitStage`): its inputs are set,
    its outputs read, each of its cycles iterated."""

    inputs: tuple[VarIndex, ...]
    outputs: tuple[VarIndex, ...]
    cycles: tuple[PlannedLoop, ...]


@dataclass(frozen=True)
class Column:
    """One recorded column: an output's visible value or a driven input's value."""

    instance: int
    kind: ColumnKind
    idx: int
    meta: SignalMeta


@dataclass(frozen=True)
class Plan:
    """Everything about a run that does not change while it runs."""

    scenario: Scenario
    instances: tuple[PlannedInstance, ...]
    #: how each driven column is driven when the run starts
    driven: tuple[DrivenSpec, ...]
    columns: tuple[Column, ...]
    events: tuple[PlannedEvent, ...]
    #: the algebraic loops, each after those it depends on, solved at every communication point
    loops: tuple[PlannedLoop, ...] = ()
    #: initialization, variable by variable: inputs set as soon as their sources are read
    init_stages: tuple[PlannedStage, ...] = ()

    @property
    def step_ns(self) -> int:
        return self.scenario.step_ns

    @property
    def n_ticks(self) -> int:
        """The tick the run ends at (tick k is at ``k * step``: the scenario's clock from 0)."""
        return self.scenario.duration_ns // self.scenario.step_ns

    @property
    def start_tick(self) -> int:
        """The tick the run begins at: 0, or ``scenario.start`` (a run that begins later)."""
        return self.scenario.start_ns // self.scenario.step_ns

    @property
    def out_every(self) -> int:
        """Ticks between two recorded rows."""
        return self.scenario.output_interval_ns // self.scenario.step_ns

    def column_names(self) -> set[str]:
        """The names of every recorded column."""
        return {c.meta.name for c in self.columns}

    def role_columns(self, role: str) -> list[str]:
        """The recorded outputs that play ``role`` for the twin (:func:`twin.fmu.catalog.roles`:
        the swing-cycle counter, a body's true thermal displacement), one per instance whose
        model has it; a model is never named."""
        out = []
        for inst in self.instances:
            variable = model_roles(inst.model).get(role)
            if variable is not None and variable in inst.outputs:
                out.append(f"{inst.name}.{variable}")
        return out

    def roles(self, roles: Sequence[str]) -> dict[str, str]:
        """The recorded column that plays each of ``roles`` (the first instance's that has
        it); a role no instance has is left out."""
        out = {}
        for role in roles:
            columns = self.role_columns(role)
            if columns:
                out[role] = columns[0]
        return out

    def progress_ticks(self) -> list[int]:
        """The ticks after which the run reports its progress (the last one is the end)."""
        k0, n = self.start_tick, self.n_ticks
        return sorted({k0 + (n - k0) * j // PROGRESS_MARKS for j in range(1, PROGRESS_MARKS + 1)})

    def batch_limit_ticks(self) -> range:
        """The ticks a batch never runs past, so that its buffers stay bounded."""
        return range(BATCH_TICKS, self.n_ticks, BATCH_TICKS)

    def checkpoint_ticks(self, every_ns: int | None) -> range:
        """The ticks a checkpoint is taken at (never at the end: the run is complete then)."""
        every = (every_ns or 0) // self.step_ns
        return range(every, self.n_ticks, every) if every > 0 else range(0)


def _real_outputs(model: str) -> tuple[str, ...]:
    variables = model_variables(model)
    return tuple(n for n, v in variables.items() if v.causality == "output" and v.type == "Real")


def _input_names(scenario: Scenario, instance: str) -> list[str]:
    """Every input something feeds or drives: connections, profiles, set and ramp events."""
    targets = [c.dst for c in scenario.connections] + [p.target for p in scenario.profiles]
    targets += [e.target for e in scenario.events if e.action != "bias"]
    return sorted({t.split(".")[1] for t in targets if t.split(".")[0] == instance})


class _Builder:
    """Resolves the scenario's names to indices, numbering the driven columns as it goes."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.index = {f.name: i for i, f in enumerate(scenario.fmus)}
        self.outputs = {f.name: _real_outputs(f.model) for f in scenario.fmus}
        self.feeds: dict[str, Connection] = {c.dst: c for c in scenario.connections}
        self.profiles = {p.target: n for n, p in enumerate(scenario.profiles)}
        self.driven: list[DrivenSpec] = []

    def input(self, target: str, variables: Mapping[str, Any]) -> PlannedInput:
        name = target.split(".")[1]
        vr = int(variables[name].value_reference)
        c = self.feeds.get(target)
        if c is not None:
            src, out = c.src.split(".")
            kind = InputKind.DELAYED if c.delay else InputKind.CONNECTION
            initial = float(c.initial or 0.0) if c.delay else 0.0
            idx = self.outputs[src].index(out)
            return PlannedInput(name, vr, kind, self.index[src], idx, initial, c.factor, c.offset)
        start = variables[name].start
        initial = float(start) if start is not None else 0.0
        profile = self.profiles.get(target)
        self.driven.append(("constant", initial) if profile is None else ("profile", profile))
        return PlannedInput(name, vr, InputKind.DRIVEN, len(self.driven) - 1, 0, initial)

    def instance(self, i: int, spec: FMUSpec) -> PlannedInstance:
        variables = model_variables(spec.model)
        params: list[tuple[str, ParameterValue]] = [(n, p.value) for n, p in spec.parameters.items()]
        if "seed" in variables and "seed" not in spec.parameters:
            params.insert(0, ("seed", instance_seed(self.scenario.seed, i)))
        outputs = self.outputs[spec.name]
        return PlannedInstance(
            index=i,
            name=spec.name,
            model=spec.model,
            period_ns=spec.period_ns,
            period_ticks=spec.period_ns // self.scenario.step_ns,
            outputs=outputs,
            out_vrs=tuple(int(variables[n].value_reference) for n in outputs),
            inputs=tuple(
                self.input(f"{spec.name}.{n}", variables) for n in _input_names(self.scenario, spec.name)
            ),
            parameters=tuple(params),
        )

    def event(self, e: Event, instances: Sequence[PlannedInstance]) -> PlannedEvent:
        step = self.scenario.step_ns
        if e.at_ns % step:
            raise ConfigError(
                f"an event at {e.at_ns / NS_PER_S:g} s is not on the step grid ({step / NS_PER_S:g} s)",
                source=self.scenario.source_path,
                key="event",
            )
        name, var = e.target.split(".")
        inst = instances[self.index[name]]
        if e.action == "bias":
            return PlannedEvent(e.at_ns, "bias", inst.index, inst.outputs.index(var), -1, e.value, 0)
        k = inst.in_names.index(var)
        if inst.inputs[k].kind != InputKind.DRIVEN:
            raise ConfigError(
                f"{e.action} needs a free input, {e.target} is fed by a connection", key="event"
            )
        return PlannedEvent(e.at_ns, e.action, inst.index, k, inst.inputs[k].src, e.value, e.duration_ns)


def _columns(instances: Sequence[PlannedInstance], scenario: Scenario) -> tuple[Column, ...]:
    """Every output of every instance, then its driven inputs, instance by instance; each in
    its unit (the scenario's, where it gives one to a variable its FMU declares none for)."""
    cols = []
    for inst in instances:
        variables = model_variables(inst.model)
        spec = scenario.fmus[inst.index]

        def meta(
            name: str, inst: PlannedInstance = inst, variables: Any = variables, spec: Any = spec
        ) -> SignalMeta:
            v = variables[name]
            return SignalMeta(f"{inst.name}.{name}", spec.unit(name), inst.name, v.description or "")

        cols += [Column(inst.index, ColumnKind.OUTPUT, k, meta(n)) for k, n in enumerate(inst.outputs)]
        cols += [
            Column(inst.index, ColumnKind.INPUT, k, meta(i.name))
            for k, i in enumerate(inst.inputs)
            if i.kind == InputKind.DRIVEN
        ]
    return tuple(cols)


class _Resolver:
    """Names of variables on loops and initialization stages, resolved to indices."""

    def __init__(self, instances: Sequence[PlannedInstance]) -> None:
        self.by_name = {inst.name: inst for inst in instances}

    def input(self, ref: str) -> VarIndex:
        inst, var = ref.split(".")
        return self.by_name[inst].index, self.by_name[inst].in_names.index(var)

    def output(self, ref: str) -> VarIndex:
        inst, var = ref.split(".")
        return self.by_name[inst].index, self.by_name[inst].outputs.index(var)

    def loop(self, cycle: Cycle) -> PlannedLoop:
        return PlannedLoop(
            cycle.text, tuple(map(self.input, cycle.inputs)), tuple(map(self.output, cycle.outputs))
        )


def _loops(scenario: Scenario, instances: Sequence[PlannedInstance]) -> tuple[PlannedLoop, ...]:
    """The algebraic loops (a :class:`ConfigError` for one the master cannot solve)."""
    fmus = {f.name: f for f in scenario.fmus}
    try:
        cycles = check_loops(fmus, scenario.connections)
    except ConfigError as exc:
        raise ConfigError(exc.message or "", source=scenario.source_path, key=exc.key) from None
    return tuple(map(_Resolver(instances).loop, cycles))


def _init_stages(scenario: Scenario, instances: Sequence[PlannedInstance]) -> tuple[PlannedStage, ...]:
    r = _Resolver(instances)
    stages = initialization_stages({f.name: f for f in scenario.fmus}, scenario.connections)
    return tuple(
        PlannedStage(
            tuple(map(r.input, s.inputs)), tuple(map(r.output, s.outputs)), tuple(map(r.loop, s.cycles))
        )
        for s in stages
    )


def _shape(scenario: Scenario) -> tuple[object, ...]:
    """Everything of ``scenario`` its plan is made of but the parameters' values and the
    seed: the instances (names, models, periods, which parameters, units), the connections,
    which inputs the profiles drive (not their values: the plan names a profile by its
    place), the events and the clock."""
    fmus = tuple(
        (f.name, f.model, f.period_ns, tuple(f.parameters), tuple(f.units.items())) for f in scenario.fmus
    )
    return (
        scenario.source_path,
        scenario.step_ns,
        scenario.start_ns,
        scenario.duration_ns,
        scenario.output_interval_ns,
        fmus,
        scenario.connections,
        tuple(p.target for p in scenario.profiles),
        scenario.events,
    )


def _parameters(scenario: Scenario, like: PlannedInstance) -> tuple[tuple[str, ParameterValue], ...]:
    """Instance ``like``'s parameters as ``scenario`` sets them: the same names in the same
    order (:func:`_shape` says so), the generated seed where ``like`` has one."""
    spec = scenario.fmus[like.index]
    params = [(n, p.value) for n, p in spec.parameters.items()]
    if len(like.parameters) > len(params):  # the seed the scenario does not set
        params.insert(0, ("seed", instance_seed(scenario.seed, like.index)))
    return tuple(params)


def make_plan(scenario: Scenario, like: Plan | None = None) -> Plan:
    """The plan of ``scenario`` (reads the models' descriptions; loads no FMU).

    ``like``, the plan of a scenario of the same structure (a Monte Carlo's or a sweep's
    other sample: the same FMUs, connections, profiles' targets and events, other parameter
    values, profile values or seed), gives everything but the parameters: the plan is
    equal to the one made from scratch, without reading the descriptions again. A ``like``
    of another structure is ignored."""
    if like is not None and _shape(like.scenario) == _shape(scenario):
        instances = tuple(
            dataclasses.replace(inst, parameters=_parameters(scenario, inst)) for inst in like.instances
        )
        return dataclasses.replace(like, scenario=scenario, instances=instances)
    b = _Builder(scenario)
    instances = tuple(b.instance(i, spec) for i, spec in enumerate(scenario.fmus))
    return Plan(
        scenario=scenario,
        instances=instances,
        driven=tuple(b.driven),
        columns=_columns(instances, scenario),
        events=tuple(b.event(e, instances) for e in scenario.events),
        loops=_loops(scenario, instances),
        init_stages=_init_stages(scenario, instances),
    )


T = TypeVar("T")

#: what :func:`shared` made, by what it is and its owners' ids: (the owners, the value)
_SHARED: dict[tuple[str, tuple[int, ...]], tuple[tuple[object, ...], Any]] = {}
_SHARED_KEPT = 16
_SHARED_LOCK = threading.Lock()


def shared(what: str, owners: tuple[object, ...], make: Callable[[], T]) -> T:
    """``make()``, made once for as long as ``owners`` (parts of a plan: its columns, its
    instances' inputs) are the same objects, and given again after that.

    A plan made ``like`` another (:func:`make_plan`: a Monte Carlo's samples, a sweep's points)
    holds the other's parts themselves, so what a run derives from those parts alone (the
    arrays the stepper reads, the order of initialization) is derived once for all of them
    instead of once per run. The owners are kept with the value: their ids cannot be taken by
    other objects while it is here. ``make`` must derive its value from the owners alone, and
    the value must not be changed by those who are given it (they share it, across threads)."""
    key = (what, tuple(map(id, owners)))
    with _SHARED_LOCK:
        hit = _SHARED.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], owners, strict=True)):
        return hit[1]
    value = make()
    with _SHARED_LOCK:
        while len(_SHARED) >= _SHARED_KEPT:
            del _SHARED[next(iter(_SHARED))]
        _SHARED[key] = (owners, value)
    return value


def exact_key(values: tuple[Any, ...]) -> object:
    """``values`` (numbers, strings, tuples of them) as a key equal to another's only when the
    two are the same bit for bit: a float by its eight bytes (0.0 is not -0.0), an int, a
    bool and a float told apart, one serialization (marshal's, which writes no references
    to objects before version 3) of the values only, never read back. A value it cannot
    write is a key equal to nothing else (what it keys is never taken for another's)."""
    try:
        return marshal.dumps(values, 2)
    except ValueError:
        return object()


__all__ = [
    "BATCH_TICKS",
    "Column",
    "ColumnKind",
    "DrivenSpec",
    "InputKind",
    "Plan",
    "PlannedEvent",
    "PlannedInput",
    "PlannedInstance",
    "PlannedLoop",
    "PlannedStage",
    "exact_key",
    "make_plan",
    "shared",
]
