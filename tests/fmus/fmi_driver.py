"""Drive an FMU through fmpy's thin FMI 2.0 binding (no master involved)."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


class Driver:
    """One instantiated co-simulation slave with name-based access."""

    def __init__(self, fmu: Path, name: str = "inst", unzipdir: str | None = None) -> None:
        self.md = read_model_description(str(fmu))
        self.unzipdir = unzipdir or _extracted(fmu)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.unzipdir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate()
        self.time = 0.0

    @classmethod
    def started(
        cls,
        fmu: Path,
        parameters: dict[str, float] | None = None,
        inputs: dict[str, float] | None = None,
        name: str = "inst",
    ) -> Driver:
        """A slave already through initialization with these parameters and inputs."""
        d = cls(fmu, name)
        d.init(parameters, inputs)
        return d

    def vr(self, name: str) -> int:
        return self.vars[name].valueReference

    def set(self, values: dict[str, float | bool]) -> None:
        for name, value in values.items():
            v = self.vars[name]
            if v.type == "Boolean":
                self.slave.setBoolean([v.valueReference], [bool(value)])
            elif v.type == "Integer":
                self.slave.setInteger([v.valueReference], [int(value)])
            else:
                self.slave.setReal([v.valueReference], [float(value)])

    def init(
        self, parameters: dict[str, float] | None = None, inputs: dict[str, float] | None = None
    ) -> None:
        self.slave.setupExperiment(startTime=0.0)
        self.set(parameters or {})
        self.set(inputs or {})
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def outputs(self) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == "output" and v.type == "Real"]

    def get(self, names: list[str]) -> np.ndarray:
        return np.array(self.slave.getReal([self.vr(n) for n in names]))

    def step(self, h: float) -> None:
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def _extracted(fmu: Path) -> str:
    """``fmu`` unpacked into a new temporary folder, removed when the test process ends (fmpy's
    own ``extract`` leaves its folder behind: thousands of them had piled up in /tmp)."""
    folder = tempfile.mkdtemp(prefix="twin-test-fmu-")
    atexit.register(shutil.rmtree, folder, True)
    return extract(str(fmu), unzipdir=folder)
