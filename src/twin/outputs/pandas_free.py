"""rerun's conversions to Arrow without importing pandas (:func:`without_pandas`).

rerun converts a recording's names, values and blueprint with ``pyarrow.array`` from Python
lists and numpy arrays, and pyarrow, the first time it converts one, imports pandas only to
ask whether the object is pandas' (its lazy "pandas shim"; its C++ converter asks again on
each conversion from a list until pandas has loaded). Importing pandas is a sizeable part of
a short run's time, and the twin hands rerun no pandas object. So while a recording is
written, this thread's ``import pandas`` is refused: pyarrow takes pandas for missing and
converts the same lists and arrays to the same arrays.

pyarrow's shim remembers that look: until told otherwise it would treat pandas objects as
plain sequences (a categorical column written to Parquet as strings, a time zone lost). So the
first real ``import pandas`` of the process (another thread's, or any after the recording)
tells pyarrow once pandas has loaded (:class:`_Watch`), and from then on pyarrow works with
pandas as it always did. Nothing changes in a process where pandas was imported already.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from types import ModuleType
from typing import Any

__all__ = ["without_pandas"]

_PANDAS = "pandas"
#: the threads refusing pandas now (their ids), and the one watch on pandas' import
_refusing: set[int] = set()
_lock = threading.Lock()


@contextmanager
def without_pandas() -> Iterator[None]:
    """Within the block, this thread's ``import pandas`` fails as if pandas were not installed
    (see the module); a no-op where pandas is loaded already."""
    if _PANDAS in sys.modules:
        yield
        return
    me = threading.get_ident()
    with _lock:
        if not any(isinstance(f, _Watch) for f in sys.meta_path):
            sys.meta_path.insert(0, _Watch())
        _refusing.add(me)
    try:
        yield
    finally:
        with _lock:
            _refusing.discard(me)


class _Watch(importlib.abc.MetaPathFinder):
    """Refuses pandas to the threads in :data:`_refusing`; for any other, finds pandas as the
    other finders do and tells pyarrow once it has loaded (then leaves ``sys.meta_path``)."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname != _PANDAS:
            return None
        if threading.get_ident() in _refusing:
            raise ModuleNotFoundError("pandas is not imported while a recording is written", name=fullname)
        with _lock:
            if self in sys.meta_path:
                sys.meta_path.remove(self)
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            spec = find(fullname, path, target) if find is not None else None
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _TellsPyarrow(spec.loader)
                return spec
        return None


class _TellsPyarrow(importlib.abc.Loader):
    """pandas' own loader, which then asks pyarrow for pandas: the shim, having found none
    before, imports it (loaded now) and uses it from then on."""

    def __init__(self, loader: Any) -> None:
        self.loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self.loader.create_module(spec)  # type: ignore[no-any-return]

    def exec_module(self, module: ModuleType) -> None:
        self.loader.exec_module(module)
        module.__loader__ = module.__spec__.loader = self.loader  # pandas as if found plainly
        if "pyarrow" in sys.modules:
            _ = sys.modules["pyarrow"].lib._pandas_api.pd  # the shim's look that imports, and keeps

    def __getattr__(self, name: str) -> Any:  # the rest of the loader's interface (resources)
        return getattr(self.loader, name)
