"""SSP archives written by hand around the twin's real FMUs (``twin.fmu.catalog.fmu``), and the
two masters that run them: the twin (``twin run X.ssp``) and libcosim (libcosimpy's
``CosimExecution.from_ssp_file``)."""

from __future__ import annotations

import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from twin.cli import main
from twin.fmu import catalog
from twin.outputs.csv import read_signals_csv

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSM = "http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
TWIN = "https://github.com/twin/ssp-annotations"
NAMESPACES = f'xmlns:ssd="{SSD}" xmlns:ssc="{SSC}" xmlns:ssv="{SSV}" xmlns:ssm="{SSM}" xmlns:osp="{OSP}"'


def connector(name: str, kind: str, type_: str = "Real", unit: str | None = None) -> str:
    u = f' unit="{unit}"' if unit else ""
    return f'<ssd:Connector name="{name}" kind="{kind}"><ssc:{type_}{u}/></ssd:Connector>'


def component(
    name: str,
    model: str,
    connectors: Sequence[str],
    *,
    bindings: str = "",
    hint: float | None = None,
    attrs: str = "",
    annotations: str = "",
) -> str:
    """A component running the twin's ``model`` (its FMU at ``resources/<model>.fmu``)."""
    osp = (
        f'<ssc:Annotation type="com.opensimulationplatform"><osp:StepSizeHint value="{hint!r}"/></ssc:Annotation>'
        if hint is not None
        else ""
    )
    notes = f"<ssd:Annotations>{osp}{annotations}</ssd:Annotations>" if osp or annotations else ""
    binds = f"<ssd:ParameterBindings>{bindings}</ssd:ParameterBindings>" if bindings else ""
    return (
        f'<ssd:Component name="{name}" source="resources/{model}.fmu" {attrs}>'
        f"<ssd:Connectors>{''.join(connectors)}</ssd:Connectors>{binds}{notes}</ssd:Component>"
    )


def connection(src: str, dst: str, inner: str = "", attrs: str = "") -> str:
    (se, sc), (de, dc) = src.split("."), dst.split(".")
    return (
        f'<ssd:Connection startElement="{se}" startConnector="{sc}" endElement="{de}" endConnector="{dc}" '
        f"{attrs}>{inner}</ssd:Connection>"
    )


def parameter_set(values: Mapping[str, tuple[str, str] | tuple[str, str, str]], *, extra: str = "") -> str:
    """An ``ssv:ParameterSet``: name -> (type, value[, unit]); ``extra`` after the parameters
    (its Enumerations and Units)."""
    params = []
    for name, v in values.items():
        unit = f' unit="{v[2]}"' if len(v) > 2 else ""
        params.append(f'<ssv:Parameter name="{name}"><ssv:{v[0]} value="{v[1]}"{unit}/></ssv:Parameter>')
    return (
        f'<ssv:ParameterSet xmlns:ssv="{SSV}" xmlns:ssc="{SSC}" version="1.0" name="set">'
        f"<ssv:Parameters>{''.join(params)}</ssv:Parameters>{extra}</ssv:ParameterSet>"
    )


def experiment(stop: float, step: float | None) -> str:
    osp = (
        '<ssd:Annotations><ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm>'
        f'<osp:FixedStepAlgorithm baseStepSize="{step!r}"/></osp:Algorithm></ssc:Annotation></ssd:Annotations>'
        if step is not None
        else ""
    )
    return f'<ssd:DefaultExperiment startTime="0.0" stopTime="{stop!r}">{osp}</ssd:DefaultExperiment>'


def ssd(
    components: Sequence[str],
    connections: Sequence[str],
    exp: str,
    *,
    head: str = "",
    tail: str = "",
    system_extra: str = "",
) -> str:
    """A SystemStructure.ssd: ``head`` inside the system before its elements (its connectors,
    bindings), ``system_extra`` after its connections, ``tail`` after the system (Enumerations,
    Units), then the experiment."""
    conns = f"<ssd:Connections>{''.join(connections)}</ssd:Connections>" if connections else ""
    return (
        f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {NAMESPACES} '
        f'version="1.0" name="variant"><ssd:System name="variant">{head}'
        f"<ssd:Elements>{''.join(components)}</ssd:Elements>{conns}{system_extra}</ssd:System>"
        f"{tail}{exp}</ssd:SystemStructureDescription>\n"
    )


def archive(path: Path, ssd_text: str, models: Sequence[str], files: Mapping[str, str] | None = None) -> Path:
    """The archive ``path``: the SSD, the twin's FMUs of ``models``, and ``files`` (name -> text)."""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd_text)
        for model in models:
            zf.writestr(f"resources/{model}.fmu", catalog.fmu(model).read_bytes())
        for name, text in (files or {}).items():
            zf.writestr(name, text)
    return path


# ----------------------------------------------------------------------------- the two masters


def twin_run(ssp: Path, out: Path, *sets: str) -> dict[str, np.ndarray]:
    """The twin's run of the archive: each recorded column, one value per output row."""
    args = ["run", str(ssp), "--out", str(out), "--quiet", "--uncertainty", "0"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    table = read_signals_csv(out / "signals.csv")
    return {n: np.asarray(table[n]) for n in table.names()}


def libcosim_run(
    ssp: Path, names: Sequence[str], steps: int, every: int, step_ns: int | None = None
) -> dict[str, np.ndarray]:
    """libcosim's run of the archive: after every ``every`` base steps, the last value of each
    named variable ("instance.variable"); ``step_ns`` for an archive that gives no step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    execution = (
        CosimExecution.from_ssp_file(str(ssp))
        if step_ns is None
        else CosimExecution.from_ssp_file(str(ssp), step_size=step_ns)
    )
    index = {i.name.decode(): i.index for i in execution.slave_infos()}
    refs = {n: {v.name.decode(): v.reference for v in execution.slave_variables(i)} for n, i in index.items()}
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    rows = []
    for _ in range(steps):
        assert execution.step(every)
        row = []
        for name in names:
            inst, var = name.split(".", 1)
            row.append(observer.last_real_values(index[inst], [refs[inst][var]])[0])
        rows.append(row)
    values = np.array(rows)
    return {name: values[:, j] for j, name in enumerate(names)}
