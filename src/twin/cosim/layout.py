"""The one description of what the master and the compiled stepper share.

``native/stepper.c`` includes ``twin_layout.h``, which :func:`c_header` writes from the
declarations below at build time (it is never checked in), and :mod:`twin.cosim.native` uses
the ctypes classes built here from the same declarations: a member added, removed or retyped
here changes both sides at once. The header also asserts, field by field, that the C compiler put each member
at the offset ctypes computed, so a type spelled differently on the two sides fails the build
instead of corrupting memory. The entry point's prototype is in the header too: a definition
in ``stepper.c`` that disagrees with it is a compile error, and its ctypes argtypes are
read from the same text. The enumerations both sides use come from the IntEnums named in
:data:`ENUMS`.
"""

from __future__ import annotations

import ctypes
import re
from enum import IntEnum
from typing import Any

from twin.cosim.plan import ColumnKind, InputKind

HEADER = "twin_layout.h"


class Call(IntEnum):
    """The step at which the stepper stopped on a failure (``TwinCounters.fail_call``)."""

    SET_REAL = 1
    DO_STEP = 2
    GET_REAL = 3
    NON_FINITE = 4  # fmi2GetReal gave NaN or an infinity although the FMU reported fmi2OK


class Status(IntEnum):
    """What ``twin_run_ticks`` returns."""

    OK = 0
    FAILED = -1  # an FMU failed: TwinCounters says which, where and how
    OVERFLOW = -2  # the row buffer was too small (the master sizes it: cannot happen)


#: enumerations shared with C, each constant named with its prefix (IN_CONNECTION, CALL_DO_STEP)
ENUMS: tuple[tuple[str, type[IntEnum]], ...] = (
    ("IN_", InputKind),
    ("COL_", ColumnKind),
    ("CALL_", Call),
    ("STEP_", Status),
)

#: function pointer types (the FMI 2.0 signatures the stepper calls)
FUNCTION_TYPES: tuple[str, ...] = (
    "typedef int (*set_real_fn)(void *, const unsigned int *, size_t, const double *);",
    "typedef int (*get_real_fn)(void *, const unsigned int *, size_t, double *);",
    "typedef int (*do_step_fn)(void *, double, double, int);",
)

#: the structures, one member a line in C syntax, each with what it holds
STRUCTS: dict[str, str] = {
    "TwinSlot": """
        void *comp;                  /* the FMU instance (fmi2Component) */
        set_real_fn set_real;        /* its fmi2SetReal */
        get_real_fn get_real;        /* its fmi2GetReal */
        do_step_fn do_step;          /* its fmi2DoStep */
        int64_t period_ticks;        /* it steps at the ticks that are multiples of this */
        int64_t period_ns;           /* its communication step */
        int32_t n_in;                /* number of inputs */
        int32_t n_out;               /* number of Real outputs */
        int32_t read_always;         /* 1: a connection reads its outputs, fetched after every step */
        int32_t pad;
        const unsigned int *in_vr;   /* input value references */
        double *in_val;              /* the inputs last set */
        const int32_t *in_kind;      /* IN_CONNECTION, IN_DELAYED or IN_DRIVEN */
        const int32_t *in_src;       /* source slot (connection, delayed) or driven column */
        const int32_t *in_idx;       /* source output index (connection, delayed) */
        const double *in_factor;     /* a connection gives factor * output + offset ... */
        const double *in_offset;     /* ... (1 and 0: the output itself, untouched) */
        double *delay_buf;           /* the value a delayed input takes at its next exchange */
        const unsigned int *out_vr;  /* output value references */
        double *out_raw;             /* the visible outputs without their bias */
        double *out_cur;             /* the visible outputs (raw + bias) */
        double *out_pending;         /* the outputs of the last step, not visible yet */
        const double *bias;          /* bias events added to each output */
        int64_t *pending_at;         /* the tick the pending outputs become visible (-1: none) */
    """,
    "TwinColumn": """
        int32_t slot;  /* instance */
        int32_t kind;  /* COL_OUTPUT (visible value) or COL_INPUT (value last set) */
        int32_t idx;   /* output or input index */
        int32_t pad;
    """,
    "TwinCounters": """
        int64_t macro_steps;  /* ticks done */
        int64_t fmu_steps;    /* fmi2DoStep calls done */
        int64_t rows;         /* rows recorded in this batch */
        int64_t fail_tick;    /* on a failure: the tick */
        int32_t fail_slot;    /* the instance (-1: none) */
        int32_t fail_call;    /* a CALL_ value */
        int32_t fail_status;  /* the FMI status, or the output index for CALL_NON_FINITE */
        int32_t pad;
    """,
}

#: the entry point
ENTRY = (
    "int twin_run_ticks(TwinSlot *slots, int32_t n_slots, int64_t k0, int64_t k1, int64_t step_ns, "
    "int64_t out_every, const double *driven, int32_t n_driven, int64_t driven_every, double *rec, "
    "int64_t rec_capacity, const TwinColumn *cols, int32_t n_cols, TwinCounters *c)"
)

_DECLARATION = re.compile(r"(?P<type>.+?)\s*\b(?P<name>\w+)")
_SCALARS: dict[str, Any] = {"int": ctypes.c_int, "int32_t": ctypes.c_int32, "int64_t": ctypes.c_int64}
_FUNCTION_NAMES = {re.search(r"\(\*(\w+)\)", t).group(1) for t in FUNCTION_TYPES}  # type: ignore[union-attr]


def _declaration(text: str) -> tuple[str, str]:
    """(type, name) of a C declaration such as ``const double *bias``."""
    m = _DECLARATION.fullmatch(text.strip())
    if m is None:
        raise ValueError(f"layout: cannot read the C declaration {text!r}")
    return m["type"].strip(), m["name"]


def members(struct: str) -> list[tuple[str, str]]:
    """(type, name) of each member of a structure, in order."""
    lines = (line.split("/*")[0].strip() for line in STRUCTS[struct].splitlines())
    return [_declaration(line.removesuffix(";")) for line in lines if line]


def entry() -> tuple[str, list[tuple[str, str]]]:
    """The entry point's name and its parameters' (type, name)."""
    head, params = ENTRY.removesuffix(")").split("(", 1)
    return _declaration(head)[1], [_declaration(p) for p in params.split(",")]


def _ctype(spelling: str, structs: dict[str, Any]) -> Any:
    """The ctypes type of a C type: a scalar, a pointer to a structure, any other pointer as an address."""
    bare = spelling.removeprefix("const ").strip()
    if bare in _SCALARS:
        return _SCALARS[bare]
    target = bare.removesuffix("*").strip()
    if bare.endswith("*") and target in structs:
        return ctypes.POINTER(structs[target])
    if bare.endswith("*") or bare in _FUNCTION_NAMES:
        return ctypes.c_void_p
    raise TypeError(f"layout: no ctypes type for C type {spelling!r}")


def _structures() -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in STRUCTS:
        doc = f"``{name}`` of ``{HEADER}`` (generated from twin.cosim.layout.STRUCTS)."
        fields = [(member, _ctype(t, out)) for t, member in members(name)]
        out[name] = type(name, (ctypes.Structure,), {"_fields_": fields, "__doc__": doc})
    return out


STRUCTURES = _structures()
TwinSlot = STRUCTURES["TwinSlot"]
TwinColumn = STRUCTURES["TwinColumn"]
TwinCounters = STRUCTURES["TwinCounters"]


def entry_argtypes() -> list[Any]:
    """The ctypes argtypes of the entry point."""
    return [_ctype(t, STRUCTURES) for t, _ in entry()[1]]


def _c_struct(name: str) -> list[str]:
    body = [line.strip() for line in STRUCTS[name].strip().splitlines()]
    cls = STRUCTURES[name]
    # the compiler must agree with ctypes on every offset and on the size
    checks = [
        f'_Static_assert(offsetof({name}, {m}) == {getattr(cls, m).offset}, "{name}.{m}: offset differs from ctypes");'
        for _, m in members(name)
    ]
    size = f'_Static_assert(sizeof({name}) == {ctypes.sizeof(cls)}, "{name}: size differs from ctypes");'
    return ["typedef struct {", *(f"    {line}" for line in body), f"}} {name};", *checks, size]


def c_header() -> str:
    """The text of ``twin_layout.h``."""
    lines = [
        f"/* {HEADER}: generated by twin.cosim.layout at build time; do not edit. */",
        "#ifndef TWIN_LAYOUT_H",
        "#define TWIN_LAYOUT_H",
        "#include <stddef.h>",
        "#include <stdint.h>",
        "",
    ]
    for prefix, enum in ENUMS:
        lines.append("enum { " + ", ".join(f"{prefix}{m.name} = {int(m)}" for m in enum) + " };")
    lines += ["", *FUNCTION_TYPES]
    for name in STRUCTS:
        lines += ["", *_c_struct(name)]
    lines += ["", f"{ENTRY};", "", "#endif", ""]
    return "\n".join(lines)


__all__ = [
    "ENTRY",
    "HEADER",
    "STRUCTS",
    "Call",
    "Status",
    "TwinColumn",
    "TwinCounters",
    "TwinSlot",
    "c_header",
    "entry_argtypes",
]
