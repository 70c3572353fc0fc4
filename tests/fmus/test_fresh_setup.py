"""A fresh process's first instances, set up with less work and the same result.

Their prototypes come from :func:`twin.fmu.slot.fmi2_prototypes` (read from fmpy's annotations)
instead of fmpy's loader (``inspect.signature`` of every method): both must give every
function the same argument names, argument types and result type, for a real library of the
twin's. The description of a file :func:`twin.fmu.catalog.fmu` has just given is the sources'
own without their hash worked out again; any other file's is checked as before.
"""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path

from fmpy.fmi2 import FMU2Slave

from twin.fmu import catalog
from twin.fmu.build import built_library
from twin.fmu.slot import FMUSlot, _built_description, fmi2_prototypes


def _fmpy_typed(library: Path) -> dict[str, tuple[object, object, object]]:
    """What fmpy's own loader gives each function of ``library``."""
    description = catalog.description("FixtureMechanics")
    slave = FMU2Slave(
        guid=description.guid,
        unzipDirectory=str(library.parent),
        modelIdentifier=description.model_identifier,
        instanceName="probe",
        libraryPath=str(library),
    )
    return {name: (f.argnames, f.argtypes, f.restype) for name, f in slave._functions.items()}


def test_the_annotations_give_every_function_fmpys_prototype() -> None:
    library = built_library(catalog.fmu("FixtureMechanics"))
    assert library is not None
    theirs = _fmpy_typed(library)
    ours = fmi2_prototypes()
    assert ours is not None, "fmpy's methods are no longer read by the annotations' rules"
    assert len(theirs) >= 30
    assert ours == theirs
    # the types that matter to a call: a real pointer for the values, an int status back
    names, argtypes, restype = ours["fmi2SetReal"]
    assert names == ["c", "vr", "nvr", "value"]
    assert argtypes[3] is ctypes.POINTER(ctypes.c_double)
    assert restype is ctypes.c_int


def test_an_instance_typed_by_the_annotations_runs_as_fmpy_typed_it() -> None:
    path = catalog.fmu("FixtureMechanics")
    slot = FMUSlot(path, "probe-typed")
    try:
        for name, (names, argtypes, restype) in fmi2_prototypes().items():  # type: ignore[union-attr]
            f = slot._slave._functions[name]
            assert (f.argnames, f.argtypes, f.restype) == (names, argtypes, restype), name
        slot.setup(0.0)
        slot.enter_initialization()
        slot.exit_initialization()
        slot.do_step(0.0, 0.01)  # typed arguments: a float time and step go through
        assert slot.time == 0.01
    finally:
        slot.close()


def test_the_build_the_catalog_gave_is_known_and_a_copy_of_it_is_not(tmp_path: Path) -> None:
    path = catalog.fmu("FixtureMechanics")
    assert catalog.built_model(path) == "FixtureMechanics"
    assert _built_description(path) is catalog.description("FixtureMechanics")
    # the same bytes elsewhere, under the build's name: not the file the catalog gave, so its
    # name is checked against the sources' hash (it matches) or its zip read (a stale name)
    copy = tmp_path / path.name
    shutil.copyfile(path, copy)
    assert catalog.built_model(copy) is None
    assert _built_description(copy) is catalog.description("FixtureMechanics")
    stale = tmp_path / "FixtureMechanics-0000000000000000.fmu"
    shutil.copyfile(path, stale)
    assert catalog.built_model(stale) is None
    assert _built_description(stale) == catalog.description("FixtureMechanics")  # its own zip's
