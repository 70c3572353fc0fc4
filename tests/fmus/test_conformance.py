"""FMI 2.0 conformance of every FMU in fmus/: validation, a second importer, determinism, state."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from twin.fmu.build import model_names

from .cases import CASES
from .fmi_driver import Driver

MODELS = model_names()


def test_every_model_has_a_conformance_case() -> None:
    assert sorted(CASES) == MODELS


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate_finds_no_problem(model: str, fmu_paths: dict[str, Path]) -> None:
    assert validate_fmu(str(fmu_paths[model])) == []


@pytest.mark.parametrize("model", MODELS)
def test_fmu_ships_sources_and_binary(model: str, fmu_paths: dict[str, Path]) -> None:
    import zipfile

    names = zipfile.ZipFile(fmu_paths[model]).namelist()
    assert "modelDescription.xml" in names
    assert f"binaries/linux64/{model}.so" in names
    for src in ("sources/fmi2_wrapper.c", "sources/model.c", "sources/model_vars.h", "sources/config.h"):
        assert src in names


def run_fmpy(fmu: Path, model: str) -> np.ndarray:
    case = CASES[model]
    d = Driver(fmu)
    d.init(case.parameters, case.inputs)
    outs = d.outputs()
    rows = [d.get(outs)]
    n = round(case.stop / case.step)
    for k in range(n):
        d.slave.doStep(currentCommunicationPoint=k * case.step, communicationStepSize=case.step)
        rows.append(d.get(outs))
    d.close()
    return np.array(rows)


def run_libcosim(fmu: Path, model: str) -> np.ndarray:
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    case = CASES[model]
    step_ns = round(case.step * 1e9)
    execution = CosimExecution.from_step_size(step_size=step_ns)
    slave = CosimLocalSlave(fmu_path=str(fmu), instance_name="inst")
    idx = execution.add_local_slave(local_slave=slave)
    refs = {v.name.decode(): (v.reference, v.type) for v in execution.slave_variables(idx)}
    for name, value in {**case.parameters, **case.inputs}.items():
        ref, vtype = refs[name]
        if vtype == CosimVariableType.BOOLEAN.value:
            execution.boolean_initial_value(idx, ref, bool(value))
        elif vtype == CosimVariableType.INTEGER.value:
            execution.integer_initial_value(idx, ref, int(value))
        else:
            assert vtype == CosimVariableType.REAL.value
            execution.real_initial_value(idx, ref, float(value))
    d = Driver(fmu)
    outs = d.outputs()
    d.slave.freeInstance()
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    refs_out = [refs[name][0] for name in outs]
    rows = []
    for _ in range(round(case.stop / case.step)):
        assert execution.step()
        rows.append(observer.last_real_values(idx, refs_out))
    return np.array(rows)


@pytest.mark.parametrize("model", MODELS)
def test_libcosim_runs_the_fmu_and_agrees_with_fmpy(model: str, fmu_paths: dict[str, Path]) -> None:
    ref = run_fmpy(fmu_paths[model], model)
    other = run_libcosim(fmu_paths[model], model)
    # libcosim is read after each step; fmpy also recorded the initial values
    assert other.shape == (ref.shape[0] - 1, ref.shape[1])
    np.testing.assert_allclose(other, ref[1:], rtol=1e-12, atol=1e-12)
    assert np.all(np.isfinite(ref))


@pytest.mark.parametrize("model", MODELS)
def test_one_double_step_equals_two_single_steps_bit_for_bit(model: str, fmu_paths: dict[str, Path]) -> None:
    case = CASES[model]
    a, b = Driver(fmu_paths[model], "a"), Driver(fmu_paths[model], "b")
    for d in (a, b):
        d.init(case.parameters, case.inputs)
    outs = a.outputs()
    h = case.step
    for k in range(20):
        a.slave.doStep(currentCommunicationPoint=2 * k * h, communicationStepSize=2 * h)
        b.slave.doStep(currentCommunicationPoint=2 * k * h, communicationStepSize=h)
        b.slave.doStep(currentCommunicationPoint=(2 * k + 1) * h, communicationStepSize=h)
        assert a.get(outs).tobytes() == b.get(outs).tobytes()
    a.close()
    b.close()


@pytest.mark.parametrize("model", MODELS)
def test_restored_state_reproduces_the_trajectory_bit_for_bit(model: str, fmu_paths: dict[str, Path]) -> None:
    case = CASES[model]
    d = Driver(fmu_paths[model])
    d.init(case.parameters, case.inputs)
    outs = d.outputs()
    h = case.step
    for k in range(5):
        d.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
    saved = d.slave.getFMUstate()
    serialized = bytes(d.slave.serializeFMUstate(saved))

    def trajectory(start_k: int) -> bytes:
        rows = []
        for k in range(start_k, start_k + 10):
            d.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            rows.append(d.get(outs).tobytes())
        return b"".join(rows)

    first = trajectory(5)
    d.slave.setFMUstate(saved)
    assert trajectory(5) == first
    # a serialized state goes into a fresh instance and gives the same trajectory
    other = Driver(fmu_paths[model], "other", unzipdir=d.unzipdir)
    other.init(case.parameters, case.inputs)
    restored = other.slave.deSerializeFMUstate(serialized)
    other.slave.setFMUstate(restored)
    rows = []
    for k in range(5, 15):
        other.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        rows.append(other.get(outs).tobytes())
    assert b"".join(rows) == first
    other.slave.freeFMUstate(restored)
    d.slave.freeFMUstate(saved)
    d.close()
    other.close()


@pytest.mark.parametrize("model", MODELS)
def test_start_values_in_binary_match_the_model_description(model: str, fmu_paths: dict[str, Path]) -> None:
    d = Driver(fmu_paths[model])
    d.slave.setupExperiment(startTime=0.0)
    d.slave.enterInitializationMode()
    for v in d.md.modelVariables:
        if v.type == "Real" and v.start is not None and v.causality in ("parameter", "input"):
            assert d.slave.getReal([v.valueReference])[0] == float(v.start), v.name
    d.slave.freeInstance()


@pytest.mark.parametrize("model", MODELS)
def test_corrupt_or_truncated_serialized_state_is_rejected(model: str, fmu_paths: dict[str, Path]) -> None:
    from fmpy.fmi1 import FMICallException

    d = Driver(fmu_paths[model])
    d.init(CASES[model].parameters, CASES[model].inputs)
    state = d.slave.getFMUstate()
    data = bytearray(d.slave.serializeFMUstate(state))
    for bad in (bytes(data[:-1]), b"BADMAGIC" + bytes(data[8:])):
        buf = (ctypes.c_char * len(bad)).from_buffer_copy(bad)
        out = ctypes.c_void_p()
        with pytest.raises(FMICallException) as exc:
            d.slave.fmi2DeSerializeFMUstate(d.slave.component, buf, len(bad), ctypes.byref(out))
        assert exc.value.status == 3  # fmi2Error
    d.slave.freeFMUstate(state)
    d.close()


@pytest.mark.parametrize("model", MODELS)
def test_outputs_in_initialization_mode_are_the_initial_values(
    model: str, fmu_paths: dict[str, Path]
) -> None:
    # importers (libcosim) read the outputs before exiting initialization mode
    case = CASES[model]
    d = Driver(fmu_paths[model])
    d.slave.setupExperiment(startTime=0.0)
    d.set(case.parameters)
    d.set(case.inputs)
    d.slave.enterInitializationMode()
    outs = d.outputs()
    during = d.get(outs)
    d.slave.exitInitializationMode()
    after = d.get(outs)
    d.close()
    assert during.tobytes() == after.tobytes()
    assert np.all(np.isfinite(during))
