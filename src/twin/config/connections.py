"""``[connections]`` and ``[[delay]]``: which output feeds which input.

Checked before any run (as mosaik does): endpoints exist, an output feeds an input, no input
is fed twice, units convert (pint: a K output feeds a degC input through factor and offset;
different dimensions are refused), and an algebraic loop can be solved
(:mod:`twin.config.loops`). A delay is a choice, not a requirement: a loop through an output
without direct feedthrough runs as it is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from twin.config.endpoints import check_range, endpoint
from twin.config.loops import check_loops as check_algebraic_loops
from twin.config.reader import Problems, array_of_tables, table
from twin.config.spec import Connection, FMUSpec
from twin.errors import ConfigError, UnitError
from twin.fmu.catalog import variables as model_variables
from twin.units import conversion, same_unit


def _plain(p: Problems, data: Mapping[str, Any]) -> list[Connection]:
    """``"instance.output" = "instance.input"`` or a list of inputs."""
    out = []
    for src, dsts in table(p, data, "connections").items():
        key = f'connections."{src}"'
        if isinstance(dsts, str):
            dsts = [dsts]
        if isinstance(dsts, dict):
            p.add(
                key, f'expected an input name or a list of them (quote the output: "{src}.<variable>" = ...)'
            )
            continue
        if not isinstance(dsts, list) or not all(isinstance(d, str) for d in dsts):
            p.add(key, "expected an input name or a list of them")
            continue
        out.extend(Connection(src, dst) for dst in dsts)
    return out


def _delays(p: Problems, data: Mapping[str, Any]) -> list[tuple[str, Connection]]:
    """``[[delay]]`` entries (from, to, initial), each with its key (``delay[i]``)."""
    out = []
    for _i, key, raw in array_of_tables(p, data, "delay", " with from, to, initial"):
        p.unknown_keys(raw, {"from", "to", "initial"}, key + ".")
        initial = p.number(raw, "initial", key + ".")
        ends = isinstance(raw.get("from"), str) and isinstance(raw.get("to"), str)
        if ends and initial is not None:
            out.append((key, Connection(raw["from"], raw["to"], delay=True, initial=initial)))
        elif not ends:
            p.add(key, "needs 'from' and 'to' as 'instance.variable'")
    return out


def _check_initial_values(
    p: Problems, fmus: Mapping[str, FMUSpec], delays: Sequence[tuple[str, Connection]]
) -> None:
    """A delayed connection's initial value is the input's first value: in the input's declared
    range, or the FMU refuses it at the first exchange (mid-run)."""
    for key, c in delays:
        inst, _, var = c.dst.partition(".")
        spec = fmus.get(inst)
        v = model_variables(spec.model).get(var) if spec is not None else None
        if v is not None and v.causality == "input" and v.type == "Real" and c.initial is not None:
            check_range(p, fmus, c.dst, [c.initial], key + ".initial")


def _converted(p: Problems, fmus: Mapping[str, FMUSpec], c: Connection, key: str) -> Connection:
    """``c`` with the unit conversion from its output's unit to its input's (pint, through
    :mod:`twin.units`) composed into its factor and offset; unchanged, bit for bit, when the
    units are written alike. A unit the input lacks (or the output) must be given by the
    scenario (``[fmu.<instance>] units``); units of different dimensions are a problem."""
    (si, sv), (di, dv) = c.src.split("."), c.dst.split(".")
    su, du = fmus[si].unit(sv), fmus[di].unit(dv)
    if same_unit(su, du):
        return c
    if not su or not du:
        inst, var = (di, dv) if not du else (si, sv)
        what = (
            f"{c.src} is in '{su}', {c.dst} has no unit"
            if not du
            else f"{c.src} has no unit, {c.dst} is in '{du}'"
        )
        p.add(
            key, f'{what}: give {inst}.{var} the unit it means with [fmu.{inst}] units = {{ {var} = "..." }}'
        )
        return c
    try:
        factor, offset = conversion(su, du)
    except UnitError as exc:
        p.add(key, f"unit mismatch: {c.src} is in '{su}', {c.dst} in '{du}' ({exc.message})")
        return c
    return dataclasses.replace(c, factor=factor * c.factor, offset=factor * c.offset + offset)


def _check_endpoints(
    p: Problems, fmus: Mapping[str, FMUSpec], connections: Sequence[Connection]
) -> list[Connection]:
    """The connections whose endpoints exist, each with its unit conversion; problems for the
    others and for an input fed twice."""
    fed: dict[str, str] = {}
    out = []
    for c in connections:
        key = f'connections."{c.src}"' if not c.delay else "delay"
        vs = endpoint(p, fmus, c.src, key, "output")
        vd = endpoint(p, fmus, c.dst, key, "input")
        if c.dst in fed:
            p.add(key, f"input {c.dst!r} is already fed by {fed[c.dst]!r}")
        fed[c.dst] = c.src
        out.append(_converted(p, fmus, c, key) if vs is not None and vd is not None else c)
    return out


def check_loops(p: Problems, connections: Sequence[Connection], fmus: Mapping[str, FMUSpec]) -> None:
    """A loop between instances runs as it is unless it is a true algebraic loop (direct
    feedthrough all round, :mod:`twin.config.loops`) that the master cannot solve: one across
    instances of different periods, refused naming its cycle."""
    try:
        check_algebraic_loops(fmus, connections)
    except ConfigError as exc:
        p.add(exc.key or "connections", exc.message or "")


def load_connections(p: Problems, data: Mapping[str, Any], fmus: Mapping[str, FMUSpec]) -> list[Connection]:
    """Every connection, plain then delayed, checked."""
    delays = _delays(p, data)
    out = _check_endpoints(p, fmus, _plain(p, data) + [c for _, c in delays])
    _check_initial_values(p, fmus, delays)
    check_loops(p, out, fmus)
    return out
