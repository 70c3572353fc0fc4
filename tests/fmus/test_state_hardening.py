"""Crafted FMU states and endless steps are refused, and the instance goes on (issue 13).

Regression tests through fmpy, the way a host meets the FMUs; test_fuzz_sanitized.py covers
every invariant under the sanitizers.
"""

from __future__ import annotations

import ctypes
import time
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from twin.fmu.build import model_names

from .cases import CASES
from .fmi_driver import Driver

#: fmi2DoStep's limit (TWIN_MAX_SUBSTEPS in fmus/common/model.h)
MAX_SUBSTEPS = 1_000_000
#: a serialized state: magic (8), GUID (64), size (8), then the Reals, the Integers, ...
HEADER = 80


def integer_offset(d: Driver, name: str) -> int:
    """Byte offset of Integer variable ``name`` in a serialized state of ``d``'s FMU."""
    n_reals = sum(v.type == "Real" for v in d.md.modelVariables)
    return HEADER + 8 * n_reals + 4 * d.vr(name)


def deserialize_raw(d: Driver, data: bytes) -> ctypes.c_void_p:
    """fmi2DeSerializeFMUstate of exactly these bytes (fmpy's helper would copy them)."""
    buf = (ctypes.c_char * len(data)).from_buffer_copy(data)
    out = ctypes.c_void_p()
    d.slave.fmi2DeSerializeFMUstate(d.slave.component, buf, len(data), ctypes.byref(out))
    return out


def run(d: Driver, steps: int, h: float) -> bytes:
    """``steps`` communication steps of ``h`` from the driver's current time; the outputs' bytes."""
    outs = d.outputs()
    rows = []
    for _ in range(steps):
        d.step(h)
        rows.append(d.get(outs).tobytes())
    return b"".join(rows)


TABLE = {"profile": 3, "table_n": 4}


@pytest.mark.parametrize("table_n", [0, -1, -(2**31), 9, 2**31 - 1])
def test_crafted_table_size_is_refused_and_the_instance_goes_on(
    table_n: int, fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's crash: table_n <= 0 under profile 3 read outside the table in doStep (SIGSEGV)."""
    fmu = fmu_paths["HydraulicLoader"]
    d, ref = Driver(fmu, "d"), Driver(fmu, "ref")
    for x in (d, ref):
        x.init(TABLE)
        run(x, 3, 0.01)
    data = bytearray(d.slave.serializeFMUstate(d.slave.getFMUstate()))
    at = integer_offset(d, "table_n")
    assert int.from_bytes(data[at : at + 4], "little", signed=True) == 4  # the layout is the one assumed
    data[at : at + 4] = table_n.to_bytes(4, "little", signed=True)
    with pytest.raises(FMICallException) as exc:
        deserialize_raw(d, bytes(data))
    assert exc.value.status == 3  # fmi2Error
    assert "table_n" in capsys.readouterr().out
    # unchanged and usable: it goes on exactly like an instance that never saw the bytes
    assert run(d, 20, 0.01) == run(ref, 20, 0.01)
    d.close()
    ref.close()


def test_a_state_of_another_model_is_refused(
    fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    hl = Driver.started(fmu_paths["HydraulicLoader"], name="hl")
    tn, ref = (Driver.started(fmu_paths["ThermalNetwork"], name=n) for n in ("tn", "ref"))
    foreign = hl.slave.getFMUstate()
    with pytest.raises(FMICallException):
        tn.slave.setFMUstate(foreign)  # a pointer to another model's (smaller) state
    assert "not a state of this FMU" in capsys.readouterr().out
    with pytest.raises(FMICallException):
        deserialize_raw(tn, bytes(hl.slave.serializeFMUstate(foreign)))
    assert "a state of this FMU has" in capsys.readouterr().out
    assert run(tn, 5, 60.0) == run(ref, 5, 60.0)
    hl.slave.freeFMUstate(foreign)
    for d in (hl, tn, ref):
        d.close()


@pytest.mark.parametrize("model", model_names())
def test_a_step_beyond_the_substep_limit_is_refused_at_once(
    model: str, fmu_paths: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    case = CASES[model]
    d = Driver.started(fmu_paths[model], case.parameters, case.inputs)
    h = float(d.get(["solver_step"])[0])
    for n in (MAX_SUBSTEPS + 1, 10**12):  # 10**12 internal steps took hours before
        begin = time.perf_counter()
        with pytest.raises(FMICallException) as exc:
            d.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=n * h)
        assert time.perf_counter() - begin < 1.0
        assert exc.value.status == 3
        assert "split it into smaller communication steps" in capsys.readouterr().out
    # nothing moved: the next step starts at 0 and the instance goes on like a fresh one
    ref = Driver.started(fmu_paths[model], case.parameters, case.inputs, name="ref")
    assert run(d, 3, case.step) == run(ref, 3, case.step)
    d.close()
    ref.close()


def test_a_step_of_exactly_the_limit_is_taken(fmu_paths: dict[str, Path]) -> None:
    d = Driver.started(fmu_paths["HydraulicLoader"])  # the cheapest model: a million steps take ms
    h = float(d.get(["solver_step"])[0])
    d.step(MAX_SUBSTEPS * h)
    assert d.slave.getRealStatus(2) == pytest.approx(MAX_SUBSTEPS * h)  # fmi2LastSuccessfulTime
    assert np.all(np.isfinite(d.get(d.outputs())))
    d.close()
