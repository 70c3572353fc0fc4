"""The one place every other package asks about an FMU: its variables and its file.

A model is one of the twin's own (a folder of ``fmus/``: :mod:`twin.fmu.sources`, built by
:mod:`twin.fmu.build`) or an FMU file a scenario names by path (:mod:`twin.fmu.external`,
whose name ends in ``.fmu``); either way :func:`variables` answers from its
``modelDescription.xml`` (:mod:`twin.fmu.description`, the one reader) and :func:`fmu`
returns the ``.fmu`` to load: built and cached on first use, or the external file hashed
again. :func:`roles` says which output of a model plays a part the twin reads by meaning
(the swing-cycle counter, a body's true displacement), so no other package names a model.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from pathlib import Path

from twin.errors import ConfigError, did_you_mean
from twin.fmu import external
from twin.fmu.build import ensure_fmu
from twin.fmu.description import Description, Variable, describe
from twin.fmu.sources import SOURCES_ENV, Model, model, model_names, shipped_folder, sources_dir

__all__ = [
    "SOURCES_ENV",
    "Description",
    "Model",
    "Variable",
    "built_model",
    "describe",
    "fmu",
    "inspectable",
    "model",
    "model_names",
    "roles",
    "shipped_folder",
    "sources_dir",
    "variables",
]


def description(name: str) -> Description:
    """The description of model ``name`` (no build needed); an external FMU's from its file."""
    if external.is_external(name):
        return external.check(name).description
    return _description(name, sources_dir())


@cache  # every connection, parameter and input check asks (a sweep's client, once per point)
def _description(name: str, src: Path) -> Description:
    return model(name, src).description


def variables(name: str) -> Mapping[str, Variable]:
    """The variables of model ``name`` by name, from its modelDescription.xml."""
    return description(name).variables


def roles(name: str) -> Mapping[str, str]:
    """What model ``name``'s variables mean to the twin: role -> variable name (the
    ``io.github.twin`` annotation of its modelDescription.xml; none for most FMUs)."""
    return description(name).roles


def inspectable(target: str) -> Description:
    """The description ``twin inspect`` lists: an FMU file's, or a model of the twin's by name."""
    path = Path(target)
    if not path.exists() and path.suffix != ".fmu" and len(path.parts) == 1:
        names = model_names()
        if target not in names:
            raise ConfigError(
                f"no FMU file or model named {target!r}{did_you_mean(target, names)}", source="inspect"
            )
        return description(target)
    return describe(path)


def fmu(name: str) -> Path:
    """Path of an up-to-date ``.fmu`` of model ``name`` (built and cached on first use); an
    external FMU's own file, hashed again (it must be the file that was checked)."""
    if external.is_external(name):
        return external.verified_path(name)
    path = ensure_fmu(name)
    _BUILDS[name] = path
    return path


#: the .fmu :func:`fmu` gave last for each model of the twin's: the build of its sources then
_BUILDS: dict[str, Path] = {}


def built_model(path: Path) -> str | None:
    """The model of the twin's whose build :func:`fmu` gave last as ``path`` (None: it gave
    another file, or none in this process). An instance of it loads the description the
    sources give (:func:`description`) without the sources' hash worked out again, moments
    after :func:`fmu` worked it out to name the file."""
    name = Path(path).stem.rpartition("-")[0]
    return name if _BUILDS.get(name) == Path(path) else None
