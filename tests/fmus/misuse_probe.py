"""Run one misuse of an FMU in this (child) process and print the status it returned.

Used by test_misuse.py through subprocess, so that a crash of the FMU would show up as a
dead child (non-zero exit, signal) rather than take the test runner down with it.
Usage: python -m tests.fmus.misuse_probe FMU CASE
"""

from __future__ import annotations

import ctypes
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave


@dataclass
class Probe:
    """One instance of the FMU and the variables the misuses need."""

    slave: FMU2Slave
    an_input: Any
    an_output: Any
    a_fixed: Any  # a fixed parameter with a declared max
    unknown: int  # a value reference no variable has

    # the states a misuse starts from
    def instantiated(self) -> None:
        pass

    def setup(self) -> None:
        self.slave.setupExperiment(startTime=0.0)

    def in_init_mode(self) -> None:
        self.setup()
        self.slave.enterInitializationMode()

    def init(self) -> None:
        self.in_init_mode()
        self.slave.exitInitializationMode()

    def terminated(self) -> None:
        self.init()
        self.slave.terminate()

    # the calls
    def set_real(self, var: Any, value: float) -> None:
        self.slave.setReal([var.valueReference], [value])

    def step(self, t: float, h: float) -> None:
        self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def input_derivatives(self) -> None:
        order = (ctypes.c_int * 1)(1)
        vr = (ctypes.c_uint * 1)(self.an_input.valueReference)
        value = (ctypes.c_double * 1)(1.0)
        self.slave.fmi2SetRealInputDerivatives(self.slave.component, vr, 1, order, value)


#: case -> (the state it starts from, the wrong call)
CASES: dict[str, tuple[Callable[[Probe], None], Callable[[Probe], object]]] = {
    "unknown_vr_get": (Probe.init, lambda p: p.slave.getReal([p.unknown])),
    "unknown_vr_set": (Probe.init, lambda p: p.slave.setReal([p.unknown], [1.0])),
    "nan_input": (Probe.init, lambda p: p.set_real(p.an_input, math.nan)),
    "inf_input": (Probe.init, lambda p: p.set_real(p.an_input, math.inf)),
    "parameter_out_of_range": (
        Probe.instantiated,
        lambda p: p.set_real(p.a_fixed, float(p.a_fixed.max) * 10 + 1),
    ),
    "set_output": (Probe.init, lambda p: p.set_real(p.an_output, 1.0)),
    "fixed_parameter_after_init": (Probe.init, lambda p: p.set_real(p.a_fixed, float(p.a_fixed.start))),
    "do_step_before_init": (Probe.setup, lambda p: p.step(0.0, 1.0)),
    "do_step_in_init_mode": (Probe.in_init_mode, lambda p: p.step(0.0, 1.0)),
    "negative_step": (Probe.init, lambda p: p.step(0.0, -1.0)),
    "nan_step": (Probe.init, lambda p: p.step(0.0, math.nan)),
    "step_not_multiple_of_internal_step": (Probe.init, lambda p: p.step(0.0, 1e-4 * math.pi)),
    "wrong_communication_point": (Probe.init, lambda p: p.step(100.0, 1.0)),
    "do_step_after_terminate": (Probe.terminated, lambda p: p.step(0.0, 1.0)),
    "set_after_terminate": (Probe.terminated, lambda p: p.set_real(p.an_input, float(p.an_input.start))),
    "terminate_twice": (Probe.terminated, lambda p: p.slave.terminate()),
    "init_twice": (Probe.init, lambda p: p.slave.enterInitializationMode()),
    "input_derivatives": (Probe.init, Probe.input_derivatives),
}


def wrong_guid(slave: FMU2Slave) -> int:
    slave.guid = "{00000000-0000-0000-0000-000000000000}"
    try:
        slave.instantiate()
    except Exception as exc:  # fmpy raises when fmi2Instantiate returns NULL
        print(f"STATUS null-instance ({type(exc).__name__})")
        return 0
    print("STATUS instance-created")
    return 0


def main(fmu: str, case: str) -> int:
    md = read_model_description(fmu)
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(fmu),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="probe",
    )
    if case == "wrong_guid":
        return wrong_guid(slave)
    if case not in CASES:
        print(f"unknown case {case}")
        return 3
    reals = [v for v in md.modelVariables if v.type == "Real"]
    probe = Probe(
        slave=slave,
        an_input=next(v for v in reals if v.causality == "input"),
        an_output=next(v for v in reals if v.causality == "output"),
        a_fixed=next(
            v for v in reals if v.causality == "parameter" and v.variability == "fixed" and v.max is not None
        ),
        unknown=max(v.valueReference for v in reals) + 1000,
    )
    slave.instantiate(loggingOn=True)
    start, misuse = CASES[case]
    try:
        start(probe)
        misuse(probe)
    except FMICallException as exc:
        print(f"STATUS {exc.status}")
        sys.stdout.flush()
        # the instance must still be usable for cleanup after a rejected call
        slave.freeInstance()
        return 0
    print("STATUS 0")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
