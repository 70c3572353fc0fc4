"""Topology of a multi-body system (MBS): bodies, the lower-body array and branches.

Follows Huston's MBS theory as used by the paper: the base is body 1; every other body ``k`` has
exactly one *lower body* ``L(k)`` (the body it is mounted on). The lower-body operator is iterated:
``L^0(k) = k``, ``L^1(k) = L(k)``, ``L^n(k) = L^1(L^{n-1}(k))``, and the base maps to itself,
``L^n(1) = 1``. Tabulating ``L^n(k)`` for ``n = 0 .. max depth`` gives the paper's Table 1.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.errors import ConfigError, ConfigErrors

__all__ = ["BASE_INDEX", "Body", "Topology"]

#: Index of the base (inertial reference) body in Huston's numbering.
BASE_INDEX = 1


@dataclass(frozen=True)
class Body:
    """One rigid body: its index, a lower_snake name, and the index of its lower body.

    ``lower`` is ``None`` for the base body only.
    """

    index: int
    name: str
    lower: int | None = None


def _raise(problems: list[str], source: str | None) -> None:
    if not problems:
        return
    errors = [ConfigError(p, source=source) for p in problems]
    raise errors[0] if len(errors) == 1 else ConfigErrors(errors)


def _by_index(bodies: Iterable[Body]) -> tuple[dict[int, Body], list[str]]:
    """The bodies by index, and the problems of their indices and names."""
    problems: list[str] = []
    by_index: dict[int, Body] = {}
    names: set[str] = set()
    for b in bodies:
        if isinstance(b.index, bool) or not isinstance(b.index, int) or b.index < 1:
            problems.append(f"body '{b.name}': index must be a positive integer, got {b.index!r}")
            continue
        if b.index in by_index:
            problems.append(f"duplicate body index {b.index} ('{by_index[b.index].name}' and '{b.name}')")
            continue
        if not b.name or b.name in names:
            problems.append(f"body {b.index}: name {b.name!r} is empty or used twice")
        names.add(b.name)
        by_index[b.index] = b
    return by_index, problems


def _base_problems(by_index: dict[int, Body]) -> list[str]:
    """Exactly one base (no lower body), numbered 1 as in Huston's numbering."""
    bases = [b for b in by_index.values() if b.lower is None]
    if not bases:
        return ["no base body (exactly one body must have no lower body)"]
    if len(bases) > 1:
        return [f"several base bodies: {sorted(b.index for b in bases)} (exactly one allowed)"]
    if bases[0].index != BASE_INDEX:
        return [f"the base body must have index {BASE_INDEX} (Huston numbering), got {bases[0].index}"]
    return []


def _cycles(by_index: dict[int, Body]) -> list[str]:
    """Walk every body down its lower bodies; a walk that revisits a body is a cycle (it never
    reaches the base). Each cycle is reported once, from its smallest index, whichever body
    found it."""
    cycles: dict[frozenset[int], str] = {}
    for b in by_index.values():
        seen = [b.index]
        k = b.lower
        while k is not None and k not in seen:
            seen.append(k)
            k = by_index[k].lower
        if k is not None:
            members = seen[seen.index(k) :]
            start = members.index(min(members))
            members = members[start:] + members[:start]
            text = " -> ".join(str(i) for i in [*members, members[0]])
            cycles.setdefault(frozenset(members), f"cycle in lower bodies: {text}")
    return list(cycles.values())


class Topology:
    """A tree of bodies rooted at the base body 1, validated when built.

    Raises :class:`twin.errors.ConfigError` (one line per problem) on a duplicate index or name,
    an unknown lower body, a cycle, a missing or misnumbered base.
    """

    def __init__(self, bodies: Iterable[Body], *, source: str | None = None) -> None:
        by_index, problems = _by_index(bodies)
        problems += _base_problems(by_index)
        problems += [
            f"body {b.index} ('{b.name}'): unknown lower body {b.lower}"
            for b in by_index.values()
            if b.lower is not None and b.lower not in by_index
        ]
        _raise(problems, source)
        # Only without cycles is L^n(k) well defined for all n.
        _raise(_cycles(by_index), source)
        self._bodies = dict(sorted(by_index.items()))
        self._by_name = {b.name: b for b in self._bodies.values()}

    @property
    def bodies(self) -> tuple[Body, ...]:
        """All bodies, ordered by index."""
        return tuple(self._bodies.values())

    @property
    def indices(self) -> tuple[int, ...]:
        """Body indices in ascending order (the columns of :meth:`lower_body_array`)."""
        return tuple(self._bodies)

    @property
    def base(self) -> Body:
        """The base body (index 1)."""
        return self._bodies[BASE_INDEX]

    def body(self, key: int | str) -> Body:
        """Look a body up by index or by name; unknown keys raise ConfigError."""
        found = self._by_name.get(key) if isinstance(key, str) else self._bodies.get(key)
        if found is None:
            raise ConfigError(f"unknown body {key!r}")
        return found

    def lower(self, k: int | str, n: int = 1) -> int:
        """``L^n(k)``: the body reached by stepping ``n`` times to the lower body (base stays base)."""
        if n < 0:
            raise ConfigError(f"lower-body order must be >= 0, got {n}")
        index = self.body(k).index
        for _ in range(n):
            lower = self._bodies[index].lower
            if lower is None:
                break
            index = lower
        return index

    def depth(self, k: int | str) -> int:
        """Number of joints between the base and body ``k`` (0 for the base)."""
        return len(self.branch(k)) - 1

    def lower_body_array(self) -> NDArray[np.int64]:
        """The lower-body array: entry ``[n, c]`` is ``L^n(indices[c])``.

        Rows ``n = 0 .. max depth`` (the last row is all base), columns the bodies in index order.
        """
        rows = max(self.depth(k) for k in self._bodies) + 1
        return np.array([[self.lower(k, n) for k in self._bodies] for n in range(rows)], dtype=np.int64)

    def branch(self, end_body: int | str) -> tuple[int, ...]:
        """The chain of body indices from the base to ``end_body``, both included."""
        chain = [self.body(end_body).index]
        while (lower := self._bodies[chain[-1]].lower) is not None:
            chain.append(lower)
        return tuple(reversed(chain))

    def __repr__(self) -> str:
        inner = ", ".join(f"{b.index}:{b.name}<-{b.lower}" for b in self.bodies)
        return f"Topology({inner})"
