"""Loops between FMUs, found on the variable level from each FMU's ``<ModelStructure>``.

The connections and each FMU's declared dependencies make a directed graph of variables
(``"instance.variable"``): an output feeds the inputs it is connected to (a delayed connection
is no edge: its input holds the value of the previous exchange), and an input feeds the
outputs of its instance that depend on it (:attr:`twin.fmu.description.Description.feedthrough`
at a communication point, :attr:`~twin.fmu.description.Description.initial_dependencies` in
initialization mode). A loop between instances is harmless when it passes through an output
without direct feedthrough: that output is a value of the state at the end of the last step,
so the master's Jacobi exchange runs it as it is, with no delay (as libcosim does). A cycle of
this graph is a true algebraic loop: the values on it at one communication point depend on
each other. The master solves it by fixed-point iteration (:mod:`twin.cosim.loops`), which needs
every instance on it to stop at the same communication points: a loop across instances of
different periods is refused before anything runs (:func:`check_loops`).

In initialization mode the same graph, with the initial dependencies, says in which order the
master sets inputs and reads outputs (:func:`initialization_stages`); a cycle there (FMI's
default, an initial unknown without ``dependencies``, depends on every input) is iterated too.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from twin.config.durations import format_duration
from twin.config.spec import Connection, FMUSpec
from twin.errors import ConfigError
from twin.fmu import catalog

__all__ = [
    "Cycle",
    "InitStage",
    "algebraic_loops",
    "check_loops",
    "dependency_graph",
    "initialization_stages",
    "loop_problem",
    "strongly_connected",
]

Phase = Literal["step", "init"]
Graph = dict[str, list[str]]


@dataclass(frozen=True)
class Cycle:
    """A strongly connected set of variables: an algebraic loop.

    ``inputs`` and ``outputs`` are every variable of the set (sorted); ``path`` is one cycle
    through it, its first variable repeated at its end, which names the loop to a user."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    path: tuple[str, ...]

    @property
    def text(self) -> str:
        return " -> ".join(self.path)

    @property
    def instances(self) -> tuple[str, ...]:
        return tuple(sorted({v.split(".")[0] for v in self.inputs + self.outputs}))


@dataclass(frozen=True)
class InitStage:
    """Variables of initialization mode that depend on none of each other: ``inputs`` are set
    (from outputs read at an earlier stage), then ``outputs`` read; each of ``cycles`` is
    iterated (its own inputs and outputs are in no list)."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    cycles: tuple[Cycle, ...]


def _model_of(fmus: Mapping[str, FMUSpec], ref: str) -> tuple[str, str, str] | None:
    """(instance, variable, model) of ``ref`` if the instance exists and its model has the variable."""
    inst, _, var = ref.partition(".")
    spec = fmus.get(inst)
    if spec is None or var not in catalog.variables(spec.model):
        return None
    return inst, var, spec.model


def dependency_graph(fmus: Mapping[str, FMUSpec], connections: Iterable[Connection], phase: Phase) -> Graph:
    """The variable graph of the undelayed connections (see the module): node -> successors.

    Its nodes are the outputs that feed an undelayed connection and the inputs fed by one;
    connections naming what does not exist are left out (the loader reports them)."""
    graph: Graph = {}
    inputs_of: dict[str, list[str]] = {}
    sources_of: dict[str, list[str]] = {}
    for c in connections:
        src, dst = _model_of(fmus, c.src), _model_of(fmus, c.dst)
        if c.delay or src is None or dst is None:
            continue
        graph.setdefault(c.src, []).append(c.dst)
        graph.setdefault(c.dst, [])
        inputs_of.setdefault(dst[0], []).append(dst[1])
        sources_of.setdefault(src[0], []).append(src[1])
    for inst, outputs in sources_of.items():
        description = catalog.description(fmus[inst].model)
        deps = description.feedthrough if phase == "step" else description.initial_dependencies
        for u in inputs_of.get(inst, ()):
            graph[f"{inst}.{u}"] += [f"{inst}.{y}" for y in sorted(set(outputs)) if u in deps.get(y, ())]
    return graph


def _finishing_order(graph: Mapping[str, Sequence[str]]) -> list[str]:
    """The nodes of ``graph`` in the order a depth-first search finishes them (no recursion)."""
    seen: set[str] = set()
    order: list[str] = []
    for root in sorted(graph):
        if root in seen:
            continue
        seen.add(root)
        stack = [(root, iter(graph[root]))]
        while stack:
            node, successors = stack[-1]
            nxt = next((m for m in successors if m not in seen), None)
            if nxt is None:
                stack.pop()
                order.append(node)
            else:
                seen.add(nxt)
                stack.append((nxt, iter(graph[nxt])))
    return order


def strongly_connected(graph: Mapping[str, Sequence[str]]) -> list[list[str]]:
    """The strongly connected components of ``graph`` (Kosaraju's algorithm), each sorted,
    every component after all those it depends on."""
    reverse: dict[str, list[str]] = {n: [] for n in graph}
    for n, successors in graph.items():
        for m in successors:
            reverse[m].append(n)
    assigned: set[str] = set()
    out = []
    # the last node to finish lies in a component nothing else leads to: found first
    for root in reversed(_finishing_order(graph)):
        if root in assigned:
            continue
        assigned.add(root)
        component, stack = [], [root]
        while stack:
            node = stack.pop()
            component.append(node)
            for m in reverse[node]:
                if m not in assigned:
                    assigned.add(m)
                    stack.append(m)
        out.append(sorted(component))
    return out


def _cyclic(graph: Mapping[str, Sequence[str]], component: Sequence[str]) -> bool:
    return len(component) > 1 or component[0] in graph.get(component[0], ())


def _path(graph: Mapping[str, Sequence[str]], component: Sequence[str]) -> tuple[str, ...]:
    """One cycle through the first variable of a strongly connected ``component`` (shortest, by
    breadth-first search inside it), that variable repeated at the end."""
    members, start = set(component), component[0]
    came_from: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for node in frontier:
            for m in graph.get(node, ()):
                if m not in members or m in came_from:
                    continue
                came_from[m] = node
                if m == start:
                    path = [start]
                    while path[-1] != start or len(path) == 1:
                        path.append(came_from[path[-1]])
                    return tuple(path[::-1])
                nxt.append(m)
        frontier = nxt
    return (start, start)  # not reached for a strongly connected component


def _cycle(
    graph: Mapping[str, Sequence[str]], component: Sequence[str], fmus: Mapping[str, FMUSpec]
) -> Cycle:
    def causality(ref: str) -> str:
        found = _model_of(fmus, ref)
        return catalog.variables(found[2])[found[1]].causality if found else ""

    inputs = tuple(v for v in component if causality(v) == "input")
    outputs = tuple(v for v in component if causality(v) != "input")
    # named by its shortest cycle, from an output: "a.y -> b.u -> b.z -> a.v -> a.y"
    paths = [_path(graph, [start, *[v for v in component if v != start]]) for start in outputs or component]
    return Cycle(inputs, outputs, min(paths, key=len))


def algebraic_loops(fmus: Mapping[str, FMUSpec], connections: Iterable[Connection]) -> list[Cycle]:
    """The true algebraic loops at a communication point (cycles through direct feedthrough),
    every loop after those it depends on."""
    graph = dependency_graph(fmus, connections, "step")
    return [_cycle(graph, c, fmus) for c in strongly_connected(graph) if _cyclic(graph, c)]


def loop_problem(fmus: Mapping[str, FMUSpec], cycle: Cycle) -> str | None:
    """Why the master cannot solve ``cycle`` (instances of different periods), or None."""
    periods = {fmus[i].period_ns for i in cycle.instances}
    if len(periods) == 1:
        return None
    each = ", ".join(f"{i} {format_duration(fmus[i].period_ns)}" for i in cycle.instances)
    return (
        f"algebraic loop {cycle.text} (direct feedthrough all round) joins instances of different "
        f"periods ({each}): it can only be solved where all of them stop; give them one period or "
        "break the loop with a [[delay]] (from, to, initial)"
    )


def check_loops(fmus: Mapping[str, FMUSpec], connections: Iterable[Connection]) -> list[Cycle]:
    """The algebraic loops, each one the master can solve; a :class:`ConfigError` naming the
    first that it cannot."""
    loops = algebraic_loops(fmus, connections)
    for cycle in loops:
        why = loop_problem(fmus, cycle)
        if why is not None:
            raise ConfigError(why, key="connections")
    return loops


def initialization_stages(fmus: Mapping[str, FMUSpec], connections: Iterable[Connection]) -> list[InitStage]:
    """The order in which initialization sets inputs and reads outputs (see :class:`InitStage`):
    each variable at the stage after the last one it depends on."""
    graph = dependency_graph(fmus, connections, "init")
    components = strongly_connected(graph)
    where = {v: n for n, comp in enumerate(components) for v in comp}
    level = [0] * len(components)
    for n, comp in enumerate(components):  # every component after those it depends on
        for v in comp:
            for m in graph[v]:
                if where[m] != n:
                    level[where[m]] = max(level[where[m]], level[n] + 1)
    stages = []
    for lv in range(max(level, default=-1) + 1):
        comps = [c for n, c in enumerate(components) if level[n] == lv]
        plain = [c[0] for c in comps if not _cyclic(graph, c)]
        stages.append(
            InitStage(
                inputs=tuple(v for v in plain if _is_input(fmus, v)),
                outputs=tuple(v for v in plain if not _is_input(fmus, v)),
                cycles=tuple(_cycle(graph, c, fmus) for c in comps if _cyclic(graph, c)),
            )
        )
    return stages


def _is_input(fmus: Mapping[str, FMUSpec], ref: str) -> bool:
    found = _model_of(fmus, ref)
    return found is not None and catalog.variables(found[2])[found[1]].causality == "input"
