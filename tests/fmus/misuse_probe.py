"""Run one misuse of an FMU in this (child) process and print the status it returned.

Used by test_misuse.py through subprocess, so that a crash of the FMU would show up as a
dead child (non-zero exit, signal) rather than take the test runner down with it.
Usage: python -m tests.fmus.misuse_probe FMU CASE
"""

from __future__ import annotations

import ctypes
import math
import sys

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave


def main(fmu: str, case: str) -> int:
    md = read_model_description(fmu)
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(fmu),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="probe",
    )
    reals = [v for v in md.modelVariables if v.type == "Real"]
    an_input = next(v for v in reals if v.causality == "input")
    an_output = next(v for v in reals if v.causality == "output")
    a_fixed = next(
        v for v in reals if v.causality == "parameter" and v.variability == "fixed" and v.max is not None
    )
    unknown = max(v.valueReference for v in reals) + 1000

    if case == "wrong_guid":
        slave.guid = "{00000000-0000-0000-0000-000000000000}"
        try:
            slave.instantiate()
        except Exception as exc:  # fmpy raises when fmi2Instantiate returns NULL
            print(f"STATUS null-instance ({type(exc).__name__})")
            return 0
        print("STATUS instance-created")
        return 0

    slave.instantiate(loggingOn=True)

    def init() -> None:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()

    try:
        if case == "unknown_vr_get":
            init()
            slave.getReal([unknown])
        elif case == "unknown_vr_set":
            init()
            slave.setReal([unknown], [1.0])
        elif case == "nan_input":
            init()
            slave.setReal([an_input.valueReference], [math.nan])
        elif case == "inf_input":
            init()
            slave.setReal([an_input.valueReference], [math.inf])
        elif case == "parameter_out_of_range":
            slave.setReal([a_fixed.valueReference], [float(a_fixed.max) * 10 + 1])
        elif case == "set_output":
            init()
            slave.setReal([an_output.valueReference], [1.0])
        elif case == "fixed_parameter_after_init":
            init()
            slave.setReal([a_fixed.valueReference], [float(a_fixed.start)])
        elif case == "do_step_before_init":
            slave.setupExperiment(startTime=0.0)
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
        elif case == "do_step_in_init_mode":
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
        elif case == "negative_step":
            init()
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=-1.0)
        elif case == "nan_step":
            init()
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=math.nan)
        elif case == "step_not_multiple_of_internal_step":
            init()
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-4 * math.pi)
        elif case == "wrong_communication_point":
            init()
            slave.doStep(currentCommunicationPoint=100.0, communicationStepSize=1.0)
        elif case == "do_step_after_terminate":
            init()
            slave.terminate()
            slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
        elif case == "set_after_terminate":
            init()
            slave.terminate()
            slave.setReal([an_input.valueReference], [float(an_input.start)])
        elif case == "terminate_twice":
            init()
            slave.terminate()
            slave.terminate()
        elif case == "init_twice":
            init()
            slave.enterInitializationMode()
        elif case == "input_derivatives":
            init()
            order = (ctypes.c_int * 1)(1)
            vr = (ctypes.c_uint * 1)(an_input.valueReference)
            value = (ctypes.c_double * 1)(1.0)
            slave.fmi2SetRealInputDerivatives(slave.component, vr, 1, order, value)
        else:
            print(f"unknown case {case}")
            return 3
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
