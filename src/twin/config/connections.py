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

#: the keys of a connection written as a table (a transformation, SSP's LinearTransformation)
_TRANSFORM_KEYS = {"to", "factor", "offset", "convert_units"}


def _transformed(p: Problems, src: str, raw: dict[str, Any], key: str) -> Connection | None:
    """``{ to = "instance.input", factor = 2.0, offset = 0.0, convert_units = true }``: the
    input receives ``factor * output + offset``. ``convert_units = false`` says that factor
    and offset are the whole map (SSP's suppressUnitConversion): the ends' units are then not
    compared."""
    p.unknown_keys(raw, _TRANSFORM_KEYS, key + ".")
    dst = raw.get("to")
    if not isinstance(dst, str):
        p.add(key + ".to", "missing (the input this output feeds, 'instance.input')")
        return None
    factor = p.number(raw, "factor", key + ".") if "factor" in raw else 1.0
    offset = p.number(raw, "offset", key + ".") if "offset" in raw else 0.0
    convert = p.boolean(raw, "convert_units", key + ".", default=True)
    if factor is None or offset is None:
        return None
    return Connection(src, dst, factor=factor, offset=offset, convert_units=convert)


def _plain(p: Problems, data: Mapping[str, Any]) -> list[Connection]:
    """``"instance.output" = "instance.input"``, a table with a transformation, or a list of
    them."""
    out = []
    for src, dsts in table(p, data, "connections").items():
        key = f'connections."{src}"'
        if isinstance(dsts, dict) and "to" not in dsts:  # an unquoted dotted key: "thermal".t_clamp
            p.add(
                key, f'expected an input name or a list of them (quote the output: "{src}.<variable>" = ...)'
            )
            continue
        if isinstance(dsts, str | dict):
            dsts = [dsts]
        if not isinstance(dsts, list) or not all(isinstance(d, str | dict) for d in dsts):
            p.add(key, "expected an input name, a table { to, factor, offset } or a list of them")
            continue
        for i, d in enumerate(dsts):
            if isinstance(d, str):
                out.append(Connection(src, d))
            elif (c := _transformed(p, src, d, key if len(dsts) == 1 else f"{key}[{i}]")) is not None:
                out.append(c)
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
    if not c.convert_units or same_unit(su, du):
        return c  # convert_units = false: factor and offset hold the whole map already
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


def check_inputs_fed(p: Problems, data: Mapping[str, Any], fmus: Sequence[FMUSpec]) -> None:
    """Every input of every FMU is connected, driven (a profile, a set, ramp or fault event) or
    marked as meant to stay at its start value (``[fmu.<name>] unconnected = { <input> =
    "why" }``): one problem per input that is none of these, so an input a file forgot (a
    connection lost to an ``extends``) is never left at its start value without a word. Read
    from the data as written, so an input whose connection or profile is itself wrong is
    reported once, there. A mark on an input that something feeds has no effect (a file may
    drive what its base leaves alone)."""
    if any(e.key and e.key.split(".")[0].split("[")[0] in _FEEDING for e in p.items):
        return  # what feeds which input is itself wrong: reported there, once
    named = _named_inputs(data)
    for f in fmus:
        for name, v in model_variables(f.model).items():
            target = f"{f.name}.{name}"
            if v.causality != "input" or target in named or name in f.unconnected:
                continue
            unit = "" if v.unit in (None, "", "1") else f" {v.unit}"
            start = f"start value {v.start}{unit}" if v.start is not None else "no start value"
            p.add(
                f"fmu.{f.name}",
                f"input '{name}' ({start}) is not connected: connect it, drive it with "
                f'[input.{target}], or give the reason it is left alone: unconnected = {{ {name} = "..." }}',
            )


#: the tables that feed or drive inputs
_FEEDING = frozenset({"connections", "delay", "input", "event"})


def _named_inputs(data: Mapping[str, Any]) -> set[str]:
    """Every "instance.input" the data feeds or drives, well written or not."""
    named: set[str] = set()
    for dsts in _values(data.get("connections")):
        for d in dsts if isinstance(dsts, list) else [dsts]:
            d = d.get("to") if isinstance(d, dict) else d  # { to, factor, offset }
            if isinstance(d, str):
                named.add(d)
    for group, key in (("delay", "to"), ("event", "target")):
        entries = data.get(group)
        for e in entries if isinstance(entries, list) else ():
            if isinstance(e, dict) and isinstance(e.get(key), str):
                named.add(f"{e[key]}.fault_inject" if "fault" in e else e[key])
    inputs = data.get("input")
    for inst, variables in inputs.items() if isinstance(inputs, dict) else ():
        named.update(f"{inst}.{var}" for var in _values(variables, keys=True))
    return named


def _values(node: Any, *, keys: bool = False) -> list[Any]:
    """A table's values (or keys); nothing for anything that is not a table."""
    if not isinstance(node, dict):
        return []
    return list(node) if keys else list(node.values())


def load_connections(p: Problems, data: Mapping[str, Any], fmus: Mapping[str, FMUSpec]) -> list[Connection]:
    """Every connection, plain then delayed, checked."""
    delays = _delays(p, data)
    out = _check_endpoints(p, fmus, _plain(p, data) + [c for _, c in delays])
    _check_initial_values(p, fmus, delays)
    check_loops(p, out, fmus)
    return out
