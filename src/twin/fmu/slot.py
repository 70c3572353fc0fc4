"""One instantiated FMU for the master: a thin FMI 2.0 co-simulation binding.

The life cycle (instantiate, setup, initialization, terminate, free) goes through fmpy's
:class:`~fmpy.fmi2.FMU2Slave`; the calls made every step (set inputs, doStep, get outputs)
use the raw ctypes functions of the FMU's library (``FMU2Slave._functions``, typed at its
load), with value-reference and value buffers allocated once, because fmpy's convenience
wrappers allocate per call. :meth:`FMUSlot.native_handles` hands the same functions to
compiled code.
Every status other than fmi2OK/fmi2Warning raises :class:`~twin.errors.FMUError` naming the
instance, the FMI call and the simulation time.

The variables come from the catalog's reader (:func:`twin.fmu.catalog.describe`).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import shutil
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from fmpy.fmi2 import FMU2Slave

from twin.errors import ConfigError, FMUError, RunError
from twin.fmu import external
from twin.fmu.description import Description, Variable, describe
from twin.fmu.workdir import extraction_dir

_STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]

#: where each instance's log messages go, by instance name: (status, category, message) -> None
_SINKS: dict[str, Callable[[int, str, str], None]] = {}
_CALLBACKS: Any = None


def logging_callbacks(instance_name: str, sink: Callable[[int, str, str], None]) -> Any:
    """The fmi2CallbackFunctions to instantiate ``instance_name`` with; its messages go to ``sink``.

    Every FMU instance of the process must be instantiated with these (fmpy's logger proxy is
    process-global: a second registration would redirect, and after its owner is freed crash,
    every other instance's logging). :func:`forget_logging` removes the sink.
    """
    _SINKS[instance_name] = sink
    return _callbacks()


def forget_logging(instance_name: str) -> None:
    """Stop routing ``instance_name``'s messages (its messages then go to fmpy's default logger)."""
    _SINKS.pop(instance_name, None)


def _callbacks() -> Any:
    """One callbacks structure for every instance (fmpy's C logger proxy is process-global).

    The logger files each message under the instance that logged it, so an error can say
    why. This is the one adapter to fmpy's lower layer, because fmpy has no public API that
    passes an instance's formatted messages to Python: an FMU logs printf-style with varargs,
    which ctypes cannot receive, and only fmpy's native proxy (``fmpy.logging.addLoggerProxy``,
    what ``fmpy.simulation.instantiate_fmu`` itself uses) formats them first.
    ``instantiate_fmu`` cannot be used instead: it names every instance after its model.
    """
    global _CALLBACKS
    if _CALLBACKS is None:
        from fmpy import calloc, free
        from fmpy.fmi1 import printLogMessage
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        def logger(env: Any, instance: bytes, status: int, category: bytes, message: bytes) -> None:
            name = instance.decode(errors="replace") if instance else ""
            sink = _SINKS.get(name)
            if sink is None:
                # fmpy's proxy is process-global: messages of instances that are not ours
                # go where fmpy's default logger would send them
                printLogMessage(env, instance, status, category, message)
                return
            text = message.decode(errors="replace") if message else ""
            sink(int(status), category.decode(errors="replace") if category else "", text)

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(ctypes.byref(cb))
        _CALLBACKS = cb
    return _CALLBACKS


def _status_name(status: int) -> str:
    """``fmi2OK`` ... ``fmi2Pending``, as FMI names a status."""
    return f"fmi2{_STATUS[status]}" if 0 <= status < len(_STATUS) else f"status {status}"


class RealPort:
    """A fixed set of Real variables read or written in one FMI call through shared buffers."""

    def __init__(self, vrs: Sequence[int]) -> None:
        self.n = len(vrs)
        self.vr = (ctypes.c_uint * max(self.n, 1))(*vrs)
        # the values are a ctypes array seen by numpy: the array is what the FMI call is
        # passed (ctypes takes an array of doubles for a double pointer), without the pointer
        # object numpy's ``ctypes.data_as`` makes, which cost more than the rest of a port (a
        # Monte Carlo's copies make a dozen each)
        self.ptr = (ctypes.c_double * max(self.n, 1))()
        self.values = np.frombuffer(self.ptr, dtype=np.float64)


class _Kinds(NamedTuple):
    """Variables set together (:meth:`FMUSlot.set_values`), by type: the places of the Reals,
    Integers (and enumerations: FMI 2.0 sets them as integers) and Booleans among ``names``,
    with their value references."""

    names: tuple[str, ...]
    reals: list[int]
    port: RealPort  # the Reals' references; its values are set before each call
    ints: list[int]
    int_vrs: Any
    bools: list[int]
    bool_vrs: Any

    @classmethod
    def of(cls, variables: Mapping[str, Variable], names: tuple[str, ...]) -> _Kinds:
        reals: list[int] = []
        ints: list[int] = []
        bools: list[int] = []
        for j, name in enumerate(names):
            kind = variables[name].type
            if kind == "Boolean":
                bools.append(j)
            elif kind in ("Integer", "Enumeration"):
                ints.append(j)
            else:
                reals.append(j)

        def vrs(places: list[int]) -> Any:
            return (ctypes.c_uint * max(len(places), 1))(
                *[variables[names[j]].value_reference for j in places]
            )

        port = RealPort([variables[names[j]].value_reference for j in reals])
        return cls(names, reals, port, ints, vrs(ints), bools, vrs(bools))


class NativeHandles(NamedTuple):
    """Addresses for compiled code driving an instance: its component and three FMI calls."""

    component: int
    set_real: int
    get_real: int
    do_step: int


def file_key(path: Path) -> tuple[str, int, int]:
    """An FMU file's identity for this process's caches: resolved path, size, modification time."""
    st = os.stat(path)
    return str(Path(path).resolve()), st.st_size, st.st_mtime_ns


class Loaded(NamedTuple):
    """What an instance of an FMU file loads: its description, the folder fmpy is given as the
    unpacked FMU (its ``resources/`` are there, had it any), its library, and whether the FMU
    is from elsewhere (a library that does not load is then bad input)."""

    description: Description
    unzipdir: str
    library: str
    foreign: bool = False


@functools.cache
def _description(key: tuple[str, int, int]) -> Description:
    """One FMU file's description, read from its zip once per process."""
    return describe(Path(key[0]))


def _built_description(path: Path) -> Description:
    """The description of an FMU the twin built: its modelDescription.xml is its sources' own,
    byte for byte (:func:`twin.fmu.build.build_fmu` copies it), so while the file is the
    build of the current sources (its name carries their hash) the description the scenario's
    checks already read from the sources is the one in the zip, and the zip is not read again.
    A file :func:`twin.fmu.catalog.fmu` gave last as the build of a model's sources is that
    build (:func:`~twin.fmu.catalog.built_model`); any other's name is checked against the
    hash of the sources now."""
    from twin.fmu.build import source_hash
    from twin.fmu.catalog import built_model, description
    from twin.fmu.sources import model_names

    built = built_model(path)
    if built is not None:
        return description(built)
    name, _, digest = path.stem.rpartition("-")
    if name in model_names() and digest == source_hash(name):
        return description(name)
    return _description(file_key(path))


@functools.cache
def _unpacked(key: tuple[str, int, int]) -> external.Unpacked:
    """What an instance of an FMU from elsewhere loads, unpacked once per process
    (:func:`twin.fmu.external.unpack`: the library for this platform and the resources, from a
    copy whose SHA-256 is the checked one): every instance of it (a sweep's points on a
    worker) loads the same folder instead of reading and unpacking the zip again. The folder
    is private to this process (:func:`twin.fmu.workdir.process_dir`) and removed with it. A
    failure (a full disk) is not remembered, and leaves no folder: the next instance tries
    again."""
    path = Path(key[0])
    folder = Path(extraction_dir(f"{path.stem[:40]}-"))
    try:
        return external.unpack(path, folder)
    except OSError as exc:  # zipfile's error names no file
        shutil.rmtree(folder, ignore_errors=True)
        exc.filename = exc.filename or f"{folder} (the extracted {path.name})"
        raise
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


#: the FMUs the twin built whose library this process holds loaded now, by the FMU file's path:
#: what their instances loaded and how many of fmpy's loads of it are not freed yet
#: (:func:`_load_counted`); changed, with the loads and frees it counts, under the lock
_LIVE: dict[str, tuple[Loaded, int]] = {}
_LIVE_LOCK = threading.Lock()


def _load_counted(path: Path, name: str) -> tuple[FMU2SlaveTyped, Loaded, str | None]:
    """fmpy's binding of a new instance of the FMU at ``path`` (:func:`_load`), what it loaded,
    and the key its load is counted under (None: an FMU from elsewhere, unpacked as before).

    While a load of a built FMU's library is not freed, the next instance's load does not check
    the library again: loading a path that is loaded maps nothing new (the dynamic loader finds
    the library by its path among those loaded before it opens any file), so that instance runs
    the bytes checked at the first load. The look-up and the load are one step under the lock,
    as a free and its count are (:meth:`FMUSlot.close`), so no other thread's free unloads the
    library in between. A Monte Carlo opens about a hundred instances of five libraries; once
    every load is freed, the next one checks the file again."""
    key = str(path)
    with _LIVE_LOCK:
        live = _LIVE.get(key)
        if live is not None:
            slave = _load(path, live[0], name)
            _LIVE[key] = (live[0], live[1] + 1)
            return slave, live[0], key
    loaded = _loaded(path)  # checked (or built, taken out) outside the lock
    slave = _load(path, loaded, name)
    if loaded.foreign:
        return slave, loaded, None
    with _LIVE_LOCK:
        count = _LIVE[key][1] if key in _LIVE else 0
        _LIVE[key] = (loaded, count + 1)
    return slave, loaded, key


def _free_counted(slave: FMU2SlaveTyped, key: str | None) -> None:
    """``slave.freeInstance()`` (which unloads its library when no other load holds it), and
    for a counted load (:func:`_load_counted`) its count taken back in the same step; never
    raises (a free that failed is taken back too: the next load then checks the file)."""
    if key is None:
        with contextlib.suppress(Exception):
            slave.freeInstance()
        return
    with _LIVE_LOCK:
        with contextlib.suppress(Exception):
            slave.freeInstance()
        loaded, count = _LIVE[key]
        if count > 1:
            _LIVE[key] = (loaded, count - 1)
        else:
            del _LIVE[key]


def _loaded(path: Path) -> Loaded:
    """What an instance of the FMU at ``path`` loads. An FMU the twin built
    (:func:`twin.fmu.catalog.fmu` has just verified it) loads its library from the cache, where
    it was taken out once and is checked against its recorded SHA-256 each time it is loaded
    (:func:`twin.fmu.build.built_library`): fmpy unloads a library when its last instance is
    freed, so the next instance opens the file anew (while one holds it loaded,
    :func:`_load_counted` does not ask again). Any other FMU is unpacked
    (:func:`twin.fmu.external.unpack`)."""
    from twin.fmu.build import built_library

    library = built_library(path)
    if library is not None:
        return Loaded(_built_description(path), str(library.parent), str(library))
    key = file_key(path)
    unpacked = _unpacked(key)  # the description, as the library, is that of the bytes checked
    return Loaded(external.check(path).description, str(unpacked.folder), str(unpacked.library), foreign=True)


#: a code object's flags for ``*args`` and ``**kwargs`` (inspect.CO_VARARGS, CO_VARKEYWORDS)
_VARARGS = 0x04 | 0x08


def fmi2_prototypes() -> dict[str, tuple[Any, Any, Any]] | None:
    """What fmpy's loader gives each FMI 2.0 function, name -> (argnames, argtypes, restype),
    read from its ``fmi2*`` methods' annotations without ``inspect``: the same rules (the
    parameters after ``self`` in order, a union's first type, ``int`` and ``bytes`` returned
    as ``c_int`` and ``c_char_p``) without fmpy's signature objects, which were most of a
    fresh process's first instance's load. None when a method is not one these rules read as
    fmpy does (an argument of another kind, a missing or textual annotation, a wrapped
    function): fmpy's own loader then types the first instance
    (``tests/fmus/test_fresh_setup.py`` compares both)."""
    import types
    import typing

    out: dict[str, tuple[Any, Any, Any]] = {}
    for name in sorted(dir(FMU2Slave)):
        if not name.startswith("fmi2"):
            continue
        fn = getattr(FMU2Slave, name)
        code = getattr(fn, "__code__", None)
        if not isinstance(fn, types.FunctionType) or code is None or hasattr(fn, "__wrapped__"):
            return None
        if code.co_flags & _VARARGS or code.co_kwonlyargcount or code.co_posonlyargcount:
            return None
        names = list(code.co_varnames[1 : code.co_argcount])
        annotations = fn.__annotations__
        if any(n not in annotations or isinstance(annotations[n], str) for n in [*names, "return"]):
            return None
        argtypes = [
            typing.get_args(annotations[n])[0]
            if isinstance(annotations[n], types.UnionType)
            else annotations[n]
            for n in names
        ]
        restype = annotations["return"]
        restype = ctypes.c_char_p if restype is bytes else ctypes.c_int if restype is int else restype
        out[name] = (names, argtypes, restype)
    return out or None


class FMU2SlaveTyped(FMU2Slave):
    """fmpy's FMU2Slave, with the prototypes of the FMI functions worked out once per process.

    fmpy types each function of a loaded library from its own method's signature
    (``inspect.signature`` of 34 methods, for every instance). The prototypes are the same for every FMI 2.0 library, so after the
    first instance has run fmpy's own loader, the next ones get its result: the same
    argtypes, restype and argnames on each function of their own library. A library without
    one of the functions fails as in fmpy, with AttributeError. (The name starts with
    ``FMU2``: fmpy's loader picks the functions to type by the class's name.)
    """

    #: name -> (argnames, argtypes, restype), from the first instance that fmpy typed
    _prototypes: dict[str, tuple[Any, Any, Any]] | None = None

    def _loadFunctions(self) -> None:  # fmpy's name for its loader
        if FMU2SlaveTyped._prototypes is None:
            FMU2SlaveTyped._prototypes = fmi2_prototypes()
        known = FMU2SlaveTyped._prototypes
        if known is None:
            super()._loadFunctions()
            if self._functions:  # an fmpy that keeps them elsewhere: keep its loader
                FMU2SlaveTyped._prototypes = {
                    name: (getattr(f, "argnames", None), f.argtypes, f.restype)
                    for name, f in self._functions.items()
                }
            return
        for name, (argnames, argtypes, restype) in known.items():
            # by item, not attribute: the library object does not keep it as an attribute too
            # (which costs as much as the rest); the typed functions are ``_functions``'
            c_fun = self.dll[name]
            c_fun.argnames, c_fun.argtypes, c_fun.restype = argnames, argtypes, restype
            self._functions[name] = c_fun


def _load(fmu_path: Path, loaded: Loaded, name: str) -> FMU2SlaveTyped:
    """fmpy's binding of ``library``, loaded. A library the loader or fmpy refuses (a missing
    dependency, a missing function: :mod:`twin.fmu.library` checked its headers before) is one
    line naming the FMU file, a :class:`ConfigError` for an FMU from elsewhere (bad input) and a
    :class:`RunError` for one the twin built. fmpy changes the working folder to the library's
    while it loads and leaves it there when the load fails: it is put back."""
    cwd = os.getcwd()
    try:
        return FMU2SlaveTyped(
            guid=loaded.description.guid,
            unzipDirectory=loaded.unzipdir,
            modelIdentifier=loaded.description.model_identifier,
            instanceName=name,
            libraryPath=loaded.library,
        )
    except Exception as exc:  # fmpy raises Exception and AttributeError for a library it cannot bind
        why = " ".join(str(exc).split()).replace(f"Failed to load shared library {loaded.library}. ", "")
        if isinstance(exc, AttributeError):
            why = f"a function is missing ({why})"
        why = why[:300]
        if loaded.foreign:
            raise ConfigError(f"cannot load its library: {why}", source=str(fmu_path)) from None
        raise RunError(f"{fmu_path}: cannot load its library: {why}") from None
    finally:
        if os.getcwd() != cwd:
            os.chdir(cwd)


class FMUSlot:
    """An FMU instance with name-based setup and buffer-based stepping.

    ``messages`` collects what the FMU logged (its reasons for errors end up in FMUError).
    With a ``log`` the instance is made with its debug logging on (``loggingOn``, as fmpy's
    ``--debug-logging`` does) and ``log(instance, status, category, message)`` receives every
    message as well (``twin run --fmi-logging``).
    """

    def __init__(
        self, fmu_path: Path, instance_name: str, log: Callable[[str, str, str, str], None] | None = None
    ) -> None:
        self.name = instance_name
        self.messages: list[str] = []
        self._log = log
        self.time = 0.0
        # its load counted until close frees it (an instance that fails to instantiate is never
        # freed: its load, and so its library, stay, counted)
        self._slave, loaded, self._live_key = _load_counted(Path(fmu_path), instance_name)
        self.description, self.unzipdir, self.library = loaded.description, loaded.unzipdir, loaded.library
        self.variables: Mapping[str, Variable] = self.description.variables
        self._slave.instantiate(callbacks=self._make_callbacks(), loggingOn=log is not None)
        # the FMU library's functions as typed when it was loaded (never the library object's
        # attributes: an attribute not typed there would be a function without a prototype)
        self._fns = fns = self._slave._functions
        self._set_real = fns["fmi2SetReal"]
        self._get_real = fns["fmi2GetReal"]
        self._do_step = fns["fmi2DoStep"]
        self._c = self._slave.component
        self._handles: NativeHandles | None = None
        self._kinds: _Kinds | None = None  # the names set last (set_values)
        self.pool_key: Any = None  # set by the SlotPool that made it (twin.fmu.pool)
        self._initialized = False  # fmi2Terminate is allowed only after initialization

    def native_handles(self) -> NativeHandles:
        """The component pointer and the fmi2SetReal/fmi2GetReal/fmi2DoStep addresses, as ints
        (worked out once: they are the instance's for its life, a reset one's too, and a
        pooled instance is handed to many runs)."""
        if self._handles is None:

            def address(fn: Any) -> int:
                return int(ctypes.cast(fn, ctypes.c_void_p).value or 0)

            self._handles = NativeHandles(
                int(self._c or 0), address(self._set_real), address(self._get_real), address(self._do_step)
            )
        return self._handles

    # -- logging: keep the FMU's messages so an error can say why ---------------------------

    def _make_callbacks(self) -> Any:
        def keep(status: int, category: str, message: str) -> None:
            self.messages.append(message)
            del self.messages[:-20]  # the last few say why a call failed
            if self._log is not None:
                self._log(self.name, _status_name(status), category, message)

        return logging_callbacks(self.name, keep)

    def error(self, call: str, status: int) -> FMUError:
        """The :class:`FMUError` for ``call`` returning ``status``, with the FMU's last message."""
        why = (
            self.messages[-1] if self.messages else f"status fmi2{_STATUS[status] if status < 6 else status}"
        )
        return FMUError(self.name, call, self.time, why)

    # -- set-up ------------------------------------------------------------------------------

    def vr(self, name: str) -> int:
        """The value reference of variable ``name``."""
        return self.variables[name].value_reference

    # The calls of every run's set-up go to the library's functions (typed by fmpy) directly,
    # as the hot path's do: fmpy's wrappers add only their call logger, which the twin never
    # gives them, and a Monte Carlo makes a dozen of these calls per sample.

    def _check(self, call: str, status: int) -> None:
        if status > 1:  # fmi2OK and fmi2Warning go on, as in fmpy
            raise self.error(call, status)

    def setup(self, start_time: float = 0.0) -> None:
        """fmi2SetupExperiment at ``start_time``, no tolerance, no stop time (as fmpy's
        ``setupExperiment(startTime=...)``)."""
        self.time = start_time
        self._check(
            "fmi2SetupExperiment", self._fns["fmi2SetupExperiment"](self._c, 0, 0.0, start_time, 0, 0.0)
        )

    def enter_initialization(self) -> None:
        self._check("fmi2EnterInitializationMode", self._fns["fmi2EnterInitializationMode"](self._c))

    def exit_initialization(self) -> None:
        self._check("fmi2ExitInitializationMode", self._fns["fmi2ExitInitializationMode"](self._c))
        self._initialized = True

    def set_values(self, items: Sequence[tuple[str, float | int | bool]]) -> None:
        """Set many variables: the Reals in one fmi2SetReal, the Integers (and enumerations) in
        one fmi2SetInteger, the Booleans in one fmi2SetBoolean (an instance's parameters: a
        hundred calls were most of its set-up). The FMU checks the whole request and names the
        variable it refuses, as it does for one.

        Which names are of which type, and their value references, are worked out once for
        the names set last: a pooled instance is given the same parameters, other values, by
        every run of a Monte Carlo."""
        names = tuple(name for name, _ in items)
        kinds = self._kinds if self._kinds is not None and self._kinds.names == names else None
        if kinds is None:
            kinds = self._kinds = _Kinds.of(self.variables, names)
        values = [value for _, value in items]
        if kinds.reals:
            port = kinds.port
            port.values[: port.n] = [float(values[j]) for j in kinds.reals]
            self.write(port)
        if kinds.ints:
            n = len(kinds.ints)
            ints = (ctypes.c_int * n)(*[int(values[j]) for j in kinds.ints])
            self._check("fmi2SetInteger", self._fns["fmi2SetInteger"](self._c, kinds.int_vrs, n, ints))
        if kinds.bools:
            n = len(kinds.bools)
            bools = (ctypes.c_int * n)(*[bool(values[j]) for j in kinds.bools])
            self._check("fmi2SetBoolean", self._fns["fmi2SetBoolean"](self._c, kinds.bool_vrs, n, bools))

    def set_value(self, name: str, value: float | int | bool) -> None:
        v = self.variables[name]
        vr = [v.value_reference]
        if v.type == "Boolean":
            self._call("fmi2SetBoolean", lambda: self._slave.setBoolean(vr, [bool(value)]))
        elif v.type in ("Integer", "Enumeration"):  # FMI 2.0 sets an enumeration as an integer
            self._call("fmi2SetInteger", lambda: self._slave.setInteger(vr, [int(value)]))
        else:
            self._call("fmi2SetReal", lambda: self._slave.setReal(vr, [float(value)]))

    def _call(self, call: str, fn: Any) -> Any:
        from fmpy.fmi1 import FMICallException

        try:
            return fn()
        except FMICallException as exc:
            raise self.error(call, exc.status) from None

    # -- the hot path: preallocated buffers, raw calls ------------------------------------------

    def port(self, names: Sequence[str]) -> RealPort:
        return RealPort([self.vr(n) for n in names])

    def write(self, port: RealPort) -> None:
        if port.n:
            status = self._set_real(self._c, port.vr, port.n, port.ptr)
            if status > 1:
                raise self.error("fmi2SetReal", status)

    def read(self, port: RealPort) -> None:
        if port.n:
            status = self._get_real(self._c, port.vr, port.n, port.ptr)
            if status > 1:
                raise self.error("fmi2GetReal", status)

    def do_step(self, t: float, h: float) -> None:
        self.time = t
        status = self._do_step(self._c, t, h, 1)
        if status > 1:
            raise self.error("fmi2DoStep", status)
        self.time = t + h

    # -- FMU state -------------------------------------------------------------------------------

    def save_state(self) -> bytes:
        """The FMU's serialized state (for whole-twin checkpoints)."""
        state = self._call("fmi2GetFMUstate", self._slave.getFMUstate)
        try:
            return bytes(self._call("fmi2SerializeFMUstate", lambda: self._slave.serializeFMUstate(state)))
        finally:
            self._slave.freeFMUstate(state)

    def restore_state(self, data: bytes) -> None:
        state = self._call("fmi2DeSerializeFMUstate", lambda: self._slave.deSerializeFMUstate(data))
        try:
            self._call("fmi2SetFMUstate", lambda: self._slave.setFMUstate(state))
        finally:
            self._slave.freeFMUstate(state)

    # -- reuse (twin.fmu.pool) ----------------------------------------------------------------------

    def reset(self) -> bool:
        """``fmi2Reset``: back to the state after instantiation, every variable at its start
        value. False when the FMU refuses (the caller then frees it)."""
        if self._fns["fmi2Reset"](self._c) > 1:
            return False
        self._initialized = False
        forget_logging(self.name)
        return True

    def reuse(self) -> None:
        """Take a reset instance into a new run: its own messages again, the clock at zero."""
        self.messages.clear()
        self.time = 0.0
        self._make_callbacks()  # routes this name's messages to this instance again

    # -- end -------------------------------------------------------------------------------------

    def close(self) -> None:
        """Terminate (if initialized) and free the instance; never raises."""
        if self._initialized:
            with contextlib.suppress(Exception):
                self._slave.terminate()
        key, self._live_key = self._live_key, None
        _free_counted(self._slave, key)
        forget_logging(self.name)
